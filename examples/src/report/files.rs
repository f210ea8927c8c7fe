//! The output files of a calibration, written all or nothing.
//!
//! Every file is first written to a temporary file in its target folder; the temporary files
//! are renamed into place only when all of them were written, so an error leaves no partial
//! output (and a folder this function created is removed again).

use std::path::{Path, PathBuf};

use ibc_camera_models::camodocal::{format_camera, format_extrinsics};
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
    /// The folder of the CamOdoCal files (`<name>_camera_calib.yaml` per camera and
    /// `extrinsic.txt`).
    pub const CAMODOCAL_DIR: &str = "camodocal";
    /// The top view.
    pub const TOP_VIEW: &str = "top_view.svg";
    /// The reprojection-error distribution.
    pub const ERRORS: &str = "reprojection_errors.svg";
}

/// Why the output files could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// A folder could not be created.
    #[error("cannot create the output folder {}: {source}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file could not be written or renamed.
    #[error(transparent)]
    File(#[from] DataFileError),
    /// A camera name cannot be a file name.
    #[error(
        "camera name `{0}` cannot be used in a file name (CamOdoCal names files after cameras)"
    )]
    CameraName(String),
}

/// The calibrated rig: the calibration's names, intrinsics and extrinsics, with the topics of
/// `prior` (the camera file) when it has them.
pub fn calibrated_rig(calibration: &Calibration, prior: Option<&Rig>) -> Rig {
    Rig::new(
        calibration
            .camera_names
            .iter()
            .zip(&calibration.cameras)
            .zip(&calibration.rig_from_camera)
            .enumerate()
            .map(|(c, ((name, camera), pose))| {
                let mut rc = RigCamera::new(name.clone(), camera.clone(), *pose);
                rc.topic = prior
                    .and_then(|p| p.cameras.get(c))
                    .and_then(|p| p.topic.clone());
                rc
            })
            .collect(),
    )
}

/// Creates `dir` and its missing parents; returns the topmost folder it created, if any.
fn create_folder(dir: &Path) -> Result<Option<PathBuf>, OutputError> {
    let mut missing = None;
    let mut p = Some(dir);
    while let Some(d) = p {
        if d.as_os_str().is_empty() || d.exists() {
            break;
        }
        missing = Some(d.to_path_buf());
        p = d.parent();
    }
    std::fs::create_dir_all(dir).map_err(|source| OutputError::Folder {
        path: dir.to_path_buf(),
        source,
    })?;
    Ok(missing)
}

/// Writes every output file into `dir` (created if missing): the JSON report, the text table,
/// the Kalibr camchain, the CamOdoCal folder and the two SVG plots (see [`output_names`]).
/// Returns the files written.
///
/// # Errors
/// [`OutputError`]; nothing is left behind then.
pub fn write_outputs(
    dir: impl AsRef<Path>,
    calibration: &Calibration,
    report: &Report,
    prior: Option<&Rig>,
) -> Result<Vec<PathBuf>, OutputError> {
    use output_names as n;
    let dir = dir.as_ref();
    for name in &calibration.camera_names {
        if name.is_empty() || name.contains(['/', '\\', '\0']) || name == "." || name == ".." {
            return Err(OutputError::CameraName(name.clone()));
        }
    }
    let rig = calibrated_rig(calibration, prior);
    let mut contents: Vec<(PathBuf, String)> = vec![
        (dir.join(n::REPORT_JSON), report.to_json() + "\n"),
        (dir.join(n::REPORT_TEXT), text_table(report)),
        (dir.join(n::CAMCHAIN), rig.to_kalibr_string()),
        (dir.join(n::TOP_VIEW), top_view_svg(calibration)),
        (dir.join(n::ERRORS), error_histogram_svg(calibration)),
    ];
    let camodocal = dir.join(n::CAMODOCAL_DIR);
    for c in &rig.cameras {
        contents.push((
            camodocal.join(format!("{}_camera_calib.yaml", c.name)),
            format_camera(&c.name, &c.camera),
        ));
    }
    contents.push((
        camodocal.join("extrinsic.txt"),
        format_extrinsics(
            rig.cameras
                .iter()
                .map(|c| (c.name.as_str(), &c.rig_from_camera)),
        ),
    ));
    let created = create_folder(&camodocal)?;
    let staged = (|| {
        let mut files = StagedFiles::new();
        for (path, text) in &contents {
            files.stage(path, text.as_bytes())?;
        }
        files.commit()
    })();
    match staged {
        Ok(written) => Ok(written),
        Err(e) => {
            if let Some(top) = created {
                // Best effort: the error reported is the write's.
                let _ = std::fs::remove_dir_all(top);
            }
            Err(e.into())
        }
    }
}
