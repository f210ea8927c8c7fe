//! The command line's errors: one line that names the problem and a likely cause.

use std::path::PathBuf;

use ibc_pipeline::calib::CalibrationError;
use ibc_pipeline::data::TruthMismatch;
use ibc_pipeline::data::io::{DataFileError, DescriptorLayout};
use ibc_pipeline::intrinsics::IntrinsicsError;
use ibc_pipeline::report::OutputError;
use ibc_pipeline::sim::SimError;

/// Why a command failed.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// A target calibration's input, detection or output failed.
    #[error("{0}")]
    Target(#[from] ibc_pipeline::target::TargetError),
    /// A scenario could not be resolved, simulated or written.
    #[error("{0}")]
    Simulation(#[from] SimError),
    /// A map, log or ground-truth file could not be read.
    #[error("{what}: {source}{}", hint(source))]
    Data {
        /// Which input (`map`, `rig log`, `ground truth`).
        what: &'static str,
        /// The reader's error, naming the file.
        source: DataFileError,
    },
    /// A COLMAP model or database could not be read.
    #[error("{what}: {source}")]
    Colmap {
        /// Which input (`map`, `rig log`).
        what: &'static str,
        /// The reader's error, naming the file.
        source: ibc_pipeline::colmap::ColmapError,
    },
    /// A COLMAP sparse model was given as the map without its database.
    #[error(
        "--map {}: a COLMAP sparse model needs --database, the COLMAP database it was built \
         from (its keypoints and descriptors)",
        path.display()
    )]
    ColmapDatabaseMissing {
        /// The model folder.
        path: PathBuf,
    },
    /// The ground truth is not the truth of the rig log.
    #[error("ground truth {}: {source}", path.display())]
    TruthMismatch {
        /// The ground-truth file.
        path: PathBuf,
        /// What differs.
        source: TruthMismatch,
    },
    /// The camera file could not be read.
    #[error("{}", camera_file_message(path, source))]
    Cameras {
        /// The file or folder given.
        path: PathBuf,
        /// The reader's error.
        source: Box<ibc_camera_models::CameraFileError>,
    },
    /// The vocabulary file could not be read.
    #[error("vocabulary: {source}")]
    Vocabulary {
        /// The reader's error, naming the file.
        source: ibc_vocab_tree::VocabError,
    },
    /// The map and the log hold different kinds of descriptors.
    #[error(
        "the map holds {map} descriptors but the rig log holds {log}: were they extracted \
         with different feature detectors?"
    )]
    DescriptorMismatch {
        /// The map's layout.
        map: DescriptorLayout,
        /// The log's layout.
        log: DescriptorLayout,
    },
    /// The descriptors are of a kind this build does not calibrate with.
    #[error(
        "{0} descriptors are not supported (binary 256 or 512 bits, float 32, 64 or 128 \
         values are)"
    )]
    UnsupportedDescriptor(DescriptorLayout),
    /// The calibration failed.
    #[error("calibration failed: {0}")]
    Calibration(#[from] CalibrationError),
    /// The output files could not be written.
    #[error("{0}")]
    Output(#[from] OutputError),
    /// The intrinsic calibration failed (its error names the input or the views at fault).
    #[error("{0}")]
    Intrinsics(#[from] IntrinsicsError),
    /// The self-calibration failed.
    #[error("self-calibration failed: {0}")]
    SelfCalibration(#[from] ibc_pipeline::sfm::SelfCalibrationError),
    /// `--baseline` could not be understood.
    #[error("--baseline {value}: {reason}")]
    Baseline {
        /// The value given.
        value: String,
        /// What is wrong with it.
        reason: String,
    },
    /// `--colmap` asked of a log whose descriptors COLMAP cannot store.
    #[error(
        "--colmap: COLMAP databases hold 128-value SIFT or binary descriptors, not this log's \
         {floats}-value float ones"
    )]
    ColmapDescriptor {
        /// Values per descriptor of the log.
        floats: usize,
    },
    /// Standard output could not be written.
    #[error("cannot write to standard output: {0}")]
    Stdout(std::io::Error),
}

/// The message of a camera-file error: the path once (the reader's error names the file it
/// was reading, inside a CamOdoCal folder too), and what a camera file is when the file was
/// not one.
fn camera_file_message(
    path: &std::path::Path,
    error: &ibc_camera_models::CameraFileError,
) -> String {
    use ibc_camera_models::CameraFileError as E;
    use ibc_camera_models::io::IoError;
    let named = if error.path().is_some() {
        format!("camera file: {error}")
    } else {
        format!("camera file {}: {error}", path.display())
    };
    let not_a_camera_file = match error {
        E::InFile { source, .. } => {
            !matches!(**source, E::Implausible { .. } | E::Parameters { .. })
        }
        E::Implausible { .. }
        | E::Parameters { .. }
        | E::Io(IoError::TooLarge { .. } | IoError::NotRegularFile { .. }) => false,
        _ => true,
    };
    if not_a_camera_file {
        named
            + " (expected a Kalibr camchain YAML, or a CamOdoCal folder with extrinsic.txt and \
               a <name>_calib.yaml or <name>_camera_calib.yaml file per camera)"
    } else {
        named
    }
}

/// A likely cause of a data-file error the reader's message does not already give.
fn hint(error: &DataFileError) -> &'static str {
    use ibc_camera_models::io::IoError;
    match error {
        DataFileError::Io(IoError::Os { source, .. })
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            " (is the path right? `ibc simulate` writes map.ibcmap, log.ibclog, camchain.yaml \
             and truth.json)"
        }
        _ => "",
    }
}

impl CliError {
    /// The message on one line.
    pub fn one_line(&self) -> String {
        self.to_string().replace(['\n', '\r'], " ")
    }
}
