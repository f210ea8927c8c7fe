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
    /// A scenario value is out of its valid range (checked before simulating).
    #[error("invalid scenario: {0}")]
    Invalid(String),
    /// A rig's camera file could not be read, or a camera was refused.
    #[error("rig: {0}")]
    Rig(String),
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
