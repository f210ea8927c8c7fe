//! The generic solver on synthetic problems: the three reduced solvers agree with each other
//! and with solving without elimination, manifolds and constant blocks behave, thread counts
//! give deterministic results, covariances match (JᵀJ)⁻¹, and singular steps raise damping.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::assert_relative_eq;
use common::{perturb, split_problem, synthetic_bal};
use ibc_bundle_adjust::{
    CostFunction, Jacobians, LinearSolverType, ParameterBlockId, Problem, RobustLoss,
    SolverOptions, Termination,
};
use nalgebra::{DMatrix, DVector, SMatrix};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn options(solver: LinearSolverType) -> SolverOptions {
    SolverOptions {
        linear_solver: solver,
        max_iterations: 100,
        ..Default::default()
    }
}

#[test]
fn reduced_solvers_agree_on_a_split_camera_problem() {
    let truth = synthetic_bal(7, 8, 120, 0.5);
    let truth_cost = truth.cost(RobustLoss::Trivial).unwrap();
    let mut bal = truth.clone();
    perturb(&mut bal, 8, 0.01, 0.05, 0.05);
    let mut costs = Vec::new();
    for solver in [
        LinearSolverType::DenseSchur,
        LinearSolverType::SparseSchur,
        LinearSolverType::IterativeSchur,
    ] {
        let (mut problem, blocks) = split_problem(&bal, RobustLoss::Trivial);
        // Gauge: hold the first pose and the second camera's intrinsics.
        problem.set_constant(blocks.poses[0], true).unwrap();
        problem.set_constant(blocks.intrinsics[1], true).unwrap();
        let o = SolverOptions {
            eta: 1e-3,
            ..options(solver)
        };
        let summary = problem.solve(&o).unwrap();
        assert!(
            summary.termination.is_converged(),
            "{solver:?}: {:?}",
            summary.termination
        );
        assert_eq!(summary.linear_solver, solver);
        // The least-squares optimum is at or below the cost of the true scene.
        assert!(summary.final_cost <= truth_cost, "{}", summary.report());
        assert!(summary.initial_cost > 20.0 * truth_cost);
        costs.push(summary.final_cost);
    }
    assert_relative_eq!(costs[0], costs[1], max_relative = 1e-9);
    assert_relative_eq!(costs[0], costs[2], max_relative = 1e-6);
}

#[test]
fn eliminating_points_matches_solving_without_elimination() {
    let mut bal = synthetic_bal(11, 5, 40, 0.3);
    perturb(&mut bal, 12, 0.01, 0.05, 0.05);
    let (mut eliminated, _) = bal.to_problem(RobustLoss::Cauchy { scale: 2.0 }).unwrap();
    let (mut plain, blocks) = bal.to_problem(RobustLoss::Cauchy { scale: 2.0 }).unwrap();
    for &p in &blocks.points {
        plain.set_eliminated(p, false).unwrap();
    }
    let o = SolverOptions {
        automatic_elimination: false,
        max_iterations: 8,
        function_tolerance: 0.0,
        parameter_tolerance: 0.0,
        gradient_tolerance: 0.0,
        ..options(LinearSolverType::DenseSchur)
    };
    let a = eliminated.solve(&o).unwrap();
    let b = plain.solve(&o).unwrap();
    assert_eq!(a.num_eliminated, 3 * bal.points.len());
    assert_eq!(b.num_eliminated, 0);
    // Same steps in exact arithmetic: the iteration logs agree to rounding.
    for (x, y) in a.log.iter().zip(&b.log) {
        assert_relative_eq!(x.cost, y.cost, max_relative = 1e-8);
        assert_eq!(x.step_is_successful, y.step_is_successful);
    }
}

#[test]
fn results_are_deterministic_per_thread_count() {
    let mut bal = synthetic_bal(21, 8, 200, 0.5);
    perturb(&mut bal, 22, 0.01, 0.05, 0.05);
    let run = |threads: usize| {
        let mut b = bal.clone();
        let o = SolverOptions {
            num_threads: threads,
            ..options(LinearSolverType::DenseSchur)
        };
        let s = b.solve(RobustLoss::Huber { scale: 1.0 }, &o).unwrap();
        assert_eq!(s.num_threads, threads);
        (s.final_cost, b.cameras.clone(), b.points.clone())
    };
    let one = run(1);
    let two = run(2);
    let two_again = run(2);
    assert_eq!(two.0.to_bits(), two_again.0.to_bits());
    assert_eq!(two.1, two_again.1);
    assert_eq!(two.2, two_again.2);
    assert_relative_eq!(one.0, two.0, max_relative = 1e-9);
}

/// r = A x − b: a linear model with a known covariance (AᵀA)⁻¹.
struct Linear {
    a: SMatrix<f64, 3, 4>,
    b: [f64; 3],
}

impl CostFunction for Linear {
    fn num_residuals(&self) -> usize {
        3
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[2, 2]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let x = nalgebra::Vector4::new(p[0][0], p[0][1], p[1][0], p[1][1]);
        let y = self.a * x;
        for k in 0..3 {
            r[k] = y[k] - self.b[k];
        }
        if let Some(j) = j {
            j.set(0, &self.a.fixed_columns::<2>(0).into_owned());
            j.set(1, &self.a.fixed_columns::<2>(2).into_owned());
        }
        true
    }
}

#[test]
fn covariance_matches_the_inverse_normal_matrix() {
    let mut problem = Problem::new();
    let e = problem.add_parameter_block(&[0.3, -0.2]).unwrap();
    let f = problem.add_parameter_block(&[1.0, 2.0]).unwrap();
    problem.set_eliminated(e, true).unwrap();
    let mut stacked = DMatrix::zeros(0, 4);
    for k in 0..4 {
        let a = SMatrix::<f64, 3, 4>::from_fn(|i, j| {
            (((i * 5 + j * 3 + k * 7).pow(2)) as f64 * 0.37).sin()
        });
        problem
            .add_residual_block(
                Linear {
                    a,
                    b: [1.0, 0.5, -0.3],
                },
                RobustLoss::Trivial,
                &[e, f],
            )
            .unwrap();
        let rows = stacked.nrows();
        stacked = stacked.insert_rows(rows, 3, 0.0);
        stacked.view_mut((rows, 0), (3, 4)).copy_from(&a);
    }
    let summary = problem.solve(&SolverOptions::default()).unwrap();
    assert!(summary.termination.is_converged());
    let cov = problem.covariance(&[f], &SolverOptions::default()).unwrap();
    let full = (stacked.transpose() * &stacked).try_inverse().unwrap();
    assert_relative_eq!(
        cov.matrix().clone(),
        full.view((2, 2), (2, 2)).into_owned(),
        max_relative = 1e-9
    );
    assert_relative_eq!(
        cov.block(f, f).unwrap(),
        full.view((2, 2), (2, 2)).into_owned(),
        max_relative = 1e-9
    );
    assert!(problem.covariance(&[e], &SolverOptions::default()).is_err());
    // Rank-deficient information (columns spanning two directions only) is reported.
    let mut singular = Problem::new();
    let e = singular.add_parameter_block(&[0.0, 0.0]).unwrap();
    let f = singular.add_parameter_block(&[0.0, 0.0]).unwrap();
    singular.set_eliminated(e, true).unwrap();
    for k in 0..4 {
        let a = SMatrix::<f64, 3, 4>::from_fn(|i, j| ((i * 5 + j * 3 + k * 7) as f64 * 0.7).sin());
        singular
            .add_residual_block(
                Linear {
                    a,
                    b: [1.0, 0.5, -0.3],
                },
                RobustLoss::Trivial,
                &[e, f],
            )
            .unwrap();
    }
    // The reduced information is singular: named, with its reciprocal condition number at
    // rounding level, and the block it lies in.
    match singular.covariance(&[f], &SolverOptions::default()) {
        Err(ibc_bundle_adjust::BundleAdjustError::CovarianceRankDeficient {
            reciprocal_condition_number,
            block,
            ..
        }) => {
            assert!(
                reciprocal_condition_number.abs() < 1e-14,
                "{reciprocal_condition_number}"
            );
            assert_eq!(block, f.index());
        }
        other => panic!("{other:?}"),
    }
}

/// r = A [x; y] − b for a point-sized block x (3) and a pose-sized block y (6).
struct LinearPointPose {
    a: SMatrix<f64, 2, 9>,
}

impl CostFunction for LinearPointPose {
    fn num_residuals(&self) -> usize {
        2
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[3, 6]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let x = SMatrix::<f64, 9, 1>::from_iterator(p[0].iter().chain(p[1]).copied());
        let y = self.a * x;
        r[0] = y[0] - 0.4;
        r[1] = y[1] + 0.2;
        if let Some(j) = j {
            j.set(0, &self.a.fixed_columns::<3>(0).into_owned());
            j.set(1, &self.a.fixed_columns::<6>(3).into_owned());
        }
        true
    }
}

/// Points (3) each seen by every pose (6): the blocks of two poses receive chunk products
/// only, the diagonal blocks residual products too (the two paths of the grouped
/// elimination); the poses' covariance from the eliminated system is the pose block of the
/// full (JᵀJ)⁻¹.
#[test]
fn covariance_of_poses_seen_by_points_matches_the_inverse_normal_matrix() {
    let (points, poses) = (7, 4);
    let mut problem = Problem::new();
    let x: Vec<_> = (0..points)
        .map(|i| {
            let v = [0.1 * i as f64, -0.2, 0.3];
            let id = problem.add_parameter_block(&v).unwrap();
            problem.set_eliminated(id, true).unwrap();
            id
        })
        .collect();
    let y: Vec<_> = (0..poses)
        .map(|k| problem.add_parameter_block(&[0.05 * k as f64; 6]).unwrap())
        .collect();
    let n = 3 * points + 6 * poses;
    let mut stacked = DMatrix::zeros(0, n);
    for (i, &xi) in x.iter().enumerate() {
        for (k, &yk) in y.iter().enumerate() {
            let a = SMatrix::<f64, 2, 9>::from_fn(|r, c| {
                (((r * 7 + c * 3 + i * 11 + k * 5).pow(2)) as f64 * 0.31).sin()
            });
            problem
                .add_residual_block(LinearPointPose { a }, RobustLoss::Trivial, &[xi, yk])
                .unwrap();
            let rows = stacked.nrows();
            stacked = stacked.insert_rows(rows, 2, 0.0);
            let mut row = stacked.view_mut((rows, 0), (2, n));
            row.view_mut((0, 3 * i), (2, 3))
                .copy_from(&a.fixed_columns::<3>(0));
            row.view_mut((0, 3 * points + 6 * k), (2, 6))
                .copy_from(&a.fixed_columns::<6>(3));
        }
    }
    let full = (stacked.transpose() * &stacked).try_inverse().unwrap();
    let want = full.view((3 * points, 3 * points), (6 * poses, 6 * poses));
    let cov = problem.covariance(&y, &SolverOptions::default()).unwrap();
    assert_relative_eq!(cov.matrix().clone(), want.into_owned(), max_relative = 1e-9);
    for (k, &yk) in y.iter().enumerate() {
        for (l, &yl) in y.iter().enumerate() {
            let block = want.view((6 * k, 6 * l), (6, 6)).into_owned();
            assert_relative_eq!(cov.block(yk, yl).unwrap(), block, max_relative = 1e-9);
        }
    }
}

/// r = [x − 1, x − 1] for a block [x, y]: y does not enter, so JᵀJ is singular.
struct IgnoresY;

impl CostFunction for IgnoresY {
    fn num_residuals(&self) -> usize {
        2
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[2]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        r[0] = p[0][0] - 1.0;
        r[1] = p[0][0] - 1.0;
        if let Some(j) = j {
            j.set(0, &SMatrix::<f64, 2, 2>::new(1.0, 0.0, 1.0, 0.0));
        }
        true
    }
}

#[test]
fn a_singular_step_raises_the_damping() {
    let mut problem = Problem::new();
    let x = problem.add_parameter_block(&[5.0, 3.0]).unwrap();
    problem
        .add_residual_block(IgnoresY, RobustLoss::Trivial, &[x])
        .unwrap();
    // The damping of the y column, min_lm_diagonal / μ, underflows to zero at the start: the
    // damped normal matrix is singular until μ has shrunk enough.
    let o = SolverOptions {
        min_lm_diagonal: 1e-310,
        initial_trust_region_radius: 1e16,
        ..Default::default()
    };
    let summary = problem.solve(&o).unwrap();
    let invalid: Vec<_> = summary.log[1..]
        .iter()
        .take_while(|l| !l.step_is_successful)
        .collect();
    assert!(!invalid.is_empty(), "{}", summary.report());
    assert!(
        invalid
            .windows(2)
            .all(|w| w[1].trust_region_radius < w[0].trust_region_radius)
    );
    assert!(invalid[0].trust_region_radius < 1e16);
    assert!(summary.termination.is_converged(), "{}", summary.report());
    assert!(summary.final_cost < 1e-20);
    assert_eq!(problem.parameter_block(x).unwrap()[1], 3.0);
}

#[test]
fn constant_blocks_do_not_move_and_fixed_cost_is_counted() {
    let mut bal = synthetic_bal(31, 4, 30, 0.2);
    perturb(&mut bal, 32, 0.01, 0.05, 0.05);
    let (mut problem, blocks) = bal.to_problem(RobustLoss::Trivial).unwrap();
    let before = problem.parameter_block(blocks.cameras[0]).unwrap().to_vec();
    problem.set_constant(blocks.cameras[0], true).unwrap();
    // A point seen only by the constant camera: its residual still counts as free (the
    // point moves); make every point constant for one camera's fixed-cost residuals.
    let summary = problem.solve(&SolverOptions::default()).unwrap();
    assert_eq!(
        problem.parameter_block(blocks.cameras[0]).unwrap(),
        &before[..]
    );
    assert!(summary.final_cost < summary.initial_cost);
    let mut all_constant = bal.to_problem(RobustLoss::Trivial).unwrap();
    for &b in all_constant.1.cameras.iter().chain(&all_constant.1.points) {
        all_constant.0.set_constant(b, true).unwrap();
    }
    let s = all_constant.0.solve(&SolverOptions::default()).unwrap();
    assert_eq!(s.termination, Termination::NoFreeParameters);
    assert_relative_eq!(
        s.initial_cost,
        bal.cost(RobustLoss::Trivial).unwrap(),
        max_relative = 1e-12
    );
    assert_eq!(s.initial_cost, s.final_cost);
}

#[test]
fn iteration_log_is_consistent() {
    let mut bal = synthetic_bal(41, 5, 50, 0.3);
    perturb(&mut bal, 42, 0.01, 0.05, 0.05);
    let s = bal
        .solve(RobustLoss::Trivial, &SolverOptions::default())
        .unwrap();
    assert_eq!(s.log[0].iteration, 0);
    assert_eq!(s.log.len(), s.iterations + 1);
    assert_eq!(
        s.accepted_iterations,
        s.log
            .iter()
            .skip(1)
            .filter(|l| l.step_is_successful)
            .count()
    );
    assert!(s.linear_solves >= s.iterations);
    let accepted: Vec<f64> = s
        .log
        .iter()
        .filter(|l| l.step_is_successful)
        .map(|l| l.cost)
        .collect();
    assert!(accepted.windows(2).all(|w| w[1] <= w[0]));
    assert_relative_eq!(accepted[accepted.len() - 1], s.final_cost);
    assert!(!s.report().is_empty());
    assert!(s.times.total >= s.times.linear_solver());
    let g = DVector::from_iterator(s.log.len(), s.log.iter().map(|l| l.gradient_max_norm));
    assert!(g[g.len() - 1] < g[0]);
}

/// r = A [x_a; x_b] − c, linear in the two blocks it couples: its Gauss-Newton model is the
/// cost itself.
struct PointPoseLinear {
    a: SMatrix<f64, 2, 9>,
    c: [f64; 2],
    sizes: [usize; 2],
}

impl CostFunction for PointPoseLinear {
    fn num_residuals(&self) -> usize {
        2
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let x: Vec<f64> = p[0].iter().chain(p[1]).copied().collect();
        for (row, out) in r.iter_mut().enumerate() {
            *out = (0..9).map(|k| self.a[(row, k)] * x[k]).sum::<f64>() - self.c[row];
        }
        if let Some(j) = j {
            j.set(0, &self.a.fixed_view::<2, 3>(0, 0).into_owned());
            j.set(1, &self.a.fixed_view::<2, 6>(0, 3).into_owned());
        }
        true
    }
}

/// A linear least-squares problem shaped as a bundle adjustment: 40 "points" of 3 (the
/// eliminated group), each tied to 4 of 6 "poses" of 6 by random 2 × 9 rows.
fn linear_problem() -> (Problem, Vec<ParameterBlockId>) {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut next = move || rng.random_range(-1.0..1.0);
    let mut problem = Problem::new();
    let poses: Vec<_> = (0..6)
        .map(|_| problem.add_parameter_block(&[0.0; 6]).unwrap())
        .collect();
    let mut ids = poses.clone();
    for j in 0..40 {
        let point = problem.add_parameter_block(&[0.0; 3]).unwrap();
        ids.push(point);
        problem.set_eliminated(point, true).unwrap();
        for k in 0..4 {
            let cost = PointPoseLinear {
                a: SMatrix::from_fn(|_, _| next()),
                c: [next(), next()],
                sizes: [3, 6],
            };
            let pose = poses[(j + k) % poses.len()];
            problem
                .add_residual_block(cost, RobustLoss::Trivial, &[point, pose])
                .unwrap();
        }
    }
    (problem, ids)
}

/// The step's model decrease comes from the linear solver's reduced system (½ Q(δf) −
/// ½ |L⁻¹g_e|² plus the damping), not from a pass over the Jacobian: on a linear problem the
/// model is the cost, so every step's gain ratio is 1 to rounding, for every reduced solver
/// and for steps preconditioned by an earlier factor.
#[test]
fn model_decrease_from_the_reduced_system_is_exact_on_a_linear_problem() {
    let mut solutions = Vec::new();
    for (solver, reuse) in [
        (LinearSolverType::DenseSchur, false),
        (LinearSolverType::SparseSchur, false),
        (LinearSolverType::SparseSchur, true),
        (LinearSolverType::IterativeSchur, false),
    ] {
        let (mut problem, ids) = linear_problem();
        let o = SolverOptions {
            eta: 1e-10,
            automatic_elimination: false,
            reuse_factorization: reuse,
            function_tolerance: 1e-14,
            // A small trust region: several damped steps to the minimum.
            initial_trust_region_radius: 1e-2,
            ..options(solver)
        };
        let s = problem.solve(&o).unwrap();
        // Steps whose decrease stands above the cost's rounding.
        let steps: Vec<_> = s
            .log
            .iter()
            .skip(1)
            .filter(|l| l.step_is_successful && l.cost_change > 1e-9 * l.cost)
            .collect();
        assert!(steps.len() >= 3, "{solver:?}: {}", s.report());
        for l in &steps {
            assert!(
                (l.relative_decrease - 1.0).abs() <= 1e-6,
                "{solver:?}, reuse {reuse}: {}",
                s.report()
            );
        }
        solutions.push(
            ids.iter()
                .flat_map(|&b| problem.parameter_block(b).unwrap().to_vec())
                .collect::<Vec<f64>>(),
        );
        if reuse {
            // Direct solves log one iteration; a step preconditioned by the last factor
            // takes at least two (the stopping rule cannot hold at the first).
            assert!(
                steps.iter().any(|l| l.linear_solver_iterations >= 2),
                "{}",
                s.report()
            );
        }
    }
    // One minimum, reached by all four.
    for other in &solutions[1..] {
        for (a, b) in solutions[0].iter().zip(other) {
            assert!((a - b).abs() <= 1e-8 * (1.0 + a.abs()), "{a} vs {b}");
        }
    }
}

/// Reusing the sparse factorization changes the steps, not the minimum: on a perturbed
/// synthetic bundle adjustment with a robust loss the solve with reuse ends at the cost of
/// the one without, and it did reuse (conjugate-gradient steps in its log). The parameters
/// are compared on the linear problem above: this one converges slowly along weakly
/// determined directions (about 40 iterations either way), where two solves stopped by the
/// cost's tolerance differ more than their costs do.
#[test]
fn reusing_the_factorization_reaches_the_same_minimum() {
    let mut bal = synthetic_bal(17, 8, 150, 0.5);
    perturb(&mut bal, 18, 0.01, 0.05, 0.05);
    let mut results = Vec::new();
    for reuse in [false, true] {
        let (mut problem, blocks) = split_problem(&bal, RobustLoss::Cauchy { scale: 1.0 });
        problem.set_constant(blocks.poses[0], true).unwrap();
        problem.set_constant(blocks.intrinsics[1], true).unwrap();
        let o = SolverOptions {
            reuse_factorization: reuse,
            function_tolerance: 1e-12,
            ..options(LinearSolverType::SparseSchur)
        };
        let s = problem.solve(&o).unwrap();
        assert!(s.termination.is_converged(), "{}", s.report());
        let reused = s.log.iter().any(|l| l.linear_solver_iterations >= 2);
        assert_eq!(reused, reuse, "{}", s.report());
        results.push(s.final_cost);
    }
    assert_relative_eq!(results[0], results[1], max_relative = 1e-10);
}

/// Σ of every value of its arguments minus a target: `sizes` gives the arguments.
struct Sum {
    sizes: Vec<usize>,
    target: f64,
}

impl CostFunction for Sum {
    fn num_residuals(&self) -> usize {
        1
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        r[0] = p.iter().flat_map(|b| b.iter()).sum::<f64>() - self.target;
        if let Some(j) = j {
            for k in 0..p.len() {
                if let Some(block) = j.row_major_mut(k) {
                    block.fill(1.0);
                }
            }
        }
        true
    }
}

/// A residual block of more arguments than a residual block holds in place (four): six
/// scalar blocks, each with a prior p_i, tied by one residual Σ x_i − t over all six, reach
/// the closed-form minimum of Σ (x_i − p_i)² + (Σ x_i − t)² (every x_i moved by
/// (t − Σ p) / 7), and removing the tie leaves the priors' values.
#[test]
fn a_residual_of_six_arguments_reaches_the_closed_form_and_can_be_removed() {
    let priors = [0.5, -1.0, 2.0, 0.25, 3.0, -0.75];
    // A linear problem, solved past the default tolerances (the damped steps end within
    // about 2e-9 of the minimum); a wrong argument would be off by order one.
    let exact = SolverOptions {
        function_tolerance: 1e-15,
        gradient_tolerance: 1e-15,
        parameter_tolerance: 1e-15,
        ..options(LinearSolverType::DenseSchur)
    };
    let prior = |i: usize| Sum {
        sizes: vec![1],
        target: priors[i],
    };
    let mut split = Problem::new();
    let xs: Vec<ParameterBlockId> = (0..6)
        .map(|_| split.add_parameter_block(&[0.0]).unwrap())
        .collect();
    for (i, &x) in xs.iter().enumerate() {
        split
            .add_residual_block(prior(i), RobustLoss::Trivial, &[x])
            .unwrap();
    }
    let tie = Sum {
        sizes: vec![1; 6],
        target: 10.0,
    };
    let tie_id = split
        .add_residual_block(tie, RobustLoss::Trivial, &xs)
        .unwrap();
    split.solve(&exact).unwrap();

    let shift = (10.0 - priors.iter().sum::<f64>()) / 7.0;
    for (i, &x) in xs.iter().enumerate() {
        let v = split.parameter_block(x).unwrap()[0];
        assert_relative_eq!(v, priors[i] + shift, epsilon = 1e-7);
    }
    split.remove_residual_block(tie_id).unwrap();
    split.solve(&exact).unwrap();
    for (i, &x) in xs.iter().enumerate() {
        assert_relative_eq!(
            split.parameter_block(x).unwrap()[0],
            priors[i],
            epsilon = 1e-7
        );
    }
}
