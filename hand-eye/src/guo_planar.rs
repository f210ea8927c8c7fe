//! Hand-eye calibration for planar motion of sensor `b` (a ground vehicle's odometry).
//!
//! C. X. Guo, F. M. Mirzaei, S. I. Roumeliotis, "An analytical least-squares solution to the
//! odometer-camera extrinsic calibration problem", IEEE ICRA 2012, pp. 3962-3968.
//!
//! Sensor `b` moves in the `xy` plane of its frame: `B_i` rotates by `θ_i` about `z` and
//! translates in `xy`. The method works on `Y = X⁻¹ = b_from_a`, for which
//! `B_i Y = Y A_i`, and splits `R_Y = R_z(γ) R₀`:
//!
//! 1. **Roll and pitch.** `R_z(γ)` commutes with `R_Bi`, so `q_Bi ⊗ q₀ = q₀ ⊗ q_Ai`, i.e.
//!    `(L(q_Bi) - R(q_Ai)) q₀ = 0` with sign-aligned quaternions (`L`, `R` the left and right
//!    multiplication matrices). The stacked `4m × 4` system has a two-dimensional null space,
//!    `{q_z(φ) ⊗ q₀}`; the representative is the unit combination of the last two right
//!    singular vectors on which a quadratic constraint vanishes. Left multiplication by the
//!    unit quaternion `k` commutes with `L(q_Bi)` (both are rotations about `z`) and with every
//!    `R(q_Ai)`, so the normal matrix commutes with it: its eigenvalues come in pairs and the
//!    computed null space has the form `span(v, k ⊗ v)` even with noise. On such a circle the
//!    constraint below always changes sign, so its discriminant is positive (the
//!    [`HandEyeError::NegativeDiscriminant`] check stays as a guard). Guo et al. ask for zero yaw
//!    (`2(xy + wz) = 0`: the `x` axis of `a` mapped into the `xz` plane of `b`), which
//!    degenerates when that axis is vertical; this implementation constrains whichever axis of
//!    frame `a` is closest to the plane, which is Guo's constraint when that axis is `x`, and
//!    keeps the discriminant away from zero for any mounting.
//! 2. **Yaw, in-plane translation, scale.** With `p_i = R₀ t_Ai`, the `x`, `y` rows of
//!    `(R_Bi - I) t_Y = s R_z(γ) p_i - t_Bi` are linear in `(t_x, t_y, s cos γ, s sin γ)`:
//!
//!    ```text
//!    (R₂(θ_i) - I) [t_x t_y]ᵀ - [p_x -p_y; p_y p_x] s [cos γ  sin γ]ᵀ = -t_Bi,xy
//!    ```
//!
//!    With an unknown scale `s` of the translations of `a` this is linear least squares in four
//!    unknowns. With `s = 1` the translation is eliminated and `|y| = 1` (`y = (cos γ, sin γ)`)
//!    is imposed with a Lagrange multiplier `λ`: `(W - λI) y = g`, whose condition `|y|² = 1`
//!    is Guo's quartic in `λ`. Its root at the global minimum is the one below the smallest
//!    eigenvalue of `W` (the trust-region secular equation), found by bisection on that bracket.
//! 3. **Height.** The `z` row reads `0 = (R_Y t_Ai)_z`: nothing determines `t_Y,z`, the height of
//!    the origin of `a` above the plane of `b`. It is set to the caller's prior, or to zero and
//!    reported as [`Height::Unobservable`].
//!
//! Step 1 uses the screened motions (quaternion signs); step 2 uses every motion, since straight
//! driving (no rotation) fixes the yaw well. The optional refinement minimises the residual of
//! `B_i Y = Y A_i` over every motion with `t_Y,z` held.

use nalgebra::{Isometry3, Matrix2, Matrix4, Quaternion, SymmetricEigen, Translation3};
use nalgebra::{UnitQuaternion, Vector2, Vector3, Vector4};

use crate::NonExhaustive;
use crate::error::{Decomposition, HandEyeError, NullSpaceStep, OptionField, Result, Unobservable};
use crate::motion::{MotionPair, check_pairs};
use crate::plane::reduce_to_plane;
use crate::quadratic::unit_circle_roots;
use crate::refine::{Free, Problem, RefineOptions, Uncertainty, Unknowns};
use crate::screening::{MotionScreening, screen};

/// Default largest tilt of a rotation of `b` out of its `xy` plane, and elevation of its
/// translations (RMS), radians: 0.05 (about 3 degrees; wheel odometry is exactly planar, a
/// 6-DoF odometry on a road tilts by a few degrees at most).
pub const DEFAULT_MAX_OUT_OF_PLANE: f64 = 0.05;

/// Default smallest ratio `σ₂ / σ₃` of the singular values of the roll-pitch system: 10
/// (exact data gives `σ₃ = 0`; see [`crate::DEFAULT_MIN_SIGNAL_TO_NOISE`]).
pub const DEFAULT_MIN_PLANAR_SIGNAL_TO_NOISE: f64 = 10.0;

/// Floor of the noise singular value `σ₃` relative to `σ₁`: the singular values come from the
/// normal matrix, whose rounding hides those below about `sqrt(ε) σ₁ = 1.5e-8 σ₁`.
const NORMAL_MATRIX_FLOOR: f64 = 1e-7;

/// Options of [`guo_planar`].
///
/// Write them as `PlanarOptions { field: value, ..Default::default() }`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarOptions {
    /// Which motions enter the roll-pitch step. Default [`MotionScreening::default()`]:
    /// rotations between 2 and 175 degrees.
    pub screening: MotionScreening,
    /// Estimate an unknown scale `s` of the translations of sensor `a` (a monocular camera);
    /// `s t_Ai` is then in the unit of `t_Bi`. Default `false` (both metric, `s = 1`).
    pub estimate_scale: bool,
    /// Height `t_Y,z` of the origin of frame `a` above the `xy` plane of frame `b` (the plane
    /// through its origin), in the unit of `b`, if known from elsewhere; the motions cannot tell
    /// it. Default `None`: set to zero and reported as [`Height::Unobservable`].
    pub height_prior: Option<f64>,
    /// Largest tilt out of the plane accepted for the motions of `b`, radians; default
    /// [`DEFAULT_MAX_OUT_OF_PLANE`]. The solver uses only their yaw and `xy` translation.
    pub max_out_of_plane: f64,
    /// Smallest `σ₂ / σ₃` of the roll-pitch system; default
    /// [`DEFAULT_MIN_PLANAR_SIGNAL_TO_NOISE`].
    pub min_signal_to_noise: f64,
    /// Nonlinear refinement on the residual of `B_i Y = Y A_i` over every motion (height held),
    /// or `None` (default, the paper's analytical solution). When the absolute trajectories are
    /// at hand, [`crate::refine_trajectories`] is the better refinement.
    pub refine: Option<RefineOptions>,
    /// Keeps the struct open to new fields; use `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for PlanarOptions {
    fn default() -> Self {
        Self {
            screening: MotionScreening::default(),
            estimate_scale: false,
            height_prior: None,
            max_out_of_plane: DEFAULT_MAX_OUT_OF_PLANE,
            min_signal_to_noise: DEFAULT_MIN_PLANAR_SIGNAL_TO_NOISE,
            refine: None,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// Where the out-of-plane translation of a planar solution comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Height {
    /// Planar motion cannot determine it; the solution uses zero.
    Unobservable,
    /// Taken from [`PlanarOptions::height_prior`].
    Prior(f64),
}

/// A planar hand-eye solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarSolution {
    /// `X = a_from_b` (`rig_from_odometry`), translation in the unit of `b`, with `t_Y,z` from
    /// [`PlanarSolution::height`].
    pub a_from_b: Isometry3<f64>,
    /// `Y = X⁻¹ = b_from_a` (`odometry_from_rig`), the form the method solves for.
    pub b_from_a: Isometry3<f64>,
    /// Roll of `b_from_a` (Z-Y-X Euler angles, `R = R_z(yaw) R_y(pitch) R_x(roll)`), radians.
    pub roll: f64,
    /// Pitch of `b_from_a`, radians.
    pub pitch: f64,
    /// Yaw of `b_from_a`, radians.
    pub yaw: f64,
    /// Scale of the translations of sensor `a` (1 unless [`PlanarOptions::estimate_scale`]).
    pub scale: f64,
    /// The height `t_Y,z`: unobservable (zero) or the caller's prior.
    pub height: Height,
    /// Motions in the roll-pitch step.
    pub rotation_motions_used: usize,
    /// Motions left out of the roll-pitch step for rotating less than the minimum.
    pub rejected_small_rotation: usize,
    /// Motions left out of the roll-pitch step for rotating too close to a half turn.
    pub rejected_near_half_turn: usize,
    /// Singular values of the stacked roll-pitch system, largest first (they come in equal
    /// pairs; computed from its normal matrix, so values below about `1e-8 σ₁` are rounding).
    pub singular_values: [f64; 4],
    /// The degeneracy figure `σ₂ / σ₃` of the roll-pitch system (`σ₃` floored at `1e-7 σ₁`,
    /// so about `1e7` with exact data).
    pub signal_to_noise: f64,
    /// Residuals of `B_i Y = Y A_i` over all motions and predicted standard deviations of `Y`:
    /// rotation about the axes of frame `b` (`z` is the yaw), translation in frame `b` with
    /// `z` infinite (not determined by the motions).
    pub uncertainty: Uncertainty,
    /// Levenberg-Marquardt iterations of the refinement, `None` if it was not run.
    pub refinement_iterations: Option<usize>,
}

/// Solves `A_i X = X B_i` for `X = a_from_b` when sensor `b` moves in its `xy` plane, with the
/// method of Guo, Mirzaei and Roumeliotis (see the module docs), then refines it unless
/// `options.refine` is `None`.
///
/// # Errors
/// - [`HandEyeError::NonFinite`], [`HandEyeError::NotUnitQuaternion`],
///   [`HandEyeError::InvalidOptions`] for invalid input;
/// - [`HandEyeError::NotPlanar`] if the motions of `b` leave the plane;
/// - [`HandEyeError::NoRotation`] if no motion rotates by the minimum angle,
///   [`HandEyeError::TooFewMotions`] for fewer than two motions;
/// - [`HandEyeError::Degenerate`] if the roll-pitch null space is not two-dimensional above
///   the noise, or if the translations of `a` cannot fix the yaw;
/// - [`HandEyeError::NegativeDiscriminant`] if no combination of the null space satisfies the
///   constraint (a guard: the structure of the null space rules it out, see the module docs).
pub fn guo_planar(pairs: &[MotionPair], options: &PlanarOptions) -> Result<PlanarSolution> {
    check_pairs(pairs)?;
    validate(options)?;
    let planar_b = reduce_to_plane(
        pairs.iter().map(|p| &p.b),
        &Vector3::zeros(),
        options.max_out_of_plane,
    )?;
    if pairs.len() < 2 {
        return Err(HandEyeError::too_few_motions(pairs.len()));
    }

    // Step 1: roll and pitch from the null space of the stacked L(q_B) - R(q_A).
    let screened = screen(
        pairs
            .iter()
            .zip(&planar_b)
            .map(|(p, b)| (p.a.rotation, b.rotation)),
        &options.screening,
    )?;
    screened.require(1, &options.screening)?;
    // The null space of the stacked 4m × 4 system, from its 4 × 4 normal matrix: the
    // singular values pair up (σ₁ = σ₂, σ₃ = σ₄, see the module docs), so squaring the
    // system does not cost precision in the null space.
    let normal: Matrix4<f64> = screened
        .motions
        .iter()
        .map(|motion| {
            let m = left_matrix(&motion.qb) - right_matrix(&motion.qa);
            m.transpose() * m
        })
        .sum();
    let eigen =
        SymmetricEigen::try_new(normal, f64::EPSILON, 1000).ok_or(HandEyeError::NoConvergence {
            what: Decomposition::RollPitchEigen,
        })?;
    let mut order = [0, 1, 2, 3];
    order.sort_by(|&i, &j| eigen.eigenvalues[j].total_cmp(&eigen.eigenvalues[i]));
    let singular_values = order.map(|k| eigen.eigenvalues[k].max(0.0).sqrt());
    // Rounding in the normal matrix leaves zero singular values at about sqrt(ε) σ₁.
    let noise = singular_values[2].max(NORMAL_MATRIX_FLOOR * singular_values[0]);
    let signal_to_noise = singular_values[1] / noise;
    if signal_to_noise.is_nan() || signal_to_noise < options.min_signal_to_noise {
        return Err(HandEyeError::Degenerate {
            unobservable: Unobservable::RollPitch,
            signal_to_noise,
        });
    }
    let null_vector = |k: usize| eigen.eigenvectors.column(order[k]).into_owned();
    let q0 = representative(&null_vector(2), &null_vector(3))?;

    // Step 2: yaw, in-plane translation and scale.
    let (yaw_rotation, t_xy, scale) =
        yaw_and_translation(pairs, &planar_b, &q0, options.estimate_scale)?;
    let height = options.height_prior.unwrap_or(0.0);
    let b_from_a =
        Isometry3::from_parts(Translation3::new(t_xy.x, t_xy.y, height), yaw_rotation * q0);

    let free = Free {
        translation: [true, true, false],
        scale: options.estimate_scale,
    };
    let problem = Problem::new(
        planar_b.iter().zip(pairs).map(|(b, p)| (*b, p.a)).collect(),
        free,
    );
    let start = Unknowns { z: b_from_a, scale };
    let (fit, refinement_iterations) = match &options.refine {
        Some(refine) => {
            let (fit, iterations) = problem.refine(start, refine)?;
            (fit, Some(iterations))
        }
        None => (problem.assess(start), None),
    };
    let mut uncertainty = fit.uncertainty;
    uncertainty.translation_std.z = f64::INFINITY;
    let b_from_a = fit.unknowns.z;
    let (roll, pitch, yaw) = b_from_a.rotation.euler_angles();
    Ok(PlanarSolution {
        a_from_b: b_from_a.inverse(),
        b_from_a,
        roll,
        pitch,
        yaw,
        scale: fit.unknowns.scale,
        height: options
            .height_prior
            .map_or(Height::Unobservable, Height::Prior),
        rotation_motions_used: screened.motions.len(),
        rejected_small_rotation: screened.rejected_small,
        rejected_near_half_turn: screened.rejected_half_turn,
        singular_values,
        signal_to_noise,
        uncertainty,
        refinement_iterations,
    })
}

fn validate(options: &PlanarOptions) -> Result<()> {
    if !(options.max_out_of_plane >= 0.0 && options.max_out_of_plane.is_finite()) {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::PlanarMaxOutOfPlane,
            value: options.max_out_of_plane,
        });
    }
    if options.min_signal_to_noise.is_nan() || options.min_signal_to_noise < 0.0 {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::PlanarMinSignalToNoise,
            value: options.min_signal_to_noise,
        });
    }
    if let Some(height) = options.height_prior.filter(|h| !h.is_finite()) {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::HeightPrior,
            value: height,
        });
    }
    Ok(())
}

/// `L(q)`: `q ⊗ p = L(q) p`, quaternions as `(w, x, y, z)`.
fn left_matrix(q: &Quaternion<f64>) -> Matrix4<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    Matrix4::new(w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w)
}

/// `R(q)`: `p ⊗ q = R(q) p`, quaternions as `(w, x, y, z)`.
fn right_matrix(q: &Quaternion<f64>) -> Matrix4<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    Matrix4::new(w, -x, -y, -z, x, w, z, -y, y, -z, w, x, z, y, -x, w)
}

/// Entry `(row, col)` of the rotation matrix of the (not necessarily unit) quaternion
/// `(w, x, y, z)`, a quadratic form in it.
fn rotation_entry(q: &Vector4<f64>, row: usize, col: usize) -> f64 {
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    match (row, col) {
        (0, 0) => w * w + x * x - y * y - z * z,
        (0, 1) => 2.0 * (x * y - w * z),
        (0, 2) => 2.0 * (x * z + w * y),
        (1, 0) => 2.0 * (x * y + w * z),
        (1, 1) => w * w - x * x + y * y - z * z,
        (1, 2) => 2.0 * (y * z - w * x),
        (2, 0) => 2.0 * (x * z - w * y),
        (2, 1) => 2.0 * (y * z + w * x),
        _ => w * w - x * x - y * y + z * z,
    }
}

/// The representative `q₀` of the null space `span(v₁, v₂)`: the unit combination that maps
/// the axis `k` of frame `a` closest to the plane into the `xz` half-plane `x > 0` of `b`.
fn representative(v1: &Vector4<f64>, v2: &Vector4<f64>) -> Result<UnitQuaternion<f64>> {
    // Rotations about z keep the height of every axis, so any null vector tells which axis of
    // a lies closest to the plane.
    let k = (0..3)
        .min_by(|&i, &j| {
            rotation_entry(v1, 2, i)
                .abs()
                .total_cmp(&rotation_entry(v1, 2, j).abs())
        })
        .unwrap_or(0);
    let form = |q: &Vector4<f64>| rotation_entry(q, 1, k);
    let (a, c) = (form(v1), form(v2));
    let b = 0.5 * (form(&(v1 + v2)) - form(&(v1 - v2)));
    let roots =
        unit_circle_roots(a, b, c).map_err(|discriminant| HandEyeError::NegativeDiscriminant {
            step: NullSpaceStep::RollPitch,
            discriminant,
        })?;
    let candidate = |(l1, l2): (f64, f64)| v1 * l1 + v2 * l2;
    let (q1, q2) = (candidate(roots[0]), candidate(roots[1]));
    let q = if rotation_entry(&q1, 0, k) >= rotation_entry(&q2, 0, k) {
        q1
    } else {
        q2
    };
    Ok(UnitQuaternion::new_normalize(Quaternion::new(
        q[0], q[1], q[2], q[3],
    )))
}

/// Step 2: `R_z(γ)`, `(t_x, t_y)` and the scale, from every motion.
fn yaw_and_translation(
    pairs: &[MotionPair],
    planar_b: &[Isometry3<f64>],
    q0: &UnitQuaternion<f64>,
    estimate_scale: bool,
) -> Result<(UnitQuaternion<f64>, Vector2<f64>, f64)> {
    // Sums of JᵀJ (a multiple of I), JᵀK, KᵀK, Jᵀr, Kᵀr over the motions.
    let mut jj = 0.0;
    let (mut jk, mut kk) = (Matrix2::zeros(), Matrix2::zeros());
    let (mut jr, mut kr) = (Vector2::zeros(), Vector2::zeros());
    for (pair, b) in pairs.iter().zip(planar_b) {
        let p = q0 * pair.a.translation.vector;
        let (sin, cos) = b.rotation.euler_angles().2.sin_cos();
        let j = Matrix2::new(cos - 1.0, -sin, sin, cos - 1.0);
        let k = Matrix2::new(-p.x, p.y, -p.y, -p.x);
        let r = -b.translation.vector.xy();
        jj += 2.0 * (1.0 - cos);
        jk += j.transpose() * k;
        kk += k.transpose() * k;
        jr += j.transpose() * r;
        kr += k.transpose() * r;
    }
    if jj.is_nan() || jj <= 0.0 {
        return Err(HandEyeError::Degenerate {
            unobservable: Unobservable::InPlaneTranslation,
            signal_to_noise: 0.0,
        });
    }
    // Eliminating t = (Jᵀr - JᵀK y) / jj leaves |P(K y - r)|² = yᵀ W y - 2 gᵀ y + const.
    let w = kk - jk.transpose() * jk / jj;
    let g = kr - jk.transpose() * jr / jj;
    let no_yaw = HandEyeError::Degenerate {
        unobservable: Unobservable::Yaw,
        signal_to_noise: 0.0,
    };
    let (y, scale) = if estimate_scale {
        let y = w.cholesky().ok_or(no_yaw.clone())?.solve(&g);
        let scale = y.norm();
        if scale.is_nan() || scale <= 0.0 {
            return Err(no_yaw);
        }
        (y / scale, scale)
    } else {
        (unit_constrained_minimum(&w, &g).ok_or(no_yaw)?, 1.0)
    };
    let t = (jr - jk * (y * scale)) / jj;
    let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), y.y.atan2(y.x));
    Ok((yaw, t, scale))
}

/// Minimises `yᵀ W y - 2 gᵀ y` subject to `|y| = 1` (`W` symmetric 2 × 2).
///
/// The Lagrange condition `(W - λI) y = g`, `|y|² = 1` is a quartic in `λ` (Guo et al.); the
/// global minimum is its root below the smallest eigenvalue `μ₁` of `W`, where
/// `|y(λ)|² = Σ g̃ₖ² / (μₖ - λ)²` increases from 0 to infinity, bracketed by
/// `[μ₁ - |g|, μ₁]`. `None` when `g` has no component along the eigenvector of `μ₁` and the
/// minimum is not unique (the data do not fix the yaw).
fn unit_constrained_minimum(w: &Matrix2<f64>, g: &Vector2<f64>) -> Option<Vector2<f64>> {
    let eigen = w.symmetric_eigen();
    let (i1, i2) = if eigen.eigenvalues[0] <= eigen.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let (mu1, mu2) = (eigen.eigenvalues[i1], eigen.eigenvalues[i2]);
    let (e1, e2) = (eigen.eigenvectors.column(i1), eigen.eigenvectors.column(i2));
    let (g1, g2) = (e1.dot(g), e2.dot(g));
    let norm = g.norm();
    if g1.is_nan() || g1.abs() <= 1e-14 * norm {
        return None;
    }
    let squared_norm = |lambda: f64| (g1 / (mu1 - lambda)).powi(2) + (g2 / (mu2 - lambda)).powi(2);
    let (mut lo, mut hi) = (mu1 - norm, mu1);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if squared_norm(mid) < 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let lambda = 0.5 * (lo + hi);
    let y = e1 * (g1 / (mu1 - lambda)) + e2 * (g2 / (mu2 - lambda));
    Some(y / y.norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn multiplication_matrices() {
        let p = Quaternion::new(0.3, -0.2, 0.5, 0.1);
        let q = Quaternion::new(-0.7, 0.4, 0.25, -0.6);
        let pv = Vector4::new(p.w, p.i, p.j, p.k);
        let (qp, pq) = (q * p, p * q);
        assert_relative_eq!(
            left_matrix(&q) * pv,
            Vector4::new(qp.w, qp.i, qp.j, qp.k),
            epsilon = 1e-15
        );
        assert_relative_eq!(
            right_matrix(&q) * pv,
            Vector4::new(pq.w, pq.i, pq.j, pq.k),
            epsilon = 1e-15
        );
    }

    #[test]
    fn rotation_entries_match_nalgebra() {
        let q = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let v = Vector4::new(q.w, q.i, q.j, q.k);
        let r = q.to_rotation_matrix();
        for row in 0..3 {
            for col in 0..3 {
                assert_relative_eq!(rotation_entry(&v, row, col), r[(row, col)], epsilon = 1e-15);
            }
        }
    }

    #[test]
    fn unit_constrained_minimum_matches_a_dense_search() {
        let w = Matrix2::new(3.0, 1.0, 1.0, 2.0);
        for g in [
            Vector2::new(0.5, -2.0),
            Vector2::new(10.0, 3.0),
            Vector2::new(-0.1, 0.05),
        ] {
            let y = unit_constrained_minimum(&w, &g).unwrap();
            let cost = |y: Vector2<f64>| (y.transpose() * w * y)[0] - 2.0 * g.dot(&y);
            let best = (0..100_000)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::TAU / 100_000.0;
                    cost(Vector2::new(a.cos(), a.sin()))
                })
                .fold(f64::INFINITY, f64::min);
            assert!(cost(y) <= best + 1e-9);
        }
        // No component along the smallest eigenvector: not unique.
        assert!(
            unit_constrained_minimum(&Matrix2::new(1.0, 0.0, 0.0, 2.0), &Vector2::new(0.0, 0.1))
                .is_none()
        );
    }
}
