#![doc = include_str!("../README.md")]

pub mod bal;
mod block_jacobian;
mod corrector;
mod cost;
mod covariance;
mod dense_solver;
mod error;
mod evaluator;
pub mod full_ba;
mod kernels;
pub mod levenberg_marquardt;
mod linear_solver;
pub mod manifold;
pub mod online;
mod options;
mod parallel;
mod pcg;
mod problem;
mod program;
mod reduced;
pub mod rig;
mod rig_ba_cost;
pub mod rig_bundle_adjustment;
mod schur;
mod simd;
mod sparse_solver;
mod summary;

/// The linear-algebra crate of this crate's API (`Isometry3`, `Vector3`, `SMatrix`, ...), so
/// callers can use the very version it was built with.
pub use nalgebra;

/// The robust loss of every residual block: the workspace's one loss type, from `ibc-pnp`
/// (Ceres's definitions; see its docs).
pub use ibc_pnp::RobustLoss;

pub use bal::{BalBlocks, BalObservation, BalProblem, BalReprojection};
pub use cost::{CostFunction, Jacobians};
pub use covariance::Covariance;
pub use error::{BalFileError, BalSyntaxError, BundleAdjustError, Result};
pub use full_ba::{
    BaObservation, BaProblem, BundleAdjustment, BundleAdjustmentOptions, BundleAdjustmentResult,
    Gauge, SCALE_PRIOR_WEIGHT,
};
pub use manifold::{Manifold, Se3Manifold, UnitQuaternionManifold};
pub use online::{
    OnlineCalibrator, OnlineEvent, OnlineFrameSet, OnlineObservation, OnlineOptions, OnlineUpdate,
    SkipReason,
};
pub use options::{
    AUTO_DENSE_MAX_DIM, AUTO_SPARSE_MAX_DIM, LinearSolverType, LossCurvature, SolverOptions,
};
pub use problem::{ParameterBlockId, Problem, ResidualBlockId};
pub use rig::{
    IntrinsicsSelection, RigObservation, RigProblem, RigRefinement, RigRefinementOptions,
    RigRefinementResult,
};
pub use rig_bundle_adjustment::{
    ParameterObservability, RigBaObservation, RigBundleAdjustment, RigBundleAdjustmentOptions,
    RigBundleAdjustmentResult, ScaleGauge,
};
pub use summary::{IterationControl, IterationSummary, StageTimes, Summary, Termination};

/// The last field of every options struct of this crate (`non_exhaustive`), set by the
/// struct's `Default`.
///
/// Code outside the crate cannot make one, so it writes an options struct as
/// `SolverOptions { max_iterations: 20, ..Default::default() }`: fields can then be added
/// without breaking it, as `#[non_exhaustive]` would guarantee, while the one-expression form
/// stays possible (the pattern of faer's parameter structs).
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NonExhaustive(pub(crate) ());
