//! The intrinsic calibration: validation, the model's initialization, the degeneracy check,
//! the joint refinement and the error statistics.

use std::str::FromStr;

use ibc_bundle_adjust::{SolverOptions, Termination};
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, ParameterError, PinholeRadtan};
use nalgebra::{Isometry3, SMatrix, Vector2};
use serde::{Deserialize, Serialize};

use super::board_pose::{ImageCorrespondences, all_correspondences};
use super::corners::CornerSet;
use super::error::IntrinsicsError;
use super::kb_init::{FocalHypothesis, KbInitOptions, kannala_brandt_initialization};
use super::pinhole_init::pinhole_initialization;
use super::refine::refine;
use super::target::PlanarTarget;
use super::zhang::ZhangIntrinsics;

/// Images a calibration needs at least: Zhang's closed form needs three views in general
/// (PAMI 2000, section 3.1), and every image adds six pose unknowns.
pub const MIN_IMAGES: usize = 3;

/// Corners an image needs at least: more than the four a board pose needs, so that the image
/// also constrains the intrinsics.
pub const MIN_CORNERS_PER_IMAGE: usize = 6;

/// Below this largest angle between two board normals (degrees) the boards are taken as all
/// parallel to each other, which leaves the focal length and the board distance inseparable
/// (Zhang, PAMI 2000, section 3.3). Real calibrations tilt the board by 20 to 45 degrees.
pub const MIN_NORMAL_SPREAD_DEG: f64 = 5.0;

/// The camera model to calibrate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum IntrinsicModel {
    /// [`KannalaBrandt`], initialized by the paper's vanishing-point method.
    KannalaBrandt,
    /// [`PinholeRadtan`], initialized by Zhang's closed form.
    PinholeRadtan,
}

impl IntrinsicModel {
    /// The command-line name: `kb` or `pinhole`.
    pub fn short_name(self) -> &'static str {
        match self {
            Self::KannalaBrandt => "kb",
            Self::PinholeRadtan => "pinhole",
        }
    }

    /// Parameter names in CamOdoCal order.
    pub fn param_names(self) -> [&'static str; 8] {
        match self {
            Self::KannalaBrandt => KannalaBrandt::PARAM_NAMES,
            Self::PinholeRadtan => PinholeRadtan::PARAM_NAMES,
        }
    }

    /// A camera of this model from its 8 parameters (CamOdoCal order).
    ///
    /// # Errors
    /// [`ParameterError`] for a wrong count, a non-finite value or a non-positive focal
    /// length.
    pub fn camera(self, width: u32, height: u32, params: &[f64]) -> Result<Camera, ParameterError> {
        let mut camera: Camera = match self {
            Self::KannalaBrandt => {
                KannalaBrandt::new(width, height, [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0])?.into()
            }
            Self::PinholeRadtan => {
                PinholeRadtan::new(width, height, [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0])?.into()
            }
        };
        camera.set_params(params)?;
        Ok(camera)
    }

    /// The model of a camera, if it is one of the two calibrated here.
    pub fn of(camera: &Camera) -> Option<Self> {
        match camera {
            Camera::KannalaBrandt(_) => Some(Self::KannalaBrandt),
            Camera::PinholeRadtan(_) => Some(Self::PinholeRadtan),
            _ => None,
        }
    }
}

impl FromStr for IntrinsicModel {
    type Err = IntrinsicsError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "kb" | "kannala_brandt" | "kannala-brandt" => Ok(Self::KannalaBrandt),
            "pinhole" | "pinhole_radtan" | "pinhole-radtan" => Ok(Self::PinholeRadtan),
            "mei" | "unified" => Err(IntrinsicsError::InvalidInput(
                "the unified (Mei) model is not calibrated here: its initialization is left out; \
                 use kb for fisheyes or pinhole"
                    .into(),
            )),
            other => Err(IntrinsicsError::InvalidInput(format!(
                "unknown model `{other}`: expected kb or pinhole"
            ))),
        }
    }
}

/// Options of [`calibrate_intrinsics`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct IntrinsicsOptions {
    /// The Kannala-Brandt initialization's options.
    pub kb_init: KbInitOptions,
    /// See [`MIN_NORMAL_SPREAD_DEG`] (the default).
    pub min_normal_spread_deg: f64,
    /// The refinement's Levenberg-Marquardt options. Default: Ceres's defaults with the
    /// function and parameter tolerances tightened to 1e-12 and up to 100 iterations, since
    /// the problem is small and the intrinsics are wanted to a hundredth of a pixel.
    pub solver: SolverOptions,
}

impl Default for IntrinsicsOptions {
    fn default() -> Self {
        let mut solver = SolverOptions::default();
        solver.function_tolerance = 1e-12;
        solver.parameter_tolerance = 1e-12;
        solver.max_iterations = 100;
        Self {
            kb_init: KbInitOptions::default(),
            min_normal_spread_deg: MIN_NORMAL_SPREAD_DEG,
            solver,
        }
    }
}

/// How the intrinsics were initialized.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Initialization {
    /// Kannala-Brandt: the paper's vanishing-point hypotheses.
    VanishingPoints {
        /// Every hypothesis with its score.
        hypotheses: Vec<FocalHypothesis>,
        /// Index of the one kept.
        chosen: usize,
    },
    /// Pinhole-radtan: Zhang's closed form.
    Zhang(ZhangIntrinsics),
}

/// Reprojection errors of one image at the solution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageError {
    /// The image's name.
    pub name: String,
    /// Its number of corners.
    pub corners: usize,
    /// RMS of the residual coordinates, pixels.
    pub rms_px: f64,
    /// Largest residual length, pixels.
    pub max_px: f64,
}

/// The result of [`calibrate_intrinsics`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct IntrinsicCalibration {
    /// The model calibrated.
    pub model: IntrinsicModel,
    /// The calibrated camera.
    pub camera: Camera,
    /// The camera after the initialization, before the refinement.
    pub initial_camera: Camera,
    /// How the initialization went.
    pub initialization: Initialization,
    /// `camera_from_board` of every image, in input order.
    pub camera_from_board: Vec<Isometry3<f64>>,
    /// Every corner's residual `pi(T X) - x` (pixels), image by image, in input order.
    pub residuals: Vec<Vec<Vector2<f64>>>,
    /// Per-image errors, in input order.
    pub per_image: Vec<ImageError>,
    /// RMS of all residual coordinates (pixels): comparable to the per-axis pixel noise.
    pub rms_px: f64,
    /// RMS of the residual lengths (pixels): OpenCV's `calibrateCamera` figure, `sqrt(2)`
    /// times `rms_px` for isotropic noise.
    pub rms_distance_px: f64,
    /// RMS of the residual coordinates after the initialization (pixels).
    pub initial_rms_px: f64,
    /// Standard deviation of each parameter (CamOdoCal order), from `covariance`.
    pub std_devs: [f64; 8],
    /// Covariance of the parameters with the board poses marginalized, scaled by the
    /// estimated noise variance (the solver's covariance, see
    /// [`ibc_bundle_adjust::Problem::covariance`]).
    pub covariance: SMatrix<f64, 8, 8>,
    /// The pixel noise estimated from the residuals, `sqrt(sum r^2 / (m - n))`.
    pub noise_sigma_px: f64,
    /// Largest angle between two board normals, degrees.
    pub normal_spread_deg: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why Levenberg-Marquardt stopped.
    pub termination: Termination,
}

/// The largest angle between the normals of two boards (degrees): 0 when every board is
/// parallel to every other.
pub fn normal_spread_deg(camera_from_board: &[Isometry3<f64>]) -> f64 {
    let normals: Vec<_> = camera_from_board
        .iter()
        .map(|t| t.rotation * nalgebra::Vector3::z())
        .collect();
    let mut widest: f64 = 0.0;
    for (i, a) in normals.iter().enumerate() {
        for b in &normals[i + 1..] {
            widest = widest.max(a.angle(b));
        }
    }
    widest.to_degrees()
}

/// Calibrates a camera's intrinsics from corners of a planar target.
///
/// Kannala-Brandt starts from the paper's vanishing-point hypotheses, pinhole-radtan from
/// Zhang's closed form; both then refine the 8 parameters and every board pose together (see
/// [`crate::intrinsics`]).
///
/// # Errors
/// The validation errors of [`CornerSet::validate`] (with [`MIN_CORNERS_PER_IMAGE`] and
/// [`MIN_IMAGES`]), [`IntrinsicsError::DegenerateViews`], the initialization's errors,
/// [`IntrinsicsError::Solver`] or [`IntrinsicsError::Refinement`] if the refinement fails,
/// and [`IntrinsicsError::SingularInformation`] if the intrinsics have no covariance.
pub fn calibrate_intrinsics(
    corners: &CornerSet,
    target: &PlanarTarget,
    model: IntrinsicModel,
    options: &IntrinsicsOptions,
) -> Result<IntrinsicCalibration, IntrinsicsError> {
    target.validate()?;
    corners.validate(target, MIN_CORNERS_PER_IMAGE, MIN_IMAGES)?;
    if !(options.min_normal_spread_deg.is_finite() && options.min_normal_spread_deg >= 0.0) {
        return Err(IntrinsicsError::InvalidInput(format!(
            "min_normal_spread_deg must be finite and non-negative, got {}",
            options.min_normal_spread_deg
        )));
    }
    let (w, h) = (corners.width, corners.height);
    let (initial_camera, initial_poses, initialization): (Camera, _, _) = match model {
        IntrinsicModel::KannalaBrandt => {
            let init = kannala_brandt_initialization(corners, target, &options.kb_init)?;
            (
                init.camera.into(),
                init.camera_from_board,
                Initialization::VanishingPoints {
                    hypotheses: init.hypotheses,
                    chosen: init.chosen,
                },
            )
        }
        IntrinsicModel::PinholeRadtan => {
            let init = pinhole_initialization(corners, target)?;
            (
                init.camera.into(),
                init.camera_from_board,
                Initialization::Zhang(init.zhang),
            )
        }
    };
    let spread = normal_spread_deg(&initial_poses);
    if spread < options.min_normal_spread_deg {
        return Err(IntrinsicsError::DegenerateViews {
            reason: format!(
                "the board normals span only {spread:.2} degrees (at least {:.1} are needed): \
                 every board is nearly parallel to every other, for instance all parallel to \
                 the image",
                options.min_normal_spread_deg
            ),
        });
    }
    let data = all_correspondences(target, corners);
    let mut initial = [0.0; 8];
    initial.copy_from_slice(initial_camera.params());
    let initial_rms_px = residual_stats(&initial_camera, &initial_poses, &data)?.0;
    let refined = refine(
        model,
        w,
        h,
        &initial,
        &initial_poses,
        &data,
        &options.solver,
    )?;
    let camera = model.camera(w, h, &refined.params)?;
    let (rms_px, rms_distance_px, residuals) =
        residual_stats(&camera, &refined.camera_from_board, &data)?;
    let per_image = corners
        .images
        .iter()
        .zip(&residuals)
        .map(|(image, r)| {
            let n = r.len().max(1) as f64;
            ImageError {
                name: image.name.clone(),
                corners: r.len(),
                rms_px: (r.iter().map(|e| e.norm_squared()).sum::<f64>() / (2.0 * n)).sqrt(),
                max_px: r.iter().map(|e| e.norm()).fold(0.0, f64::max),
            }
        })
        .collect();
    let std_devs = std::array::from_fn(|i| refined.covariance[(i, i)].max(0.0).sqrt());
    Ok(IntrinsicCalibration {
        model,
        camera,
        initial_camera,
        initialization,
        camera_from_board: refined.camera_from_board,
        residuals,
        per_image,
        rms_px,
        rms_distance_px,
        initial_rms_px,
        std_devs,
        covariance: refined.covariance,
        noise_sigma_px: refined.noise_variance.sqrt(),
        normal_spread_deg: spread,
        iterations: refined.summary.iterations,
        termination: refined.summary.termination,
    })
}

/// Type of the per-image residual lists.
type Residuals = Vec<Vec<Vector2<f64>>>;

/// (RMS per coordinate, RMS length, residuals) of a camera and poses.
fn residual_stats(
    camera: &Camera,
    poses: &[Isometry3<f64>],
    data: &[ImageCorrespondences],
) -> Result<(f64, f64, Residuals), IntrinsicsError> {
    let mut sum = 0.0;
    let mut n = 0usize;
    let mut all = Vec::with_capacity(data.len());
    for (i, ((points, pixels), pose)) in data.iter().zip(poses).enumerate() {
        let mut image = Vec::with_capacity(points.len());
        for (x, obs) in points.iter().zip(pixels) {
            let p = camera.project(&(pose * x).coords).map_err(|e| {
                IntrinsicsError::Refinement(format!(
                    "a corner of image {i} does not project with the estimated camera: {e}"
                ))
            })?;
            let r = p - obs;
            sum += r.norm_squared();
            n += 1;
            image.push(r);
        }
        all.push(image);
    }
    let n = n.max(1) as f64;
    Ok(((sum / (2.0 * n)).sqrt(), (sum / n).sqrt(), all))
}
