//! The residuals and the constrained pose manifold of the rig bundle adjustment
//! ([`crate::rig_bundle_adjustment`]).
//!
//! - [`RigBaReprojection`]: the reprojection error of a free point seen by one camera of the rig
//!   in one frame, π_c(camera_from_rig_c · rig_from_world_i · X_j) − x, with the Jacobians of
//!   the map-fixed rig refinement ([`crate::rig`]) for the two poses, ∂/∂X for the point and
//!   the model's parameter Jacobian for the free intrinsics.
//! - [`SpherePoseManifold`]: a pose whose translation is held at a fixed distance from a fixed
//!   centre (a known baseline between two cameras, a known distance travelled between two rig
//!   poses): the hard scale gauge. Rotation updated on the right as [`crate::Se3Manifold`]
//!   does, translation moved along the sphere, five degrees of freedom.
//! - [`PointDistancePrior`]: (|X_a − X_b| − d) / σ, the soft scale gauge of a known distance
//!   between two points.

use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};

use ibc_camera_models::{Camera, CameraModel, ParamJacobian};
use nalgebra::{DMatrix, Isometry3, Matrix2x3, Matrix3, Matrix3x2, SMatrix, Vector2, Vector3};

use crate::cost::{CostFunction, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::manifold::{
    Manifold, se3_from_params, se3_from_unit_params, se3_to_params, so3_exp, sphere_tangent_basis,
};
use crate::problem::{ParameterBlockId, Problem};
use crate::rig::{residual_and_rig_jacobian, rig_from_camera_jacobian, world_from_rig_jacobian};

/// A pose `[qw, qx, qy, qz, tx, ty, tz]` whose translation stays on the sphere of radius
/// `radius` about `centre`: x ⊞ δ with δ = `[a, b, φ]` rotates as T · Exp(φ) and moves the
/// translation to `centre + radius · (t − centre + B [a, b]) / |t − centre + B [a, b]|`, B the
/// sphere's tangent basis at t ([`sphere_tangent_basis`]), so ∂t/∂[a, b] = B at δ = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SpherePoseManifold {
    pub centre: Vector3<f64>,
    pub radius: f64,
}

impl SpherePoseManifold {
    /// `pose` with its translation moved radially onto the sphere.
    pub(crate) fn project(&self, pose: &Isometry3<f64>) -> Isometry3<f64> {
        let d = pose.translation.vector - self.centre;
        let mut out = *pose;
        out.translation.vector = self.centre + d * (self.radius / d.norm());
        out
    }

    /// The tangent basis of the sphere at translation `t`.
    #[inline]
    pub(crate) fn basis(&self, t: &Vector3<f64>) -> Matrix3x2<f64> {
        sphere_tangent_basis(&(t - self.centre).normalize())
    }
}

impl Manifold for SpherePoseManifold {
    fn ambient_size(&self) -> usize {
        7
    }
    fn tangent_size(&self) -> usize {
        5
    }
    fn plus(&self, x: &[f64], delta: &[f64], x_plus_delta: &mut [f64]) {
        let pose = se3_from_params(x);
        let t = pose.translation.vector;
        let step = self.basis(&t) * Vector2::new(delta[0], delta[1]);
        let moved = t - self.centre + step;
        let mut out = pose;
        out.translation.vector = self.centre + moved * (self.radius / moved.norm());
        out.rotation = pose.rotation * so3_exp(&Vector3::new(delta[2], delta[3], delta[4]));
        out.rotation.renormalize();
        x_plus_delta.copy_from_slice(&se3_to_params(&out));
    }
}

/// Writes the Jacobian of a pose argument: the 2 × 6 right-perturbation Jacobian `j6`
/// (`[ρ, φ]`, ρ in the pose's own frame) as is for an SE(3) block, or for a
/// [`SpherePoseManifold`] block (5 columns `[a, b, φ]`) as `[J_ρ Rᵀ B, J_φ]`, since a sphere
/// step moves the translation by B [a, b] = R ρ.
#[inline]
fn set_pose_jacobian(
    jac: &mut Jacobians<'_>,
    slot: usize,
    j6: &SMatrix<f64, 2, 6>,
    sphere: Option<&SpherePoseManifold>,
    pose: &Isometry3<f64>,
) {
    match sphere {
        None => jac.set(slot, j6),
        Some(m) => {
            let r: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
            let lift = r.transpose() * m.basis(&pose.translation.vector);
            let mut j = SMatrix::<f64, 2, 5>::zeros();
            j.fixed_view_mut::<2, 2>(0, 0)
                .copy_from(&(j6.fixed_view::<2, 3>(0, 0) * lift));
            j.fixed_view_mut::<2, 3>(0, 2)
                .copy_from(&j6.fixed_view::<2, 3>(0, 3));
            jac.set(slot, &j);
        }
    }
}

/// A camera whose free intrinsics follow their parameter block (the held ones stay at the
/// camera's values): rebuilt and validated by its model only when the values change.
///
/// Two levels: the shared camera (behind a lock, rebuilt when the values change) and a
/// per-thread copy in a small memo keyed by the cache's unique id, which answers the
/// evaluations of one linearization point without touching the lock (whose atomic operations
/// and checks were about 2 % of an intrinsics-free rig bundle adjustment's profile). A rig's
/// caches get consecutive ids, so up to
/// [`MEMO_SLOTS`] cameras never evict each other; beyond, an evicted camera is copied back
/// from the shared one.
#[derive(Debug)]
pub(crate) struct IntrinsicsCache {
    id: u64,
    camera: RwLock<Camera>,
    /// Indices (CamOdoCal order) of the free parameters, the order of the block.
    pub free: Vec<usize>,
}

/// Slots of the per-thread memo of [`IntrinsicsCache`] cameras.
const MEMO_SLOTS: usize = 16;

/// The next [`IntrinsicsCache`] id (ids are never reused, so a memo entry of a dropped cache
/// never answers for another).
static NEXT_CACHE_ID: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Per thread: the camera last used by the cache of each id modulo [`MEMO_SLOTS`].
    static MEMO: RefCell<[Option<(u64, Camera)>; MEMO_SLOTS]> =
        const { RefCell::new([const { None }; MEMO_SLOTS]) };
}

impl IntrinsicsCache {
    pub(crate) fn new(camera: Camera, free: Vec<usize>) -> Self {
        Self {
            id: NEXT_CACHE_ID.fetch_add(1, Ordering::Relaxed),
            camera: RwLock::new(camera),
            free,
        }
    }

    fn matches(&self, camera: &Camera, values: &[f64]) -> bool {
        let params = camera.params();
        self.free
            .iter()
            .zip(values)
            .all(|(&i, &v)| params.get(i) == Some(&v))
    }

    /// Calls `f` with the camera at the free values `values`, or `None` when the model
    /// refuses them.
    #[inline]
    pub(crate) fn with<R>(&self, values: &[f64], f: impl FnOnce(&Camera) -> R) -> Option<R> {
        let slot = (self.id % MEMO_SLOTS as u64) as usize;
        // `f` is called in place, its result written once: results are large (a projection's
        // Jacobians), and moving them through nested options showed as memory copies.
        let mut f = Some(f);
        let mut out = None;
        // The memo is unavailable while a thread is torn down or from a call inside `f`:
        // then the shared camera answers alone.
        let _ = MEMO.try_with(|memo| {
            let Ok(mut memo) = memo.try_borrow_mut() else {
                return;
            };
            let hit = matches!(&memo[slot], Some((id, camera))
                if *id == self.id && self.matches(camera, values));
            if !hit {
                match self.shared(values, Clone::clone) {
                    Some(camera) => memo[slot] = Some((self.id, camera)),
                    // Refused: `out` stays `None`.
                    None => {
                        f = None;
                        return;
                    }
                }
            }
            if let (Some((_, camera)), Some(f)) = (&memo[slot], f.take()) {
                out = Some(f(camera));
            }
        });
        match f {
            Some(f) => self.shared(values, f),
            None => out,
        }
    }

    /// `f` of the shared camera, first set to `values` if it holds others; `None` when the
    /// model refuses them.
    fn shared<R>(&self, values: &[f64], f: impl FnOnce(&Camera) -> R) -> Option<R> {
        if let Ok(camera) = self.camera.read()
            && self.matches(&camera, values)
        {
            return Some(f(&camera));
        }
        let mut camera = self.camera.write().ok()?;
        if !self.matches(&camera, values) {
            let mut params = camera.params().to_vec();
            for (&i, &v) in self.free.iter().zip(values) {
                *params.get_mut(i)? = v;
            }
            camera.set_params(&params).ok()?;
        }
        Some(f(&camera))
    }
}

/// The free intrinsics of one camera: their indices (CamOdoCal order), the camera that
/// follows them and their start values (the block's).
pub(crate) struct FreeIntrinsics {
    pub cache: Arc<IntrinsicsCache>,
    pub values: Vec<f64>,
}

/// Per camera, its free intrinsics (`None` when every parameter is held): `free(c, camera)`
/// lists camera `c`'s free parameter indices.
pub(crate) fn free_intrinsics(
    cameras: &[Camera],
    free: impl Fn(usize, &Camera) -> Vec<usize>,
) -> Vec<Option<FreeIntrinsics>> {
    cameras
        .iter()
        .enumerate()
        .map(|(c, camera)| {
            let free = free(c, camera);
            (!free.is_empty()).then(|| FreeIntrinsics {
                values: free.iter().map(|&p| camera.params()[p]).collect(),
                cache: Arc::new(IntrinsicsCache::new(camera.clone(), free)),
            })
        })
        .collect()
}

/// A camera's block of free intrinsics and the free parameters' indices (CamOdoCal order).
pub(crate) type IntrinsicsBlock = Option<(ParameterBlockId, Vec<usize>)>;

/// Adds a parameter block for each camera's free intrinsics to `problem`: per camera, the
/// block and the free parameters' indices, `None` where every parameter is held.
pub(crate) fn add_intrinsics_blocks(
    problem: &mut Problem,
    free: &[Option<FreeIntrinsics>],
) -> Result<Vec<IntrinsicsBlock>> {
    free.iter()
        .map(|f| {
            f.as_ref()
                .map(|f| {
                    Ok((
                        problem.add_parameter_block(&f.values)?,
                        f.cache.free.clone(),
                    ))
                })
                .transpose()
        })
        .collect()
}

/// A typed error when a `(camera, parameter)` of `held` names no camera or no parameter.
pub(crate) fn validate_held_intrinsics(cameras: &[Camera], held: &[(usize, usize)]) -> Result<()> {
    let invalid = |reason| BundleAdjustError::InvalidOption {
        name: "held_intrinsics",
        reason,
    };
    for &(c, p) in held {
        let Some(camera) = cameras.get(c) else {
            return Err(invalid(format!(
                "camera {c} does not exist ({} cameras)",
                cameras.len()
            )));
        };
        if p >= camera.num_params() {
            return Err(invalid(format!(
                "camera {c} has {} parameters, not a parameter {p}",
                camera.num_params()
            )));
        }
    }
    Ok(())
}

/// `cameras` with the values of their free-intrinsics blocks (`blocks[c]`: the block and its
/// parameter indices) read from `problem`.
///
/// # Errors
/// [`BundleAdjustError::RefinedIntrinsicsRejected`] when a model refuses its refined values.
pub(crate) fn refined_cameras(
    cameras: &[Camera],
    blocks: &[IntrinsicsBlock],
    problem: &Problem,
) -> Result<Vec<Camera>> {
    let mut refined = cameras.to_vec();
    for (camera, (model, block)) in refined.iter_mut().zip(blocks).enumerate() {
        if let Some((id, free)) = block {
            let mut params = model.params().to_vec();
            for (&p, &v) in free.iter().zip(problem.parameter_block(*id)?) {
                params[p] = v;
            }
            model.set_params(&params).map_err(|source| {
                BundleAdjustError::RefinedIntrinsicsRejected { camera, source }
            })?;
        }
    }
    Ok(refined)
}

/// The full covariance (CamOdoCal order, zero rows and columns for held parameters) of a
/// camera with `num_params` parameters from the covariance `block` of its free ones.
pub(crate) fn full_intrinsic_covariance(
    block: &DMatrix<f64>,
    free: &[usize],
    num_params: usize,
) -> DMatrix<f64> {
    let mut full = DMatrix::zeros(num_params, num_params);
    for (a, &pa) in free.iter().enumerate() {
        for (b, &pb) in free.iter().enumerate() {
            full[(pa, pb)] = block[(a, b)];
        }
    }
    full
}

/// Where a reprojection residual takes its intrinsics from.
pub(crate) enum Intrinsics {
    /// Held: the camera, shared by its residuals.
    Fixed(Arc<Camera>),
    /// Free (some of them): the last argument is the block of the free parameters.
    Free(Arc<IntrinsicsCache>),
}

impl Intrinsics {
    /// Camera `camera`'s: free when it has free intrinsics, else held (`fixed` the shared
    /// list); with the number of free parameters.
    pub(crate) fn of(
        fixed: &[Arc<Camera>],
        camera: usize,
        free: Option<&FreeIntrinsics>,
    ) -> (Self, usize) {
        match free {
            Some(f) => (Intrinsics::Free(Arc::clone(&f.cache)), f.values.len()),
            None => (Intrinsics::Fixed(Arc::clone(&fixed[camera])), 0),
        }
    }
}

impl Intrinsics {
    /// The pixel of `p_cam`, `None` outside the model's domain; `free` is the block of the
    /// free parameters (ignored when held).
    #[inline]
    pub(crate) fn project(
        &self,
        p_cam: &Vector3<f64>,
        free: Option<&[f64]>,
    ) -> Option<Vector2<f64>> {
        match (self, free) {
            (Intrinsics::Fixed(camera), _) => camera.project(p_cam).ok(),
            (Intrinsics::Free(cache), Some(values)) => {
                cache.with(values, |cam| cam.project(p_cam).ok()).flatten()
            }
            (Intrinsics::Free(_), None) => None,
        }
    }

    /// Writes the reprojection residual `pixel − observed` of `p_cam` into `residuals`;
    /// false (nothing written) outside the model's domain, as [`Self::project`].
    #[inline]
    pub(crate) fn reprojection_residual(
        &self,
        p_cam: &Vector3<f64>,
        free: Option<&[f64]>,
        observed: &Vector2<f64>,
        residuals: &mut [f64],
    ) -> bool {
        let Some(pixel) = self.project(p_cam, free) else {
            return false;
        };
        residuals[0] = pixel.x - observed.x;
        residuals[1] = pixel.y - observed.y;
        true
    }

    /// Calls `f` with the pixel of `p_cam`, d pixel / d point and, when the intrinsics are
    /// free, d pixel / d params; false (and `f` not called) outside the model's domain or for
    /// intrinsics the model refuses. The Jacobians are lent, not returned: moving them out
    /// through the camera cache cost the evaluation memory copies.
    #[inline]
    pub(crate) fn with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
        free: Option<&[f64]>,
        f: impl FnOnce(&Vector2<f64>, &Matrix2x3<f64>, Option<&ParamJacobian<2>>),
    ) -> bool {
        match (self, free) {
            (Intrinsics::Fixed(camera), _) => match camera.project_with_point_jacobian(p_cam) {
                Ok((pixel, d_pixel)) => {
                    f(&pixel, &d_pixel, None);
                    true
                }
                Err(_) => false,
            },
            (Intrinsics::Free(cache), Some(values)) => cache
                .with(values, |cam| match cam.project_with_jacobians(p_cam) {
                    Ok(pj) => {
                        f(&pj.pixel, &pj.d_pixel_d_point, Some(&pj.d_pixel_d_params));
                        true
                    }
                    Err(_) => false,
                })
                .unwrap_or(false),
            (Intrinsics::Free(_), None) => false,
        }
    }

    /// Writes the free parameters' columns of `d_params` into argument `slot`'s Jacobian
    /// when it is wanted.
    #[inline]
    pub(crate) fn set_jacobian(
        &self,
        jac: &mut Jacobians<'_>,
        slot: usize,
        d_params: Option<&ParamJacobian<2>>,
    ) {
        if let (Intrinsics::Free(cache), Some(d_params)) = (self, d_params)
            && let Some(j) = jac.row_major_mut(slot)
        {
            let n = cache.free.len();
            for row in 0..2 {
                for (col, &p) in cache.free.iter().enumerate() {
                    j[row * n + col] = d_params[(row, p)];
                }
            }
        }
    }
}

/// The reprojection error of one observation; arguments `[world_from_rig (7), rig_from_camera
/// (7), point (3)]` and, with free intrinsics, `[.., intrinsics (free count)]`. A pose argument
/// on a [`SpherePoseManifold`] gets its 5-column Jacobian.
pub(crate) struct RigBaReprojection {
    pub intrinsics: Intrinsics,
    /// The argument sizes: `[7, 7, 3]` or `[7, 7, 3, free intrinsics]`.
    pub sizes: [usize; 4],
    pub n_args: usize,
    pub pixel: Vector2<f64>,
    /// The manifold of the rig pose's block, when it is the odometry-scale pose.
    pub frame_sphere: Option<Arc<SpherePoseManifold>>,
    /// The manifold of the extrinsic's block, when it is the baseline camera.
    pub camera_sphere: Option<Arc<SpherePoseManifold>>,
}

impl CostFunction for RigBaReprojection {
    fn num_residuals(&self) -> usize {
        2
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes[..self.n_args]
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let world_from_rig = se3_from_unit_params(parameters[0]);
        let rig_from_camera = se3_from_unit_params(parameters[1]);
        let x = Vector3::new(parameters[2][0], parameters[2][1], parameters[2][2]);
        let p_rig =
            world_from_rig.inverse_transform_vector(&(x - world_from_rig.translation.vector));
        let p_cam =
            rig_from_camera.inverse_transform_vector(&(p_rig - rig_from_camera.translation.vector));
        let free = parameters.get(3).copied();
        let Some(jac) = jacobians else {
            return self
                .intrinsics
                .reprojection_residual(&p_cam, free, &self.pixel, residuals);
        };
        self.intrinsics
            .with_jacobians(&p_cam, free, |pixel, d_pixel, d_params| {
                let d_rig = residual_and_rig_jacobian(
                    residuals,
                    pixel,
                    &self.pixel,
                    d_pixel,
                    &rig_from_camera,
                );
                if jac.wants(0) {
                    let j = world_from_rig_jacobian(&d_rig, &p_rig);
                    set_pose_jacobian(jac, 0, &j, self.frame_sphere.as_deref(), &world_from_rig);
                }
                if jac.wants(1) {
                    let j = rig_from_camera_jacobian(d_pixel, &p_cam);
                    set_pose_jacobian(jac, 1, &j, self.camera_sphere.as_deref(), &rig_from_camera);
                }
                if jac.wants(2) {
                    let rig_from_world: Matrix3<f64> = world_from_rig
                        .rotation
                        .to_rotation_matrix()
                        .into_inner()
                        .transpose();
                    jac.set(2, &(d_rig * rig_from_world));
                }
                self.intrinsics.set_jacobian(jac, 3, d_params);
            })
    }
}

/// (|X_a − X_b| − d) / σ; arguments `[X_a (3), X_b (3)]`.
pub(crate) struct PointDistancePrior {
    pub distance: f64,
    pub sigma: f64,
}

impl CostFunction for PointDistancePrior {
    fn num_residuals(&self) -> usize {
        1
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &[3, 3]
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let a = Vector3::new(parameters[0][0], parameters[0][1], parameters[0][2]);
        let b = Vector3::new(parameters[1][0], parameters[1][1], parameters[1][2]);
        let d = a - b;
        let norm = d.norm();
        if norm.is_nan() || norm <= 0.0 {
            return false;
        }
        residuals[0] = (norm - self.distance) / self.sigma;
        if let Some(jac) = jacobians {
            let u = d / (norm * self.sigma);
            jac.set(0, &u.transpose());
            jac.set(1, &(-u.transpose()));
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// The per-thread memo answers for its own cache only: caches sharing a memo slot, values
    /// that change, values the model refuses and a call from inside `f` all see the camera
    /// at their own values.
    #[test]
    fn intrinsics_caches_answer_with_their_own_values() {
        use ibc_camera_models::KannalaBrandt;
        let params = [0.01, -0.002, 0.0005, -0.0001, 400.0, 401.0, 640.0, 480.0];
        let camera = Camera::from(KannalaBrandt::new(1280, 960, params).unwrap());
        // Focal lengths free; of MEMO_SLOTS + 1 caches, two share a slot (whatever other
        // tests create meanwhile).
        let caches: Vec<IntrinsicsCache> = (0..=MEMO_SLOTS)
            .map(|_| IntrinsicsCache::new(camera.clone(), vec![4, 5]))
            .collect();
        let slot = |c: &IntrinsicsCache| c.id % MEMO_SLOTS as u64;
        let (i, j) = (0..caches.len())
            .flat_map(|i| (i + 1..caches.len()).map(move |j| (i, j)))
            .find(|&(i, j)| slot(&caches[i]) == slot(&caches[j]))
            .unwrap();
        let (a, b) = (&caches[i], &caches[j]);
        let p = Vector3::new(0.3, -0.2, 1.0);
        let u = |cache: &IntrinsicsCache, f: [f64; 2]| {
            cache.with(&f, |c| c.project(&p).unwrap().x).unwrap()
        };
        let expected = |f: f64| {
            let mut q = params;
            q[4] = f;
            KannalaBrandt::new(1280, 960, q)
                .unwrap()
                .project(&p)
                .unwrap()
                .x
        };
        for _ in 0..2 {
            assert_eq!(u(a, [410.0, 401.0]), expected(410.0));
            assert_eq!(u(b, [390.0, 401.0]), expected(390.0));
        }
        assert_eq!(u(a, [420.0, 401.0]), expected(420.0));
        // A negative focal length is refused, and the next valid values answer again.
        assert!(a.with(&[-1.0, 401.0], |c| c.params()[4]).is_none());
        assert_eq!(u(a, [410.0, 401.0]), expected(410.0));
        // Re-entrant: the inner call answers from the shared camera.
        let nested = a.with(&[430.0, 401.0], |_| u(b, [380.0, 401.0])).unwrap();
        assert_eq!(nested, expected(380.0));
    }

    #[test]
    fn sphere_manifold_stays_on_the_sphere_and_matches_its_basis() {
        let m = SpherePoseManifold {
            centre: Vector3::new(0.3, -0.2, 0.1),
            radius: 2.5,
        };
        let pose = m.project(&Isometry3::new(
            Vector3::new(2.0, 1.0, 0.5),
            Vector3::new(0.1, 0.2, -0.3),
        ));
        let x = se3_to_params(&pose);
        let mut out = [0.0; 7];
        m.plus(&x, &[0.3, -0.2, 0.01, 0.02, -0.03], &mut out);
        let moved = se3_from_params(&out);
        assert_relative_eq!(
            (moved.translation.vector - m.centre).norm(),
            2.5,
            epsilon = 1e-12
        );
        // ∂t/∂[a, b] = B at δ = 0.
        let h = 1e-7;
        let basis = m.basis(&pose.translation.vector);
        for k in 0..2 {
            let mut d = [0.0; 5];
            d[k] = h;
            m.plus(&x, &d, &mut out);
            let fd = (se3_from_params(&out).translation.vector - pose.translation.vector) / h;
            assert_relative_eq!(fd, basis.column(k).into_owned(), epsilon = 1e-6);
        }
    }
}
