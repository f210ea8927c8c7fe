//! The report and output files of a self-calibration (`ibc selfcalib`).
//!
//! The JSON report uses the calibration report's conventions and keys where they apply (poses
//! `{"translation": [x, y, z], "rotation_wxyz": [w, x, y, z]}`, the rig frame camera 0's, angles
//! in degrees, `null` for a number that does not exist), plus `scale_source` (`"odometry"`,
//! `"baseline"` or `"unknown"`) and `translation_unit` (`"m"`, or `"unknown"` when the
//! translations are only known up to one common factor).
//!
//! ```json
//! {
//!   "format": "ibc-selfcalibration-report", "version": 1,
//!   "scale_source": "odometry", "scale_factor": 6.33, "translation_unit": "m",
//!   "cameras": [{
//!     "name": "left", "model": "kannala_brandt",
//!     "rig_from_camera": {...}, "rig_from_camera_std": {"translation": [...], "rotation_deg": [...]},
//!     "initial_rig_from_camera": {...},
//!     "rotation_error_deg": 0.0018, "translation_error_m": 0.0004
//!   }, ...],
//!   "status": "ok", "warnings": [],
//!   "frames": 100, "frames_posed": 100, "points": 27000, "observations": 190000,
//!   "reprojection_error_px": {"final": 0.63},
//!   "tracks": {"images": 400, "candidate_pairs": 4349, "verified_pairs": 4141, ...},
//!   "rounds": [{"points": ..., "observations": ..., "outliers": ...,
//!               "wide_observations": ..., "rms_px": ..., "iterations": ...,
//!               "rotation_change_deg": ..., "translation_change": ...,
//!               "completed_observations": ..., "merged_tracks": ...}],
//!   "converged": true
//! }
//! ```

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use ibc_camera_models::{Camera, CameraModel, Rig, RigCamera};
use nalgebra::Isometry3;
use serde::Serialize;

use super::files::{OutputError, output_names, write_with_rig};
use super::json::PoseJson;
use super::svg::{TopView, top_view};
use crate::data::GroundTruth;
use crate::sfm::{ScaleEstimate, SelfCalibration, TrackStats, extrinsic_errors};

/// The value of [`SelfCalibrationReport::format`].
pub const SELFCALIB_REPORT_FORMAT: &str = "ibc-selfcalibration-report";

/// Standard deviations of an extrinsic (translation in the report's unit, rotation degrees).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StdJson {
    /// Translation, per axis.
    pub translation: [f64; 3],
    /// Rotation about each axis, degrees.
    pub rotation_deg: [f64; 3],
}

/// One camera in the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SelfCalibCameraJson {
    /// The camera's name.
    pub name: String,
    /// Its model (`kannala_brandt`, `pinhole_radtan`, `unified`).
    pub model: &'static str,
    /// The estimate.
    pub rig_from_camera: PoseJson,
    /// Its standard deviations; `null` for camera 0 (the gauge) or without a covariance.
    pub rig_from_camera_std: Option<StdJson>,
    /// The averaging's estimate, before triangulation and adjustment.
    pub initial_rig_from_camera: PoseJson,
    /// Rotation error against the truth, degrees (with a truth file).
    pub rotation_error_deg: Option<f64>,
    /// Translation error against the truth, metres (with a truth file; after aligning the
    /// scale when it is unknown).
    pub translation_error_m: Option<f64>,
}

/// One round of triangulation and adjustment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RoundJson {
    /// Points.
    pub points: usize,
    /// Observations.
    pub observations: usize,
    /// Observations left out as outliers.
    pub outliers: usize,
    /// Observations whose ray is at or beyond 90 degrees from the optical axis.
    pub wide_observations: usize,
    /// RMS reprojection error after the adjustment, pixels.
    pub rms_px: f64,
    /// Solver iterations.
    pub iterations: usize,
    /// Largest extrinsic rotation change, degrees.
    pub rotation_change_deg: f64,
    /// Largest extrinsic translation change, in the reconstruction's unit before scaling.
    pub translation_change: f64,
    /// Observations the track completion added after the round.
    pub completed_observations: usize,
    /// Tracks the completion merged into another after the round.
    pub merged_tracks: usize,
}

/// A warning of the report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SelfCalibWarning {
    /// Its kind (`scale_unknown`, `not_converged`, `no_covariance`).
    pub kind: &'static str,
    /// The message.
    pub message: String,
}

/// The report of a self-calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SelfCalibrationReport {
    /// [`SELFCALIB_REPORT_FORMAT`].
    pub format: &'static str,
    /// Layout version (1).
    pub version: u32,
    /// The scenario of the truth file, if any.
    pub scenario: Option<String>,
    /// Where the scale came from.
    pub scale_source: &'static str,
    /// Metres per unit of the reconstruction (with odometry), else `null`.
    pub scale_factor: Option<f64>,
    /// `"m"`, or `"unknown"` when the translations are up to scale.
    pub translation_unit: &'static str,
    /// The cameras.
    pub cameras: Vec<SelfCalibCameraJson>,
    /// `ok`, or `poor` when the result should not be trusted (the warnings say why).
    pub status: &'static str,
    /// Warnings.
    pub warnings: Vec<SelfCalibWarning>,
    /// Frames of the log.
    pub frames: usize,
    /// Frames with a rig pose.
    pub frames_posed: usize,
    /// Points of the reconstruction.
    pub points: usize,
    /// Observations in the last adjustment.
    pub observations: usize,
    /// Final RMS reprojection error, pixels.
    pub reprojection_error_px: f64,
    /// Feature tracking.
    pub tracks: TrackStats,
    /// The rounds.
    pub rounds: Vec<RoundJson>,
    /// Whether the extrinsics stopped changing.
    pub converged: bool,
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl SelfCalibrationReport {
    /// The report of `result` for the cameras `names` / `cameras`, scored against `truth` when
    /// given.
    pub fn new(
        result: &SelfCalibration,
        names: &[String],
        cameras: &[Camera],
        truth: Option<&GroundTruth>,
    ) -> Self {
        let unknown = matches!(result.scale, ScaleEstimate::Unknown);
        let errors =
            truth.map(|t| extrinsic_errors(&result.rig_from_camera, &t.rig_from_camera, unknown));
        let mut warnings = Vec::new();
        if unknown {
            warnings.push(SelfCalibWarning {
                kind: "scale_unknown",
                message: "the log has no odometry and no baseline was given: the translations \
                          are known up to one common factor (their ratios and every rotation \
                          are calibrated); give --baseline CAM_A:CAM_B=METRES for metres"
                    .into(),
            });
        }
        if !result.converged {
            warnings.push(SelfCalibWarning {
                kind: "not_converged",
                message: format!(
                    "the extrinsics still changed by more than the set fraction of their \
                     standard deviation (default a half) after {} rounds of triangulation and \
                     adjustment",
                    result.rounds.len()
                ),
            });
        }
        if let Some(reason) = &result.covariance_error {
            warnings.push(SelfCalibWarning {
                kind: "no_covariance",
                message: format!(
                    "the extrinsics have no standard deviations ({reason}): whether the data \
                     determines each of them is not known, and the rounds could only stop on \
                     the fixed tolerances"
                ),
            });
        }
        let cameras_json = names
            .iter()
            .zip(cameras)
            .enumerate()
            .map(|(c, (name, camera))| {
                let std = result
                    .extrinsic_covariance
                    .get(c)
                    .and_then(Option::as_ref)
                    .map(|cov| {
                        let sd = |k: usize| cov[(k, k)].max(0.0).sqrt();
                        StdJson {
                            translation: [sd(0), sd(1), sd(2)],
                            rotation_deg: [
                                sd(3).to_degrees(),
                                sd(4).to_degrees(),
                                sd(5).to_degrees(),
                            ],
                        }
                    });
                SelfCalibCameraJson {
                    name: name.clone(),
                    model: camera.model_name(),
                    rig_from_camera: PoseJson::from(&result.rig_from_camera[c]),
                    rig_from_camera_std: std,
                    initial_rig_from_camera: PoseJson::from(&result.initial_rig_from_camera[c]),
                    rotation_error_deg: errors
                        .as_ref()
                        .and_then(|e| e.get(c))
                        .and_then(|e| finite(e.0.to_degrees())),
                    translation_error_m: errors
                        .as_ref()
                        .and_then(|e| e.get(c))
                        .and_then(|e| finite(e.1)),
                }
            })
            .collect();
        let last = result.rounds.last();
        Self {
            format: SELFCALIB_REPORT_FORMAT,
            version: 1,
            scenario: truth.map(|t| t.scenario.clone()),
            scale_source: result.scale.name(),
            scale_factor: match result.scale {
                ScaleEstimate::Odometry { factor } => finite(factor),
                _ => None,
            },
            translation_unit: if unknown { "unknown" } else { "m" },
            cameras: cameras_json,
            status: if result.converged && result.covariance_error.is_none() {
                "ok"
            } else {
                "poor"
            },
            warnings,
            frames: result.world_from_rig.len(),
            frames_posed: result.world_from_rig.iter().flatten().count(),
            points: result.points.len(),
            observations: last.map_or(0, |r| r.observations),
            reprojection_error_px: last.map_or(f64::NAN, |r| r.rms_px),
            tracks: result.tracks,
            rounds: result
                .rounds
                .iter()
                .map(|r| RoundJson {
                    points: r.points,
                    observations: r.observations,
                    outliers: r.outliers,
                    wide_observations: r.wide_observations,
                    rms_px: r.rms_px,
                    iterations: r.iterations,
                    rotation_change_deg: r.rotation_change.to_degrees(),
                    translation_change: r.translation_change,
                    completed_observations: r.completed_observations,
                    merged_tracks: r.merged_tracks,
                })
                .collect(),
            converged: result.converged,
        }
    }

    /// Whether the result can be trusted (status `ok`).
    pub fn is_ok(&self) -> bool {
        self.status == "ok"
    }

    /// The report as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // Plain structs of numbers and strings; non-finite numbers were made `null`, except
        // the reprojection error of a run without rounds, which cannot be reported.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// The report as a text table.
    pub fn text_table(&self) -> String {
        let mut s = String::new();
        let unit = if self.translation_unit == "m" {
            "mm"
        } else {
            "units/1000"
        };
        let _ = writeln!(
            s,
            "self-calibration ({} frames, {} posed; {} points, {} observations; rms {:.3} px; \
             scale: {})",
            self.frames,
            self.frames_posed,
            self.points,
            self.observations,
            self.reprojection_error_px,
            self.scale_source
        );
        let _ = writeln!(
            s,
            "{:<12} {:>10} {:>10} {:>10} {:>11} {:>9} {:>9}",
            "camera", "x", "y", "z", "std t", "std deg", "err deg"
        );
        for c in &self.cameras {
            let t = c.rig_from_camera.translation;
            let std = c.rig_from_camera_std.as_ref();
            let st = std.map_or("-".into(), |s| {
                format!(
                    "{:.3}",
                    s.translation.iter().fold(0.0_f64, |a, b| a.max(*b)) * 1e3
                )
            });
            let sr = std.map_or("-".into(), |s| {
                format!(
                    "{:.5}",
                    s.rotation_deg.iter().fold(0.0_f64, |a, b| a.max(*b))
                )
            });
            let err = c
                .rotation_error_deg
                .map_or("-".into(), |e| format!("{e:.5}"));
            let _ = writeln!(
                s,
                "{:<12} {:>10.2} {:>10.2} {:>10.2} {:>11} {:>9} {:>9}",
                c.name,
                t[0] * 1e3,
                t[1] * 1e3,
                t[2] * 1e3,
                st,
                sr,
                err
            );
        }
        let _ = writeln!(s, "(translations and their standard deviations in {unit})");
        if self.cameras.iter().any(|c| c.translation_error_m.is_some()) {
            let worst = self
                .cameras
                .iter()
                .filter_map(|c| c.translation_error_m)
                .fold(0.0_f64, f64::max);
            let _ = writeln!(
                s,
                "worst translation error against the truth: {:.3} mm",
                worst * 1e3
            );
        }
        let _ = writeln!(s, "status: {}", self.status);
        for w in &self.warnings {
            let _ = writeln!(s, "warning ({}): {}", w.kind, w.message);
        }
        s
    }
}

/// The self-calibrated rig: the log's camera names, the camera file's cameras (intrinsics,
/// Kalibr metadata; in the log's order) with the estimated extrinsics.
pub fn self_calibrated_rig(prior: &Rig, names: &[String], result: &SelfCalibration) -> Rig {
    Rig::new(
        prior
            .cameras
            .iter()
            .zip(names)
            .zip(&result.rig_from_camera)
            .map(|((p, name), pose)| {
                let mut rc = RigCamera::new(name.clone(), p.camera.clone(), *pose);
                rc.topic.clone_from(&p.topic);
                rc.overlaps.clone_from(&p.overlaps);
                rc.timeshift_cam_imu_s = p.timeshift_cam_imu_s;
                rc
            })
            .collect(),
    )
}

/// Writes the report (JSON and text), the top view, the Kalibr camchain and the CamOdoCal
/// folder of a self-calibration into `dir`, all or nothing. Returns the files written.
///
/// # Errors
/// [`OutputError`]; nothing is left behind then.
pub fn write_selfcalib_outputs(
    dir: impl AsRef<Path>,
    report: &SelfCalibrationReport,
    result: &SelfCalibration,
    rig: &Rig,
) -> Result<Vec<PathBuf>, OutputError> {
    use output_names as n;
    let dir = dir.as_ref();
    let contents = vec![
        (dir.join(n::REPORT_JSON), report.to_json() + "\n"),
        (dir.join(n::REPORT_TEXT), report.text_table()),
        (
            dir.join(n::TOP_VIEW),
            self_calibration_top_view(result, rig),
        ),
    ];
    write_with_rig(dir, contents, rig)
}

/// The top view of a self-calibration: the reconstruction's points, the rig trajectory, the
/// camera centres, and the rig seen from above (the layout of [`super::top_view_svg`]).
pub fn self_calibration_top_view(result: &SelfCalibration, rig: &Rig) -> String {
    let poses: Vec<Isometry3<f64>> = result.world_from_rig.iter().flatten().copied().collect();
    let names: Vec<String> = rig.cameras.iter().map(|c| c.name.clone()).collect();
    top_view(&TopView {
        title: "top view of the reconstruction: points, camera centres, rig trajectory",
        points_label: "reconstructed points",
        points: result.points.iter().map(|p| p.coords).collect(),
        camera_seen: vec![vec![true; result.rig_from_camera.len()]; poses.len()],
        world_from_rig: poses,
        rig_from_camera: &result.rig_from_camera,
        camera_names: &names,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sfm::{ScaleEstimate, TrackStats};
    use ibc_camera_models::PinholeRadtan;
    use nalgebra::Vector3;

    fn result(covariance_error: Option<String>) -> SelfCalibration {
        let pose = Isometry3::translation(0.5, 0.0, 0.0);
        SelfCalibration {
            rig_from_camera: vec![Isometry3::identity(), pose],
            initial_rig_from_camera: vec![Isometry3::identity(), pose],
            world_from_rig: vec![Some(Isometry3::identity())],
            points: vec![Vector3::new(0.0, 0.0, 5.0).into()],
            extrinsic_covariance: vec![None, None],
            covariance_error,
            odometry_distances: 0,
            scale: ScaleEstimate::Baseline,
            rounds: Vec::new(),
            converged: true,
            tracks: TrackStats {
                images: 2,
                candidate_pairs: 1,
                verified_pairs: 1,
                cross_camera_pairs: 1,
                tracks: 1,
                inconsistent_tracks: 0,
            },
        }
    }

    /// A self-calibration whose covariance could not be computed is not trusted: status
    /// `poor` with a `no_covariance` warning that carries the reason.
    #[test]
    fn a_result_without_covariance_is_poor_and_says_why() {
        let names = vec!["a".to_string(), "b".to_string()];
        let camera = Camera::PinholeRadtan(
            PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0])
                .expect("a valid pinhole"),
        );
        let cameras = vec![camera.clone(), camera];
        let ok = SelfCalibrationReport::new(&result(None), &names, &cameras, None);
        assert!(ok.is_ok(), "{:?}", ok.warnings);
        let reason = "the covariance is undefined: the information matrix is singular";
        let poor = SelfCalibrationReport::new(&result(Some(reason.into())), &names, &cameras, None);
        assert!(!poor.is_ok());
        let w = poor
            .warnings
            .iter()
            .find(|w| w.kind == "no_covariance")
            .expect("a no_covariance warning");
        assert!(w.message.contains(reason), "{}", w.message);
        assert!(poor.text_table().contains("no_covariance"));
    }
}
