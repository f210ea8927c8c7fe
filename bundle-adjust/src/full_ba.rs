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

use std::sync::{Arc, RwLock};

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, SMatrix, Vector2, Vector3};

use crate::cost::{CostFunction, Jacobians};
use crate::error::{BundleAdjustError, Result};
use crate::loss::Loss;
use crate::manifold::{Se3Manifold, se3_from_params, se3_from_unit_params, se3_to_params, skew};
use crate::options::SolverOptions;
use crate::problem::{ParameterBlockId, Problem};
use crate::summary::Summary;

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
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct BundleAdjustmentOptions {
    /// Robust loss on the squared pixel error (default: Cauchy with a = 1 pixel).
    pub loss: Loss,
    /// Optimize the intrinsics too (default false).
    pub optimize_intrinsics: bool,
    /// Images whose poses are held fixed (default: image 0).
    pub fixed_images: Vec<usize>,
    /// Solver options (default: [`SolverOptions::default`]).
    pub solver: SolverOptions,
}

impl Default for BundleAdjustmentOptions {
    fn default() -> Self {
        Self {
            loss: Loss::Cauchy(1.0),
            optimize_intrinsics: false,
            fixed_images: vec![0],
            solver: SolverOptions::default(),
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
    /// Root-mean-square reprojection error (pixels) at the start.
    pub initial_rms: f64,
    /// Root-mean-square reprojection error (pixels) at the solution.
    pub final_rms: f64,
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
        let invalid = |m: String| Err(BundleAdjustError::InvalidProblem(m));
        if self.image_camera.len() != self.camera_from_world.len() {
            return invalid(format!(
                "{} images have poses but {} have cameras",
                self.camera_from_world.len(),
                self.image_camera.len()
            ));
        }
        if let Some(&c) = self.image_camera.iter().find(|&&c| c >= self.cameras.len()) {
            return invalid(format!(
                "camera {c} does not exist ({} cameras)",
                self.cameras.len()
            ));
        }
        if let Some(&i) = options
            .fixed_images
            .iter()
            .find(|&&i| i >= self.camera_from_world.len())
        {
            return invalid(format!("fixed image {i} does not exist"));
        }
        for (i, p) in self.camera_from_world.iter().enumerate() {
            if !se3_to_params(p).iter().all(|v| v.is_finite()) {
                return invalid(format!("camera_from_world[{i}] is not finite"));
            }
        }
        for (i, o) in self.observations.iter().enumerate() {
            if o.image >= self.camera_from_world.len() || o.point >= self.points.len() {
                return invalid(format!(
                    "observation {i} refers to image {} or point {} that does not exist",
                    o.image, o.point
                ));
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
        let mut sum = 0.0;
        let mut n = 0usize;
        for o in &self.observations {
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

    /// Adjusts the scene.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidProblem`] for inconsistent indices or sizes,
    /// [`BundleAdjustError::NonFiniteObservation`], and the errors of [`Problem::solve`].
    pub fn solve(&self, options: &BundleAdjustmentOptions) -> Result<BundleAdjustmentResult> {
        self.validate(options)?;
        let mut problem = Problem::new();
        let poses = self
            .camera_from_world
            .iter()
            .map(|p| problem.add_manifold_block(&se3_to_params(p), Se3Manifold))
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
        let caches: Vec<Arc<CameraCache>> = self
            .cameras
            .iter()
            .map(|c| Arc::new(CameraCache(RwLock::new(c.clone()))))
            .collect();
        for o in &self.observations {
            let c = self.image_camera[o.image];
            problem.add_residual_block(
                BaReprojection {
                    camera: Arc::clone(&caches[c]),
                    sizes: [7, 3, self.cameras[c].num_params()],
                    pixel: o.pixel,
                },
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
        for (camera, &id) in cameras.iter_mut().zip(&intrinsics) {
            camera.set_params(block(id)?).map_err(|e| {
                BundleAdjustError::InvalidProblem(format!("refined intrinsics rejected: {e}"))
            })?;
        }
        Ok(BundleAdjustmentResult {
            initial_rms: self.rms_error(&self.cameras, &self.camera_from_world, &self.points),
            final_rms: self.rms_error(&cameras, &camera_from_world, &points),
            cameras,
            camera_from_world,
            points,
            summary,
        })
    }
}
