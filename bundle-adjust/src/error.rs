//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong when building or solving a problem.
///
/// Every variant says what was wrong with the input; caller input never causes a panic.
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
    /// A parameter block id does not belong to this problem.
    #[error("parameter block {block} does not exist: the problem has {count} parameter blocks")]
    UnknownParameterBlock {
        /// The id that was passed.
        block: usize,
        /// Number of parameter blocks in the problem.
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
    /// A loss scale is not a finite positive number.
    #[error("loss scale {0} is invalid: it must be finite and positive")]
    InvalidLossScale(f64),
    /// A solver option is out of its valid domain.
    #[error("invalid solver option `{name}`: {reason}")]
    InvalidOption {
        /// Name of the option.
        name: &'static str,
        /// What is wrong with it.
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
    /// The information matrix is singular, so the covariance is undefined.
    #[error(
        "the covariance is undefined: the information matrix is singular (unfixed gauge or unobservable parameters)"
    )]
    SingularInformation,
    /// Covariance was requested for a constant or eliminated parameter block.
    #[error(
        "covariance is only available for free, non-eliminated parameter blocks; block {block} is not"
    )]
    CovarianceUnavailable {
        /// Id of the block.
        block: usize,
    },
    /// A worker thread pool could not be created.
    #[error("could not create a thread pool: {0}")]
    ThreadPool(String),
    /// A BAL file could not be parsed.
    #[error("BAL file, line {line}: {reason}")]
    BalParse {
        /// One-based line number.
        line: usize,
        /// What was wrong.
        reason: String,
    },
    /// Reading a file failed.
    #[error("cannot read {path}: {reason}")]
    Io {
        /// The path.
        path: String,
        /// The operating system's message.
        reason: String,
    },
    /// A rig or full bundle-adjustment problem description is inconsistent.
    #[error("invalid problem description: {0}")]
    InvalidProblem(String),
}

/// Shorthand for results of this crate.
pub type Result<T> = core::result::Result<T, BundleAdjustError>;
