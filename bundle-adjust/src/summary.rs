//! What a solve reports: a per-iteration log in Ceres's format and a summary.

use crate::options::LinearSolverType;
use core::fmt;

/// Why the solver stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Termination {
    /// |Δcost| ≤ function_tolerance · cost.
    FunctionTolerance,
    /// Gradient max-norm ≤ gradient_tolerance.
    GradientTolerance,
    /// |Δx| ≤ parameter_tolerance · (|x| + parameter_tolerance).
    ParameterTolerance,
    /// The iteration budget ran out (Ceres: `NO_CONVERGENCE`).
    MaxIterations,
    /// The trust region shrank below its minimum radius.
    TrustRegionTooSmall,
    /// Too many consecutive steps could not be computed (a singular or indefinite system).
    TooManyInvalidSteps,
    /// The residuals or Jacobians became non-finite at an accepted point.
    EvaluationFailed,
    /// Nothing to optimize: every parameter block is constant.
    NoFreeParameters,
    /// The time budget [`crate::SolverOptions::max_solver_time_in_seconds`] ran out (Ceres:
    /// `NO_CONVERGENCE`); the parameters are those of the last accepted step.
    MaxSolverTime,
    /// The iteration callback of [`crate::Problem::solve_with_callback`] returned
    /// [`IterationControl::Stop`]; the parameters are those of the last accepted step.
    UserStop,
}

/// What an iteration callback ([`crate::Problem::solve_with_callback`]) tells the solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IterationControl {
    /// Go on iterating.
    Continue,
    /// Stop now, keeping the last accepted point ([`Termination::UserStop`]).
    Stop,
}

impl Termination {
    /// True for the three convergence criteria.
    #[must_use]
    pub fn is_converged(self) -> bool {
        matches!(
            self,
            Self::FunctionTolerance | Self::GradientTolerance | Self::ParameterTolerance
        )
    }

    /// A short snake-case name (`function_tolerance`, `max_iterations`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::FunctionTolerance => "function_tolerance",
            Self::GradientTolerance => "gradient_tolerance",
            Self::ParameterTolerance => "parameter_tolerance",
            Self::MaxIterations => "max_iterations",
            Self::TrustRegionTooSmall => "trust_region_too_small",
            Self::TooManyInvalidSteps => "too_many_invalid_steps",
            Self::EvaluationFailed => "evaluation_failed",
            Self::NoFreeParameters => "no_free_parameters",
            Self::MaxSolverTime => "max_solver_time",
            Self::UserStop => "user_stop",
        }
    }
}

impl fmt::Display for Termination {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// One line of the iteration log, with Ceres's meanings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterationSummary {
    /// Iteration number; 0 is the initial evaluation.
    pub iteration: usize,
    /// Cost ½ Σ ρ(|rᵢ|²) at the accepted point, or at the rejected candidate.
    pub cost: f64,
    /// Decrease of the cost from the current point to the candidate (negative if it rose).
    pub cost_change: f64,
    /// Max-norm of the gradient at the current point.
    pub gradient_max_norm: f64,
    /// Euclidean norm of the step in the stored (ambient) parameters.
    pub step_norm: f64,
    /// Gain ratio: actual over model cost decrease.
    pub relative_decrease: f64,
    /// Trust-region radius after the iteration.
    pub trust_region_radius: f64,
    /// Conjugate-gradient iterations (1 for direct solvers, 0 for iteration 0).
    pub linear_solver_iterations: usize,
    /// Whether the step was accepted.
    pub step_is_successful: bool,
    /// Seconds spent in this iteration.
    pub iteration_time: f64,
    /// Seconds since the solve started.
    pub cumulative_time: f64,
}

impl IterationSummary {
    /// The header matching [`IterationSummary::log_line`].
    #[must_use]
    pub fn log_header() -> &'static str {
        "iter      cost      cost_change  |gradient|   |step|    tr_ratio  tr_radius  ls_iter  iter_time  total_time"
    }

    /// One line of the log, formatted like Ceres's `minimizer_progress_to_stdout`.
    #[must_use]
    pub fn log_line(&self) -> String {
        format!(
            "{:4} {:>12.6e} {:>11.2e} {:>11.2e} {:>11.2e} {:>11.2e} {:>9.2e} {:>8} {:>10.2e} {:>11.2e}",
            self.iteration,
            self.cost,
            self.cost_change,
            self.gradient_max_norm,
            self.step_norm,
            self.relative_decrease,
            self.trust_region_radius,
            self.linear_solver_iterations,
            self.iteration_time,
            self.cumulative_time
        )
    }
}

/// Seconds spent per stage of a solve.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub struct StageTimes {
    /// Building the program, orderings and the symbolic factorization.
    pub preprocessing: f64,
    /// Residual-only evaluations (candidate points).
    pub residual_evaluation: f64,
    /// Residual and Jacobian evaluations, with the loss correction and column scaling.
    pub jacobian_evaluation: f64,
    /// Forming the reduced system (Schur elimination of the eliminated group).
    pub schur_elimination: f64,
    /// Solving the reduced system (Cholesky factorization and solves, or PCG).
    pub reduced_solve: f64,
    /// Back substitution of the eliminated blocks.
    pub back_substitution: f64,
    /// Everything else in the iterations (gradient, model cost, updates, bookkeeping).
    pub other: f64,
    /// Wall time of the whole solve.
    pub total: f64,
}

impl StageTimes {
    /// Total time of the linear solver: elimination, reduced solve and back substitution.
    #[must_use]
    pub fn linear_solver(&self) -> f64 {
        self.schur_elimination + self.reduced_solve + self.back_substitution
    }
}

/// The outcome of a solve.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Summary {
    /// Cost ½ Σ ρ(|rᵢ|²) at the start.
    pub initial_cost: f64,
    /// Cost at the returned parameters (the last accepted point).
    pub final_cost: f64,
    /// Iterations as Ceres counts them: the number of the last logged iteration (a step that
    /// ends the solve by a tolerance is computed but not logged, as in Ceres).
    pub iterations: usize,
    /// Steps computed, including one that ended the solve by a tolerance.
    pub linear_solves: usize,
    /// Accepted steps (iteration 0 not counted).
    pub accepted_iterations: usize,
    /// Why the solver stopped.
    pub termination: Termination,
    /// The reduced-system solver used.
    pub linear_solver: LinearSolverType,
    /// The thread count the work was split for ([`crate::SolverOptions::num_threads`]);
    /// without the crate's `rayon` feature all of it ran on the calling thread.
    pub num_threads: usize,
    /// Number of unknowns eliminated by the Schur complement.
    pub num_eliminated: usize,
    /// Number of unknowns of the reduced system.
    pub num_reduced: usize,
    /// Residual blocks in the problem.
    pub num_residual_blocks: usize,
    /// Seconds per stage.
    pub times: StageTimes,
    /// The iteration log (iteration 0 first).
    pub log: Vec<IterationSummary>,
}

impl Summary {
    /// A multi-line report in the spirit of Ceres's `FullReport`.
    #[must_use]
    pub fn report(&self) -> String {
        let t = &self.times;
        let seconds = |v: f64| format!("{v:.4} s");
        let rows: [(&str, String); 18] = [
            ("Residual blocks", self.num_residual_blocks.to_string()),
            ("Eliminated unknowns", self.num_eliminated.to_string()),
            ("Reduced unknowns", self.num_reduced.to_string()),
            ("Linear solver", self.linear_solver.name().to_string()),
            ("Threads", self.num_threads.to_string()),
            ("Initial cost", format!("{:.6e}", self.initial_cost)),
            ("Final cost", format!("{:.6e}", self.final_cost)),
            ("Iterations", self.iterations.to_string()),
            ("Accepted steps", self.accepted_iterations.to_string()),
            ("Linear solves", self.linear_solves.to_string()),
            ("Preprocessing", seconds(t.preprocessing)),
            ("Residual evaluation", seconds(t.residual_evaluation)),
            ("Jacobian evaluation", seconds(t.jacobian_evaluation)),
            ("Schur elimination", seconds(t.schur_elimination)),
            ("Reduced solve", seconds(t.reduced_solve)),
            ("Back substitution", seconds(t.back_substitution)),
            ("Other", seconds(t.other)),
            ("Total", seconds(t.total)),
        ];
        let mut s: String = rows
            .iter()
            .map(|(label, value)| format!("{label:<25}{value}\n"))
            .collect();
        s.push_str(&format!("{:<25}{}\n", "Termination", self.termination));
        s
    }
}
