//! Manifolds for parameter blocks that are not plain vectors: the update x ⊞ δ of a block with
//! `ambient_size` stored values by a `tangent_size` step δ (Absil, Mahony, Sepulchre,
//! "Optimization Algorithms on Matrix Manifolds", 2008, chapter 4: retractions).
//!
//! Cost functions return Jacobians with respect to the tangent step,
//! ∂r(x ⊞ δ)/∂δ at δ = 0, so a block on a manifold contributes `tangent_size` columns.
//!
//! Built-in manifolds:
//! - [`Se3Manifold`]: a rigid motion stored as `[qw, qx, qy, qz, tx, ty, tz]` (unit quaternion
//!   first, `[w, x, y, z]` order), updated on the right, T ⊞ δ = T · Exp(δ) with
//!   δ = `[ρ, φ]` (translation part first, Barfoot, "State Estimation for Robotics", 2017,
//!   section 7.1.9). [`Se3Manifold::params`] and [`Se3Manifold::pose`] convert between a
//!   pose and its block.
//! - [`UnitQuaternionManifold`]: a rotation `[w, x, y, z]`, q ⊞ φ = q ⊗ Exp(φ);
//!   [`UnitQuaternionManifold::params`] and [`UnitQuaternionManifold::rotation`] convert.
//!
//! The Lie-group maths behind them (Exp of so(3) and se(3), the left Jacobian of SO(3)) is
//! internal; for the cross-product matrix `[v]×` of a Jacobian use nalgebra's
//! `Vector3::cross_matrix`, and for Exp(φ) `UnitQuaternion::from_scaled_axis`.

use nalgebra::{Isometry3, Matrix3, Matrix3x2, Quaternion, Translation3, UnitQuaternion, Vector3};

/// A manifold on which a parameter block lives.
pub trait Manifold: Send + Sync + core::fmt::Debug {
    /// Number of stored values.
    fn ambient_size(&self) -> usize;
    /// Dimension of the tangent space (the step size the solver works with).
    fn tangent_size(&self) -> usize;
    /// Writes x ⊞ δ into `x_plus_delta`; slices have the ambient, tangent and ambient sizes.
    fn plus(&self, x: &[f64], delta: &[f64], x_plus_delta: &mut [f64]);
}

/// SE(3) stored as `[qw, qx, qy, qz, tx, ty, tz]`, updated by right multiplication with the
/// exponential of δ = `[ρ, φ]`: T ⊞ δ = T · Exp(δ), translation part ρ first.
///
/// For the pose `a_from_b` and a point p_b, ∂(T ⊞ δ)(p_b)/∂δ at δ = 0 is
/// `R · [I₃, −[p_b]×]`: the right-perturbation Jacobian cost functions supply. A cost
/// function reads its pose with [`Se3Manifold::pose`]; a block is made from a pose with
/// [`Se3Manifold::params`].
///
/// ```
/// use ibc_bundle_adjust::nalgebra::{Isometry3, Point3, Vector3};
/// use ibc_bundle_adjust::{Problem, Se3Manifold};
///
/// let camera_from_world = Isometry3::new(Vector3::new(0.1, 0.2, 3.0), Vector3::y() * 0.3);
/// let mut problem = Problem::new();
/// let params = Se3Manifold::params(&camera_from_world);
/// let block = problem.add_manifold_block(&params, Se3Manifold)?;
/// // In a cost function: the pose, and d(T Exp(δ) p)/dδ = R [I, −[p]×] for δ = [ρ, φ].
/// let Some(pose) = Se3Manifold::pose(problem.parameter_block(block)?) else { unreachable!() };
/// let p = Point3::new(1.0, -1.0, 2.0);
/// let r = pose.rotation.to_rotation_matrix().into_inner();
/// let d_rotation = -r * p.coords.cross_matrix();
/// assert!((pose * p - camera_from_world * p).norm() < 1e-15);
/// assert_eq!(d_rotation, -r * Vector3::new(1.0, -1.0, 2.0).cross_matrix());
/// # Ok::<(), ibc_bundle_adjust::BundleAdjustError>(())
/// ```
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Se3Manifold;

impl Se3Manifold {
    /// The seven stored values `[qw, qx, qy, qz, tx, ty, tz]` of a pose: the block of a pose
    /// parameter.
    #[inline]
    #[must_use]
    pub fn params(pose: &Isometry3<f64>) -> [f64; 7] {
        se3_to_params(pose)
    }

    /// The pose stored in a block `[qw, qx, qy, qz, tx, ty, tz]` (the first seven values of
    /// `params`), or `None` when `params` holds fewer than seven values. The quaternion is
    /// normalized; a zero quaternion gives the identity rotation.
    #[inline]
    #[must_use]
    pub fn pose(params: &[f64]) -> Option<Isometry3<f64>> {
        (params.len() >= 7).then(|| se3_from_params(params))
    }
}

/// A unit quaternion stored as `[w, x, y, z]`, updated on the right as q ⊞ φ = q ⊗ Exp(φ)
/// with a 3-vector φ (the rotation vector of the step, in the rotated frame).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UnitQuaternionManifold;

impl UnitQuaternionManifold {
    /// The four stored values `[w, x, y, z]` of a rotation.
    #[inline]
    #[must_use]
    pub fn params(rotation: &UnitQuaternion<f64>) -> [f64; 4] {
        [rotation.w, rotation.i, rotation.j, rotation.k]
    }

    /// The rotation stored in a block `[w, x, y, z]` (the first four values of `params`), or
    /// `None` when `params` holds fewer than four values. The quaternion is normalized; a zero
    /// quaternion gives the identity.
    #[inline]
    #[must_use]
    pub fn rotation(params: &[f64]) -> Option<UnitQuaternion<f64>> {
        (params.len() >= 4).then(|| quaternion_from_params(params))
    }
}

impl Manifold for Se3Manifold {
    fn ambient_size(&self) -> usize {
        7
    }
    fn tangent_size(&self) -> usize {
        6
    }
    fn plus(&self, x: &[f64], delta: &[f64], x_plus_delta: &mut [f64]) {
        let pose = se3_from_params(x);
        let step = se3_exp(
            &Vector3::new(delta[0], delta[1], delta[2]),
            &Vector3::new(delta[3], delta[4], delta[5]),
        );
        let mut out = pose * step;
        // Keep the stored quaternion unit despite rounding, so readers may skip normalizing.
        out.rotation.renormalize();
        x_plus_delta.copy_from_slice(&se3_to_params(&out));
    }
}

impl Manifold for UnitQuaternionManifold {
    fn ambient_size(&self) -> usize {
        4
    }
    fn tangent_size(&self) -> usize {
        3
    }
    fn plus(&self, x: &[f64], delta: &[f64], x_plus_delta: &mut [f64]) {
        let q = quaternion_from_params(x);
        let step = so3_exp(&Vector3::new(delta[0], delta[1], delta[2]));
        let mut out = q * step;
        out.renormalize();
        x_plus_delta.copy_from_slice(&[out.w, out.i, out.j, out.k]);
    }
}

/// The seven stored values `[qw, qx, qy, qz, tx, ty, tz]` of a pose.
#[inline]
pub(crate) fn se3_to_params(pose: &Isometry3<f64>) -> [f64; 7] {
    let q = pose.rotation;
    let t = pose.translation.vector;
    [q.w, q.i, q.j, q.k, t.x, t.y, t.z]
}

/// The pose stored as `[qw, qx, qy, qz, tx, ty, tz]`; the quaternion is normalized (a zero
/// quaternion gives the identity rotation). `params` must hold at least seven values.
#[inline]
#[must_use]
pub(crate) fn se3_from_params(params: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(params[4], params[5], params[6]),
        quaternion_from_params(params),
    )
}

/// The pose stored as `[qw, qx, qy, qz, tx, ty, tz]` whose quaternion is already unit (as
/// [`Se3Manifold`] keeps it), without normalizing.
#[inline]
pub(crate) fn se3_from_unit_params(params: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(params[4], params[5], params[6]),
        UnitQuaternion::new_unchecked(Quaternion::new(params[0], params[1], params[2], params[3])),
    )
}

/// The unit quaternion stored as `[w, x, y, z]` (normalized; zero gives the identity).
#[inline]
#[must_use]
pub(crate) fn quaternion_from_params(params: &[f64]) -> UnitQuaternion<f64> {
    let q = Quaternion::new(params[0], params[1], params[2], params[3]);
    UnitQuaternion::try_new(q, 0.0).unwrap_or_else(UnitQuaternion::identity)
}

/// An orthonormal basis (3 × 2) of the plane orthogonal to the unit vector `u`, a
/// deterministic function of `u` (a manifold that moves a point on a sphere and the cost
/// functions that differentiate through it must agree on it): the sphere's tangent basis.
#[inline]
#[must_use]
pub(crate) fn sphere_tangent_basis(u: &Vector3<f64>) -> Matrix3x2<f64> {
    let a = if u.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let b1 = a.cross(u).normalize();
    let b2 = u.cross(&b1);
    Matrix3x2::from_columns(&[b1, b2])
}

/// Exp of so(3): the rotation by angle |φ| about φ/|φ|.
#[inline]
#[must_use]
pub(crate) fn so3_exp(phi: &Vector3<f64>) -> UnitQuaternion<f64> {
    let theta2 = phi.norm_squared();
    let theta = theta2.sqrt();
    // sin(θ/2)/θ, by its Taylor series below 1e-4 rad where the division loses digits.
    let (c, s) = if theta < 1e-4 {
        (1.0 - theta2 / 8.0, 0.5 - theta2 / 48.0)
    } else {
        let (sin, cos) = (0.5 * theta).sin_cos();
        (cos, sin / theta)
    };
    UnitQuaternion::new_unchecked(Quaternion::new(c, s * phi.x, s * phi.y, s * phi.z))
}

/// The left Jacobian of SO(3),
/// `J_l(φ) = I + (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×²`, θ = |φ|.
#[inline]
#[must_use]
pub(crate) fn so3_left_jacobian(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta2 = phi.norm_squared();
    let k = skew(phi);
    let (a, b) = if theta2 < 1e-8 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        let theta = theta2.sqrt();
        let (sin, cos) = theta.sin_cos();
        ((1.0 - cos) / theta2, (theta - sin) / (theta2 * theta))
    };
    Matrix3::identity() + k * a + k * k * b
}

/// Exp of se(3) for δ = `[ρ, φ]`: rotation Exp(φ), translation J_l(φ) ρ.
#[inline]
#[must_use]
pub(crate) fn se3_exp(rho: &Vector3<f64>, phi: &Vector3<f64>) -> Isometry3<f64> {
    let t = so3_left_jacobian(phi) * rho;
    Isometry3::from_parts(Translation3::from(t), so3_exp(phi))
}

/// The cross-product matrix `[v]×`, with `[v]× w = v × w`.
#[inline]
#[must_use]
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn se3_plus_zero_is_identity() {
        let pose = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.3, -0.2, 0.9));
        let x = se3_to_params(&pose);
        let mut out = [0.0; 7];
        Se3Manifold.plus(&x, &[0.0; 6], &mut out);
        for (a, b) in x.iter().zip(out.iter()) {
            assert_relative_eq!(a, b, epsilon = 1e-15);
        }
    }

    /// The documented right-perturbation Jacobian R [I, −[p]×] matches finite differences of
    /// the retraction.
    #[test]
    fn se3_right_perturbation_jacobian() {
        let pose = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.3, -0.2, 0.9));
        let p = nalgebra::Point3::new(0.4, 1.1, -2.0);
        let x = se3_to_params(&pose);
        let r = pose.rotation.to_rotation_matrix().into_inner();
        let mut analytic = nalgebra::Matrix3x6::zeros();
        analytic.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        analytic
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&(-r * skew(&p.coords)));
        let h = 1e-7;
        for k in 0..6 {
            let mut d = [0.0; 6];
            d[k] = h;
            let mut plus = [0.0; 7];
            Se3Manifold.plus(&x, &d, &mut plus);
            d[k] = -h;
            let mut minus = [0.0; 7];
            Se3Manifold.plus(&x, &d, &mut minus);
            let fd = (se3_from_params(&plus) * p - se3_from_params(&minus) * p) / (2.0 * h);
            for row in 0..3 {
                assert_relative_eq!(fd[row], analytic[(row, k)], epsilon = 1e-7);
            }
        }
    }

    #[test]
    fn quaternion_plus_matches_composition() {
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.2, 0.1, -0.4));
        let phi = Vector3::new(0.01, -0.03, 0.02);
        let mut out = [0.0; 4];
        UnitQuaternionManifold.plus(&[q.w, q.i, q.j, q.k], phi.as_slice(), &mut out);
        let expected = q * UnitQuaternion::from_scaled_axis(phi);
        assert_relative_eq!(quaternion_from_params(&out), expected, epsilon = 1e-14);
    }

    #[test]
    fn left_jacobian_series_is_continuous() {
        let phi = Vector3::new(0.6e-4, -0.5e-4, 0.4e-4);
        let big = phi * 1.0001;
        assert_relative_eq!(
            so3_left_jacobian(&phi),
            so3_left_jacobian(&big),
            epsilon = 1e-8
        );
        let exp = so3_exp(&Vector3::new(0.5e-4, 0.2e-4, 0.0));
        let reference = UnitQuaternion::from_scaled_axis(Vector3::new(0.5e-4, 0.2e-4, 0.0));
        assert_relative_eq!(exp, reference, epsilon = 1e-15);
    }
}
