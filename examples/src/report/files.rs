//! The output files of a calibration, written all or nothing.
//!
//! Every file is first written into a hidden staging folder of the output folder and renamed
//! into place only when all of them were written ([`StagedFiles`]), so an error or an
//! interrupt leaves no partial output (and a folder this function created is removed again).

use std::path::{Path, PathBuf};

use ibc_camera_models::camodocal::{
    EXTRINSIC_FILE_NAME, calib_file_name, format_camera, format_extrinsics,
};
use ibc_camera_models::{Rig, RigCamera};

use super::json::Report;
use super::svg::{error_histogram_svg, top_view_svg};
use super::table::text_table;
use crate::calib::Calibration;
use crate::data::io::{DataFileError, StagedFiles};

/// The names of the output files.
pub mod output_names {
    /// The JSON report.
    pub const REPORT_JSON: &str = "report.json";
    /// The text table.
    pub const REPORT_TEXT: &str = "report.txt";
    /// The Kalibr camchain with the intrinsics and the estimated extrinsics (named so that it
    /// never overwrites the input `camchain.yaml` of a simulated world's folder).
    pub const CAMCHAIN: &str = "camchain-calibrated.yaml";
    /// The folder of the CamOdoCal files, laid out as CamOdoCal's `CameraSystem` writes and
    /// reads a rig (`<name>_calib.yaml` per camera and `extrinsic.txt`).
    pub const CAMODOCAL_DIR: &str = "camodocal";
    /// The top view.
    pub const TOP_VIEW: &str = "top_view.svg";
    /// The reprojection-error distribution.
    pub const ERRORS: &str = "reprojection_errors.svg";
    /// The rig for COLMAP's `rig_configurator` (`crate::colmap::rig_config_json`), written
    /// when every camera has a COLMAP model (not for the unified model).
    pub const RIG_CONFIG: &str = "rig_config.json";
    /// The calibration as a COLMAP text model (its cameras and rig; no images or points),
    /// written with [`RIG_CONFIG`].
    pub const COLMAP_MODEL_DIR: &str = "colmap";
}

/// Why the output files could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// A file could not be written or renamed.
    #[error(transparent)]
    File(#[from] DataFileError),
    /// A camera name cannot be a file name.
    #[error(
        "camera name `{0}` cannot be used in a file name (CamOdoCal names files after cameras, \
         and keeps only the first word of a name)"
    )]
    CameraName(String),
}

/// The calibrated rig: the calibration's names, intrinsics and extrinsics, with the Kalibr
/// metadata of the camera file's cameras (topic, overlaps, time shift to the IMU). The
/// camera file's `T_cam_imu` is carried over through camera 0, which defines the rig frame:
/// the IMU is taken as fixed to it, so camera `c`'s new `camera_from_imu` is
/// `rig_from_camera_c^-1 camera_0_from_imu` (none when camera 0 has no `T_cam_imu`).
pub fn calibrated_rig(calibration: &Calibration) -> Rig {
    let prior = &calibration.prior_rig.cameras;
    let rig_from_imu = prior.first().and_then(|c| c.camera_from_imu);
    Rig::new(
        calibration
            .camera_names
            .iter()
            .zip(&calibration.cameras)
            .zip(&calibration.rig_from_camera)
            .enumerate()
            .map(|(c, ((name, camera), pose))| {
                let mut rc = RigCamera::new(name.clone(), camera.clone(), *pose);
                if let Some(p) = prior.get(c) {
                    rc.topic.clone_from(&p.topic);
                    rc.overlaps.clone_from(&p.overlaps);
                    rc.timeshift_cam_imu_s = p.timeshift_cam_imu_s;
                }
                rc.camera_from_imu = rig_from_imu.map(|r| pose.inverse() * r);
                rc
            })
            .collect(),
    )
}

/// Refuses a camera name that cannot name a file (CamOdoCal names files after cameras).
pub(crate) fn check_camera_name(name: &str) -> Result<(), OutputError> {
    if name.is_empty()
        || name.contains(['/', '\\', '\0'])
        || name.chars().any(char::is_whitespace)
        || name == "."
        || name == ".."
    {
        return Err(OutputError::CameraName(name.to_owned()));
    }
    Ok(())
}

/// Writes every output file into `dir` (created if missing): the JSON report, the text table,
/// the Kalibr camchain, the CamOdoCal folder and the two SVG plots (see [`output_names`]),
/// all or nothing ([`StagedFiles`]). Returns the files written.
///
/// # Errors
/// [`OutputError`]; nothing is left behind then.
pub fn write_outputs(
    dir: impl AsRef<Path>,
    calibration: &Calibration,
    report: &Report,
) -> Result<Vec<PathBuf>, OutputError> {
    use output_names as n;
    let dir = dir.as_ref();
    for name in &calibration.camera_names {
        check_camera_name(name)?;
    }
    let rig = calibrated_rig(calibration);
    let contents: Vec<(PathBuf, String)> = vec![
        (dir.join(n::REPORT_JSON), report.to_json() + "\n"),
        (dir.join(n::REPORT_TEXT), text_table(report)),
        (dir.join(n::TOP_VIEW), top_view_svg(calibration)),
        (dir.join(n::ERRORS), error_histogram_svg(calibration)),
    ];
    write_with_rig(dir, contents, &rig)
}

/// Writes `contents` and the rig's files (the Kalibr camchain and the CamOdoCal folder) into
/// `dir`, all or nothing.
pub(crate) fn write_with_rig(
    dir: &Path,
    mut contents: Vec<(PathBuf, String)>,
    rig: &Rig,
) -> Result<Vec<PathBuf>, OutputError> {
    use output_names as n;
    for c in &rig.cameras {
        check_camera_name(&c.name)?;
    }
    contents.push((dir.join(n::CAMCHAIN), rig.to_kalibr_string()));
    if let Ok(json) = crate::colmap::rig_config_json(rig) {
        contents.push((dir.join(n::RIG_CONFIG), json));
    }
    // The calibration as a COLMAP text model: its cameras and its rig, no images or points.
    let empty: crate::data::Map<[u64; 4]> = crate::data::Map {
        points: Vec::new(),
        images: Vec::new(),
    };
    if let Ok(export) = crate::colmap::colmap_from_map(rig, &empty, &[], dir) {
        let model = dir.join(n::COLMAP_MODEL_DIR);
        for (name, text) in crate::colmap::model_to_text(&export.model) {
            contents.push((model.join(name), text));
        }
    }
    let camodocal = dir.join(n::CAMODOCAL_DIR);
    for c in &rig.cameras {
        contents.push((
            camodocal.join(calib_file_name(&c.name)),
            format_camera(&c.name, &c.camera),
        ));
    }
    contents.push((
        camodocal.join(EXTRINSIC_FILE_NAME),
        format_extrinsics(
            rig.cameras
                .iter()
                .map(|c| (c.name.as_str(), &c.rig_from_camera)),
        ),
    ));
    let mut files = StagedFiles::new(dir)?;
    for (path, text) in &contents {
        files.stage(path, text.as_bytes())?;
    }
    Ok(files.commit()?)
}
