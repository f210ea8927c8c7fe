//! Bad input gives typed errors, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::{
    BalProblem, BundleAdjustError as E, CostFunction, Jacobians, Problem, RobustLoss, Se3Manifold,
    SolverOptions,
};
use nalgebra::{SMatrix, Vector2};
use proptest::prelude::*;

/// r = x − target for a 2-vector, with a Jacobian of a chosen (possibly wrong) width.
struct Prior<const C: usize> {
    target: [f64; 2],
}

impl<const C: usize> CostFunction for Prior<C> {
    fn num_residuals(&self) -> usize {
        2
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[2]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        r[0] = p[0][0] - self.target[0];
        r[1] = p[0][1] - self.target[1];
        if let Some(j) = j {
            j.set(0, &SMatrix::<f64, 2, C>::identity());
        }
        true
    }
}

/// Residuals from a closure, for evaluation failures.
struct Custom(fn(&[f64], &mut [f64]) -> bool);

impl CostFunction for Custom {
    fn num_residuals(&self) -> usize {
        1
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[1]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        if let Some(j) = j {
            j.set(0, &SMatrix::<f64, 1, 1>::new(1.0));
        }
        (self.0)(p[0], r)
    }
}

#[test]
fn non_finite_parameters_are_rejected() {
    let mut p = Problem::new();
    assert!(matches!(
        p.add_parameter_block(&[1.0, f64::NAN]),
        Err(E::NonFiniteParameter { index: 1, .. })
    ));
    assert!(matches!(
        p.add_parameter_block(&[f64::INFINITY]),
        Err(E::NonFiniteParameter { .. })
    ));
    let x = p.add_parameter_block(&[1.0, 2.0]).unwrap();
    assert!(matches!(
        p.set_parameter_block(x, &[0.0, f64::NAN]),
        Err(E::NonFiniteParameter { .. })
    ));
    assert!(matches!(
        p.set_parameter_block(x, &[0.0]),
        Err(E::ParameterSizeMismatch { .. })
    ));
    assert_eq!(p.parameter_block(x).unwrap(), &[1.0, 2.0]);
    assert!(matches!(
        p.add_parameter_block(&[]),
        Err(E::EmptyParameterBlock)
    ));
}

#[test]
fn non_finite_observations_are_rejected() {
    let mut bal = BalProblem::parse("1 1 1\n0 0 1.0 2.0\n0 0 0 0 0 -5 100 0 0\n0 0 -1\n").unwrap();
    bal.observations[0].pixel[1] = f64::NAN;
    assert!(matches!(
        bal.to_problem(RobustLoss::Trivial),
        Err(E::NonFiniteObservation { index: 0 })
    ));
    assert!(matches!(
        BalProblem::parse("1 1 1\n0 0 1.0 inf\n0 0 0 0 0 -5 100 0 0\n0 0 -1\n"),
        Err(E::BalParse { line: 2, .. })
    ));
    // A NaN residual at the start is an error, not a silent solve.
    let mut p = Problem::new();
    let x = p.add_parameter_block(&[1.0]).unwrap();
    p.add_residual_block(
        Custom(|_, r| {
            r[0] = f64::NAN;
            true
        }),
        RobustLoss::Trivial,
        &[x],
    )
    .unwrap();
    assert!(matches!(
        p.solve(&SolverOptions::default()),
        Err(E::NonFiniteResidual { residual: 0 })
    ));
}

#[test]
fn empty_problems_are_rejected() {
    let mut p = Problem::new();
    assert!(matches!(
        p.solve(&SolverOptions::default()),
        Err(E::EmptyProblem)
    ));
    p.add_parameter_block(&[1.0]).unwrap();
    assert!(matches!(
        p.solve(&SolverOptions::default()),
        Err(E::EmptyProblem)
    ));
    assert!(matches!(
        p.covariance(&[], &SolverOptions::default()),
        Err(E::EmptyProblem)
    ));
    let empty = BalProblem::parse("0 0 0").unwrap();
    assert!(
        empty
            .clone()
            .solve(RobustLoss::Trivial, &SolverOptions::default())
            .is_err()
    );
}

#[test]
fn missing_blocks_are_rejected() {
    let mut other = Problem::new();
    other.add_parameter_block(&[0.0, 0.0]).unwrap();
    let foreign = other.add_parameter_block(&[0.0, 0.0]).unwrap();
    let mut p = Problem::new();
    p.add_parameter_block(&[0.0, 0.0]).unwrap();
    let err = p.add_residual_block(
        Prior::<2> { target: [1.0, 1.0] },
        RobustLoss::Trivial,
        &[foreign],
    );
    assert!(matches!(
        err,
        Err(E::UnknownParameterBlock { block: 1, count: 1 })
    ));
    assert!(matches!(
        p.set_constant(foreign, true),
        Err(E::UnknownParameterBlock { .. })
    ));
    assert!(matches!(
        p.parameter_block(foreign),
        Err(E::UnknownParameterBlock { .. })
    ));
    // A BAL observation of a camera that does not exist.
    assert!(matches!(
        BalProblem::parse("1 1 1\n4 0 1.0 2.0\n0 0 0 0 0 -5 100 0 0\n0 0 -1\n"),
        Err(E::BalParse { line: 2, .. })
    ));
}

#[test]
fn mismatched_sizes_are_rejected() {
    let mut p = Problem::new();
    let small = p.add_parameter_block(&[0.0]).unwrap();
    let pair = p.add_parameter_block(&[0.0, 0.0]).unwrap();
    let target = [1.0, 1.0];
    assert!(matches!(
        p.add_residual_block(Prior::<2> { target }, RobustLoss::Trivial, &[small]),
        Err(E::ParameterSizeMismatch {
            position: 0,
            expected: 2,
            got: 1,
            ..
        })
    ));
    assert!(matches!(
        p.add_residual_block(Prior::<2> { target }, RobustLoss::Trivial, &[pair, small]),
        Err(E::ParameterCountMismatch {
            expected: 1,
            got: 2
        })
    ));
    assert!(matches!(
        p.add_manifold_block(&[1.0, 0.0, 0.0, 0.0], Se3Manifold),
        Err(E::ManifoldSizeMismatch {
            expected: 7,
            got: 4
        })
    ));
    assert!(matches!(
        p.add_residual_block(
            Prior::<2> { target },
            RobustLoss::Cauchy { scale: -1.0 },
            &[pair]
        ),
        Err(E::InvalidLossScale { scale: -1.0 })
    ));
    // A Jacobian written with the wrong number of columns.
    p.add_residual_block(Prior::<3> { target }, RobustLoss::Trivial, &[pair])
        .unwrap();
    assert!(matches!(
        p.solve(&SolverOptions::default()),
        Err(E::JacobianShapeMismatch { position: 0, .. })
    ));
}

#[test]
fn structural_mistakes_are_rejected() {
    let mut p = Problem::new();
    let a = p.add_parameter_block(&[0.0, 0.0]).unwrap();
    let b = p.add_parameter_block(&[0.0, 0.0]).unwrap();
    struct Pair;
    impl CostFunction for Pair {
        fn num_residuals(&self) -> usize {
            2
        }
        fn parameter_block_sizes(&self) -> &[usize] {
            &[2, 2]
        }
        fn evaluate(&self, p: &[&[f64]], r: &mut [f64], _: Option<&mut Jacobians<'_>>) -> bool {
            r[0] = p[0][0] - p[1][0];
            r[1] = p[0][1] - p[1][1];
            true
        }
    }
    assert!(matches!(
        p.add_residual_block(Pair, RobustLoss::Trivial, &[a, a]),
        Err(E::DuplicateParameterBlock { .. })
    ));
    p.add_residual_block(Pair, RobustLoss::Trivial, &[a, b])
        .unwrap();
    p.set_eliminated(a, true).unwrap();
    p.set_eliminated(b, true).unwrap();
    assert!(matches!(
        p.solve(&SolverOptions::default()),
        Err(E::EliminatedBlocksCoupled {
            first: 0,
            second: 1
        })
    ));
}

#[test]
fn invalid_options_are_rejected() {
    let mut p = Problem::new();
    let x = p.add_parameter_block(&[0.0, 0.0]).unwrap();
    p.add_residual_block(Prior::<2> { target: [1.0, 2.0] }, RobustLoss::Trivial, &[x])
        .unwrap();
    let o = SolverOptions {
        num_threads: 0,
        ..Default::default()
    };
    assert!(matches!(
        p.solve(&o),
        Err(E::InvalidOption {
            name: "num_threads",
            ..
        })
    ));
    let o = SolverOptions {
        function_tolerance: f64::NAN,
        ..Default::default()
    };
    assert!(matches!(
        p.solve(&o),
        Err(E::InvalidOption {
            name: "function_tolerance",
            ..
        })
    ));
    let o = SolverOptions {
        initial_trust_region_radius: -1.0,
        ..Default::default()
    };
    assert!(p.solve(&o).is_err());
    let s = p.solve(&SolverOptions::default()).unwrap();
    assert!(s.termination.is_converged());
    assert!(s.final_cost < 1e-12, "{}", s.report());
}

#[test]
fn evaluation_failures_during_the_solve_reject_steps() {
    // r = x − 3, undefined for x > 2.5: the solver stays where the residual is defined.
    let mut p = Problem::new();
    let x = p.add_parameter_block(&[0.0]).unwrap();
    p.add_residual_block(
        Custom(|x, r| {
            r[0] = x[0] - 3.0;
            x[0] <= 2.5
        }),
        RobustLoss::Trivial,
        &[x],
    )
    .unwrap();
    let s = p.solve(&SolverOptions::default()).unwrap();
    let v = p.parameter_block(x).unwrap()[0];
    assert!(v <= 2.5);
    assert!(s.final_cost <= s.initial_cost);
    assert!(s.log.iter().any(|l| !l.step_is_successful));
    // Undefined at the start: an error naming the residual block.
    let mut q = Problem::new();
    let y = q.add_parameter_block(&[3.0]).unwrap();
    q.add_residual_block(
        Custom(|x, r| {
            r[0] = x[0];
            x[0] < 1.0
        }),
        RobustLoss::Trivial,
        &[y],
    )
    .unwrap();
    assert!(matches!(
        q.solve(&SolverOptions::default()),
        Err(E::InitialEvaluationFailed { residual: 0 })
    ));
}

proptest! {
    /// Arbitrary BAL text never panics the parser.
    #[test]
    fn bal_parser_never_panics(text in "[0-9 .eE+\\-\\n]{0,200}") {
        let _ = BalProblem::parse(&text);
    }

    /// Arbitrary finite or non-finite values in a tiny problem never panic the solver.
    #[test]
    fn solver_never_panics(x in prop::array::uniform2(prop_oneof![Just(f64::NAN), -1e300..1e300]),
                           t in prop::array::uniform2(-1e3..1e3f64)) {
        let mut p = Problem::new();
        if let Ok(b) = p.add_parameter_block(&x) {
            p.add_residual_block(Prior::<2> { target: t }, RobustLoss::Cauchy { scale: 1.0 }, &[b]).unwrap();
            let _ = p.solve(&SolverOptions::default());
            let _ = Vector2::new(0.0, 0.0);
        }
    }
}
