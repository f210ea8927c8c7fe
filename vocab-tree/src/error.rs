//! The crate's error type.

use std::path::PathBuf;

use crate::descriptor::DescriptorKind;

/// Everything that can go wrong in `ibc-vocab-tree`.
///
/// Every variant says what was wrong with the input; no function of this crate panics on
/// caller input.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VocabError {
    /// Training was given no descriptor at all (every image was empty).
    #[error("training needs at least one descriptor, but every training image was empty")]
    NoTrainingData,
    /// A training option is outside its valid domain.
    #[error("invalid training option `{name}`: {reason}")]
    InvalidOption {
        /// The option's field name.
        name: &'static str,
        /// Why the value is invalid.
        reason: String,
    },
    /// A float descriptor holds NaN or an infinity.
    #[error("descriptor {index} of image {image} holds a non-finite value")]
    NonFiniteDescriptor {
        /// The image (training set index) holding the descriptor.
        image: usize,
        /// The descriptor's index in its image.
        index: usize,
    },
    /// The tree would need more nodes than a 32-bit node id can name.
    #[error("the vocabulary would need {nodes} nodes, more than a u32 node id can name")]
    TooManyNodes {
        /// The number of nodes that was needed.
        nodes: u64,
    },
    /// The parts of a vocabulary do not form a valid tree.
    #[error("invalid vocabulary tree: {0}")]
    InvalidTree(String),
    /// A word id is not in the vocabulary.
    #[error("word id {word} is out of range: the vocabulary has {word_count} words")]
    WordOutOfRange {
        /// The offending word id.
        word: u32,
        /// The number of words in the vocabulary.
        word_count: u32,
    },
    /// A bag-of-words vector is not sorted by strictly increasing word id, or holds a weight
    /// that is negative or not finite.
    #[error("invalid bag-of-words vector: {0}")]
    InvalidBowVector(String),
    /// A feature vector (direct index entry) is malformed or names a feature that does not
    /// exist.
    #[error("invalid feature vector: {0}")]
    InvalidFeatureVector(String),
    /// The database holds `u32::MAX` images already.
    #[error("the database is full: image ids are u32")]
    DatabaseFull,
    /// The database keeps a direct index, so images must come with their feature vectors.
    #[error("this database keeps a direct index: add images with their feature vector")]
    MissingFeatureVector,
    /// The instruction set asked for is not supported by this CPU.
    #[error("the instruction set {0:?} is not supported by this CPU")]
    UnsupportedIsa(crate::simd::Isa),
    /// A vocabulary file could not be read or written (missing, not a regular file, or the
    /// operating system's error); names the file.
    #[error(transparent)]
    Io(#[from] ibc_camera_models::io::IoError),
    /// A vocabulary's bytes or text are not valid.
    #[error("invalid vocabulary file: {0}")]
    File(#[from] VocabFileError),
    /// A vocabulary file read from a path is not valid.
    #[error("invalid vocabulary file {}: {source}", path.display())]
    InvalidFile {
        /// The file.
        path: PathBuf,
        /// Why it was rejected.
        source: VocabFileError,
    },
}

impl VocabError {
    /// The error with the file's path attached when it is a [`VocabError::File`] (the other
    /// errors of a file name it already, or are not about the file).
    #[must_use]
    pub fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            Self::File(source) => Self::InvalidFile {
                path: path.to_path_buf(),
                source,
            },
            other => other,
        }
    }
}

/// Why a vocabulary file was rejected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum VocabFileError {
    /// The file does not start with the format's magic bytes.
    #[error("not an ibc vocabulary file (bad magic bytes)")]
    BadMagic,
    /// The file was written by a format version this build does not read.
    #[error("unsupported format version {found} (this build reads version {supported})")]
    UnsupportedVersion {
        /// The version in the file.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// The file holds another kind or width of descriptor than the one asked for.
    #[error(
        "descriptor mismatch: the file holds {found_kind:?} descriptors of width {found_width}, \
         but {expected_kind:?} of width {expected_width} were asked for"
    )]
    DescriptorMismatch {
        /// The kind asked for.
        expected_kind: DescriptorKind,
        /// The width asked for (u64 words or f32 elements).
        expected_width: u32,
        /// The kind in the file.
        found_kind: DescriptorKind,
        /// The width in the file.
        found_width: u32,
    },
    /// The file is shorter than its header says.
    #[error("truncated file: {expected} bytes expected, {found} found")]
    Truncated {
        /// The length the header implies.
        expected: u64,
        /// The actual length.
        found: u64,
    },
    /// The file is longer than its header says.
    #[error("{extra} unexpected bytes after the end of the vocabulary")]
    TrailingBytes {
        /// How many bytes follow the checksum.
        extra: u64,
    },
    /// The checksum does not match the content: the file is corrupt.
    #[error("checksum mismatch (stored {stored:#018x}, computed {computed:#018x}): corrupt file")]
    ChecksumMismatch {
        /// The checksum stored in the file.
        stored: u64,
        /// The checksum of the content.
        computed: u64,
    },
    /// A header field holds a value outside its domain.
    #[error("invalid header field `{field}`: {value}")]
    InvalidHeader {
        /// The field's name.
        field: &'static str,
        /// The value found.
        value: u64,
    },
    /// A text (DBoW2 / ORB-SLAM) vocabulary could not be parsed.
    #[error("text vocabulary, line {line}: {reason}")]
    Text {
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
}

/// The crate's result type.
pub type Result<T, E = VocabError> = std::result::Result<T, E>;
