//! Levenberg-Marquardt as a trust-region method, with Ceres Solver 2.1's rules
//! (`TrustRegionMinimizer` and `LevenbergMarquardtStrategy`; Madsen, Nielsen, Tingleff,
//! "Methods for Non-Linear Least Squares Problems", 2004, for the radius update).
//!
//! Each iteration solves (JᵀJ + D/μ) δ = −Jᵀr on the Jacobi-scaled Jacobian, with
//! D = diag(JᵀJ) clamped to [`SolverOptions::min_lm_diagonal`, `max_lm_diagonal`] and μ the
//! trust-region radius. The gain ratio ρ = (cost − cost(x ⊞ δ)) / (model decrease) uses the
//! true robust cost ½ Σ ρ(|r|²). A step is accepted when ρ exceeds
//! [`SolverOptions::min_relative_decrease`]; then μ ← μ / max(1/3, 1 − (2ρ − 1)³) and ν = 2,
//! otherwise μ ← μ / ν, ν ← 2ν, and the Jacobian (and D) are reused. A step the linear
//! solver cannot compute (a singular system) is treated as a rejected one, so it raises the
//! damping. The model decrease −(gᵀδ + ½ δᵀJᵀJδ) is found from the linear solver's value of
//! the damped model, gᵀδ + ½ δᵀ(JᵀJ + D/μ)δ, computed on its reduced system, less
//! ½ δᵀ(D/μ)δ: no pass over the Jacobian.

use std::time::Instant;

use crate::block_jacobian::scale_columns;
use crate::error::{BundleAdjustError, Result};
use crate::evaluator::{Accumulated, EvalError, Evaluator};
use crate::linear_solver::LinearSolver;
use crate::options::SolverOptions;
use crate::parallel::Executor;
use crate::problem::Problem;
use crate::program::Program;
use crate::summary::{IterationControl, IterationSummary, StageTimes, Summary, Termination};

fn initial_error(e: EvalError) -> BundleAdjustError {
    match e {
        EvalError::Failed(residual) => BundleAdjustError::InitialEvaluationFailed { residual },
        EvalError::NonFinite(residual) => BundleAdjustError::NonFiniteResidual { residual },
        EvalError::Shape(residual, position) => {
            BundleAdjustError::JacobianShapeMismatch { residual, position }
        }
    }
}

/// A step's Jacobian is evaluated with its cost only when the model predicts a decrease
/// above this many times the function tolerance (a step that would end the solve needs only
/// its cost).
const SPECULATION_MARGIN: f64 = 10.0;

/// Scales the columns of a Jacobian evaluated without them, its gradient and its squared
/// column norms by `scale`.
fn apply_scale(
    program: &Program,
    scale: &[f64],
    jac: &mut [f64],
    g: &mut [f64],
    column_norms: &mut [f64],
) {
    for ((s, c), gi) in scale.iter().zip(column_norms.iter_mut()).zip(g.iter_mut()) {
        *c *= *s * *s;
        *gi *= *s;
    }
    scale_columns(program, jac, scale);
}

/// Max-norm and Euclidean norm of the unscaled gradient from the scaled one.
fn gradient_norms(g_scaled: &[f64], scale: &[f64]) -> (f64, f64) {
    let mut max = 0.0f64;
    let mut sum = 0.0;
    for (g, s) in g_scaled.iter().zip(scale) {
        // A held coordinate (scale 0) has no gradient.
        if *s == 0.0 {
            continue;
        }
        let v = g / s;
        max = max.max(v.abs());
        sum += v * v;
    }
    (max, sum.sqrt())
}

/// |x| over the free blocks.
fn free_norm(problem: &Problem, program: &Program, x: &[f64]) -> f64 {
    program
        .active_blocks
        .iter()
        .flat_map(|&b| problem.slice(x, b))
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
}

/// candidate = x ⊞ step on the free blocks.
fn plus(problem: &Problem, program: &Program, x: &[f64], step: &[f64], candidate: &mut [f64]) {
    for &b in &program.active_blocks {
        let block = &problem.blocks[b];
        let col = program.block_col[b] as usize;
        let d = &step[col..col + block.tangent];
        let xs = &x[block.offset..block.offset + block.size];
        let out = &mut candidate[block.offset..block.offset + block.size];
        match &block.manifold {
            Some(m) => m.plus(xs, d, out),
            None => {
                for ((o, xv), dv) in out.iter_mut().zip(xs).zip(d) {
                    *o = xv + dv;
                }
                // Held entries stay bit-identical (their step is zero, but 0 + −0 is 0).
                for &h in &block.held {
                    out[h] = xs[h];
                }
            }
        }
    }
}

/// Minimizes the problem's cost; see the module documentation.
pub(crate) fn solve(
    problem: &mut Problem,
    options: &SolverOptions,
    callback: &mut dyn FnMut(&IterationSummary) -> IterationControl,
) -> Result<Summary> {
    solve_with(problem, options, callback, true)
}

/// [`solve`], evaluating a candidate's Jacobian with its cost after accepted steps
/// (`speculate`) or, as Ceres does, only once it is accepted: the same iterates either way.
fn solve_with(
    problem: &mut Problem,
    options: &SolverOptions,
    callback: &mut dyn FnMut(&IterationSummary) -> IterationControl,
    speculate: bool,
) -> Result<Summary> {
    let start = Instant::now();
    options.validate()?;
    problem.check_values()?;
    let program = Program::new(problem, options.automatic_elimination)?;
    let exec = Executor::new(options.num_threads)?;
    let mut x = problem.values.clone();
    let problem_ref: &Problem = problem;
    let mut linear = LinearSolver::new(&program, options, exec.threads())?;
    let evaluator = Evaluator::new(problem_ref, &program).with_curvature(options.loss_curvature);
    let mut times = StageTimes {
        preprocessing: start.elapsed().as_secs_f64(),
        ..Default::default()
    };

    let n = program.n_tangent();
    let mut res = vec![0.0; program.n_res_values];
    let mut jac = vec![0.0; program.n_jac_values];
    // Held coordinates have scale 0: their Jacobian columns and steps are zero.
    let mut scale = if program.col_mask.is_empty() {
        vec![1.0; n]
    } else {
        program.col_mask.clone()
    };
    let fixed_cost = evaluator.fixed_cost(&x).map_err(initial_error)?;
    let mut g = vec![0.0; n];
    let mut column_norms = vec![0.0; n];
    let t = Instant::now();
    let acc = Accumulated {
        gradient: &mut g,
        column_norms: &mut column_norms,
    };
    let mut cost = evaluator
        .jacobian(&x, &mut res, &mut jac, None, acc, &exec)
        .map_err(initial_error)?;
    times.jacobian_evaluation += t.elapsed().as_secs_f64();
    if options.jacobi_scaling {
        for (s, c) in scale.iter_mut().zip(&column_norms) {
            *s *= 1.0 / (1.0 + c.sqrt());
        }
        apply_scale(&program, &scale, &mut jac, &mut g, &mut column_norms);
    }
    let (mut gmax, _) = gradient_norms(&g, &scale);

    let mut radius = options.initial_trust_region_radius;
    // A log line with no step yet: the current cost, gradient and radius.
    let fresh = |iteration: usize, cost: f64, gmax: f64, radius: f64| IterationSummary {
        iteration,
        cost: cost + fixed_cost,
        cost_change: 0.0,
        gradient_max_norm: gmax,
        step_norm: 0.0,
        relative_decrease: 0.0,
        trust_region_radius: radius,
        linear_solver_iterations: 0,
        step_is_successful: iteration == 0,
        iteration_time: 0.0,
        cumulative_time: 0.0,
    };
    let mut log = vec![fresh(0, cost, gmax, radius)];
    log[0].iteration_time = start.elapsed().as_secs_f64();
    log[0].cumulative_time = log[0].iteration_time;
    if options.log_to_stderr {
        eprintln!("{}", IterationSummary::log_header());
        eprintln!("{}", log[0].log_line());
    }
    let initial_cost = cost + fixed_cost;
    let mut accepted = 0usize;
    let mut linear_solves = 0usize;

    let stop_at_start = callback(&log[0]) == IterationControl::Stop;
    let termination = if n == 0 {
        Termination::NoFreeParameters
    } else if stop_at_start {
        Termination::UserStop
    } else if options.max_iterations == 0 {
        Termination::MaxIterations
    } else if gmax <= options.gradient_tolerance {
        Termination::GradientTolerance
    } else {
        let mut candidate = x.clone();
        let mut diag_base = vec![0.0; n];
        let mut diag = vec![0.0; n];
        let mut step = vec![0.0; n];
        let mut unscaled = vec![0.0; n];
        let mut x_norm = free_norm(problem_ref, &program, &x);
        let mut decrease_factor = 2.0;
        let mut reuse_diagonal = false;
        let mut invalid_steps = 0usize;
        let mut iteration = 0usize;
        // The last step was accepted (or none was tried): speculate on the next.
        let mut speculate_next = speculate;
        loop {
            let iteration_start = Instant::now();
            let other_start = Instant::now();
            iteration += 1;
            if !reuse_diagonal {
                for (d, c) in diag_base.iter_mut().zip(&column_norms) {
                    *d = c.clamp(options.min_lm_diagonal, options.max_lm_diagonal);
                }
            }
            for (d, b) in diag.iter_mut().zip(&diag_base) {
                *d = b / radius;
            }
            let mut other = other_start.elapsed().as_secs_f64();
            linear_solves += 1;
            let solved = linear.solve(&program, &jac, &g, &diag, &mut step, &exec, &mut times);
            let other_start = Instant::now();
            // The Gauss-Newton model's decrease −(gᵀδ + ½ δᵀJᵀJδ), from the damped model's
            // value: the linear solver's, without a pass over the Jacobian.
            let model_change = solved.map_or(0.0, |s| {
                let damping: f64 = step.iter().zip(&diag).map(|(d, w)| w * d * d).sum();
                0.5 * damping - s.quadratic
            });
            let ls_iterations = solved.map_or(0, |s| s.iterations);
            let mut entry = fresh(iteration, cost, gmax, radius);
            entry.linear_solver_iterations = ls_iterations;
            if solved.is_none() || model_change.is_nan() || model_change <= 0.0 {
                // An invalid step: no progress, shrink the trust region.
                invalid_steps += 1;
                if invalid_steps >= options.max_consecutive_invalid_steps {
                    break Termination::TooManyInvalidSteps;
                }
                radius /= decrease_factor;
                decrease_factor *= 2.0;
                reuse_diagonal = true;
            } else {
                invalid_steps = 0;
                for ((u, s), sc) in unscaled.iter_mut().zip(&step).zip(&scale) {
                    *u = s * sc;
                }
                plus(problem_ref, &program, &x, &unscaled, &mut candidate);
                let step_norm = program
                    .active_blocks
                    .iter()
                    .flat_map(|&b| {
                        problem_ref
                            .slice(&x, b)
                            .iter()
                            .zip(problem_ref.slice(&candidate, b))
                    })
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt();
                entry.step_norm = step_norm;
                if step_norm <= options.parameter_tolerance * (x_norm + options.parameter_tolerance)
                {
                    break Termination::ParameterTolerance;
                }
                // After an accepted step the next is likely accepted too: its Jacobian is
                // then evaluated with its cost, in one pass, unless the model predicts a
                // decrease small enough to end the solve. The buffers then hold the
                // candidate's, and a rejection evaluates x's again.
                let speculate = speculate_next
                    && model_change > SPECULATION_MARGIN * options.function_tolerance * cost.abs();
                other += other_start.elapsed().as_secs_f64();
                let t = Instant::now();
                let mut at_candidate = false;
                let candidate_cost = if speculate {
                    let acc = Accumulated {
                        gradient: &mut g,
                        column_norms: &mut column_norms,
                    };
                    match evaluator.jacobian(
                        &candidate,
                        &mut res,
                        &mut jac,
                        Some(&scale),
                        acc,
                        &exec,
                    ) {
                        Ok(c) => {
                            at_candidate = true;
                            times.jacobian_evaluation += t.elapsed().as_secs_f64();
                            c
                        }
                        Err(_) => {
                            let c = evaluator.cost(&candidate, &exec).unwrap_or(f64::INFINITY);
                            times.residual_evaluation += t.elapsed().as_secs_f64();
                            c
                        }
                    }
                } else {
                    let c = evaluator.cost(&candidate, &exec).unwrap_or(f64::INFINITY);
                    times.residual_evaluation += t.elapsed().as_secs_f64();
                    c
                };
                let other_start = Instant::now();
                let cost_change = cost - candidate_cost;
                entry.cost_change = cost_change;
                if cost_change.abs() <= options.function_tolerance * cost {
                    break Termination::FunctionTolerance;
                }
                let relative_decrease = if candidate_cost.is_finite() {
                    cost_change / model_change
                } else {
                    f64::MIN
                };
                entry.relative_decrease = relative_decrease;
                if relative_decrease > options.min_relative_decrease {
                    // A factor from before the cost fell by half no longer preconditions well
                    // (the full garage: 20 conjugate-gradient iterations after its first step,
                    // a tenfold decrease, 7 after the later ones, a few per cent).
                    linear.allow_reuse(cost_change <= 0.5 * cost);
                    core::mem::swap(&mut x, &mut candidate);
                    other += other_start.elapsed().as_secs_f64();
                    if at_candidate {
                        cost = candidate_cost;
                    } else {
                        let t = Instant::now();
                        let acc = Accumulated {
                            gradient: &mut g,
                            column_norms: &mut column_norms,
                        };
                        let evaluated =
                            evaluator.jacobian(&x, &mut res, &mut jac, Some(&scale), acc, &exec);
                        times.jacobian_evaluation += t.elapsed().as_secs_f64();
                        match evaluated {
                            Ok(c) => cost = c,
                            Err(_) => {
                                core::mem::swap(&mut x, &mut candidate);
                                break Termination::EvaluationFailed;
                            }
                        }
                    }
                    let other_start = Instant::now();
                    speculate_next = speculate;
                    x_norm = free_norm(problem_ref, &program, &x);
                    gmax = gradient_norms(&g, &scale).0;
                    let factor = 1.0 - (2.0 * relative_decrease - 1.0).powi(3);
                    radius = (radius / factor.max(1.0 / 3.0)).min(options.max_trust_region_radius);
                    decrease_factor = 2.0;
                    reuse_diagonal = false;
                    accepted += 1;
                    entry.cost = cost + fixed_cost;
                    entry.gradient_max_norm = gmax;
                    entry.step_is_successful = true;
                    other += other_start.elapsed().as_secs_f64();
                } else {
                    if speculate {
                        // The buffers hold the candidate's Jacobian: x's again, as it was
                        // evaluated (the start's scaled after its evaluation), to the bit.
                        other += other_start.elapsed().as_secs_f64();
                        let t = Instant::now();
                        let at_start = accepted == 0;
                        let acc = Accumulated {
                            gradient: &mut g,
                            column_norms: &mut column_norms,
                        };
                        let fused = (!at_start).then_some(&scale[..]);
                        let evaluated =
                            evaluator.jacobian(&x, &mut res, &mut jac, fused, acc, &exec);
                        if at_start && options.jacobi_scaling {
                            apply_scale(&program, &scale, &mut jac, &mut g, &mut column_norms);
                        }
                        times.jacobian_evaluation += t.elapsed().as_secs_f64();
                        if evaluated.is_err() {
                            break Termination::EvaluationFailed;
                        }
                    }
                    let other_start = Instant::now();
                    speculate_next = false;
                    // The same Jacobian, more damping: the last factor is close.
                    linear.allow_reuse(true);
                    radius /= decrease_factor;
                    decrease_factor *= 2.0;
                    reuse_diagonal = true;
                    entry.cost = candidate_cost + fixed_cost;
                    other += other_start.elapsed().as_secs_f64();
                }
            }
            times.other += other;
            entry.trust_region_radius = radius;
            entry.iteration_time = iteration_start.elapsed().as_secs_f64();
            entry.cumulative_time = start.elapsed().as_secs_f64();
            if options.log_to_stderr {
                eprintln!("{}", entry.log_line());
            }
            let successful = entry.step_is_successful;
            let control = callback(&entry);
            log.push(entry);
            if control == IterationControl::Stop {
                break Termination::UserStop;
            }
            if iteration >= options.max_iterations {
                break Termination::MaxIterations;
            }
            if entry.cumulative_time >= options.max_solver_time_in_seconds {
                break Termination::MaxSolverTime;
            }
            if successful && gmax <= options.gradient_tolerance {
                break Termination::GradientTolerance;
            }
            if radius < options.min_trust_region_radius {
                break Termination::TrustRegionTooSmall;
            }
        }
    };
    drop(evaluator);
    let kind = linear.kind();
    problem.values = x;
    times.total = start.elapsed().as_secs_f64();
    Ok(Summary {
        initial_cost,
        final_cost: cost + fixed_cost,
        iterations: log.last().map_or(0, |l| l.iteration),
        linear_solves,
        accepted_iterations: accepted,
        termination,
        linear_solver: kind,
        num_threads: exec.threads(),
        num_eliminated: program.n_e,
        num_reduced: program.n_f,
        num_residual_blocks: problem.live_residuals,
        times,
        log,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RobustLoss;
    use crate::cost::{CostFunction, Jacobians};
    use nalgebra::Matrix2;

    /// Rosenbrock's valley as least squares, r = (10 (y − x²), 1 − x): from (−1.2, 1) the
    /// trust region rejects steps after accepted ones.
    struct Rosenbrock;

    impl CostFunction for Rosenbrock {
        fn num_residuals(&self) -> usize {
            2
        }
        fn parameter_block_sizes(&self) -> &[usize] {
            &[2]
        }
        fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
            let (x, y) = (p[0][0], p[0][1]);
            r[0] = 10.0 * (y - x * x);
            r[1] = 1.0 - x;
            if let Some(j) = j {
                j.set(0, &Matrix2::new(-20.0 * x, 10.0, -1.0, 0.0));
            }
            true
        }
    }

    /// Speculative Jacobians change when the Jacobian is evaluated, not what it is: the
    /// iteration logs agree to the bit, through rejected steps that follow accepted ones
    /// (where the candidate's Jacobian is thrown away and x's evaluated again).
    #[test]
    fn speculative_jacobians_leave_the_iterates_unchanged() {
        let mut logs = Vec::new();
        for speculate in [false, true] {
            let mut problem = Problem::new();
            let b = problem.add_parameter_block(&[-1.2, 1.0]).unwrap();
            problem
                .add_residual_block(Rosenbrock, RobustLoss::Trivial, &[b])
                .unwrap();
            let options = SolverOptions {
                max_iterations: 200,
                function_tolerance: 1e-15,
                // A large start radius: the first steps overshoot.
                initial_trust_region_radius: 1e8,
                ..SolverOptions::default()
            };
            let summary = solve_with(
                &mut problem,
                &options,
                &mut |_| IterationControl::Continue,
                speculate,
            )
            .unwrap();
            assert!(summary.termination.is_converged(), "{}", summary.report());
            let x = problem.parameter_block(b).unwrap();
            assert!(
                (x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6,
                "{x:?}"
            );
            let rejected_after_accepted = summary
                .log
                .windows(2)
                .any(|w| w[0].step_is_successful && !w[1].step_is_successful);
            assert!(rejected_after_accepted, "{}", summary.report());
            logs.push(
                summary
                    .log
                    .iter()
                    .map(|l| {
                        (
                            l.cost,
                            l.step_norm,
                            l.relative_decrease,
                            l.gradient_max_norm,
                        )
                    })
                    .collect::<Vec<_>>(),
            );
        }
        assert_eq!(logs[0], logs[1]);
    }
}
