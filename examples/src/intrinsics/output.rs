//! The output files of a calibration, written all or nothing.

use std::path::{Path, PathBuf};

use ibc_camera_models::{Rig, RigCamera, camodocal};
use nalgebra::Isometry3;

use super::calibrate::IntrinsicCalibration;
use super::corners::CornerSet;
use super::error::IntrinsicsError;
use super::report::IntrinsicsReport;
use super::simulate::SimulatedBoards;
use super::svg::residual_svg;
use crate::data::io::StagedFiles;

/// File name of the Kalibr camchain.
pub const CAMCHAIN_FILE: &str = "camchain.yaml";
/// File name of the JSON report.
pub const REPORT_FILE: &str = "intrinsics_report.json";
/// File name of the residual plot.
pub const RESIDUALS_SVG_FILE: &str = "residuals.svg";
/// File name of the simulated corners (simulated mode).
pub const SIMULATED_CORNERS_FILE: &str = "corners.json";
/// Camera name of the true camera's CamOdoCal file (simulated mode): `truth_camera_calib.yaml`.
pub const TRUTH_CAMERA_NAME: &str = "truth";

/// CamOdoCal's file name for a camera: `<name>_camera_calib.yaml`.
pub fn camodocal_file_name(camera_name: &str) -> String {
    format!("{camera_name}_camera_calib.yaml")
}

/// The files [`write_outputs`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct OutputFiles {
    /// The CamOdoCal camera YAML, `<name>_camera_calib.yaml`.
    pub camodocal: PathBuf,
    /// The Kalibr camchain with the one camera, `camchain.yaml`.
    pub camchain: PathBuf,
    /// The JSON report, `intrinsics_report.json`.
    pub report: PathBuf,
    /// The residual plot, `residuals.svg`.
    pub residuals_svg: PathBuf,
    /// Simulated mode: the corners, `corners.json`.
    pub corners: Option<PathBuf>,
    /// Simulated mode: the true camera, `truth_camera_calib.yaml`.
    pub truth: Option<PathBuf>,
}

/// The Kalibr camchain entry (`cam0`) of a calibrated camera.
pub fn camchain_text(calibration: &IntrinsicCalibration, camera_name: &str) -> String {
    Rig::new(vec![RigCamera::new(
        camera_name,
        calibration.camera.clone(),
        Isometry3::identity(),
    )])
    .to_kalibr_string()
}

/// Writes the CamOdoCal YAML, the Kalibr camchain, the JSON report and the residual SVG (and,
/// for simulated boards, the corners and the true camera) into `dir`, creating it if needed.
/// Every file is staged in a hidden folder and renamed only when all were written
/// ([`StagedFiles`]), so an error or an interrupt leaves none of them behind.
///
/// # Errors
/// [`IntrinsicsError::Output`] if the folder cannot be created or a file cannot be written.
pub fn write_outputs(
    dir: &Path,
    camera_name: &str,
    calibration: &IntrinsicCalibration,
    corners: &CornerSet,
    report: &IntrinsicsReport,
    simulated: Option<&SimulatedBoards>,
) -> Result<OutputFiles, IntrinsicsError> {
    let files = OutputFiles {
        camodocal: dir.join(camodocal_file_name(camera_name)),
        camchain: dir.join(CAMCHAIN_FILE),
        report: dir.join(REPORT_FILE),
        residuals_svg: dir.join(RESIDUALS_SVG_FILE),
        corners: simulated.map(|_| dir.join(SIMULATED_CORNERS_FILE)),
        truth: simulated.map(|_| dir.join(camodocal_file_name(TRUTH_CAMERA_NAME))),
    };
    let mut staged = StagedFiles::new(dir)?;
    staged.stage(
        &files.camodocal,
        camodocal::format_camera(camera_name, &calibration.camera).as_bytes(),
    )?;
    staged.stage(
        &files.camchain,
        camchain_text(calibration, camera_name).as_bytes(),
    )?;
    staged.stage(&files.report, report.to_json_string().as_bytes())?;
    staged.stage(
        &files.residuals_svg,
        residual_svg(calibration, corners).as_bytes(),
    )?;
    if let (Some(sim), Some(c), Some(t)) = (simulated, &files.corners, &files.truth) {
        staged.stage(c, sim.corners.to_json_string().as_bytes())?;
        staged.stage(
            t,
            camodocal::format_camera(TRUTH_CAMERA_NAME, &sim.camera).as_bytes(),
        )?;
    }
    staged.commit()?;
    Ok(files)
}
