//! Solver options, with Ceres Solver 2.1's defaults.

use crate::NonExhaustive;
use crate::error::{BundleAdjustError, Result};

/// How a robust loss's curvature enters the Gauss-Newton model of a residual block
/// (`crate::corrector`). With s = |r|² and D = 1 + 2 s ρ″(s) / ρ′(s), the curvature of
/// ½ ρ(|r|²) along the residual is ρ′ D and across it ρ′.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum LossCurvature {
    /// Ceres's corrector: wherever ρ″ ≤ 0 (every robust loss: Huber, Cauchy, soft L1) the
    /// model's Hessian is ρ′ JᵀJ, which overstates the curvature along the residual by 1/D,
    /// so steps fall short of the minimum (the default, Ceres's).
    #[default]
    Reweighted,
    /// The full second-order correction of Triggs et al. (2000, section 6.8, equations
    /// 10-11) wherever it keeps the model convex along the residual (D ≥ 1/4: for
    /// `Cauchy { scale: c }` the residuals with |r|² ≤ 0.6 c²), Ceres's reweighting elsewhere
    /// (the outliers, where the true curvature is negative). On a rig bundle adjustment at
    /// 0.5 px of noise and a Cauchy scale of 1 px it saves about one iteration in six.
    InlierCurvature,
}

/// How the reduced (Schur-complement) system is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum LinearSolverType {
    /// Chosen by size: dense below [`AUTO_DENSE_MAX_DIM`] reduced unknowns, sparse up to
    /// [`AUTO_SPARSE_MAX_DIM`], iterative above.
    #[default]
    Auto,
    /// Dense Cholesky (faer) of the reduced system.
    DenseSchur,
    /// Sparse supernodal Cholesky (faer) of the reduced system; the symbolic factorization is
    /// computed once per solve and reused every iteration.
    SparseSchur,
    /// Preconditioned conjugate gradients on the implicit reduced system with the
    /// Schur-Jacobi (block-diagonal of the Schur complement) preconditioner.
    IterativeSchur,
}

/// Largest reduced system that [`LinearSolverType::Auto`] solves densely. A dense Cholesky of
/// this size costs about 0.1 GFLOP, below the cost of one elimination on problems that big.
pub const AUTO_DENSE_MAX_DIM: usize = 1500;

/// Largest reduced system that [`LinearSolverType::Auto`] factors with sparse Cholesky.
pub const AUTO_SPARSE_MAX_DIM: usize = 60_000;

impl LinearSolverType {
    /// The solver used for a reduced system of `dim` unknowns.
    #[must_use]
    pub fn resolve(self, dim: usize) -> Self {
        match self {
            Self::Auto if dim <= AUTO_DENSE_MAX_DIM => Self::DenseSchur,
            Self::Auto if dim <= AUTO_SPARSE_MAX_DIM => Self::SparseSchur,
            Self::Auto => Self::IterativeSchur,
            other => other,
        }
    }

    /// A short lowercase name: `auto`, `dense`, `sparse` or `iterative`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::DenseSchur => "dense",
            Self::SparseSchur => "sparse",
            Self::IterativeSchur => "iterative",
        }
    }
}

/// Options of the Levenberg-Marquardt solver.
///
/// `Default` gives Ceres Solver 2.1's defaults (`Solver::Options`), so iteration counts and
/// costs can be compared with Ceres one for one. Write the options as one expression:
///
/// ```
/// use ibc_bundle_adjust::{LinearSolverType, SolverOptions};
///
/// let options = SolverOptions {
///     max_iterations: 20,
///     linear_solver: LinearSolverType::SparseSchur,
///     ..Default::default()
/// };
/// assert_eq!(options.function_tolerance, 1e-6);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct SolverOptions {
    /// Maximum number of iterations (default 50, Ceres's): the iteration budget. A solve that
    /// reaches it ends with [`crate::Termination::MaxIterations`] after exactly this many
    /// iterations (0 evaluates the start and stops).
    pub max_iterations: usize,
    /// Time budget in seconds (default 1e9, Ceres's `max_solver_time_in_seconds`): after an
    /// iteration that ends past it (counted from the start of the solve, preprocessing
    /// included), the solve stops with [`crate::Termination::MaxSolverTime`], keeping the last
    /// accepted point. An iteration is never interrupted, so a solve may overrun the budget
    /// by one iteration. `f64::INFINITY` means no budget.
    pub max_solver_time_in_seconds: f64,
    /// Stop when |Δcost| ≤ `function_tolerance` · cost (default 1e-6, Ceres's).
    pub function_tolerance: f64,
    /// Stop when the max-norm of the gradient is ≤ this (default 1e-10, Ceres's).
    pub gradient_tolerance: f64,
    /// Stop when |Δx| ≤ `parameter_tolerance` · (|x| + `parameter_tolerance`) (default 1e-8,
    /// Ceres's).
    pub parameter_tolerance: f64,
    /// Initial trust-region radius μ, the inverse of the initial damping (default 1e4,
    /// Ceres's).
    pub initial_trust_region_radius: f64,
    /// Largest trust-region radius (default 1e16, Ceres's).
    pub max_trust_region_radius: f64,
    /// Stop when the radius falls below this (default 1e-32, Ceres's).
    pub min_trust_region_radius: f64,
    /// A step is accepted when its gain ratio exceeds this (default 1e-3, Ceres's).
    pub min_relative_decrease: f64,
    /// Lower clamp of the LM diagonal diag(JᵀJ) (default 1e-6, Ceres's).
    pub min_lm_diagonal: f64,
    /// Upper clamp of the LM diagonal (default 1e32, Ceres's).
    pub max_lm_diagonal: f64,
    /// Give up after this many consecutive steps the linear solver could not compute or that
    /// do not decrease the model (default 5, Ceres's).
    pub max_consecutive_invalid_steps: usize,
    /// Scale the Jacobian's columns by 1/(1 + |column|) computed at the start (default true,
    /// Ceres's).
    pub jacobi_scaling: bool,
    /// Reduced-system solver (default [`LinearSolverType::Auto`]).
    pub linear_solver: LinearSolverType,
    /// Forcing parameter of the truncated-Newton (iterative) solver: conjugate gradients stop
    /// when the relative decrease of the quadratic model in an iteration, times the iteration
    /// number, falls below it (Nash and Sofer's rule; default 0.1, Ceres's `eta`).
    pub eta: f64,
    /// Maximum conjugate-gradient iterations per step (default 500, Ceres's).
    pub max_linear_solver_iterations: usize,
    /// Minimum conjugate-gradient iterations per step (default 0, Ceres's).
    pub min_linear_solver_iterations: usize,
    /// Worker threads for Jacobian evaluation and Schur accumulation; 1 runs everything on the
    /// calling thread (default 1, Ceres's). The work is split by this number, so results are
    /// deterministic for a fixed value; without the crate's `rayon` feature the same split
    /// runs on the calling thread, with the same results.
    pub num_threads: usize,
    /// When no block is marked for elimination, choose the eliminated group automatically
    /// (a maximal independent set of the blocks, fewest residuals first, as Ceres does;
    /// default true).
    pub automatic_elimination: bool,
    /// Smallest reciprocal condition number of the information matrix for which
    /// [`crate::Problem::covariance`] returns a covariance (default 1e-14, the value of Ceres's
    /// `Covariance::Options::min_reciprocal_condition_number`); below it the covariance is a
    /// [`BundleAdjustError::CovarianceRankDeficient`]. Measured on the reduced information
    /// equilibrated to a unit diagonal, so the units of the parameters do not matter. Not
    /// used by the solve itself.
    pub min_reciprocal_condition_number: f64,
    /// How a robust loss's curvature enters the model (default
    /// [`LossCurvature::Reweighted`], Ceres's). The gradient, the cost and so the minimum
    /// are the same either way; only the steps towards it differ.
    pub loss_curvature: LossCurvature,
    /// With the sparse Schur solver, factor the reduced matrix only when the last factor no
    /// longer preconditions well (default false, Ceres's behaviour: a factorization per
    /// step). A later step is then solved by conjugate gradients on the exact reduced system,
    /// preconditioned by the last factorization, to a truncated-Newton tolerance of 1e-3 (the
    /// quadratic model within about 1e-3 of a direct solve's); if that takes more than 20
    /// iterations the step is solved directly and the new factor kept. A step right after
    /// one that halved the cost (its Jacobian too far from the factor's) is solved directly.
    /// Where forming the reduced matrix dominates (points seen by many images, as in a rig
    /// bundle adjustment) this saves most of the elimination of every step after the first;
    /// the minimum is the same, the steps towards it equal to the tolerance.
    pub reuse_factorization: bool,
    /// Print a Ceres-style line per iteration to standard error (default false).
    pub log_to_stderr: bool,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            max_solver_time_in_seconds: 1e9,
            function_tolerance: 1e-6,
            gradient_tolerance: 1e-10,
            parameter_tolerance: 1e-8,
            initial_trust_region_radius: 1e4,
            max_trust_region_radius: 1e16,
            min_trust_region_radius: 1e-32,
            min_relative_decrease: 1e-3,
            min_lm_diagonal: 1e-6,
            max_lm_diagonal: 1e32,
            max_consecutive_invalid_steps: 5,
            jacobi_scaling: true,
            linear_solver: LinearSolverType::Auto,
            eta: 0.1,
            max_linear_solver_iterations: 500,
            min_linear_solver_iterations: 0,
            num_threads: 1,
            automatic_elimination: true,
            min_reciprocal_condition_number: 1e-14,
            loss_curvature: LossCurvature::Reweighted,
            reuse_factorization: false,
            log_to_stderr: false,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl SolverOptions {
    /// Checks every option against its valid domain.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidOption`] naming the first invalid option.
    pub fn validate(&self) -> Result<()> {
        let positive = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(BundleAdjustError::InvalidOption {
                    name,
                    reason: format!("{v} is not a finite positive number"),
                })
            }
        };
        let non_negative = |name: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(BundleAdjustError::InvalidOption {
                    name,
                    reason: format!("{v} is not a finite non-negative number"),
                })
            }
        };
        if self.max_solver_time_in_seconds.is_nan() || self.max_solver_time_in_seconds <= 0.0 {
            return Err(BundleAdjustError::InvalidOption {
                name: "max_solver_time_in_seconds",
                reason: format!(
                    "{} is not a positive number",
                    self.max_solver_time_in_seconds
                ),
            });
        }
        non_negative("function_tolerance", self.function_tolerance)?;
        non_negative("gradient_tolerance", self.gradient_tolerance)?;
        non_negative("parameter_tolerance", self.parameter_tolerance)?;
        positive(
            "initial_trust_region_radius",
            self.initial_trust_region_radius,
        )?;
        positive("max_trust_region_radius", self.max_trust_region_radius)?;
        non_negative("min_trust_region_radius", self.min_trust_region_radius)?;
        non_negative("min_relative_decrease", self.min_relative_decrease)?;
        positive("min_lm_diagonal", self.min_lm_diagonal)?;
        positive("max_lm_diagonal", self.max_lm_diagonal)?;
        positive("eta", self.eta)?;
        if !(0.0..1.0).contains(&self.min_reciprocal_condition_number) {
            return Err(BundleAdjustError::InvalidOption {
                name: "min_reciprocal_condition_number",
                reason: format!("{} is not in [0, 1)", self.min_reciprocal_condition_number),
            });
        }
        if self.min_lm_diagonal > self.max_lm_diagonal {
            return Err(BundleAdjustError::InvalidOption {
                name: "min_lm_diagonal",
                reason: "exceeds max_lm_diagonal".into(),
            });
        }
        if self.initial_trust_region_radius > self.max_trust_region_radius {
            return Err(BundleAdjustError::InvalidOption {
                name: "initial_trust_region_radius",
                reason: "exceeds max_trust_region_radius".into(),
            });
        }
        if self.num_threads == 0 {
            return Err(BundleAdjustError::InvalidOption {
                name: "num_threads",
                reason: "must be at least 1".into(),
            });
        }
        if self.max_consecutive_invalid_steps == 0 {
            return Err(BundleAdjustError::InvalidOption {
                name: "max_consecutive_invalid_steps",
                reason: "must be at least 1".into(),
            });
        }
        if self.max_linear_solver_iterations == 0
            || self.min_linear_solver_iterations > self.max_linear_solver_iterations
        {
            return Err(BundleAdjustError::InvalidOption {
                name: "max_linear_solver_iterations",
                reason: "must be at least 1 and at least min_linear_solver_iterations".into(),
            });
        }
        Ok(())
    }
}
