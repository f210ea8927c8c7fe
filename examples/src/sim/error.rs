//! The simulator's error type.

use std::path::PathBuf;

use crate::data::io::DataFileError;

/// Why a scenario could not be loaded, simulated or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// No built-in scenario has this name (and no file has this path).
    #[error(
        "unknown scenario `{name}`: not a file and not one of the built-in scenarios ({known})"
    )]
    UnknownScenario {
        /// The name asked for.
        name: String,
        /// The built-in names, comma-separated.
        known: String,
    },
    /// A scenario file is malformed: a missing, unknown or mistyped key, or a value out of
    /// range. The message names the key.
    #[error("{}: {message}", path.as_ref().map_or_else(|| "scenario".to_owned(), |p| p.display().to_string()))]
    Scenario {
        /// The scenario file, when the scenario came from one.
        path: Option<PathBuf>,
        /// What is wrong, naming the key.
        message: String,
    },
    /// A scenario file's content is refused by a check that does not name the file: the
    /// file, then the reason.
    #[error("{}: {source}", path.as_ref().map_or_else(|| "scenario".to_owned(), |p| p.display().to_string()))]
    InScenario {
        /// The scenario file, when the scenario came from one.
        path: Option<PathBuf>,
        /// Why.
        source: Box<SimError>,
    },
    /// A scenario value is out of its valid range (checked before simulating).
    #[error("invalid scenario: {0}")]
    Invalid(String),
    /// A rig's camera file could not be read (the error names the file), or its cameras'
    /// names are not unique.
    #[error("rig: {0}")]
    CameraFile(#[from] ibc_camera_models::CameraFileError),
    /// A rig's camera file holds no camera.
    #[error("rig: {} has no camera", path.display())]
    EmptyRig {
        /// The camera file.
        path: PathBuf,
    },
    /// A built-in camera's parameters were refused (a bug of the built-in rigs).
    #[error("built-in camera {name}: {source}")]
    BuiltinCamera {
        /// The camera's name.
        name: String,
        /// Why its parameters were refused.
        source: ibc_camera_models::ParameterError,
    },
    /// The environment cannot hold the trajectory asked for.
    #[error("environment: {0}")]
    Environment(String),
    /// A scenario file could not be read (missing, not a regular file, too large, not text);
    /// names the file.
    #[error(transparent)]
    Io(#[from] ibc_camera_models::io::IoError),
    /// Writing a world's files failed.
    #[error(transparent)]
    File(#[from] DataFileError),
}
