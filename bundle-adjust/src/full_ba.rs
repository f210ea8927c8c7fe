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
//! **Gauge.** A similarity of the world (7 degrees of freedom) leaves the cost unchanged. The
//! images in [`BundleAdjustmentOptions::fixed_images`] keep their poses; one fixed image
//! removes rotation and translation, two remove the scale as well. A remaining scale
//! freedom is harmless to Levenberg-Marquardt (the damping keeps the step finite) but leaves
//! the covariance undefined.
//!
//! **Bad starts.** An observation that cannot be evaluated at the initial estimate (its point
//! behind the camera, outside the camera model's domain, or a non-finite residual or
//! Jacobian) is left out and reported in [`BundleAdjustmentResult::excluded_observations`].
//! An image whose pose is free, a point, or (with
//! [`BundleAdjustmentOptions::optimize_intrinsics`]) a camera left without observations is a
//! typed error naming it.

use std::sync::{Arc, RwLock};

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, SMatrix, Vector2, Vector3};

use crate::corrector::validate_loss;
use crate::cost::{CostFunction, EvaluationProbe, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::manifold::{Se3Manifold, se3_from_params, se3_from_unit_params, se3_to_params, skew};
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

/// Options of [`BundleAdjustment::solve`].
///
/// ```
/// use ibc_bundle_adjust::{BundleAdjustmentOptions, RobustLoss};
///
/// let options = BundleAdjustmentOptions {
///     optimize_intrinsics: true,
///     fixed_images: vec![0, 1],
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
    /// Images whose poses are held fixed (default `vec![0]`, image 0).
    pub fixed_images: Vec<usize>,
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
    /// The solver's summary.
    pub summary: Summary,
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

/// Reprojection residual; arguments `[camera_from_world (7, SE(3)), point (3), intrinsics]`.
struct BaReprojection {
    camera: Arc<CameraCache>,
    sizes: [usize; 3],
    pixel: Vector2<f64>,
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
            jac.set(0, &j);
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
        if let Some(&i) = options.fixed_images.iter().find(|&&i| i >= images) {
            return Err(BundleAdjustError::InvalidOption {
                name: "fixed_images",
                reason: format!("image {i} does not exist ({images} images)"),
            });
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

    /// Adjusts the scene, leaving out the observations that cannot be evaluated at the
    /// initial estimate (see the module documentation).
    ///
    /// # Errors
    /// [`BundleAdjustError::LengthMismatch`], [`BundleAdjustError::IndexOutOfRange`],
    /// [`BundleAdjustError::NonFiniteInput`] or [`BundleAdjustError::NonFiniteObservation`]
    /// for an inconsistent scene, [`BundleAdjustError::InvalidOption`] for a fixed image that
    /// does not exist, [`BundleAdjustError::InvalidLossScale`],
    /// [`BundleAdjustError::ImageWithoutObservations`],
    /// [`BundleAdjustError::PointWithoutObservations`] or
    /// [`BundleAdjustError::CameraWithoutObservations`] naming what is left without a usable
    /// observation, [`BundleAdjustError::RefinedIntrinsicsRejected`], and the errors of
    /// [`Problem::solve`].
    pub fn solve(&self, options: &BundleAdjustmentOptions) -> Result<BundleAdjustmentResult> {
        self.validate(options)?;
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
            };
            let params: [&[f64]; 3] = [
                &pose_params[o.image],
                self.points[o.point].as_slice(),
                self.cameras[c].params(),
            ];
            if probe.evaluates(&cost, &params, &[6, 3, n]) {
                used_by_image[o.image] += 1;
                used_by_point[o.point] += 1;
                used_by_camera[c] += 1;
                costs.push((o, c, cost));
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
        if let Some(image) = (0..used_by_image.len())
            .find(|&i| used_by_image[i] == 0 && !options.fixed_images.contains(&i))
        {
            return Err(BundleAdjustError::ImageWithoutObservations {
                image,
                excluded: excluded(&|o| o.image == image),
            });
        }
        if let Some(point) = used_by_point.iter().position(|&n| n == 0) {
            return Err(BundleAdjustError::PointWithoutObservations {
                point,
                excluded: excluded(&|o| o.point == point),
            });
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
            .map(|p| problem.add_manifold_block(p, Se3Manifold))
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
        for &i in &options.fixed_images {
            problem.set_constant(poses[i], true)?;
        }
        if !options.optimize_intrinsics {
            for &k in &intrinsics {
                problem.set_constant(k, true)?;
            }
        }
        for (o, c, cost) in costs {
            problem.add_residual_block(
                cost,
                options.loss,
                &[poses[o.image], points[o.point], intrinsics[c]],
            )?;
        }
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
            summary,
        })
    }
}
