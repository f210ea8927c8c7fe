//! The crate's error types.

use std::path::PathBuf;

use thiserror::Error;

/// `Result` with [`BundleAdjustError`] as the default error.
pub type Result<T, E = BundleAdjustError> = std::result::Result<T, E>;

/// Everything that can go wrong when building or solving a problem.
///
/// Every variant says what was wrong with the input and names it (block, residual,
/// observation, camera, frame set, image, point or option); caller input never causes a panic.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum BundleAdjustError {
    /// A parameter value is NaN or infinite.
    #[error("parameter block {block} has the non-finite value {value} at index {index}")]
    NonFiniteParameter {
        /// Index of the parameter block.
        block: usize,
        /// Index of the value inside the block.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// An observation (or another constant of a residual) is NaN or infinite.
    #[error("observation {index} has a non-finite value")]
    NonFiniteObservation {
        /// Index of the observation.
        index: usize,
    },
    /// A pose or point of a problem description (an extrinsic, a rig pose, an image pose, a
    /// point) has a NaN or infinite component.
    #[error("{what}[{index}] is not finite")]
    NonFiniteInput {
        /// The field holding it: `rig_from_camera`, `world_from_rig`, `camera_from_world` or
        /// `points`.
        what: &'static str,
        /// Its index in that field.
        index: usize,
    },
    /// Two parts of a problem description that must have one entry each for the same things
    /// have different lengths.
    #[error("{what} has {got} entries, {expected} expected")]
    LengthMismatch {
        /// The field (or argument) with the wrong length, for instance `rig_from_camera`.
        what: &'static str,
        /// The length it must have (the number of cameras, images, ...).
        expected: usize,
        /// Its length.
        got: usize,
    },
    /// An index in a problem description points past the end of what it indexes.
    #[error("{what} {position} refers to {target} {index}, but there are {count}")]
    IndexOutOfRange {
        /// What holds the index: `observation` or `image`.
        what: &'static str,
        /// Position of that observation or image.
        position: usize,
        /// What the index is of: `camera`, `frame set`, `image` or `point`.
        target: &'static str,
        /// The index.
        index: usize,
        /// Number of those things.
        count: usize,
    },
    /// A camera has no observation that can be evaluated at the initial estimate, so nothing
    /// determines it (in a rig refinement its extrinsic; in a bundle adjustment with
    /// [`crate::BundleAdjustmentOptions::optimize_intrinsics`] its intrinsics).
    #[error(
        "camera {camera} has no usable observation ({excluded} excluded: they cannot be evaluated at the initial estimate)"
    )]
    CameraWithoutObservations {
        /// Index of the camera.
        camera: usize,
        /// How many of its observations were excluded (behind the camera, outside the
        /// model's domain or not finite at the start); 0 when it had none.
        excluded: usize,
    },
    /// A frame set of a rig refinement has no observation that can be evaluated at the
    /// initial estimate, so nothing determines its rig pose.
    #[error(
        "frame set {frame} has no usable observation ({excluded} excluded: they cannot be evaluated at the initial estimate)"
    )]
    FrameWithoutObservations {
        /// Index of the frame set.
        frame: usize,
        /// How many of its observations were excluded; 0 when it had none.
        excluded: usize,
    },
    /// An image of a bundle adjustment whose pose is not held fixed has no observation that
    /// can be evaluated at the initial estimate, so nothing determines its pose.
    #[error(
        "image {image} has no usable observation ({excluded} excluded: they cannot be evaluated at the initial estimate)"
    )]
    ImageWithoutObservations {
        /// Index of the image.
        image: usize,
        /// How many of its observations were excluded; 0 when it had none.
        excluded: usize,
    },
    /// A point of a bundle adjustment has no observation that can be evaluated at the
    /// initial estimate, so nothing determines it.
    #[error(
        "point {point} has no usable observation ({excluded} excluded: they cannot be evaluated at the initial estimate)"
    )]
    PointWithoutObservations {
        /// Index of the point.
        point: usize,
        /// How many of its observations were excluded; 0 when it had none.
        excluded: usize,
    },
    /// A point of a rig bundle adjustment has a single observation that can be evaluated at
    /// the initial estimate: two are needed to determine it.
    #[error(
        "point {point} has a single usable observation ({excluded} excluded): two are needed to determine it"
    )]
    PointSeenOnce {
        /// Index of the point.
        point: usize,
        /// How many of its observations were excluded (they cannot be evaluated at the
        /// initial estimate).
        excluded: usize,
    },
    /// A parameter block id does not belong to this problem.
    #[error("parameter block {block} does not exist: the problem has {count} parameter blocks")]
    UnknownParameterBlock {
        /// The id that was passed.
        block: usize,
        /// Number of parameter blocks in the problem.
        count: usize,
    },
    /// [`crate::Problem::set_constant_subset`] was given an index outside the block.
    #[error(
        "parameter block {block} has {tangent} tangent coordinates: index {index} cannot be held"
    )]
    SubsetIndexOutOfRange {
        /// Id of the parameter block.
        block: usize,
        /// The offending index.
        index: usize,
        /// The block's tangent size (its size for a vector block).
        tangent: usize,
    },
    /// A residual block id does not belong to this problem, or its block was removed.
    #[error(
        "residual block {residual} does not exist or was removed: the problem has {count} residual blocks"
    )]
    UnknownResidualBlock {
        /// The id that was passed.
        residual: usize,
        /// Number of residual blocks in the problem (not counting removed ones).
        count: usize,
    },
    /// A parameter block was created with no values.
    #[error("a parameter block must hold at least one value")]
    EmptyParameterBlock,
    /// A manifold's sizes do not fit the values it was attached to.
    #[error("the manifold needs {expected} ambient values, the block holds {got}")]
    ManifoldSizeMismatch {
        /// Ambient size of the manifold.
        expected: usize,
        /// Size of the values.
        got: usize,
    },
    /// A residual block was given a different number of parameter blocks than its cost
    /// function declares.
    #[error("the cost function takes {expected} parameter blocks, {got} were given")]
    ParameterCountMismatch {
        /// Number declared by the cost function.
        expected: usize,
        /// Number passed.
        got: usize,
    },
    /// A parameter block's size differs from the size its cost function declares.
    #[error(
        "parameter block {block} (argument {position}) holds {got} values, the cost function expects {expected}"
    )]
    ParameterSizeMismatch {
        /// Id of the parameter block.
        block: usize,
        /// Position of the block in the residual's argument list.
        position: usize,
        /// Size the cost function declares.
        expected: usize,
        /// Size of the block.
        got: usize,
    },
    /// The same parameter block appears twice in one residual block.
    #[error("parameter block {block} appears more than once in one residual block")]
    DuplicateParameterBlock {
        /// Id of the repeated block.
        block: usize,
    },
    /// A cost function declares zero residuals or zero parameter blocks.
    #[error("a cost function must have at least one residual and one parameter block")]
    DegenerateCostFunction,
    /// The problem has no residual blocks.
    #[error("the problem is empty: it has no residual blocks")]
    EmptyProblem,
    /// A cost function could not be evaluated at the initial parameters.
    #[error("residual block {residual} cannot be evaluated at the initial parameters")]
    InitialEvaluationFailed {
        /// Index of the residual block.
        residual: usize,
    },
    /// A cost function returned a NaN or infinite residual or Jacobian at the initial
    /// parameters.
    #[error("residual block {residual} is not finite at the initial parameters")]
    NonFiniteResidual {
        /// Index of the residual block.
        residual: usize,
    },
    /// A cost function wrote a Jacobian of the wrong shape.
    #[error(
        "residual block {residual}: the Jacobian written for argument {position} has the wrong shape"
    )]
    JacobianShapeMismatch {
        /// Index of the residual block.
        residual: usize,
        /// Position of the parameter block in the residual's argument list.
        position: usize,
    },
    /// The scale of a robust loss ([`crate::RobustLoss`]) is not a finite positive number.
    #[error("the scale of the robust loss must be finite and positive, got {scale}")]
    InvalidLossScale {
        /// The scale given.
        scale: f64,
    },
    /// A solver or problem option is out of its valid domain.
    #[error("invalid option `{name}`: {reason}")]
    InvalidOption {
        /// Name of the option (the field name).
        name: &'static str,
        /// What is wrong with it, with the value.
        reason: String,
    },
    /// The eliminated group is not an independent set: two eliminated blocks share a residual
    /// block.
    #[error(
        "parameter blocks {first} and {second} are both eliminated but appear in the same residual block"
    )]
    EliminatedBlocksCoupled {
        /// First eliminated block.
        first: usize,
        /// Second eliminated block.
        second: usize,
    },
    /// The information of an eliminated block (a point seen from one image, say) is
    /// singular, so the covariance is undefined. (A reduced information singular up to
    /// rounding is a [`BundleAdjustError::CovarianceRankDeficient`].)
    #[error(
        "the covariance is undefined: the information matrix is singular (unfixed gauge or unobservable parameters)"
    )]
    SingularInformation,
    /// The information matrix is singular up to rounding, so its inverse would be
    /// meaningless: its reciprocal condition number (smallest over largest eigenvalue of the
    /// reduced information equilibrated to a unit diagonal) is below the threshold
    /// [`crate::SolverOptions::min_reciprocal_condition_number`]. Typically a gauge freedom
    /// left open (the scale of a bundle adjustment with one fixed image) or an unobservable
    /// parameter; see [`crate::Problem::covariance`].
    #[error(
        "the covariance is undefined: the information matrix is singular up to rounding (reciprocal condition number {reciprocal_condition_number:.3e} < {min_reciprocal_condition_number:.1e}; parameter block {block} has the largest share of the undetermined direction: an unfixed gauge or an unobservable parameter)"
    )]
    CovarianceRankDeficient {
        /// The estimated reciprocal condition number λmin/λmax: at rounding level (about
        /// 1e-16, possibly slightly negative) for a matrix singular in exact arithmetic; 0 when
        /// the matrix has a coordinate without any information.
        reciprocal_condition_number: f64,
        /// The threshold it fell below.
        min_reciprocal_condition_number: f64,
        /// The parameter block with the largest component of the eigenvector of the smallest
        /// eigenvalue.
        block: usize,
    },
    /// Covariance was requested for a constant or eliminated parameter block.
    #[error(
        "covariance is only available for free, non-eliminated parameter blocks; block {block} is not"
    )]
    CovarianceUnavailable {
        /// Id of the block.
        block: usize,
    },
    /// The sparse symbolic factorization of the reduced system failed (its indices overflow
    /// or memory ran out).
    #[error("the sparse factorization of the {unknowns}-unknown reduced system failed: {source}")]
    SparseFactorization {
        /// Number of unknowns of the reduced system.
        unknowns: usize,
        /// faer's error.
        #[source]
        source: faer::sparse::FaerError,
    },
    /// The problem is too large: an offset or index of its compiled form does not fit the
    /// solver's 32-bit indices.
    #[error("the problem is too large: index {index} exceeds the supported 2^32")]
    TooLarge {
        /// The index that does not fit.
        index: usize,
    },
    /// A worker thread pool could not be created.
    #[error("could not create a pool of {threads} threads: {reason}")]
    ThreadPool {
        /// The number of threads asked for ([`crate::SolverOptions::num_threads`]).
        threads: usize,
        /// rayon's message (its error type is not part of this crate's API, since `rayon` is
        /// an optional dependency).
        reason: String,
    },
    /// The text of a BAL file is malformed.
    #[error("BAL file, line {line}: {source}")]
    BalParse {
        /// One-based line number; for a file that ends too early
        /// ([`BalSyntaxError::UnexpectedEnd`]), its last line (1 for an empty file).
        line: usize,
        /// What is wrong there.
        #[source]
        source: BalSyntaxError,
    },
    /// The refined intrinsics of a camera were refused by its model (they left the model's
    /// valid domain).
    #[error("the refined intrinsics of camera {camera} were refused: {source}")]
    RefinedIntrinsicsRejected {
        /// Index of the camera.
        camera: usize,
        /// The model's reason.
        #[source]
        source: ibc_camera_models::ParameterError,
    },
    /// An internal invariant does not hold: a bug of this crate, to be reported.
    #[error("internal error of ibc-bundle-adjust (please report): {reason}")]
    Internal {
        /// What went wrong.
        reason: &'static str,
    },
}

/// What is wrong at a line of a BAL file ([`BundleAdjustError::BalParse`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum BalSyntaxError {
    /// The file ends before a value it must hold.
    #[error("the file ends before {expected}")]
    UnexpectedEnd {
        /// The value that is missing, for instance `a camera parameter`.
        expected: &'static str,
    },
    /// A token is not a number of the expected kind.
    #[error("cannot read {expected} from `{token}`")]
    Malformed {
        /// The value expected there.
        expected: &'static str,
        /// The token found.
        token: String,
    },
    /// A number is NaN or infinite.
    #[error("{expected} is not finite")]
    NonFinite {
        /// The value expected there.
        expected: &'static str,
    },
    /// An observation names a camera or point beyond the counts in the header.
    #[error(
        "observation of camera {camera} and point {point} is out of range ({cameras} cameras, {points} points)"
    )]
    ObservationOutOfRange {
        /// The camera index read.
        camera: usize,
        /// The point index read.
        point: usize,
        /// Number of cameras in the header.
        cameras: usize,
        /// Number of points in the header.
        points: usize,
    },
    /// Data follows the last point.
    #[error("unexpected data `{token}` after the last point")]
    TrailingData {
        /// The first extra token.
        token: String,
    },
}

/// Why [`crate::BalProblem::from_file`] failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BalFileError {
    /// The file could not be read (missing, not a regular file, too large, not text, or the
    /// operating system's error); names the file.
    #[error(transparent)]
    Io(#[from] ibc_camera_models::io::IoError),
    /// The file was read but its text is not a valid BAL problem.
    #[error("{}: {source}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why it was rejected ([`BundleAdjustError::BalParse`]).
        #[source]
        source: BundleAdjustError,
    },
}
