//! Errors of the map, rig-log and ground-truth files.

use std::fmt;
use std::path::PathBuf;

use ibc_camera_models::io::IoError;

use ibc_vocab_tree::DescriptorKind;

/// The descriptor layout a file records: its kind and width.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DescriptorLayout {
    /// Binary (`u64` words) or float (`f32` values).
    pub kind: DescriptorKind,
    /// Number of elements: `u64` words or `f32` values.
    pub width: u32,
}

impl fmt::Display for DescriptorLayout {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            DescriptorKind::Binary => write!(
                f,
                "binary {}-bit ({} u64 words)",
                u64::from(self.width) * 64,
                self.width
            ),
            DescriptorKind::Float => write!(f, "float ({} f32 values)", self.width),
        }
    }
}

/// Why the bytes of a map or rig-log file are not a valid file of the kind asked for (or why
/// data cannot be written as one). Carried by [`DataFileError::Format`] with the file's path.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FormatError {
    /// Fewer bytes than the fixed header and checksum.
    #[error(
        "the file has only {len} bytes, fewer than the {minimum} of an empty {expected}: it is \
         truncated or not an ibc file"
    )]
    TooShort {
        /// The file's length in bytes.
        len: u64,
        /// The smallest valid file of that kind.
        minimum: u64,
        /// `"map"` or `"rig log"`.
        expected: &'static str,
    },
    /// The first eight bytes are not an ibc magic.
    #[error("not an ibc {expected} file: it starts with {found:?}")]
    BadMagic {
        /// `"map"` or `"rig log"`.
        expected: &'static str,
        /// The first eight bytes, escaped.
        found: String,
    },
    /// The file is an ibc file of the other kind (a rig log given as the map, say).
    #[error("this is an ibc {found} file, not a {expected} file: were the arguments swapped?")]
    WrongFileKind {
        /// What was asked for.
        expected: &'static str,
        /// What the file is.
        found: &'static str,
    },
    /// A format version this build cannot read.
    #[error(
        "format version {found} is not supported (this build reads version {supported}): was \
         the file written by a newer ibc?"
    )]
    UnsupportedVersion {
        /// The file's version.
        found: u32,
        /// The version this build reads and writes.
        supported: u32,
    },
    /// The descriptor kind code is neither binary nor float.
    #[error("unknown descriptor kind code {code} (1 is binary, 2 is float)")]
    UnknownDescriptorKind {
        /// The code found.
        code: u8,
    },
    /// The file holds descriptors of another kind or width than the type asked for.
    #[error("the file holds {found} descriptors but {expected} descriptors were asked for")]
    DescriptorMismatch {
        /// What the file holds.
        found: DescriptorLayout,
        /// What the reader was asked for.
        expected: DescriptorLayout,
    },
    /// The length written in the header is not the file's length.
    #[error(
        "the header says the file has {declared} bytes but it has {actual}: it is truncated \
         or something was appended"
    )]
    LengthMismatch {
        /// The length in the header.
        declared: u64,
        /// The actual length.
        actual: u64,
    },
    /// The stored checksum is not the checksum of the content.
    #[error(
        "checksum mismatch (stored {stored:#018x}, computed {computed:#018x}): the file is \
         corrupt"
    )]
    ChecksumMismatch {
        /// The XXH64 stored at the end of the file.
        stored: u64,
        /// The XXH64 of the bytes before it.
        computed: u64,
    },
    /// The counts in the header do not add up to the file's length.
    #[error("the counts in the header ({counts}) need {needed} bytes but the file has {actual}")]
    LayoutMismatch {
        /// The counts, described.
        counts: String,
        /// The length they imply (saturated at `u64::MAX`).
        needed: u64,
        /// The file's length.
        actual: u64,
    },
    /// A value in the file (or in the data to write) is out of its valid range: an index past
    /// its array, a non-finite number, a quaternion that is not a unit, a flag that is not 0 or
    /// 1, non-zero reserved bytes, inconsistent lengths.
    #[error("invalid content: {what}")]
    Invalid {
        /// What is wrong and where.
        what: String,
    },
}

/// An error reading or writing a data file, naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DataFileError {
    /// The file could not be read, created, written or renamed (or is not a regular file, or
    /// is too large); names the file.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The file's bytes are not a valid file of the kind asked for, or the data cannot be
    /// written as one.
    #[error("{}: {source}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// Why.
        source: FormatError,
    },
    /// The ground-truth JSON is malformed or misses a field.
    #[error("{}: not a valid ground-truth JSON file: {source}", path.display())]
    Json {
        /// The file.
        path: PathBuf,
        /// The parser's error, with line and column.
        source: serde_json::Error,
    },
}

impl DataFileError {
    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            Self::Io(e) => e.path(),
            Self::Format { path, .. } | Self::Json { path, .. } => path,
        }
    }
}

/// Shorthand for [`FormatError::Invalid`].
pub(crate) fn invalid(what: impl Into<String>) -> FormatError {
    FormatError::Invalid { what: what.into() }
}
