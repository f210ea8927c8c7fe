//! The intrinsic calibration's error type: every way the input can be unusable and every step
//! that can have no answer.

use std::path::PathBuf;

use crate::data::io::DataFileError;

/// Why an intrinsic calibration (or its input, simulation or outputs) failed.
///
/// Caller input never causes a panic: each unusable input is one of these variants, and the
/// message says what was wrong with it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IntrinsicsError {
    /// The planar target is not a board: fewer than 2 x 2 corners, or a square size that is
    /// not finite and positive.
    #[error("invalid target: {0}")]
    InvalidTarget(String),
    /// An option, command-line value or camera is outside its valid range.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// Fewer usable images than the calibration needs.
    #[error("{got} images with corners, but the calibration needs at least {needed}")]
    TooFewImages {
        /// Images given.
        got: usize,
        /// The minimum ([`crate::intrinsics::MIN_IMAGES`]).
        needed: usize,
    },
    /// An image has fewer corners than a board pose needs.
    #[error("image `{image}` has {got} corners, but each image needs at least {needed}")]
    TooFewCorners {
        /// The image's name.
        image: String,
        /// Corners it has.
        got: usize,
        /// The minimum ([`crate::intrinsics::MIN_CORNERS_PER_IMAGE`]).
        needed: usize,
    },
    /// A corner lies outside the image `[-0.5, width - 0.5] x [-0.5, height - 0.5]` (pixel
    /// centres at integers) or is not finite.
    #[error(
        "image `{image}`: corner (row {row}, col {col}) at ({u}, {v}) is outside the {width}x{height} image"
    )]
    CornerOutsideImage {
        /// The image's name.
        image: String,
        /// Board row of the corner.
        row: u32,
        /// Board column of the corner.
        col: u32,
        /// Its horizontal pixel coordinate.
        u: f64,
        /// Its vertical pixel coordinate.
        v: f64,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
    },
    /// A corner's board index is not on the board.
    #[error(
        "image `{image}`: corner (row {row}, col {col}) is not on the {rows}x{cols} board (indices start at 0)"
    )]
    CornerNotOnBoard {
        /// The image's name.
        image: String,
        /// Board row given.
        row: u32,
        /// Board column given.
        col: u32,
        /// Rows of inner corners of the board.
        rows: u32,
        /// Columns of inner corners of the board.
        cols: u32,
    },
    /// The same board corner appears twice in one image.
    #[error("image `{image}`: corner (row {row}, col {col}) is listed twice")]
    DuplicateCorner {
        /// The image's name.
        image: String,
        /// Board row.
        row: u32,
        /// Board column.
        col: u32,
    },
    /// An image's corners all lie on one board line, so its pose is undetermined.
    #[error("image `{image}`: all its corners lie on one board row, column or diagonal")]
    CollinearCorners {
        /// The image's name.
        image: String,
    },
    /// The views cannot separate the focal length from the board distance: every board is
    /// (nearly) parallel to every other, for instance all parallel to the image plane (Zhang,
    /// PAMI 2000, section 3.3: parallel planes add no constraint).
    #[error(
        "degenerate views: {reason}; tilt the board by 20 to 45 degrees in different directions across the images"
    )]
    DegenerateViews {
        /// What was measured.
        reason: String,
    },
    /// The Kannala-Brandt initialization found no focal length: no image has two board rows
    /// (or columns) whose fitted circles meet in two vanishing points.
    #[error(
        "no focal-length hypothesis: no image has two board rows or columns of at least {min_corners} corners whose circles meet in two vanishing points"
    )]
    NoFocalHypothesis {
        /// Corners a row needs to be fitted ([`crate::intrinsics::MIN_LINE_CORNERS`]).
        min_corners: usize,
    },
    /// A closed-form initialization has no answer for these views.
    #[error("initialization failed: {0}")]
    Initialization(String),
    /// A board pose could not be computed from an image's corners.
    #[error("image `{image}`: no board pose: {source}")]
    BoardPose {
        /// The image's name.
        image: String,
        /// Why the pose solver refused.
        source: ibc_pnp::PnpError,
    },
    /// The joint refinement failed to run or did not converge.
    #[error("refinement: {0}")]
    Refinement(String),
    /// The refinement's solver refused the problem.
    #[error("refinement: {0}")]
    Solver(#[from] ibc_bundle_adjust::BundleAdjustError),
    /// The information matrix of the intrinsics is singular at the solution, so they have no
    /// covariance (an unobservable parameter).
    #[error("the intrinsics' information matrix is singular: {0}")]
    SingularInformation(String),
    /// A camera's parameters were refused by the model.
    #[error("camera: {0}")]
    Camera(#[from] ibc_camera_models::ParameterError),
    /// A camera file could not be read.
    #[error("camera file: {0}")]
    CameraFile(#[from] ibc_camera_models::CameraFileError),
    /// The corner file is malformed: the message names the field and, for JSON syntax, the
    /// line and column.
    #[error("{}: {message}", path.as_ref().map_or_else(|| "corner file".to_owned(), |p| p.display().to_string()))]
    CornerFile {
        /// The corner file, when the corners came from one.
        path: Option<PathBuf>,
        /// What is wrong with it.
        message: String,
    },
    /// The corner file is not valid JSON or misses a field (the parser's error gives the line
    /// and column).
    #[error("{}: {source}", path.as_ref().map_or_else(|| "corner file".to_owned(), |p| p.display().to_string()))]
    CornerJson {
        /// The corner file, when the corners came from one.
        path: Option<PathBuf>,
        /// The JSON parser's error.
        source: serde_json::Error,
    },
    /// A file could not be read or written (missing, not a regular file, too large, not
    /// text, standard output closed); names the file.
    #[error(transparent)]
    Io(#[from] ibc_camera_models::io::IoError),
    /// Writing an output file failed (nothing is left behind).
    #[error(transparent)]
    Output(#[from] DataFileError),
}
