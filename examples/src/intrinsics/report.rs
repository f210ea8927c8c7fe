//! The calibration report: a JSON document and a text summary.

use std::fmt::Write as _;

use ibc_camera_models::{Camera, CameraModel};
use serde::Serialize;

use super::calibrate::{
    ImageError, ImageStatus, Initialization, IntrinsicCalibration, IntrinsicsStatus,
    IntrinsicsWarning,
};
use super::kb_init::FocalHypothesis;
use super::target::PlanarTarget;

/// The `format` value of the JSON report.
pub const REPORT_FORMAT: &str = "ibc-intrinsics-report";

/// One parameter with its standard deviation.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParameterEstimate {
    /// Its name (CamOdoCal order: `k1, k2, k3, k4, mu, mv, u0, v0` or
    /// `k1, k2, p1, p2, fx, fy, cx, cy`).
    pub name: String,
    /// The estimate.
    pub value: f64,
    /// Its standard deviation from the refinement's covariance.
    pub std_dev: f64,
    /// The value after the initialization.
    pub initial: f64,
    /// The true value (simulated boards only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<f64>,
    /// `value - truth` (simulated boards only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
}

/// How the intrinsics were initialized, as reported.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "method", rename_all = "snake_case")]
#[non_exhaustive]
pub enum InitializationReport {
    /// The paper's vanishing points (Kannala-Brandt).
    VanishingPoints {
        /// The focal length kept, pixels.
        focal_px: f64,
        /// Every hypothesis with its score.
        hypotheses: Vec<FocalHypothesis>,
        /// Index of the one kept.
        chosen: usize,
    },
    /// Zhang's closed form (pinhole).
    Zhang {
        /// fx, fy, cx, cy of the closed form, pixels.
        fx: f64,
        /// Vertical focal length, pixels.
        fy: f64,
        /// Principal point, horizontal, pixels.
        cx: f64,
        /// Principal point, vertical, pixels.
        cy: f64,
        /// Conditioning of Zhang's constraints (see `zhang::ZHANG_MIN_CONDITION`).
        condition: f64,
    },
    /// The centred fallback (pinhole): the principal point at the image centre, one focal
    /// length.
    CentredFocal {
        /// The focal length, pixels.
        focal_px: f64,
    },
    /// Mei and Rives's line conics (unified): `xi = 1` and a generalized focal length.
    LineConics {
        /// The generalized focal length `gamma` kept, pixels.
        gamma_px: f64,
        /// Every hypothesis with its score (`focal` is `gamma`).
        hypotheses: Vec<FocalHypothesis>,
        /// Index of the one kept.
        chosen: usize,
    },
}

/// A failed quality gate as reported: its fields and its message.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WarningEntry {
    /// The warning (its kind and figures).
    #[serde(flatten)]
    pub warning: IntrinsicsWarning,
    /// What it means, in words.
    pub message: String,
}

/// The JSON report of an intrinsic calibration.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct IntrinsicsReport {
    /// [`REPORT_FORMAT`].
    pub format: &'static str,
    /// `kannala_brandt` or `pinhole_radtan`.
    pub model: &'static str,
    /// Image width, pixels.
    pub image_width: u32,
    /// Image height, pixels.
    pub image_height: u32,
    /// The target.
    pub board: PlanarTarget,
    /// The parameters, CamOdoCal order.
    pub parameters: Vec<ParameterEstimate>,
    /// RMS of the residual coordinates, pixels.
    pub rms_px: f64,
    /// RMS of the residual lengths (OpenCV's figure), pixels.
    pub rms_distance_px: f64,
    /// RMS of the residual coordinates after the initialization, pixels.
    pub initial_rms_px: f64,
    /// Pixel noise estimated from the residuals, pixels.
    pub noise_sigma_px: f64,
    /// Per-image errors, with every corner's residual.
    pub images: Vec<ImageError>,
    /// The residual length above which a corner was excluded as an outlier, pixels.
    pub outlier_px: f64,
    /// Corners excluded as outliers.
    pub outlier_corners: usize,
    /// `"ok"`, or `"poor"` when a quality gate failed (see `warnings`).
    pub status: IntrinsicsStatus,
    /// The failed quality gates, each with its message.
    pub warnings: Vec<WarningEntry>,
    /// Largest angle between two board normals, degrees.
    pub normal_spread_deg: f64,
    /// The initialization.
    pub initialization: InitializationReport,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why Levenberg-Marquardt stopped.
    pub termination: String,
    /// Wall time of the calibration, seconds.
    pub seconds: f64,
}

impl IntrinsicsReport {
    /// The report of a calibration, compared with `truth` when the boards were simulated.
    pub fn new(
        calibration: &IntrinsicCalibration,
        board: &PlanarTarget,
        truth: Option<&Camera>,
        seconds: f64,
    ) -> Self {
        let names = calibration.model.param_names();
        let values = calibration.camera.params();
        let initial = calibration.initial_camera.params();
        let truth_values = truth.map(CameraModel::params);
        let parameters = (0..names.len().min(values.len()))
            .map(|i| {
                let t = truth_values.and_then(|t| t.get(i).copied());
                ParameterEstimate {
                    name: names[i].to_owned(),
                    value: values[i],
                    std_dev: calibration.std_devs[i],
                    initial: initial[i],
                    truth: t,
                    error: t.map(|t| values[i] - t),
                }
            })
            .collect();
        let initialization = match &calibration.initialization {
            Initialization::VanishingPoints { hypotheses, chosen } => {
                InitializationReport::VanishingPoints {
                    focal_px: hypotheses.get(*chosen).map_or(f64::NAN, |h| h.focal),
                    hypotheses: hypotheses.clone(),
                    chosen: *chosen,
                }
            }
            Initialization::Zhang(z) => InitializationReport::Zhang {
                fx: z.fx,
                fy: z.fy,
                cx: z.cx,
                cy: z.cy,
                condition: z.condition,
            },
            Initialization::CentredFocal { focal_px } => InitializationReport::CentredFocal {
                focal_px: *focal_px,
            },
            Initialization::LineConics { hypotheses, chosen } => InitializationReport::LineConics {
                gamma_px: hypotheses.get(*chosen).map_or(f64::NAN, |h| h.focal),
                hypotheses: hypotheses.clone(),
                chosen: *chosen,
            },
        };
        Self {
            format: REPORT_FORMAT,
            model: calibration.camera.model_name(),
            image_width: calibration.camera.width(),
            image_height: calibration.camera.height(),
            board: *board,
            parameters,
            rms_px: calibration.rms_px,
            rms_distance_px: calibration.rms_distance_px,
            initial_rms_px: calibration.initial_rms_px,
            noise_sigma_px: calibration.noise_sigma_px,
            images: calibration.per_image.clone(),
            outlier_px: calibration.outlier_px,
            outlier_corners: calibration.outlier_corners,
            status: calibration.status(),
            warnings: calibration
                .warnings
                .iter()
                .map(|w| WarningEntry {
                    warning: w.clone(),
                    message: w.to_string(),
                })
                .collect(),
            normal_spread_deg: calibration.normal_spread_deg,
            initialization,
            iterations: calibration.iterations,
            termination: calibration.termination.name().to_owned(),
            seconds,
        }
    }

    /// The report as pretty-printed JSON (non-finite numbers become `null`).
    pub fn to_json_string(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
            + "\n"
    }

    /// A human-readable summary: parameters with standard deviations (and errors against the
    /// truth), RMS, the initialization, and the worst images.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let used = self
            .images
            .iter()
            .filter(|i| i.status == ImageStatus::Used)
            .count();
        let _ = writeln!(
            s,
            "{} camera, {}x{} px, board {}x{} corners of {} m, {used} of {} images used",
            self.model,
            self.image_width,
            self.image_height,
            self.board.rows,
            self.board.cols,
            self.board.square,
            self.images.len()
        );
        for i in &self.images {
            match i.status {
                ImageStatus::Used => {}
                ImageStatus::TooFewCorners => {
                    let _ = writeln!(
                        s,
                        "  skipped `{}`: {} corners, fewer than {}",
                        i.name,
                        i.corners,
                        super::MIN_CORNERS_PER_IMAGE
                    );
                }
                ImageStatus::Outliers => {
                    let _ = writeln!(
                        s,
                        "  excluded `{}`: {} of its {} corners do not fit the other images",
                        i.name, i.outliers, i.corners
                    );
                }
            }
        }
        match &self.initialization {
            InitializationReport::VanishingPoints {
                focal_px,
                hypotheses,
                ..
            } => {
                let _ = writeln!(
                    s,
                    "initialization: vanishing points, f = {focal_px:.2} px (best of {} hypotheses)",
                    hypotheses.len()
                );
            }
            InitializationReport::Zhang { fx, fy, cx, cy, .. } => {
                let _ = writeln!(
                    s,
                    "initialization: Zhang, fx = {fx:.2}, fy = {fy:.2}, cx = {cx:.2}, cy = {cy:.2} px"
                );
            }
            InitializationReport::CentredFocal { focal_px } => {
                let _ = writeln!(
                    s,
                    "initialization: principal point at the centre, f = {focal_px:.2} px \
                     (Zhang's closed form refined to a poor fit)"
                );
            }
            InitializationReport::LineConics {
                gamma_px,
                hypotheses,
                ..
            } => {
                let _ = writeln!(
                    s,
                    "initialization: line conics, xi = 1, gamma = {gamma_px:.2} px (best of {} \
                     hypotheses)",
                    hypotheses.len()
                );
            }
        }
        let with_truth = self.parameters.iter().any(|p| p.truth.is_some());
        let _ = writeln!(
            s,
            "{:<6} {:>16} {:>12}{}",
            "param",
            "value",
            "std dev",
            if with_truth {
                "        truth        error"
            } else {
                ""
            }
        );
        for p in &self.parameters {
            let _ = write!(s, "{:<6} {:>16.8} {:>12.3e}", p.name, p.value, p.std_dev);
            if let (Some(t), Some(e)) = (p.truth, p.error) {
                let _ = write!(s, " {t:>12.6} {e:>12.3e}");
            }
            s.push('\n');
        }
        let _ = writeln!(
            s,
            "RMS {:.4} px per coordinate ({:.4} px per corner; {:.4} px after initialization), \
             {} iterations ({}), board normals span {:.1} deg",
            self.rms_px,
            self.rms_distance_px,
            self.initial_rms_px,
            self.iterations,
            self.termination,
            self.normal_spread_deg
        );
        if self.outlier_corners > 0 {
            let _ = writeln!(
                s,
                "{} corners excluded as outliers (residual above {:.2} px)",
                self.outlier_corners, self.outlier_px
            );
        }
        let mut worst: Vec<&ImageError> = self
            .images
            .iter()
            .filter(|i| i.status == ImageStatus::Used)
            .collect();
        worst.sort_by(|a, b| b.rms_px.total_cmp(&a.rms_px));
        let _ = writeln!(s, "worst images (RMS / max px):");
        for e in worst.iter().take(3) {
            let _ = writeln!(
                s,
                "  {:<24} {:>4} corners {:>8.4} {:>8.4}",
                e.name, e.corners, e.rms_px, e.max_px
            );
        }
        let _ = writeln!(s, "time {:.3} s", self.seconds);
        let _ = writeln!(
            s,
            "status: {}",
            match self.status {
                IntrinsicsStatus::Ok => "ok",
                IntrinsicsStatus::Poor => "poor",
            }
        );
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {}", w.message);
        }
        s
    }
}
