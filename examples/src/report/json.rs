//! The JSON report of a calibration: [`Report`], built by [`Report::new`].
//!
//! Conventions: poses are `{"translation": [x, y, z], "rotation_wxyz": [w, x, y, z]}`, named
//! `a_from_b`; the rig frame is camera 0's; lengths in metres, angles in degrees, pixels with
//! centres at integer coordinates. A number that does not exist (a standard deviation the data
//! cannot determine, an error without ground truth) is `null`.
//!
//! ```json
//! {
//!   "format": "ibc-calibration-report", "version": 1,
//!   "scenario": "garage", "seed": 1,
//!   "cameras": [{
//!     "name": "left", "model": "kannala_brandt", "images_localized": 497,
//!     "rig_from_camera": {"translation": [...], "rotation_wxyz": [...]},
//!     "rig_from_camera_std": {"translation_m": [...], "rotation_deg": [...]},
//!     "change_from_prior": {"translation_m": [...], "distance_m": 0.097, "rotation_deg": 0.0},
//!     "rotation_error_deg": 0.001, "translation_error_deg": 0.01, "translation_error_m": 0.0002,
//!     "inliers": 98000, "correspondences": 50000,
//!     "reprojection_px": {"initial": {"mean": 0.7, "rms": 0.8, "mad": 0.55},
//!                         "final": {"mean": 0.62, "rms": 0.7, "mad": 0.5}},
//!     "outlier_fraction": 0.0,
//!     "residual_pattern": {"pattern_px": 0.03, "noise_px": 0.01, "chi2_per_dof": 1.1},
//!     "intrinsics": [-0.01, 0.002, 0.0, 0.0, 391.0, 391.9, 640.1, 480.2],
//!     "intrinsics_refinement": {"refined": [{"name": "mu", "camera_file": 395.0,
//!         "refined": 391.0, "std": 0.01, "observability": 0.3, "error": 0.01}, ...],
//!         "held": [{"name": "k4", "observability": 0.00002}]} or null
//!   }, ...],
//!   "status": "ok",
//!   "warnings": [{"kind": "systematic_residuals", "camera": "left", "message": "..."}],
//!   "frames": 500, "images": 2000, "images_localized": 1990,
//!   "frame_sets_used": 480, "mean_poses_per_set": 3.98, "correspondences": 380000,
//!   "reprojection_error_px": {"initial": 0.8, "final": 0.62, "at_truth": 0.62},
//!   "initialization": {"hypothesis": "frame set 12", "hypotheses": 98, "score_px": 0.8},
//!   "refinement": {"iterations": 5, "termination": "function tolerance", ...},
//!   "hand_eye": {"method": "guo-planar", "rig_from_odometry": {...}, ...} or null,
//!   "timing_s": {"vocabulary": 0.6, "localization": 2.0, "initialization": 0.1,
//!                "refinement": 0.4, "hand_eye": 0.01, "total": 3.2}
//! }
//! ```

use ibc_hand_eye::HandEyeError;
use nalgebra::{Isometry3, Vector3};
use serde::Serialize;

use crate::calib::accuracy::relative_to_first;
use crate::calib::quality::{CameraQuality, ResidualPattern, ResidualStats};
use crate::calib::{
    Calibration, CalibrationError, CameraMatching, HandEyeFailure, InitialHypothesis, Status,
    Timing,
};
use crate::data::GroundTruth;

/// What the refinement did with camera `c`'s intrinsics, `None` when none was selected.
fn intrinsics_json(
    calibration: &Calibration,
    truth: Option<&GroundTruth>,
    c: usize,
) -> Option<IntrinsicsRefinementJson> {
    let i = calibration.refinement.intrinsics.get(c)?;
    if i.refined.is_empty() && i.held.is_empty() {
        return None;
    }
    let true_params = truth.and_then(|t| t.intrinsics.get(c));
    Some(IntrinsicsRefinementJson {
        refined: i
            .refined
            .iter()
            .map(|p| IntrinsicJson {
                name: p.name.to_owned(),
                camera_file: p.prior,
                refined: p.value,
                std: finite(p.std),
                observability: p.observability,
                error: true_params
                    .and_then(|t| t.get(p.index))
                    .map(|t| p.value - t),
            })
            .collect(),
        held: i
            .held
            .iter()
            .map(|h| HeldIntrinsicJson {
                name: h.name.to_owned(),
                observability: h.observability,
            })
            .collect(),
    })
}

/// The value of [`Report::format`].
pub const REPORT_FORMAT: &str = "ibc-calibration-report";

/// The version of the report's layout.
pub const REPORT_VERSION: u32 = 1;

/// A pose as written in reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PoseJson {
    /// Translation, metres.
    pub translation: [f64; 3],
    /// Unit quaternion `[w, x, y, z]`.
    pub rotation_wxyz: [f64; 4],
}

impl From<&Isometry3<f64>> for PoseJson {
    fn from(p: &Isometry3<f64>) -> Self {
        let q = p.rotation.quaternion();
        let t = p.translation.vector;
        Self {
            translation: [t.x, t.y, t.z],
            rotation_wxyz: [q.w, q.i, q.j, q.k],
        }
    }
}

/// Standard deviations of a pose (`null` where the data do not determine a component).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PoseStdJson {
    /// Of the translation per axis, metres.
    pub translation_m: [Option<f64>; 3],
    /// Of the rotation about each axis, degrees.
    pub rotation_deg: [Option<f64>; 3],
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

impl PoseStdJson {
    fn new(translation_m: &Vector3<f64>, rotation_rad: &Vector3<f64>) -> Self {
        Self {
            translation_m: [0, 1, 2].map(|i| finite(translation_m[i])),
            rotation_deg: [0, 1, 2].map(|i| finite(rotation_rad[i].to_degrees())),
        }
    }
}

/// How a camera differs from the camera file's configuration, relative to camera 0.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChangeJson {
    /// Translation of the camera centre, in the rig frame, metres.
    pub translation_m: [f64; 3],
    /// Its length, metres.
    pub distance_m: f64,
    /// Angle of the rotation between the two orientations, degrees.
    pub rotation_deg: f64,
}

/// One camera's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraJson {
    /// Name (from the rig log).
    pub name: String,
    /// Camera model (`kannala_brandt`, `pinhole_radtan`, `unified`).
    pub model: String,
    /// Images of this camera localized.
    pub images_localized: usize,
    /// The estimate (rig frame = camera 0).
    pub rig_from_camera: PoseJson,
    /// Its standard deviations from the refinement's covariance, in the rig frame (zero for
    /// camera 0, which defines the frame; `null` if the covariance was not available).
    pub rig_from_camera_std: Option<PoseStdJson>,
    /// The change from the camera file's configuration.
    pub change_from_prior: ChangeJson,
    /// With ground truth (and for cameras after the first): rotation error relative to camera
    /// 0, degrees.
    pub rotation_error_deg: Option<f64>,
    /// With ground truth: translation direction error relative to camera 0, degrees.
    pub translation_error_deg: Option<f64>,
    /// With ground truth: translation error relative to camera 0, metres.
    pub translation_error_m: Option<f64>,
    /// Localization inliers over its localized images.
    pub inliers: usize,
    /// Its correspondences in the refinement.
    pub correspondences: usize,
    /// Its reprojection residuals before and after the refinement.
    pub reprojection_px: CameraReprojectionJson,
    /// Share of its refined residuals that are outliers under the Cauchy loss (see
    /// [`crate::calib::quality`]).
    pub outlier_fraction: f64,
    /// The pattern of its refined residuals over the image, `null` when too few to measure.
    pub residual_pattern: Option<PatternJson>,
    /// Its intrinsics as the calibration carries them (CamOdoCal order, the camera file's
    /// model).
    pub intrinsics: Vec<f64>,
    /// With `--refine-intrinsics`: what the refinement did with them; `null` when they were
    /// held.
    pub intrinsics_refinement: Option<IntrinsicsRefinementJson>,
}

/// One refined intrinsic parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntrinsicJson {
    /// Its name in the model (`mu`, `fx`, `u0`, `k1`, ...).
    pub name: String,
    /// The camera file's value.
    pub camera_file: f64,
    /// The refined value.
    pub refined: f64,
    /// Its standard deviation (`null` when not available).
    pub std: Option<f64>,
    /// Its observability in [0, 1] (1 / variance-inflation factor).
    pub observability: f64,
    /// With ground truth: refined minus true value.
    pub error: Option<f64>,
}

/// A selected intrinsic parameter held because the data does not determine it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HeldIntrinsicJson {
    /// Its name in the model.
    pub name: String,
    /// Its observability when free (below the threshold).
    pub observability: f64,
}

/// What the refinement did with one camera's intrinsics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntrinsicsRefinementJson {
    /// The refined parameters.
    pub refined: Vec<IntrinsicJson>,
    /// The selected parameters held at the camera file's values.
    pub held: Vec<HeldIntrinsicJson>,
}

/// Statistics of a camera's residuals at one estimate (see [`ResidualStats`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResidualJson {
    /// Mean error length, pixels.
    pub mean: Option<f64>,
    /// RMS of the error lengths, pixels.
    pub rms: Option<f64>,
    /// Robust spread per axis (`1.4826 median |r|`), pixels.
    pub mad: Option<f64>,
}

impl From<&ResidualStats> for ResidualJson {
    fn from(s: &ResidualStats) -> Self {
        Self {
            mean: finite(s.mean_px),
            rms: finite(s.rms_px),
            mad: finite(s.mad_px),
        }
    }
}

/// A camera's residuals before and after the refinement.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraReprojectionJson {
    /// At the initial estimate.
    pub initial: ResidualJson,
    /// At the refined estimate.
    pub r#final: ResidualJson,
}

impl CameraReprojectionJson {
    fn new(quality: Option<&CameraQuality>) -> Self {
        let empty = ResidualStats::of(&[]);
        let (initial, refined) = quality.map_or((&empty, &empty), |q| (&q.initial, &q.refined));
        Self {
            initial: initial.into(),
            r#final: refined.into(),
        }
    }
}

/// The residual pattern of a camera (see [`crate::calib::quality`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PatternJson {
    /// The count-weighted RMS of the cell means, pixels.
    pub pattern_px: f64,
    /// What noise alone gives on average, pixels.
    pub noise_px: f64,
    /// `chi^2 / dof` of the cell means (about 1 for noise alone).
    pub chi2_per_dof: f64,
}

impl From<ResidualPattern> for PatternJson {
    fn from(p: ResidualPattern) -> Self {
        Self {
            pattern_px: p.pattern_px,
            noise_px: p.noise_px,
            chi2_per_dof: p.chi2_per_dof,
        }
    }
}

/// One failed quality gate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WarningJson {
    /// Its kind (`systematic_residuals`, `residual_spread`, `outliers`, `not_converged`,
    /// `no_covariance`).
    pub kind: &'static str,
    /// The camera it names, if any.
    pub camera: Option<String>,
    /// The message, with the likely cause.
    pub message: String,
}

/// Mean reprojection errors.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReprojectionJson {
    /// At the initial estimate, pixels.
    pub initial: Option<f64>,
    /// At the refined estimate, pixels.
    pub r#final: Option<f64>,
    /// With ground truth: at the true poses (the pixel noise alone), pixels.
    pub at_truth: Option<f64>,
}

/// The initialization's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct InitializationJson {
    /// `"frame set N"` or `"averaged"`.
    pub hypothesis: String,
    /// Hypotheses scored.
    pub hypotheses: usize,
    /// The winner's mean reprojection error over the scoring observations, pixels.
    pub score_px: Option<f64>,
}

/// The refinement's entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RefinementJson {
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub termination: String,
    /// Cost `1/2 sum rho` at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
}

/// The hand-eye entry.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HandEyeJson {
    /// `"guo-planar"` or `"daniilidis"`.
    pub method: String,
    /// Why it failed, `null` on success.
    pub error: Option<String>,
    /// The estimate (rig frame = camera 0); `null` on failure.
    pub rig_from_odometry: Option<PoseJson>,
    /// Whether the rig's height above the odometry plane was determined (not with planar
    /// odometry: it is then zero in `odometry_from_rig`).
    pub height_observable: bool,
    /// Predicted standard deviations of `odometry_from_rig`, in the odometry frame.
    pub odometry_from_rig_std: Option<PoseStdJson>,
    /// Poses used.
    pub poses: usize,
    /// With ground truth: rotation error, degrees.
    pub rotation_error_deg: Option<f64>,
    /// With ground truth: yaw error (about the odometry z-axis), degrees.
    pub yaw_error_deg: Option<f64>,
    /// With ground truth: translation error over the observable components, metres.
    pub translation_error_m: Option<f64>,
    /// With ground truth: in-plane (x-y) translation error, metres.
    pub in_plane_translation_error_m: Option<f64>,
}

/// The JSON report (see the module docs for its layout).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// [`REPORT_FORMAT`].
    pub format: &'static str,
    /// [`REPORT_VERSION`].
    pub version: u32,
    /// The scenario's name, when known (from the ground truth or the simulation).
    pub scenario: Option<String>,
    /// The simulation's seed, when known.
    pub seed: Option<u64>,
    /// One entry per camera, in the log's order.
    pub cameras: Vec<CameraJson>,
    /// Frames in the log.
    pub frames: usize,
    /// Images in the log.
    pub images: usize,
    /// Images localized.
    pub images_localized: usize,
    /// Frame sets used.
    pub frame_sets_used: usize,
    /// Mean localized cameras per set.
    pub mean_poses_per_set: f64,
    /// 2D-3D correspondences in the refinement.
    pub correspondences: usize,
    /// Mean reprojection errors.
    pub reprojection_error_px: ReprojectionJson,
    /// The initialization.
    pub initialization: InitializationJson,
    /// The refinement.
    pub refinement: RefinementJson,
    /// The hand-eye calibration, `null` when there was none.
    pub hand_eye: Option<HandEyeJson>,
    /// `"ok"`, or `"poor"` when a quality gate failed (see `warnings`).
    pub status: Status,
    /// The failed quality gates, each naming the camera and the likely cause.
    pub warnings: Vec<WarningJson>,
    /// What the reader should know about how the inputs were taken (cameras matched by order
    /// because the camera file has no names, IMU transforms carried over); absent when none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// Seconds per stage.
    pub timing_s: Timing,
}

/// The report's notes (see [`Report::notes`]).
fn notes(calibration: &Calibration) -> Vec<String> {
    let mut notes = Vec::new();
    let prior = &calibration.prior_rig.cameras;
    if calibration.camera_matching == CameraMatching::ByOrder {
        let pairs: Vec<String> = prior
            .iter()
            .zip(&calibration.camera_names)
            .map(|(p, name)| format!("{} = {name}", p.name))
            .collect();
        notes.push(format!(
            "the camera file names no cameras: matched to the log by order ({})",
            pairs.join(", ")
        ));
    }
    if prior.iter().any(|c| c.camera_from_imu.is_some()) {
        let reference = calibration.camera_names.first().map_or("", String::as_str);
        notes.push(match prior.first().and_then(|c| c.camera_from_imu) {
            Some(_) => format!(
                "the camera file's T_cam_imu is written for every camera through `{reference}`'s, \
                 which defines the rig frame (the IMU is taken as fixed to it)"
            ),
            None => format!(
                "the camera file's T_cam_imu is not written: `{reference}`, which defines the rig \
                 frame, has none"
            ),
        });
    }
    notes
}

impl Report {
    /// The report of a calibration, with the errors against `truth` when given (its scenario
    /// name and seed then name the report).
    ///
    /// # Errors
    /// [`CalibrationError::Truth`] when the truth does not fit the calibration.
    pub fn new(
        calibration: &Calibration,
        truth: Option<&GroundTruth>,
    ) -> Result<Self, CalibrationError> {
        let accuracy = truth.map(|t| calibration.accuracy(t)).transpose()?;
        let std = calibration.refinement.rig_from_camera_std.as_ref();
        let prior = relative_to_first(&calibration.prior_rig_from_camera());
        let estimate = relative_to_first(&calibration.rig_from_camera);
        let per_camera = calibration.localizations.localized_per_camera();
        let cameras = (0..calibration.cameras.len())
            .map(|c| {
                let error = accuracy.as_ref().and_then(|a| a.cameras[c]);
                let quality = calibration.quality.cameras.get(c);
                let (p, e) = (prior[c], estimate[c]);
                let moved = e.translation.vector - p.translation.vector;
                CameraJson {
                    name: calibration.camera_names[c].clone(),
                    model: ibc_camera_models::CameraModel::model_name(&calibration.cameras[c])
                        .to_owned(),
                    images_localized: per_camera.get(c).copied().unwrap_or(0),
                    rig_from_camera: PoseJson::from(&calibration.rig_from_camera[c]),
                    rig_from_camera_std: std
                        .map(|s| PoseStdJson::new(&s[c].translation_m, &s[c].rotation_rad)),
                    change_from_prior: ChangeJson {
                        translation_m: [moved.x, moved.y, moved.z],
                        distance_m: moved.norm(),
                        rotation_deg: p.rotation.angle_to(&e.rotation).to_degrees(),
                    },
                    rotation_error_deg: error.map(|a| a.rotation_error_deg),
                    translation_error_deg: error.map(|a| a.translation_error_deg),
                    translation_error_m: error.map(|a| a.translation_error_m),
                    inliers: quality.map_or(0, |q| q.inliers),
                    correspondences: quality.map_or(0, |q| q.observations),
                    reprojection_px: CameraReprojectionJson::new(quality),
                    outlier_fraction: quality.map_or(0.0, |q| q.outlier_fraction),
                    residual_pattern: quality.and_then(|q| q.pattern).map(PatternJson::from),
                    intrinsics: ibc_camera_models::CameraModel::params(&calibration.cameras[c])
                        .to_vec(),
                    intrinsics_refinement: intrinsics_json(calibration, truth, c),
                }
            })
            .collect();
        let hand_eye = calibration.hand_eye.as_ref().map(|h| match h {
            Ok(h) => {
                let a = accuracy.as_ref().and_then(|a| a.hand_eye);
                let u = &h.uncertainty;
                HandEyeJson {
                    method: h.solver.name().to_owned(),
                    error: None,
                    rig_from_odometry: Some(PoseJson::from(&h.rig_from_odometry)),
                    height_observable: h.height_observable,
                    odometry_from_rig_std: Some(PoseStdJson::new(
                        &u.translation_std,
                        &u.rotation_std,
                    )),
                    poses: h.poses,
                    rotation_error_deg: a.map(|a| a.rotation_error_deg),
                    yaw_error_deg: a.map(|a| a.yaw_error_deg),
                    translation_error_m: a.map(|a| a.translation_error_m),
                    in_plane_translation_error_m: a.map(|a| a.in_plane_translation_error_m),
                }
            }
            Err(e) => HandEyeJson {
                method: calibration
                    .hand_eye_solver
                    .map_or("none", |s| s.name())
                    .to_owned(),
                error: Some(match e {
                    HandEyeFailure::Solver(HandEyeError::ParallelRotationAxes { .. }) => {
                        format!("{e} (`ibc --hand-eye planar`)")
                    }
                    _ => e.to_string(),
                }),
                rig_from_odometry: None,
                height_observable: false,
                odometry_from_rig_std: None,
                poses: 0,
                rotation_error_deg: None,
                yaw_error_deg: None,
                translation_error_m: None,
                in_plane_translation_error_m: None,
            },
        });
        let init = &calibration.initialization;
        let t = &calibration.timing;
        Ok(Self {
            format: REPORT_FORMAT,
            version: REPORT_VERSION,
            scenario: truth.map(|t| t.scenario.clone()),
            seed: truth.map(|t| t.seed),
            cameras,
            frames: calibration.localizations.images.len(),
            images: calibration.localizations.image_count(),
            images_localized: calibration.localizations.localized_count(),
            frame_sets_used: calibration.frame_sets_used(),
            mean_poses_per_set: calibration.mean_poses_per_set(),
            correspondences: calibration.correspondences(),
            reprojection_error_px: ReprojectionJson {
                initial: finite(calibration.initial_error_px()),
                r#final: finite(calibration.final_error_px()),
                at_truth: accuracy
                    .as_ref()
                    .and_then(|a| finite(a.reprojection_error_at_truth_px)),
            },
            initialization: InitializationJson {
                hypothesis: match init.hypothesis {
                    InitialHypothesis::FrameSet(s) => format!("frame set {s}"),
                    InitialHypothesis::Averaged => "averaged".to_owned(),
                },
                hypotheses: init.hypotheses,
                score_px: finite(init.score_px),
            },
            refinement: RefinementJson {
                iterations: calibration.refinement.iterations,
                termination: calibration.refinement.termination.clone(),
                initial_cost: calibration.refinement.initial_cost,
                final_cost: calibration.refinement.final_cost,
            },
            hand_eye,
            status: calibration.quality.status(),
            warnings: calibration
                .quality
                .warnings
                .iter()
                .map(|w| WarningJson {
                    kind: w.kind(),
                    camera: w.camera().map(str::to_owned),
                    message: w.to_string(),
                })
                .collect(),
            notes: notes(calibration),
            timing_s: *t,
        })
    }

    /// The report as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // Serializing plain structs of numbers and strings cannot fail; non-finite numbers
        // were turned into `null` when the report was built.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The same report without the timings (zeroed), to compare two runs.
    #[must_use]
    pub fn without_timing(mut self) -> Self {
        self.timing_s = Timing::default();
        self
    }
}
