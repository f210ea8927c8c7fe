//! Bundle Adjustment in the Large problem-49-7776 against Ceres Solver 2.1.
//!
//! Reference figures (issue 6, measured with Ceres 2.1's `bundle_adjuster` on the same
//! file): initial cost 8.509125e+05 without a loss, 3.102958e+04 with Cauchy(1), 1.206505e+05
//! with Huber(1); with default tolerances and no loss Ceres converges in 32 iterations to
//! 1.334432e+04; after 50 iterations Cauchy(1) reaches 4.097712e+03.
//!
//! `bundle_adjuster` normalizes the reconstruction first (`BALProblem::Normalize`: recentre
//! on the median point, scale the median absolute deviation to 100), which leaves every
//! reprojection, hence the costs, unchanged but changes the solver's path; the solves below
//! do the same with [`BalProblem::normalize`]. The files are in `tests/data` (see its
//! README).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::assert_relative_eq;
use common::bal_path;
use ibc_bundle_adjust::{
    BalProblem, BalSyntaxError, BundleAdjustError, LinearSolverType, RobustLoss, SolverOptions,
    Summary,
};
use nalgebra::{Rotation3, Vector3};

fn problem49() -> BalProblem {
    let path = bal_path("problem-49-7776-pre.txt");
    let mut bal = BalProblem::from_file(path).unwrap();
    assert_eq!(
        (bal.cameras.len(), bal.points.len(), bal.observations.len()),
        (49, 7776, 31843)
    );
    bal.normalize();
    bal
}

/// Ceres's `Solver::Options` defaults, optionally without the convergence tests.
fn options(solver: LinearSolverType, full_budget: bool) -> SolverOptions {
    let o = SolverOptions {
        linear_solver: solver,
        ..Default::default()
    };
    if full_budget {
        SolverOptions {
            function_tolerance: 0.0,
            gradient_tolerance: 0.0,
            parameter_tolerance: 0.0,
            ..o
        }
    } else {
        o
    }
}

fn solve(loss: RobustLoss, solver: LinearSolverType) -> Summary {
    let mut bal = problem49();
    let s = bal.solve(loss, &options(solver, true)).unwrap();
    assert_eq!(s.iterations, 50);
    s
}

#[test]
fn initial_costs_match_ceres_to_seven_digits() {
    let bal = problem49();
    for (loss, ceres) in [
        (RobustLoss::Trivial, 8.509125e5),
        (RobustLoss::Cauchy { scale: 1.0 }, 3.102958e4),
        (RobustLoss::Huber { scale: 1.0 }, 1.206505e5),
    ] {
        let cost = bal.cost(loss).unwrap();
        // Seven significant digits: Ceres prints %e with 6 decimals.
        assert_relative_eq!(cost, ceres, max_relative = 5e-7);
    }
}

#[test]
fn default_tolerances_converge_like_ceres() {
    let mut bal = problem49();
    let s = bal
        .solve(
            RobustLoss::Trivial,
            &options(LinearSolverType::DenseSchur, false),
        )
        .unwrap();
    assert!(s.termination.is_converged(), "{}", s.report());
    assert!(
        s.iterations <= 35,
        "{} iterations (Ceres: 32)",
        s.iterations
    );
    assert!(
        s.final_cost <= 1.33444e4,
        "{} (Ceres: 1.334432e4)",
        s.final_cost
    );
    assert_relative_eq!(s.initial_cost, 8.509125e5, max_relative = 5e-7);
}

#[test]
fn fifty_iterations_dense_sparse_and_iterative_agree() {
    let dense = solve(RobustLoss::Trivial, LinearSolverType::DenseSchur);
    let sparse = solve(RobustLoss::Trivial, LinearSolverType::SparseSchur);
    let iterative = solve(RobustLoss::Trivial, LinearSolverType::IterativeSchur);
    assert!(dense.final_cost <= 1.33443e4, "{}", dense.final_cost);
    assert_eq!(sparse.linear_solver, LinearSolverType::SparseSchur);
    assert_eq!(iterative.linear_solver, LinearSolverType::IterativeSchur);
    assert_relative_eq!(sparse.final_cost, dense.final_cost, max_relative = 1e-6);
    assert_relative_eq!(iterative.final_cost, dense.final_cost, max_relative = 1e-4);
    assert!(
        iterative
            .log
            .iter()
            .skip(1)
            .all(|l| l.linear_solver_iterations >= 1)
    );
}

#[test]
fn fifty_iterations_with_robust_losses() {
    let cauchy = solve(
        RobustLoss::Cauchy { scale: 1.0 },
        LinearSolverType::DenseSchur,
    );
    assert!(
        cauchy.final_cost <= 4.0980e3,
        "{} (Ceres: 4.097712e3)",
        cauchy.final_cost
    );
    assert_relative_eq!(cauchy.initial_cost, 3.102958e4, max_relative = 5e-7);
    let huber = solve(
        RobustLoss::Huber { scale: 1.0 },
        LinearSolverType::DenseSchur,
    );
    assert!(huber.final_cost <= 7.6490e3, "{}", huber.final_cost);
    assert_relative_eq!(huber.initial_cost, 1.206505e5, max_relative = 5e-7);
}

/// Dubrovnik 3-7: parsing and the BAL camera model against an independent computation
/// (nalgebra's rotation), without optimizing (the problem is under-determined).
#[test]
fn dubrovnik_parses_and_projects() {
    let path = bal_path("dubrovnik-3-7-pre.txt");
    let bal = BalProblem::from_file(path).unwrap();
    assert_eq!(
        (bal.cameras.len(), bal.points.len(), bal.observations.len()),
        (3, 7, 19)
    );
    assert_eq!(bal.observations[0].camera, 0);
    assert_eq!(bal.observations[0].point, 0);
    assert_relative_eq!(bal.observations[0].pixel[0], -385.99);
    let mut total = 0.0;
    for (i, o) in bal.observations.iter().enumerate() {
        let c = &bal.cameras[o.camera];
        let x = Vector3::from(bal.points[o.point]);
        let p = Rotation3::new(Vector3::new(c[0], c[1], c[2])) * x + Vector3::new(c[3], c[4], c[5]);
        let (u, v) = (-p.x / p.z, -p.y / p.z);
        let r2 = u * u + v * v;
        let d = 1.0 + c[7] * r2 + c[8] * r2 * r2;
        let expected = [c[6] * d * u - o.pixel[0], c[6] * d * v - o.pixel[1]];
        let r = bal.residual(i).unwrap();
        assert_relative_eq!(r[0], expected[0], epsilon = 1e-9, max_relative = 1e-12);
        assert_relative_eq!(r[1], expected[1], epsilon = 1e-9, max_relative = 1e-12);
        total += 0.5 * (r[0] * r[0] + r[1] * r[1]);
    }
    assert_relative_eq!(
        bal.cost(RobustLoss::Trivial).unwrap(),
        total,
        max_relative = 1e-12
    );
    assert!(bal.residual(19).is_none());
}

/// A file that ends too early names its last line (defect 4 of issue 16: it said line 0),
/// wherever it is cut: in the header, in an observation, in the cameras or in the points,
/// with or without a final newline.
#[test]
fn a_truncated_file_names_its_last_line() {
    let text = std::fs::read_to_string(bal_path("dubrovnik-3-7-pre.txt")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // Cut after each of these whole lines (header, an observation, a camera value, a point
    // value), and once in the middle of the header line.
    // The last line with a value (the file may end with empty lines).
    let last = lines.iter().rposition(|l| !l.trim().is_empty()).unwrap();
    for keep in [1, 5, lines.len() / 2, last] {
        for newline in ["", "\n"] {
            let cut = format!("{}{newline}", lines[..keep].join("\n"));
            match BalProblem::parse(&cut) {
                Err(BundleAdjustError::BalParse {
                    line,
                    source: BalSyntaxError::UnexpectedEnd { .. },
                }) => assert_eq!(line, keep, "cut after line {keep}"),
                other => panic!("cut after line {keep}: {other:?}"),
            }
        }
    }
    let header: Vec<&str> = lines[0].split_whitespace().collect();
    match BalProblem::parse(&header[..2].join(" ")) {
        Err(BundleAdjustError::BalParse { line, .. }) => assert_eq!(line, 1),
        other => panic!("{other:?}"),
    }
    match BalProblem::parse("") {
        Err(BundleAdjustError::BalParse { line, .. }) => assert_eq!(line, 1),
        other => panic!("{other:?}"),
    }
    let err = BalProblem::parse(&lines[..5].join("\n")).unwrap_err();
    assert!(err.to_string().starts_with("BAL file, line 5:"), "{err}");
}
