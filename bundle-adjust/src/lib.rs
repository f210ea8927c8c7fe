#![doc = include_str!("../README.md")]

pub mod bal;
mod block_jacobian;
mod cost;
mod covariance;
mod dense_solver;
mod error;
mod evaluator;
pub mod full_ba;
mod kernels;
pub mod levenberg_marquardt;
mod linear_solver;
mod loss;
pub mod manifold;
mod options;
mod parallel;
mod pcg;
mod problem;
mod program;
mod reduced;
pub mod rig;
mod schur;
mod simd;
mod sparse_solver;
mod summary;

pub use bal::{BalBlocks, BalObservation, BalProblem, BalReprojection};
pub use cost::{CostFunction, Jacobians};
pub use covariance::Covariance;
pub use error::{BundleAdjustError, Result};
pub use full_ba::{
    BaObservation, BundleAdjustment, BundleAdjustmentOptions, BundleAdjustmentResult,
};
pub use loss::Loss;
pub use manifold::{Manifold, Se3Manifold, UnitQuaternionManifold};
pub use options::{AUTO_DENSE_MAX_DIM, AUTO_SPARSE_MAX_DIM, LinearSolverType, SolverOptions};
pub use problem::{ParameterBlockId, Problem, ResidualBlockId};
pub use rig::{RigObservation, RigRefinement, RigRefinementOptions, RigRefinementResult};
pub use summary::{IterationSummary, StageTimes, Summary, Termination};
