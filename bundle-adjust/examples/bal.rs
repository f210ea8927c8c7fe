//! Solves a Bundle Adjustment in the Large problem and reports Ceres-style figures.
//!
//! ```text
//! cargo run --release -p ibc-bundle-adjust --example bal -- FILE [--loss none|huber|cauchy]
//!     [--loss-scale A] [--solver dense|sparse|iterative] [--iterations N] [--threads N]
//!     [--normalize] [--log] [--json]
//! ```
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, ValueEnum};
use ibc_bundle_adjust::{BalProblem, LinearSolverType, RobustLoss, SolverOptions};

#[derive(Debug, Clone, Copy, ValueEnum)]
enum LossArg {
    None,
    Huber,
    Cauchy,
    SoftL1,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum SolverArg {
    Auto,
    Dense,
    Sparse,
    Iterative,
}

/// Bundle-adjusts a BAL file with ibc-bundle-adjust.
#[derive(Debug, Parser)]
struct Args {
    /// The BAL problem file.
    file: std::path::PathBuf,
    /// Robust loss.
    #[arg(long, value_enum, default_value = "none")]
    loss: LossArg,
    /// Scale a of the robust loss.
    #[arg(long, default_value_t = 1.0)]
    loss_scale: f64,
    /// Reduced-system solver.
    #[arg(long, value_enum, default_value = "auto")]
    solver: SolverArg,
    /// Maximum iterations.
    #[arg(long, default_value_t = 50)]
    iterations: usize,
    /// Worker threads.
    #[arg(long, default_value_t = 1)]
    threads: usize,
    /// Use Ceres's tolerances but never stop before the iteration budget.
    #[arg(long)]
    no_tolerances: bool,
    /// Normalize the reconstruction as Ceres's bundle_adjuster does.
    #[arg(long)]
    normalize: bool,
    /// Print the per-iteration log to stderr.
    #[arg(long)]
    log: bool,
    /// Print one JSON object instead of a report.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let loss = match args.loss {
        LossArg::None => RobustLoss::Trivial,
        LossArg::Huber => RobustLoss::Huber {
            scale: args.loss_scale,
        },
        LossArg::Cauchy => RobustLoss::Cauchy {
            scale: args.loss_scale,
        },
        LossArg::SoftL1 => RobustLoss::SoftL1 {
            scale: args.loss_scale,
        },
    };
    let read_start = Instant::now();
    let mut bal = match BalProblem::from_file(&args.file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let read_seconds = read_start.elapsed().as_secs_f64();
    if args.normalize {
        bal.normalize();
    }
    let defaults = SolverOptions::default();
    // A zero tolerance never stops the solve.
    let tolerance = |default: f64| if args.no_tolerances { 0.0 } else { default };
    let options = SolverOptions {
        max_iterations: args.iterations,
        num_threads: args.threads,
        log_to_stderr: args.log,
        linear_solver: match args.solver {
            SolverArg::Auto => LinearSolverType::Auto,
            SolverArg::Dense => LinearSolverType::DenseSchur,
            SolverArg::Sparse => LinearSolverType::SparseSchur,
            SolverArg::Iterative => LinearSolverType::IterativeSchur,
        },
        function_tolerance: tolerance(defaults.function_tolerance),
        gradient_tolerance: tolerance(defaults.gradient_tolerance),
        parameter_tolerance: tolerance(defaults.parameter_tolerance),
        ..defaults
    };
    let start = Instant::now();
    let summary = match bal.solve(loss, &options) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let t = &summary.times;
    if args.json {
        let json = serde_json::json!({
            "file": args.file.display().to_string(),
            "cameras": bal.cameras.len(),
            "points": bal.points.len(),
            "observations": bal.observations.len(),
            "loss": format!("{loss:?}"),
            "initial_cost": summary.initial_cost,
            "final_cost": summary.final_cost,
            "iterations": summary.iterations,
            "linear_solves": summary.linear_solves,
            "accepted_iterations": summary.accepted_iterations,
            "termination": summary.termination.name(),
            "seconds_total": seconds,
            "seconds_read": read_seconds,
            "seconds_preprocessing": t.preprocessing,
            "seconds_residual_evaluation": t.residual_evaluation,
            "seconds_jacobian_evaluation": t.jacobian_evaluation,
            "seconds_schur_elimination": t.schur_elimination,
            "seconds_reduced_solve": t.reduced_solve,
            "seconds_back_substitution": t.back_substitution,
            "seconds_linear_solver": t.linear_solver(),
            "seconds_other": t.other,
            "solver": summary.linear_solver.name(),
            "threads": summary.num_threads,
        });
        println!("{json}");
    } else {
        print!("{}", summary.report());
        println!("Wall time (solve)        {seconds:.4} s");
    }
    ExitCode::SUCCESS
}
