//! Full bundle adjustment with [`ibc_camera_models`] cameras: image poses, points and,
//! optionally, the intrinsics (the online refinement of intrinsics and extrinsics inside a
//! bundle adjustment, TrimBot2020 deliverable D3.1; Triggs et al., "Bundle Adjustment — A
//! Modern Synthesis", 2000).
//!
//! Minimizes Σ ρ(|π_k(camera_from_world_i · X_j) − x_ij|²) over the image poses
//! `camera_from_world_i` (on [`Se3Manifold`], right perturbations), the points X_j
//! (eliminated by the Schur complement) and, if asked, the parameters of each camera k in
//! CamOdoCal order (validated by the model at every step; an invalid step is rejected).
//!
//! **Gauge.** A similarity of the world (7 degrees of freedom: rotation, translation, scale)
//! leaves the cost unchanged; [`BundleAdjustmentOptions::gauge`] says how it is fixed
//! (Triggs et al. 2000, section 9, on gauge freedom):
//! - [`Gauge::FixedImages`] (the default) holds the poses of
//!   [`BundleAdjustmentOptions::fixed_images`], 6 degrees of freedom each. One image (the
//!   default, image 0) fixes rotation and translation and leaves the scale free: harmless to
//!   Levenberg-Marquardt (the damping keeps the step finite) but the covariance is then
//!   undefined ([`crate::BundleAdjustError::CovarianceRankDeficient`]). Two images fix 12
//!   degrees of freedom where the gauge has 7: the 5 extra ones are information thrown away
//!   (right only when both poses are known exactly), and with noisy poses the solution is
//!   biased.
//! - [`Gauge::Similarity`] fixes exactly 7: the pose of one image (6) and the distance from its
//!   centre to a second image's centre (1, the scale). The second image's pose keeps 5 degrees
//!   of freedom: its centre moves on the sphere around the first centre through its initial
//!   centre, its rotation is free (a manifold on its pose block, so the distance is held
//!   exactly).
//! - [`Gauge::ScaleOnly`] fixes only the scale, the distance between two image centres, by a
//!   stiff prior (residual [`SCALE_PRIOR_WEIGHT`] · (|c₁ − c₂| / d₀ − 1), no robust loss), and
//!   leaves the rigid motion of the whole scene free (6 degrees of freedom, kept finite by the
//!   damping): for scenes whose frame is defined afterwards (by an alignment) while the metric
//!   scale comes from a known baseline.
//!
//! **Bad starts.** An observation that cannot be evaluated at the initial estimate (its point
//! behind the camera, outside the camera model's domain, or a non-finite residual or
//! Jacobian) is left out and reported in [`BundleAdjustmentResult::excluded_observations`].
//! A point whose every observation is left out is left out too, at its initial position, and
//! reported in [`BundleAdjustmentResult::excluded_points`]; the rest of the scene is adjusted.
//! An image whose pose is free, a point without any observation in the input, or (with
//! [`BundleAdjustmentOptions::optimize_intrinsics`]) a camera left without observations is a
//! typed error naming it.

use std::sync::{Arc, RwLock};

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, SMatrix, Vector2, Vector3};

use crate::corrector::validate_loss;
use crate::cost::{CostFunction, EvaluationProbe, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::manifold::{
    Manifold, Se3Manifold, se3_from_params, se3_from_unit_params, se3_to_params, skew, so3_exp,
};
use crate::options::SolverOptions;
use crate::problem::{ParameterBlockId, Problem};
use crate::summary::Summary;
use crate::{NonExhaustive, RobustLoss};

/// One observation of point `point` in image `image`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaObservation {
    /// Image index.
    pub image: usize,
    /// Point index.
    pub point: usize,
    /// Observed pixel (pixel centres at integer coordinates).
    pub pixel: Vector2<f64>,
}

/// A bundle-adjustment problem.
#[derive(Debug, Clone)]
pub struct BundleAdjustment {
    /// The cameras (intrinsics); several images may share one.
    pub cameras: Vec<Camera>,
    /// The camera of each image (index into `cameras`).
    pub image_camera: Vec<usize>,
    /// Pose of each image.
    pub camera_from_world: Vec<Isometry3<f64>>,
    /// Points in the world frame.
    pub points: Vec<Vector3<f64>>,
    /// Observations.
    pub observations: Vec<BaObservation>,
}

/// How a bundle adjustment fixes the similarity gauge of the world (see the
/// [module documentation](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Gauge {
    /// Hold the poses of [`BundleAdjustmentOptions::fixed_images`], 6 degrees of freedom per
    /// image (the default; with the default `fixed_images`, image 0: the scale stays free).
    #[default]
    FixedImages,
    /// Hold the pose of `reference_image` (6 degrees of freedom) and the distance from its
    /// centre to the centre of `scale_image` (1): exactly the 7 of the gauge.
    /// [`BundleAdjustmentOptions::fixed_images`] is ignored.
    Similarity {
        /// The image whose pose is held.
        reference_image: usize,
        /// The image whose centre stays at its initial distance from the reference centre;
        /// its rotation and its direction from the reference centre are free.
        scale_image: usize,
    },
    /// Hold only the distance between the centres of two images (1 degree of freedom, by a
    /// stiff prior of weight [`SCALE_PRIOR_WEIGHT`]); the rigid motion of the scene stays
    /// free. [`BundleAdjustmentOptions::fixed_images`] is ignored.
    ScaleOnly {
        /// One image.
        first_image: usize,
        /// The other image.
        second_image: usize,
    },
}

/// Weight of the scale prior of [`Gauge::ScaleOnly`]: its residual is
/// `SCALE_PRIOR_WEIGHT · (|c₁ − c₂| / d₀ − 1)` next to reprojection errors in pixels, so a
/// relative change of the distance by 1e-6 costs as much as a 1-pixel error.
pub const SCALE_PRIOR_WEIGHT: f64 = 1e6;

/// Options of [`BundleAdjustment::solve`].
///
/// ```
/// use ibc_bundle_adjust::{BundleAdjustmentOptions, Gauge, RobustLoss};
///
/// let options = BundleAdjustmentOptions {
///     optimize_intrinsics: true,
///     gauge: Gauge::Similarity { reference_image: 0, scale_image: 1 },
///     loss: RobustLoss::Trivial,
///     ..Default::default()
/// };
/// assert_eq!(options.solver.max_iterations, 50);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct BundleAdjustmentOptions {
    /// Robust loss on the squared pixel error (default `RobustLoss::Cauchy { scale: 1.0 }`,
    /// a = 1 pixel).
    pub loss: RobustLoss,
    /// Optimize the intrinsics too (default false).
    pub optimize_intrinsics: bool,
    /// Images whose poses are held fixed (default `vec![0]`, image 0), for
    /// [`Gauge::FixedImages`]; ignored by the other gauges.
    pub fixed_images: Vec<usize>,
    /// How the similarity gauge is fixed (default [`Gauge::FixedImages`], the images of
    /// `fixed_images`).
    pub gauge: Gauge,
    /// Solver options (default [`SolverOptions::default`], Ceres's defaults).
    pub solver: SolverOptions,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for BundleAdjustmentOptions {
    fn default() -> Self {
        Self {
            loss: RobustLoss::Cauchy { scale: 1.0 },
            optimize_intrinsics: false,
            fixed_images: vec![0],
            gauge: Gauge::FixedImages,
            solver: SolverOptions::default(),
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// The adjusted scene.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct BundleAdjustmentResult {
    /// Cameras with their (possibly refined) intrinsics.
    pub cameras: Vec<Camera>,
    /// Refined image poses.
    pub camera_from_world: Vec<Isometry3<f64>>,
    /// Refined points.
    pub points: Vec<Vector3<f64>>,
    /// Root-mean-square reprojection error (pixels) at the start, over the observations used.
    pub initial_rms: f64,
    /// Root-mean-square reprojection error (pixels) at the solution, over the observations
    /// used.
    pub final_rms: f64,
    /// Indices (into [`BundleAdjustment::observations`], ascending) of the observations left
    /// out because they cannot be evaluated at the initial estimate: behind the camera,
    /// outside the camera model's domain, or not finite. Empty for a good start.
    pub excluded_observations: Vec<usize>,
    /// Indices (into [`BundleAdjustment::points`], ascending) of the points left out because
    /// every observation of theirs was excluded; they keep their initial positions.
    pub excluded_points: Vec<usize>,
    /// The solver's summary.
    pub summary: Summary,
}

/// A bundle adjustment compiled into a [`Problem`] by [`BundleAdjustment::to_problem`]: for
/// a covariance, an iteration callback, or online use (removing residual blocks, holding
/// some intrinsics with [`Problem::set_constant_subset`]) between solves.
#[derive(Debug)]
#[non_exhaustive]
pub struct BaProblem {
    /// The problem: one residual block per observation used, in observation order (and, for
    /// [`Gauge::ScaleOnly`], the scale prior last).
    pub problem: Problem,
    /// The SE(3) block ([`Se3Manifold`]) of each image's `camera_from_world`; for
    /// [`Gauge::Similarity`] the scale image's block has a 5-dimensional tangent (rotation
    /// `[φ]` last, as for SE(3); the first two coordinates move the centre on its sphere).
    pub camera_from_world: Vec<ParameterBlockId>,
    /// The block of each point (eliminated; constant for an excluded point).
    pub points: Vec<ParameterBlockId>,
    /// The block of each camera's parameters (constant unless
    /// [`BundleAdjustmentOptions::optimize_intrinsics`]).
    pub intrinsics: Vec<ParameterBlockId>,
    /// The residual block of each observation, `None` for an excluded one.
    pub residuals: Vec<Option<crate::ResidualBlockId>>,
    /// See [`BundleAdjustmentResult::excluded_observations`].
    pub excluded_observations: Vec<usize>,
    /// See [`BundleAdjustmentResult::excluded_points`].
    pub excluded_points: Vec<usize>,
}

/// A camera whose parameters follow its parameter block: rebuilt (and validated) only when
/// the values change, so the model's derived limits are not recomputed per residual.
#[derive(Debug)]
struct CameraCache(RwLock<Camera>);

impl CameraCache {
    fn with<R>(&self, params: &[f64], f: impl Fn(&Camera) -> R) -> Option<R> {
        if let Ok(camera) = self.0.read()
            && camera.params() == params
        {
            return Some(f(&camera));
        }
        let mut camera = self.0.write().ok()?;
        if camera.params() != params {
            camera.set_params(params).ok()?;
        }
        Some(f(&camera))
    }
}

/// A pose `camera_from_world` `[qw, qx, qy, qz, tx, ty, tz]` whose camera centre stays on the
/// sphere of radius |c − `center`| around `center` ([`Gauge::Similarity`]'s scale image).
///
/// Tangent δ = `[a, b, φ]`: with u = (c − center)/r and (e₁, e₂) an orthonormal basis of the
/// plane orthogonal to u (a fixed function of u), the centre moves along the great circle
/// u' = cos θ u + sin θ v/θ, v = a e₁ + b e₂, θ = |v|, at the same radius r, and the rotation
/// as for [`Se3Manifold`], R' = R Exp(φ). To first order this is the SE(3) right perturbation
/// `[ρ, φ]` with ρ = −r (a e₁ + b e₂) + [c]× φ ([`centre_tangent_map`]).
#[derive(Debug, Clone, Copy)]
struct CentreOnSphere {
    center: Vector3<f64>,
}

/// Camera centre c = −Rᵀ t of a pose block and its rotation matrix.
fn centre_of(params: &[f64]) -> (Vector3<f64>, Matrix3<f64>) {
    let pose = se3_from_unit_params(params);
    let r: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
    (-(r.transpose() * pose.translation.vector), r)
}

/// An orthonormal basis (e₁, e₂) of the plane orthogonal to the unit vector `u`: the
/// columns of [`crate::manifold::sphere_tangent_basis`].
fn orthogonal_basis(u: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let b = crate::manifold::sphere_tangent_basis(u);
    (b.column(0).into_owned(), b.column(1).into_owned())
}

/// The 6 × 5 map from [`CentreOnSphere`]'s tangent to the SE(3) right perturbation `[ρ, φ]`
/// at a pose with centre `c`, `center` the sphere's centre.
fn centre_tangent_map(c: &Vector3<f64>, center: &Vector3<f64>) -> SMatrix<f64, 6, 5> {
    let d = c - center;
    let r = d.norm();
    let (e1, e2) = orthogonal_basis(&(d / r));
    let mut m = SMatrix::<f64, 6, 5>::zeros();
    m.fixed_view_mut::<3, 1>(0, 0).copy_from(&(-r * e1));
    m.fixed_view_mut::<3, 1>(0, 1).copy_from(&(-r * e2));
    m.fixed_view_mut::<3, 3>(0, 2).copy_from(&skew(c));
    m.fixed_view_mut::<3, 3>(3, 2)
        .copy_from(&Matrix3::identity());
    m
}

impl Manifold for CentreOnSphere {
    fn ambient_size(&self) -> usize {
        7
    }
    fn tangent_size(&self) -> usize {
        5
    }
    fn plus(&self, x: &[f64], delta: &[f64], x_plus_delta: &mut [f64]) {
        let pose = se3_from_unit_params(x);
        let (c, _) = centre_of(x);
        let d = c - self.center;
        let r = d.norm();
        let u = d / r;
        let (e1, e2) = orthogonal_basis(&u);
        let v = e1 * delta[0] + e2 * delta[1];
        let theta = v.norm();
        // sin θ / θ by its series near 0.
        let sinc = if theta < 1e-4 {
            1.0 - theta * theta / 6.0
        } else {
            theta.sin() / theta
        };
        let u_new = (u * theta.cos() + v * sinc).normalize();
        let c_new = self.center + u_new * r;
        let mut rotation = pose.rotation * so3_exp(&Vector3::new(delta[2], delta[3], delta[4]));
        rotation.renormalize();
        let t = -(rotation * c_new);
        x_plus_delta.copy_from_slice(&[
            rotation.w, rotation.i, rotation.j, rotation.k, t.x, t.y, t.z,
        ]);
    }
}

/// Reprojection residual; arguments `[camera_from_world (7, SE(3)), point (3), intrinsics]`.
struct BaReprojection {
    camera: Arc<CameraCache>,
    sizes: [usize; 3],
    pixel: Vector2<f64>,
    /// The sphere centre when the pose block lives on [`CentreOnSphere`] (5 tangent columns).
    sphere: Option<Vector3<f64>>,
}

impl CostFunction for BaReprojection {
    fn num_residuals(&self) -> usize {
        2
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let pose = se3_from_unit_params(parameters[0]);
        let x = Vector3::new(parameters[1][0], parameters[1][1], parameters[1][2]);
        let p_cam = pose.rotation * x + pose.translation.vector;
        let Some(jac) = jacobians else {
            let Some(Ok(pixel)) = self.camera.with(parameters[2], |c| c.project(&p_cam)) else {
                return false;
            };
            residuals[0] = pixel.x - self.pixel.x;
            residuals[1] = pixel.y - self.pixel.y;
            return true;
        };
        let Some(Ok(pj)) = self
            .camera
            .with(parameters[2], |c| c.project_with_jacobians(&p_cam))
        else {
            return false;
        };
        residuals[0] = pj.pixel.x - self.pixel.x;
        residuals[1] = pj.pixel.y - self.pixel.y;
        let rotation: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
        let d_point = pj.d_pixel_d_point * rotation;
        if jac.wants(0) {
            let mut j = SMatrix::<f64, 2, 6>::zeros();
            j.fixed_view_mut::<2, 3>(0, 0).copy_from(&d_point);
            j.fixed_view_mut::<2, 3>(0, 3)
                .copy_from(&(-d_point * skew(&x)));
            match &self.sphere {
                None => jac.set(0, &j),
                Some(center) => {
                    let (c, _) = centre_of(parameters[0]);
                    jac.set(0, &(j * centre_tangent_map(&c, center)));
                }
            }
        }
        if jac.wants(1) {
            jac.set(1, &d_point);
        }
        let n = self.sizes[2];
        if let Some(j) = jac.row_major_mut(2) {
            for row in 0..2 {
                for col in 0..n {
                    j[row * n + col] = pj.d_pixel_d_params[(row, col)];
                }
            }
        }
        true
    }
}

/// [`Gauge::ScaleOnly`]'s prior `SCALE_PRIOR_WEIGHT · (|c₁ − c₂| / d₀ − 1)` on the centres of
/// two pose blocks; arguments `[camera_from_world₁ (7, SE(3)), camera_from_world₂ (7, SE(3))]`.
struct ScalePrior {
    distance: f64,
}

impl CostFunction for ScalePrior {
    fn num_residuals(&self) -> usize {
        1
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &[7, 7]
    }

    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let (c1, _) = centre_of(parameters[0]);
        let (c2, _) = centre_of(parameters[1]);
        let d = c1 - c2;
        let norm = d.norm();
        if norm == 0.0 {
            return false;
        }
        let k = SCALE_PRIOR_WEIGHT / self.distance;
        residuals[0] = k * norm - SCALE_PRIOR_WEIGHT;
        if let Some(jac) = jacobians {
            // c(T Exp(δ)) ≈ c − ρ + [c]× φ for δ = [ρ, φ].
            let n = d.transpose() * (k / norm);
            for (i, (c, sign)) in [(c1, 1.0), (c2, -1.0)].into_iter().enumerate() {
                let mut j = SMatrix::<f64, 1, 6>::zeros();
                j.fixed_view_mut::<1, 3>(0, 0).copy_from(&(-n * sign));
                j.fixed_view_mut::<1, 3>(0, 3)
                    .copy_from(&(n * skew(&c) * sign));
                jac.set(i, &j);
            }
        }
        true
    }
}

impl BundleAdjustment {
    fn validate(&self, options: &BundleAdjustmentOptions) -> Result<()> {
        let images = self.camera_from_world.len();
        if self.image_camera.len() != images {
            return Err(BundleAdjustError::LengthMismatch {
                what: "image_camera",
                expected: images,
                got: self.image_camera.len(),
            });
        }
        let cameras = self.cameras.len();
        if let Some((image, &camera)) = self
            .image_camera
            .iter()
            .enumerate()
            .find(|&(_, &c)| c >= cameras)
        {
            return Err(BundleAdjustError::IndexOutOfRange {
                what: "image",
                position: image,
                target: "camera",
                index: camera,
                count: cameras,
            });
        }
        let missing = |name: &'static str, i: usize| BundleAdjustError::InvalidOption {
            name,
            reason: format!("image {i} does not exist ({images} images)"),
        };
        match options.gauge {
            Gauge::FixedImages => {
                if let Some(&i) = options.fixed_images.iter().find(|&&i| i >= images) {
                    return Err(missing("fixed_images", i));
                }
            }
            Gauge::Similarity {
                reference_image: a,
                scale_image: b,
            }
            | Gauge::ScaleOnly {
                first_image: a,
                second_image: b,
            } => {
                if let Some(i) = [a, b].into_iter().find(|&i| i >= images) {
                    return Err(missing("gauge", i));
                }
                let centre = |i: usize| self.camera_from_world[i].inverse().translation.vector;
                let (ca, cb) = (centre(a), centre(b));
                // Coinciding centres (or one image twice) define no scale.
                if (ca - cb).norm() <= 1e-9 * (1.0 + ca.norm().max(cb.norm())) {
                    return Err(BundleAdjustError::InvalidOption {
                        name: "gauge",
                        reason: format!(
                            "the centres of images {a} and {b} coincide: their distance cannot fix the scale"
                        ),
                    });
                }
            }
        }
        validate_loss(&options.loss)?;
        for (index, p) in self.camera_from_world.iter().enumerate() {
            if !se3_to_params(p).iter().all(|v| v.is_finite()) {
                return Err(BundleAdjustError::NonFiniteInput {
                    what: "camera_from_world",
                    index,
                });
            }
        }
        for (index, x) in self.points.iter().enumerate() {
            if !x.iter().all(|v| v.is_finite()) {
                return Err(BundleAdjustError::NonFiniteInput {
                    what: "points",
                    index,
                });
            }
        }
        let points = self.points.len();
        for (i, o) in self.observations.iter().enumerate() {
            let out_of_range = |target, index, count| BundleAdjustError::IndexOutOfRange {
                what: "observation",
                position: i,
                target,
                index,
                count,
            };
            if o.image >= images {
                return Err(out_of_range("image", o.image, images));
            }
            if o.point >= points {
                return Err(out_of_range("point", o.point, points));
            }
            if !o.pixel.iter().all(|v| v.is_finite()) {
                return Err(BundleAdjustError::NonFiniteObservation { index: i });
            }
        }
        Ok(())
    }

    /// Root-mean-square reprojection error (pixels) of a scene over all observations
    /// (observations that cannot be projected are skipped).
    #[must_use]
    pub fn rms_error(
        &self,
        cameras: &[Camera],
        camera_from_world: &[Isometry3<f64>],
        points: &[Vector3<f64>],
    ) -> f64 {
        self.rms_over(&[], cameras, camera_from_world, points)
    }

    /// [`BundleAdjustment::rms_error`] without the observations in `excluded` (ascending).
    fn rms_over(
        &self,
        excluded: &[usize],
        cameras: &[Camera],
        camera_from_world: &[Isometry3<f64>],
        points: &[Vector3<f64>],
    ) -> f64 {
        let mut sum = 0.0;
        let mut n = 0usize;
        for (i, o) in self.observations.iter().enumerate() {
            if excluded.binary_search(&i).is_ok() {
                continue;
            }
            let (Some(pose), Some(x), Some(&c)) = (
                camera_from_world.get(o.image),
                points.get(o.point),
                self.image_camera.get(o.image),
            ) else {
                continue;
            };
            let Some(cam) = cameras.get(c) else { continue };
            if let Ok(px) = cam.project(&(pose * nalgebra::Point3::from(*x)).coords) {
                sum += (px - o.pixel).norm_squared();
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
    }

    /// The images whose whole pose is held by `options`.
    fn held_images(options: &BundleAdjustmentOptions) -> Vec<usize> {
        match options.gauge {
            Gauge::FixedImages => options.fixed_images.clone(),
            Gauge::Similarity {
                reference_image, ..
            } => vec![reference_image],
            Gauge::ScaleOnly { .. } => Vec::new(),
        }
    }

    /// Builds the [`Problem`]: one SE(3) block per image (held or on [`Gauge`]'s manifold as
    /// `options.gauge` says), one eliminated block per point, one block per camera's
    /// parameters, and one residual block per observation that can be evaluated at the
    /// initial estimate (see the module documentation for what is left out).
    ///
    /// # Errors
    /// As [`BundleAdjustment::solve`], except the solver's.
    pub fn to_problem(&self, options: &BundleAdjustmentOptions) -> Result<BaProblem> {
        self.validate(options)?;
        let held_images = Self::held_images(options);
        let sphere = match options.gauge {
            Gauge::Similarity {
                reference_image,
                scale_image,
            } => Some((
                scale_image,
                self.camera_from_world[reference_image]
                    .inverse()
                    .translation
                    .vector,
            )),
            _ => None,
        };
        let sphere_of = |image: usize| sphere.filter(|&(i, _)| i == image).map(|(_, c)| c);
        let caches: Vec<Arc<CameraCache>> = self
            .cameras
            .iter()
            .map(|c| Arc::new(CameraCache(RwLock::new(c.clone()))))
            .collect();
        let pose_params: Vec<[f64; 7]> = self.camera_from_world.iter().map(se3_to_params).collect();
        // Observations that cannot be evaluated at the start are left out.
        let mut probe = EvaluationProbe::default();
        let mut costs = Vec::with_capacity(self.observations.len());
        let mut excluded_observations = Vec::new();
        let mut used_by_image = vec![0usize; self.camera_from_world.len()];
        let mut used_by_point = vec![0usize; self.points.len()];
        let mut used_by_camera = vec![0usize; self.cameras.len()];
        for (i, o) in self.observations.iter().enumerate() {
            let c = self.image_camera[o.image];
            let n = self.cameras[c].num_params();
            let cost = BaReprojection {
                camera: Arc::clone(&caches[c]),
                sizes: [7, 3, n],
                pixel: o.pixel,
                sphere: sphere_of(o.image),
            };
            let params: [&[f64]; 3] = [
                &pose_params[o.image],
                self.points[o.point].as_slice(),
                self.cameras[c].params(),
            ];
            let pose_tangent = if cost.sphere.is_some() { 5 } else { 6 };
            if probe.evaluates(&cost, &params, &[pose_tangent, 3, n]) {
                used_by_image[o.image] += 1;
                used_by_point[o.point] += 1;
                used_by_camera[c] += 1;
                costs.push((i, o, c, cost));
            } else {
                excluded_observations.push(i);
            }
        }
        let excluded = |pick: &dyn Fn(&BaObservation) -> bool| {
            excluded_observations
                .iter()
                .filter(|&&i| pick(&self.observations[i]))
                .count()
        };
        if let Some(image) =
            (0..used_by_image.len()).find(|&i| used_by_image[i] == 0 && !held_images.contains(&i))
        {
            return Err(BundleAdjustError::ImageWithoutObservations {
                image,
                excluded: excluded(&|o| o.image == image),
            });
        }
        // A point whose every observation was excluded is left out; one without any
        // observation in the input is a mistake of the caller.
        let mut excluded_points = Vec::new();
        for (point, &n) in used_by_point.iter().enumerate() {
            if n == 0 {
                match excluded(&|o| o.point == point) {
                    0 => {
                        return Err(BundleAdjustError::PointWithoutObservations {
                            point,
                            excluded: 0,
                        });
                    }
                    _ => excluded_points.push(point),
                }
            }
        }
        if options.optimize_intrinsics
            && let Some(camera) = used_by_camera.iter().position(|&n| n == 0)
        {
            return Err(BundleAdjustError::CameraWithoutObservations {
                camera,
                excluded: excluded(&|o| self.image_camera[o.image] == camera),
            });
        }
        let mut problem = Problem::new();
        let poses = pose_params
            .iter()
            .enumerate()
            .map(|(i, p)| match sphere_of(i) {
                Some(center) => problem.add_manifold_block(p, CentreOnSphere { center }),
                None => problem.add_manifold_block(p, Se3Manifold),
            })
            .collect::<Result<Vec<_>>>()?;
        let points = self
            .points
            .iter()
            .map(|p| problem.add_parameter_block(p.as_slice()))
            .collect::<Result<Vec<_>>>()?;
        let intrinsics = self
            .cameras
            .iter()
            .map(|c| problem.add_parameter_block(c.params()))
            .collect::<Result<Vec<_>>>()?;
        for &p in &points {
            problem.set_eliminated(p, true)?;
        }
        for &j in &excluded_points {
            problem.set_constant(points[j], true)?;
        }
        for &i in &held_images {
            problem.set_constant(poses[i], true)?;
        }
        if !options.optimize_intrinsics {
            for &k in &intrinsics {
                problem.set_constant(k, true)?;
            }
        }
        // Residual blocks in point order, the order in which the solver visits them (a
        // stable sort: ascending within a point, so the solve is unchanged), so that its
        // passes read the residual blocks and their cost functions from memory in sequence.
        costs.sort_by_key(|(_, o, _, _)| o.point);
        let mut residuals = vec![None; self.observations.len()];
        for (i, o, c, cost) in costs {
            residuals[i] = Some(problem.add_residual_block(
                cost,
                options.loss,
                &[poses[o.image], points[o.point], intrinsics[c]],
            )?);
        }
        if let Gauge::ScaleOnly {
            first_image,
            second_image,
        } = options.gauge
        {
            let centre = |i: usize| self.camera_from_world[i].inverse().translation.vector;
            let distance = (centre(first_image) - centre(second_image)).norm();
            problem.add_residual_block(
                ScalePrior { distance },
                RobustLoss::Trivial,
                &[poses[first_image], poses[second_image]],
            )?;
        }
        Ok(BaProblem {
            problem,
            camera_from_world: poses,
            points,
            intrinsics,
            residuals,
            excluded_observations,
            excluded_points,
        })
    }

    /// Adjusts the scene, leaving out the observations that cannot be evaluated at the
    /// initial estimate, and the points left without observations by that (see the module
    /// documentation).
    ///
    /// # Errors
    /// [`BundleAdjustError::LengthMismatch`], [`BundleAdjustError::IndexOutOfRange`],
    /// [`BundleAdjustError::NonFiniteInput`] or [`BundleAdjustError::NonFiniteObservation`]
    /// for an inconsistent scene, [`BundleAdjustError::InvalidOption`] for a fixed or gauge
    /// image that does not exist or gauge images whose centres coincide,
    /// [`BundleAdjustError::InvalidLossScale`],
    /// [`BundleAdjustError::ImageWithoutObservations`] or
    /// [`BundleAdjustError::CameraWithoutObservations`] naming what is left without a usable
    /// observation, [`BundleAdjustError::PointWithoutObservations`] for a point no
    /// observation refers to, [`BundleAdjustError::RefinedIntrinsicsRejected`], and the
    /// errors of [`Problem::solve`].
    pub fn solve(&self, options: &BundleAdjustmentOptions) -> Result<BundleAdjustmentResult> {
        let BaProblem {
            mut problem,
            camera_from_world: poses,
            points,
            intrinsics,
            excluded_observations,
            excluded_points,
            ..
        } = self.to_problem(options)?;
        let summary = problem.solve(&options.solver)?;
        let block = |id: ParameterBlockId| problem.parameter_block(id);
        let camera_from_world = poses
            .iter()
            .map(|&id| Ok(se3_from_params(block(id)?)))
            .collect::<Result<Vec<_>>>()?;
        let points = points
            .iter()
            .map(|&id| block(id).map(|v| Vector3::new(v[0], v[1], v[2])))
            .collect::<Result<Vec<_>>>()?;
        let mut cameras = self.cameras.clone();
        for (camera, (model, &id)) in cameras.iter_mut().zip(&intrinsics).enumerate() {
            model.set_params(block(id)?).map_err(|source| {
                BundleAdjustError::RefinedIntrinsicsRejected { camera, source }
            })?;
        }
        Ok(BundleAdjustmentResult {
            initial_rms: self.rms_over(
                &excluded_observations,
                &self.cameras,
                &self.camera_from_world,
                &self.points,
            ),
            final_rms: self.rms_over(
                &excluded_observations,
                &cameras,
                &camera_from_world,
                &points,
            ),
            cameras,
            camera_from_world,
            points,
            excluded_observations,
            excluded_points,
            summary,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::JacobianSlot;

    /// The analytic Jacobians of a reprojection on [`CentreOnSphere`] and of the
    /// [`ScalePrior`] match central differences of their retractions, and the retraction
    /// keeps the centre on its sphere.
    #[test]
    fn gauge_jacobians_match_finite_differences() {
        let camera: Camera = ibc_camera_models::PinholeRadtan::new(
            640,
            480,
            [0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0],
        )
        .unwrap()
        .into();
        let pose = Isometry3::new(Vector3::new(0.3, -0.2, 4.0), Vector3::new(0.1, -0.3, 0.2));
        let x = se3_to_params(&pose);
        let center = Vector3::new(0.5, 0.1, -0.4);
        let point = [0.2, -0.1, 0.3];
        let cost = BaReprojection {
            camera: Arc::new(CameraCache(RwLock::new(camera.clone()))),
            sizes: [7, 3, 8],
            pixel: Vector2::new(300.0, 200.0),
            sphere: Some(center),
        };
        let slots = [
            JacobianSlot {
                offset: 0,
                cols: 5,
                wanted: true,
            },
            JacobianSlot {
                offset: 10,
                cols: 3,
                wanted: false,
            },
            JacobianSlot {
                offset: 10,
                cols: 8,
                wanted: false,
            },
        ];
        let mut jac = vec![0.0; 10];
        let mut r = [0.0; 2];
        let mut j = Jacobians::new(&mut jac, &slots, 2);
        assert!(cost.evaluate(&[&x, &point, camera.params()], &mut r, Some(&mut j)));
        let manifold = CentreOnSphere { center };
        let radius = (centre_of(&x).0 - center).norm();
        let h = 1e-6;
        for k in 0..5 {
            let mut fd = [0.0; 2];
            for (sign, weight) in [(1.0, 0.5 / h), (-1.0, -0.5 / h)] {
                let mut d = [0.0; 5];
                d[k] = sign * h;
                let mut moved = [0.0; 7];
                manifold.plus(&x, &d, &mut moved);
                assert!(((centre_of(&moved).0 - center).norm() / radius - 1.0).abs() < 1e-14);
                let mut rr = [0.0; 2];
                assert!(cost.evaluate(&[&moved, &point, camera.params()], &mut rr, None));
                fd[0] += weight * rr[0];
                fd[1] += weight * rr[1];
            }
            for row in 0..2 {
                let analytic = jac[row * 5 + k];
                assert!(
                    (fd[row] - analytic).abs() < 1e-5 * (1.0 + analytic.abs()),
                    "{k}: {fd:?} vs {analytic}"
                );
            }
        }
        // The scale prior, on SE(3) right perturbations of both poses.
        let other = se3_to_params(&Isometry3::new(
            Vector3::new(-0.5, 0.4, 3.0),
            Vector3::new(-0.2, 0.1, 0.3),
        ));
        let prior = ScalePrior { distance: 1.7 };
        let slots = [
            JacobianSlot {
                offset: 0,
                cols: 6,
                wanted: true,
            },
            JacobianSlot {
                offset: 6,
                cols: 6,
                wanted: true,
            },
        ];
        let mut jac = vec![0.0; 12];
        let mut r = [0.0];
        let mut j = Jacobians::new(&mut jac, &slots, 1);
        assert!(prior.evaluate(&[&x, &other], &mut r, Some(&mut j)));
        let h = 1e-7;
        for arg in 0..2 {
            for k in 0..6 {
                let mut fd = 0.0;
                for sign in [1.0, -1.0] {
                    let mut d = [0.0; 6];
                    d[k] = sign * h;
                    let mut params = [x, other];
                    Se3Manifold.plus(&[x, other][arg], &d, &mut params[arg]);
                    let mut rr = [0.0];
                    assert!(prior.evaluate(&[&params[0], &params[1]], &mut rr, None));
                    fd += sign * rr[0] / (2.0 * h);
                }
                let analytic = jac[arg * 6 + k];
                assert!(
                    (fd - analytic).abs() < 1e-4 * (1.0 + analytic.abs()),
                    "{arg} {k}: {fd} vs {analytic}"
                );
            }
        }
    }
}
