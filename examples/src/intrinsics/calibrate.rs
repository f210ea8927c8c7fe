//! The intrinsic calibration: validation, the model's initialization, the degeneracy check,
//! the joint refinement and the error statistics.

use std::str::FromStr;

use ibc_bundle_adjust::{SolverOptions, Termination};
use ibc_camera_models::{
    Camera, CameraModel, KannalaBrandt, ParameterError, PinholeRadtan, Unified,
};
use nalgebra::{DMatrix, Isometry3, Vector2};
use serde::{Deserialize, Serialize};

use super::board_pose::{ImageCorrespondences, all_correspondences};
use super::corners::{CornerSet, ImageCorners};
use super::error::IntrinsicsError;
use super::kb_init::{FocalHypothesis, KbInitOptions, kannala_brandt_initialization};
use super::mei_init::unified_initialization;
use super::pinhole_init::{centred_initialization, pinhole_initialization};
use super::robust::{RobustRefined, robust_refine};
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
    /// [`Unified`] (Mei), initialized from the line conics of the parabolic case
    /// ([`super::mei_init`]).
    Unified,
}

impl IntrinsicModel {
    /// The command-line name: `kb`, `pinhole` or `mei`.
    pub fn short_name(self) -> &'static str {
        match self {
            Self::KannalaBrandt => "kb",
            Self::PinholeRadtan => "pinhole",
            Self::Unified => "mei",
        }
    }

    /// Parameter names in CamOdoCal order.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            Self::KannalaBrandt => &KannalaBrandt::PARAM_NAMES,
            Self::PinholeRadtan => &PinholeRadtan::PARAM_NAMES,
            Self::Unified => &Unified::PARAM_NAMES,
        }
    }

    /// The number of parameters: 8, or 9 for the unified model.
    pub fn num_params(self) -> usize {
        self.param_names().len()
    }

    /// A camera of this model from its parameters (CamOdoCal order).
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
            Self::Unified => {
                Unified::new(width, height, [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0])?.into()
            }
        };
        camera.set_params(params)?;
        Ok(camera)
    }

    /// The model of a camera, if it is one of the three calibrated here.
    pub fn of(camera: &Camera) -> Option<Self> {
        match camera {
            Camera::KannalaBrandt(_) => Some(Self::KannalaBrandt),
            Camera::PinholeRadtan(_) => Some(Self::PinholeRadtan),
            Camera::Unified(_) => Some(Self::Unified),
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
            "mei" | "unified" | "omni" => Ok(Self::Unified),
            other => Err(IntrinsicsError::InvalidInput(format!(
                "unknown model `{other}`: expected kb, pinhole or mei"
            ))),
        }
    }
}

/// Options of [`calibrate_intrinsics`].
#[derive(Clone, Debug, PartialEq)]
pub struct IntrinsicsOptions {
    /// The line-based initializations' options: Kannala-Brandt's vanishing points and the
    /// unified model's line conics.
    pub kb_init: KbInitOptions,
    /// See [`MIN_NORMAL_SPREAD_DEG`] (the default).
    pub min_normal_spread_deg: f64,
    /// The refinement's Levenberg-Marquardt options. Default: Ceres's defaults with the
    /// function and parameter tolerances tightened to 1e-12 and up to 100 iterations, since
    /// the problem is small and the intrinsics are wanted to a hundredth of a pixel.
    pub solver: SolverOptions,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for IntrinsicsOptions {
    fn default() -> Self {
        Self {
            kb_init: KbInitOptions::default(),
            min_normal_spread_deg: MIN_NORMAL_SPREAD_DEG,
            solver: SolverOptions {
                function_tolerance: 1e-12,
                parameter_tolerance: 1e-12,
                max_iterations: 100,
                ..Default::default()
            },
            non_exhaustive: crate::NonExhaustive(()),
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
    /// Unified: the generalized focal length from the line conics of the parabolic case
    /// (Mei and Rives, ICRA 2007; [`super::mei_init`]).
    LineConics {
        /// Every hypothesis with its score (`focal` is `gamma`).
        hypotheses: Vec<FocalHypothesis>,
        /// Index of the one kept.
        chosen: usize,
    },
    /// Pinhole-radtan: the fallback when Zhang's start refined to a poor fit or had no
    /// solution: the principal point at the image centre and one focal length
    /// ([`super::pinhole_init::centred_initialization`]).
    CentredFocal {
        /// The focal length, pixels.
        focal_px: f64,
    },
}

/// A pinhole calibration refined from Zhang's start to an RMS above this (pixels, the RMS
/// gate [`MAX_RMS_PX`]), or whose closed form has no solution, is tried again from the
/// centred start; the centred fit is kept when its RMS is below half the other's (a false
/// minimum, not noisy corners, which no start fits better). Views that Zhang's constraints
/// find degenerate stay an error: no start determines the focal length then.
pub const PINHOLE_FALLBACK_RMS_PX: f64 = MAX_RMS_PX;

/// What became of an input image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageStatus {
    /// Its inlier corners are in the calibration.
    Used,
    /// Skipped: fewer than [`MIN_CORNERS_PER_IMAGE`] corners (a detector that failed on it).
    TooFewCorners,
    /// Excluded: most of its corners did not fit the others (garbage corners, a wrong
    /// ordering); see [`super::robust`].
    Outliers,
}

/// One corner's residual at the solution.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CornerResidual {
    /// Board row.
    pub row: u32,
    /// Board column.
    pub col: u32,
    /// Projected minus detected, horizontal, pixels.
    pub du: f64,
    /// Projected minus detected, vertical, pixels.
    pub dv: f64,
    /// Excluded as an outlier.
    pub outlier: bool,
}

/// Reprojection errors of one image at the solution.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ImageError {
    /// The image's name.
    pub name: String,
    /// Its number of corners.
    pub corners: usize,
    /// Whether it was used.
    pub status: ImageStatus,
    /// Its corners excluded as outliers.
    pub outliers: usize,
    /// RMS of the residual coordinates of its inlier corners, pixels (NaN, `null` in JSON,
    /// when it was not used).
    pub rms_px: f64,
    /// Largest residual length of its inlier corners, pixels.
    pub max_px: f64,
    /// Every corner's residual (none for a skipped image).
    pub residuals: Vec<CornerResidual>,
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
    /// `camera_from_board` of every image, in input order (`None` for a skipped image).
    pub camera_from_board: Vec<Option<Isometry3<f64>>>,
    /// Every corner's residual `pi(T X) - x` (pixels), image by image, in input order (none
    /// for a skipped image; an excluded image's with its pose re-estimated).
    pub residuals: Vec<Vec<Vector2<f64>>>,
    /// Whether each of those corners is an inlier of the final refinement.
    pub inliers: Vec<Vec<bool>>,
    /// Per-image errors, in input order.
    pub per_image: Vec<ImageError>,
    /// RMS of the inlier residual coordinates (pixels): comparable to the per-axis pixel
    /// noise.
    pub rms_px: f64,
    /// RMS of the inlier residual lengths (pixels): OpenCV's `calibrateCamera` figure,
    /// `sqrt(2)` times `rms_px` for isotropic noise.
    pub rms_distance_px: f64,
    /// The residual length above which a corner was an outlier, pixels (see
    /// [`super::robust`]).
    pub outlier_px: f64,
    /// Corners excluded as outliers (those of excluded images included).
    pub outlier_corners: usize,
    /// The quality gates that failed ([`IntrinsicsWarning`]): a calibration with any is
    /// [`IntrinsicsStatus::Poor`].
    pub warnings: Vec<IntrinsicsWarning>,
    /// RMS of the residual coordinates after the initialization (pixels).
    pub initial_rms_px: f64,
    /// Standard deviation of each parameter (CamOdoCal order), from `covariance`.
    pub std_devs: Vec<f64>,
    /// Covariance of the parameters with the board poses marginalized, scaled by the
    /// estimated noise variance (the solver's covariance, see
    /// [`ibc_bundle_adjust::Problem::covariance`]).
    pub covariance: DMatrix<f64>,
    /// The pixel noise estimated from the residuals, `sqrt(sum r^2 / (m - n))`.
    pub noise_sigma_px: f64,
    /// Largest angle between two board normals, degrees.
    pub normal_spread_deg: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why Levenberg-Marquardt stopped.
    pub termination: Termination,
}

/// A calibration is poor when its RMS per coordinate exceeds this, pixels: a corner
/// detector's noise is 0.05-0.5 px (OpenCV's `cornerSubPix` on a sharp board about 0.1 px),
/// so an RMS above 1 px means corners that do not belong to the board assumed, or a model
/// that cannot fit the lens.
pub const MAX_RMS_PX: f64 = 1.0;

/// A calibration is poor when a focal length's standard deviation exceeds this fraction of
/// its value: 1% (good calibrations reach 0.1% and better; the simulated 20 views 0.02%).
pub const MAX_FOCAL_RELATIVE_STD: f64 = 0.01;

/// A calibration is poor when a principal-point coordinate's standard deviation exceeds this
/// fraction of the image size along it: 1% (12.8 px on a 1280 px image).
pub const MAX_CENTER_RELATIVE_STD: f64 = 0.01;

/// A calibration is poor when more than this share of the corners are outliers: 10%.
pub const MAX_OUTLIER_SHARE: f64 = 0.1;

/// Why an intrinsic calibration should not be trusted as it is.
#[derive(Clone, Debug, PartialEq, Serialize, thiserror::Error)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum IntrinsicsWarning {
    /// The residuals are far above a corner detector's noise.
    #[error(
        "RMS {rms_px:.3} px per coordinate is far above a corner detector's noise (at most \
         {limit_px} px expected): a wrong board size or square, mismatched corner indices, or a \
         model that cannot fit the lens?"
    )]
    HighRms {
        /// The RMS per coordinate, pixels.
        rms_px: f64,
        /// [`MAX_RMS_PX`].
        limit_px: f64,
    },
    /// A parameter is poorly determined by the views.
    #[error(
        "the views do not determine `{parameter}` well: standard deviation {std:.3} px, \
         {percent:.2}% of {reference}; add views that tilt the board in different directions \
         and bring it to the image's edges",
        percent = 100.0 * std / scale
    )]
    Undetermined {
        /// The parameter's name.
        parameter: String,
        /// Its standard deviation, pixels.
        std: f64,
        /// What it is compared with, pixels.
        scale: f64,
        /// `"its value"` or `"the image size"`.
        reference: &'static str,
    },
    /// Many corners were outliers.
    #[error(
        "{outliers} of {corners} corners ({percent:.1}%) did not fit the others and were \
         excluded: is the detector reliable on these images?",
        percent = 100.0 * *outliers as f64 / *corners as f64
    )]
    ManyOutliers {
        /// Outlier corners.
        outliers: usize,
        /// All corners of the images used or excluded.
        corners: usize,
    },
    /// The refinement did not converge.
    #[error("the refinement stopped without converging ({termination})")]
    NotConverged {
        /// Why it stopped.
        termination: String,
    },
}

/// Whether an intrinsic calibration can be trusted as it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IntrinsicsStatus {
    /// Every gate passed.
    Ok,
    /// A gate failed: see the warnings.
    Poor,
}

impl IntrinsicCalibration {
    /// [`IntrinsicsStatus::Poor`] when a quality gate failed.
    pub fn status(&self) -> IntrinsicsStatus {
        if self.warnings.is_empty() {
            IntrinsicsStatus::Ok
        } else {
            IntrinsicsStatus::Poor
        }
    }
}

/// The gates of an intrinsic calibration (see the constants).
fn gates(
    camera: &Camera,
    std_devs: &[f64],
    rms_px: f64,
    outliers: usize,
    corners: usize,
    termination: Termination,
) -> Vec<IntrinsicsWarning> {
    let mut warnings = Vec::new();
    if rms_px.is_nan() || rms_px > MAX_RMS_PX {
        warnings.push(IntrinsicsWarning::HighRms {
            rms_px,
            limit_px: MAX_RMS_PX,
        });
    }
    let names = camera.param_names();
    let params = camera.params();
    let sizes = [f64::from(camera.width()), f64::from(camera.height())];
    // Every model orders its parameters [.., fx, fy, cx, cy] in the last four.
    let n = params.len();
    for (k, i) in (n.saturating_sub(4)..n).enumerate() {
        let (scale, limit, reference) = if k < 2 {
            (params[i].abs(), MAX_FOCAL_RELATIVE_STD, "its value")
        } else {
            (sizes[k - 2], MAX_CENTER_RELATIVE_STD, "the image size")
        };
        if std_devs[i].is_nan() || std_devs[i] > limit * scale {
            warnings.push(IntrinsicsWarning::Undetermined {
                parameter: names[i].to_owned(),
                std: std_devs[i],
                scale,
                reference,
            });
        }
    }
    if corners > 0 && outliers as f64 > MAX_OUTLIER_SHARE * corners as f64 {
        warnings.push(IntrinsicsWarning::ManyOutliers { outliers, corners });
    }
    if !termination.is_converged() {
        warnings.push(IntrinsicsWarning::NotConverged {
            termination: termination.name().to_owned(),
        });
    }
    warnings
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
/// Zhang's closed form, unified from Mei and Rives's line conics; each then refines all its
/// parameters and every board pose together (see
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
    // Every corner must be on the board and in the image; an image with too few corners (a
    // detector that failed on it) is skipped, not fatal.
    corners.validate(target, 0, 0)?;
    if !(options.min_normal_spread_deg.is_finite() && options.min_normal_spread_deg >= 0.0) {
        return Err(IntrinsicsError::InvalidInput(format!(
            "min_normal_spread_deg must be finite and non-negative, got {}",
            options.min_normal_spread_deg
        )));
    }
    let usable_index: Vec<usize> = (0..corners.images.len())
        .filter(|&i| corners.images[i].corners.len() >= MIN_CORNERS_PER_IMAGE)
        .collect();
    let usable = CornerSet {
        images: usable_index
            .iter()
            .map(|&i| corners.images[i].clone())
            .collect(),
        ..corners.clone()
    };
    if usable.images.len() < MIN_IMAGES {
        return Err(IntrinsicsError::TooFewImages {
            got: usable.images.len(),
            needed: MIN_IMAGES,
        });
    }
    let (w, h) = (corners.width, corners.height);
    let centred = || -> Result<(Camera, Vec<Isometry3<f64>>, Initialization), IntrinsicsError> {
        let init = centred_initialization(&usable, target)?;
        Ok((
            init.camera.into(),
            init.camera_from_board,
            Initialization::CentredFocal {
                focal_px: init.zhang.fx,
            },
        ))
    };
    let (initial_camera, initial_poses, initialization): (Camera, _, _) = match model {
        IntrinsicModel::KannalaBrandt => {
            let init = kannala_brandt_initialization(&usable, target, &options.kb_init)?;
            (
                init.camera.into(),
                init.camera_from_board,
                Initialization::VanishingPoints {
                    hypotheses: init.hypotheses,
                    chosen: init.chosen,
                },
            )
        }
        IntrinsicModel::PinholeRadtan => match pinhole_initialization(&usable, target) {
            Ok(init) => (
                init.camera.into(),
                init.camera_from_board,
                Initialization::Zhang(init.zhang),
            ),
            Err(zhang @ IntrinsicsError::Initialization(_)) => centred().map_err(|_| zhang)?,
            Err(e) => return Err(e),
        },
        IntrinsicModel::Unified => {
            let init = unified_initialization(&usable, target, &options.kb_init)?;
            (
                init.camera.into(),
                init.camera_from_board,
                Initialization::LineConics {
                    hypotheses: init.hypotheses,
                    chosen: init.chosen,
                },
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
    let data = all_correspondences(target, &usable);
    let initial = initial_camera.params().to_vec();
    let initial_rms_px = residual_stats(&initial_camera, &initial_poses, &data, None).0;
    let mut robust = robust_refine(
        model,
        (w, h),
        &initial,
        &initial_poses,
        &data,
        &options.solver,
    );
    let mut initialization = initialization;
    let mut initial_rms_px = initial_rms_px;
    let fit = |r: &RobustRefined| -> f64 {
        model
            .camera(w, h, &r.refined.params)
            .map_or(f64::INFINITY, |c| {
                residual_stats(&c, &r.refined.camera_from_board, &data, Some(&r.inliers)).0
            })
    };
    // Only a pinhole from Zhang's start gets the second start (a KB fit is never re-scored).
    if model == IntrinsicModel::PinholeRadtan
        && !matches!(initialization, Initialization::CentredFocal { .. })
        && robust
            .as_ref()
            .map_or(true, |r| fit(r) > PINHOLE_FALLBACK_RMS_PX)
        && let Ok((camera, poses, init)) = centred()
    {
        let start = camera.params().to_vec();
        if let Ok(alternative) =
            robust_refine(model, (w, h), &start, &poses, &data, &options.solver)
            && robust
                .as_ref()
                .map_or(true, |r| fit(&alternative) < 0.5 * fit(r))
        {
            initial_rms_px = residual_stats(&camera, &poses, &data, None).0;
            initialization = init;
            robust = Ok(alternative);
        }
    }
    let robust = robust?;
    let refined = &robust.refined;
    let camera = model.camera(w, h, &refined.params)?;
    let (rms_px, rms_distance_px, usable_residuals) = residual_stats(
        &camera,
        &refined.camera_from_board,
        &data,
        Some(&robust.inliers),
    );
    // Back to the input's images: a skipped image has no residuals.
    let mut residuals = vec![Vec::new(); corners.images.len()];
    let mut inliers = vec![Vec::new(); corners.images.len()];
    let mut camera_from_board = vec![None; corners.images.len()];
    for (k, &i) in usable_index.iter().enumerate() {
        residuals[i].clone_from(&usable_residuals[k]);
        inliers[i].clone_from(&robust.inliers[k]);
        camera_from_board[i] = refined.camera_from_board.get(k).copied();
    }
    let per_image: Vec<ImageError> = corners
        .images
        .iter()
        .enumerate()
        .map(|(i, image)| {
            let status = match usable_index.iter().position(|&u| u == i) {
                None => ImageStatus::TooFewCorners,
                Some(k) if !robust.kept[k] => ImageStatus::Outliers,
                Some(_) => ImageStatus::Used,
            };
            image_error(image, status, &residuals[i], &inliers[i])
        })
        .collect();
    let outlier_corners = inliers.iter().flatten().filter(|&&i| !i).count();
    let used_corners = inliers.iter().map(Vec::len).sum();
    let covariance = refined.covariance.clone().ok_or_else(|| {
        IntrinsicsError::SingularInformation(
            "some intrinsic parameter is not observable from these views".into(),
        )
    })?;
    let std_devs = covariance
        .diagonal()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect::<Vec<_>>();
    let warnings = gates(
        &camera,
        &std_devs,
        rms_px,
        outlier_corners,
        used_corners,
        refined.summary.termination,
    );
    Ok(IntrinsicCalibration {
        model,
        camera,
        initial_camera,
        initialization,
        camera_from_board,
        residuals,
        inliers,
        per_image,
        rms_px,
        rms_distance_px,
        outlier_px: robust.outlier_px,
        outlier_corners,
        warnings,
        initial_rms_px,
        std_devs,
        covariance,
        noise_sigma_px: refined.noise_variance.sqrt(),
        normal_spread_deg: spread,
        iterations: refined.summary.iterations,
        termination: refined.summary.termination,
    })
}

/// The report entry of an image from its residuals and inlier flags.
fn image_error(
    image: &ImageCorners,
    status: ImageStatus,
    residuals: &[Vector2<f64>],
    inliers: &[bool],
) -> ImageError {
    let kept: Vec<&Vector2<f64>> = residuals
        .iter()
        .zip(inliers)
        .filter(|(_, i)| **i)
        .map(|(r, _)| r)
        .collect();
    let (rms_px, max_px) = if status == ImageStatus::Used && !kept.is_empty() {
        let n = kept.len() as f64;
        (
            (kept.iter().map(|e| e.norm_squared()).sum::<f64>() / (2.0 * n)).sqrt(),
            kept.iter().map(|e| e.norm()).fold(0.0, f64::max),
        )
    } else {
        (f64::NAN, f64::NAN)
    };
    ImageError {
        name: image.name.clone(),
        corners: image.corners.len(),
        status,
        outliers: inliers.iter().filter(|&&i| !i).count(),
        rms_px,
        max_px,
        residuals: image
            .corners
            .iter()
            .zip(residuals)
            .zip(inliers)
            .map(|((c, r), &inlier)| CornerResidual {
                row: c.row,
                col: c.col,
                du: r.x,
                dv: r.y,
                outlier: !inlier,
            })
            .collect(),
    }
}

/// Type of the per-image residual lists.
type Residuals = Vec<Vec<Vector2<f64>>>;

/// (RMS per coordinate, RMS length, residuals) of a camera and poses, the statistics over the
/// corners flagged in `inliers` (all when `None`); a corner that does not project has an
/// infinite residual.
fn residual_stats(
    camera: &Camera,
    poses: &[Isometry3<f64>],
    data: &[ImageCorrespondences],
    inliers: Option<&[Vec<bool>]>,
) -> (f64, f64, Residuals) {
    let mut sum = 0.0;
    let mut n = 0usize;
    let mut all = Vec::with_capacity(data.len());
    for (i, ((points, pixels), pose)) in data.iter().zip(poses).enumerate() {
        let mut image = Vec::with_capacity(points.len());
        for (k, (x, obs)) in points.iter().zip(pixels).enumerate() {
            let r = camera
                .project(&(pose * x).coords)
                .map_or(Vector2::repeat(f64::INFINITY), |p| p - obs);
            if inliers.is_none_or(|f| f.get(i).and_then(|f| f.get(k)).copied().unwrap_or(false)) {
                sum += r.norm_squared();
                n += 1;
            }
            image.push(r);
        }
        all.push(image);
    }
    let n = n.max(1) as f64;
    ((sum / (2.0 * n)).sqrt(), (sum / n).sqrt(), all)
}
