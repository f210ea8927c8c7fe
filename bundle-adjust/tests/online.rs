//! Online use of a `Problem`: holding some entries of a block (`set_constant_subset`),
//! iteration and time budgets, an iteration callback, and removing residual blocks between
//! solves.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{perturb, synthetic_bal};
use ibc_bundle_adjust::nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Point3, SMatrix, Vector3};
use ibc_bundle_adjust::{
    BalReprojection, BundleAdjustError, CostFunction, IterationControl, Jacobians,
    LinearSolverType, ParameterBlockId, Problem, RobustLoss, Se3Manifold, SolverOptions,
    Termination,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// r = Σₖ Aₖ pₖ − b: a linear residual over any blocks.
struct Linear {
    a: Vec<DMatrix<f64>>,
    b: DVector<f64>,
    sizes: Vec<usize>,
}

impl CostFunction for Linear {
    fn num_residuals(&self) -> usize {
        self.b.len()
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &self.sizes
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let mut v = -self.b.clone();
        for (a, x) in self.a.iter().zip(p) {
            v += a * DVector::from_column_slice(x);
        }
        r.copy_from_slice(v.as_slice());
        if let Some(j) = j {
            for (k, a) in self.a.iter().enumerate() {
                if let Some(block) = j.row_major_mut(k) {
                    for row in 0..a.nrows() {
                        for col in 0..a.ncols() {
                            block[row * a.ncols() + col] = a[(row, col)];
                        }
                    }
                }
            }
        }
        true
    }
}

fn random_matrix(rng: &mut ChaCha8Rng, rows: usize, cols: usize) -> DMatrix<f64> {
    DMatrix::from_fn(rows, cols, |_, _| rng.random_range(-1.0..1.0))
}

/// A shared 4-vector x (reduced) and six 3-vectors yⱼ (eliminated), residuals
/// rⱼ = Aⱼ x + Bⱼ yⱼ − bⱼ (6 rows each): the data and the start values.
struct LinearScene {
    a: Vec<DMatrix<f64>>,
    bm: Vec<DMatrix<f64>>,
    b: Vec<DVector<f64>>,
    x0: Vec<f64>,
    y0: Vec<Vec<f64>>,
}

fn linear_scene(seed: u64) -> LinearScene {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = 6;
    LinearScene {
        a: (0..n).map(|_| random_matrix(&mut rng, 6, 4)).collect(),
        bm: (0..n).map(|_| random_matrix(&mut rng, 6, 3)).collect(),
        b: (0..n)
            .map(|_| DVector::from_fn(6, |_, _| rng.random_range(-5.0..5.0)))
            .collect(),
        x0: (0..4).map(|_| rng.random_range(-1.0..1.0)).collect(),
        y0: (0..n)
            .map(|_| (0..3).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect(),
    }
}

/// The least-squares solution with the entries `held` (indices into the stacked unknowns
/// [x, y₀, y₁, ...]) at their start values: the reference, by SVD.
fn reference_solution(s: &LinearScene, held: &[usize]) -> Vec<f64> {
    let n = s.a.len();
    let cols = 4 + 3 * n;
    let mut big = DMatrix::zeros(6 * n, cols);
    let mut rhs = DVector::zeros(6 * n);
    for j in 0..n {
        big.view_mut((6 * j, 0), (6, 4)).copy_from(&s.a[j]);
        big.view_mut((6 * j, 4 + 3 * j), (6, 3)).copy_from(&s.bm[j]);
        rhs.rows_mut(6 * j, 6).copy_from(&s.b[j]);
    }
    let mut start: Vec<f64> = s.x0.clone();
    for y in &s.y0 {
        start.extend_from_slice(y);
    }
    let free: Vec<usize> = (0..cols).filter(|c| !held.contains(c)).collect();
    for &h in held {
        rhs -= big.column(h) * start[h];
    }
    let reduced = DMatrix::from_fn(6 * n, free.len(), |r, c| big[(r, free[c])]);
    let solution = reduced.svd(true, true).solve(&rhs, 1e-14).unwrap();
    let mut out = start;
    for (k, &c) in free.iter().enumerate() {
        out[c] = solution[k];
    }
    out
}

/// (AᵀA)⁻¹ of the stacked linear problem over the columns not in `held`, scattered back to
/// the stacked indices (zero for held ones).
fn free_covariance(s: &LinearScene, held: &[usize]) -> DMatrix<f64> {
    let n = s.a.len();
    let cols = 4 + 3 * n;
    let mut big = DMatrix::zeros(6 * n, cols);
    for j in 0..n {
        big.view_mut((6 * j, 0), (6, 4)).copy_from(&s.a[j]);
        big.view_mut((6 * j, 4 + 3 * j), (6, 3)).copy_from(&s.bm[j]);
    }
    let free: Vec<usize> = (0..cols).filter(|c| !held.contains(c)).collect();
    let reduced = DMatrix::from_fn(6 * n, free.len(), |r, c| big[(r, free[c])]);
    let inv = (reduced.transpose() * &reduced).try_inverse().unwrap();
    let mut out = DMatrix::zeros(cols, cols);
    for (i, &a) in free.iter().enumerate() {
        for (j, &b) in free.iter().enumerate() {
            out[(a, b)] = inv[(i, j)];
        }
    }
    out
}

/// Holding entries of a vector block (a reduced one and an eliminated one): the held entries
/// stay bit-identical, the others reach the least-squares solution with the held values
/// substituted (by SVD), with each reduced solver.
#[test]
fn a_subset_of_a_block_is_held() {
    let s = linear_scene(11);
    // x[1], x[3] and y₂[0] held: stacked indices 1, 3 and 4 + 3·2 + 0 = 10.
    let reference = reference_solution(&s, &[1, 3, 10]);
    for solver in [
        LinearSolverType::DenseSchur,
        LinearSolverType::SparseSchur,
        LinearSolverType::IterativeSchur,
    ] {
        let mut problem = Problem::new();
        let x = problem.add_parameter_block(&s.x0).unwrap();
        let ys: Vec<_> =
            s.y0.iter()
                .map(|y| problem.add_parameter_block(y).unwrap())
                .collect();
        for (j, &y) in ys.iter().enumerate() {
            problem.set_eliminated(y, true).unwrap();
            problem
                .add_residual_block(
                    Linear {
                        a: vec![s.a[j].clone(), s.bm[j].clone()],
                        b: s.b[j].clone(),
                        sizes: vec![4, 3],
                    },
                    RobustLoss::Trivial,
                    &[x, y],
                )
                .unwrap();
        }
        problem.set_constant_subset(x, &[3, 1, 3]).unwrap();
        problem.set_constant_subset(ys[2], &[0]).unwrap();
        assert_eq!(problem.constant_subset(x).unwrap(), &[1, 3]);
        let summary = problem
            .solve(&SolverOptions {
                linear_solver: solver,
                eta: 1e-6,
                ..tight()
            })
            .unwrap();
        assert!(summary.termination.is_converged(), "{}", summary.report());
        // 4 + 18 unknowns, 3 held: the held ones still count in the layout.
        assert_eq!(summary.num_reduced + summary.num_eliminated, 22);
        let xv = problem.parameter_block(x).unwrap();
        let y2 = problem.parameter_block(ys[2]).unwrap();
        assert_eq!(xv[1].to_bits(), s.x0[1].to_bits());
        assert_eq!(xv[3].to_bits(), s.x0[3].to_bits());
        assert_eq!(y2[0].to_bits(), s.y0[2][0].to_bits());
        let tolerance = if solver == LinearSolverType::IterativeSchur {
            1e-6
        } else {
            1e-9
        };
        let mut got: Vec<f64> = xv.to_vec();
        for &y in &ys {
            got.extend_from_slice(problem.parameter_block(y).unwrap());
        }
        let mut moved = 0;
        for (k, (g, r)) in got.iter().zip(&reference).enumerate() {
            assert!(
                (g - r).abs() < tolerance,
                "{solver:?} entry {k}: {g} vs {r}"
            );
            let start = if k < 4 {
                s.x0[k]
            } else {
                s.y0[(k - 4) / 3][(k - 4) % 3]
            };
            if (g - start).abs() > 1e-3 {
                moved += 1;
            }
        }
        // Every free entry moved from its start.
        assert_eq!(moved, 22 - 3, "{solver:?}");
        // Covariance: held entries have none; the free ones are those of (AᵀA)⁻¹ over the
        // free columns (the problem is linear, so at any point).
        let cov = problem.covariance(&[x], &SolverOptions::default()).unwrap();
        let expected = free_covariance(&s, &[1, 3, 10]);
        for r in 0..4 {
            for c in 0..4 {
                let want = if [1, 3].contains(&r) || [1, 3].contains(&c) {
                    0.0
                } else {
                    expected[(r, c)]
                };
                let got = cov.matrix()[(r, c)];
                assert!(
                    (got - want).abs() < 1e-10 * (1.0 + want.abs()),
                    "({r}, {c}): {got} vs {want}"
                );
            }
        }
    }
    // Bad indices are named; holding all entries is holding the block.
    let mut problem = Problem::new();
    let x = problem.add_parameter_block(&[1.0, 2.0]).unwrap();
    assert_eq!(
        problem.set_constant_subset(x, &[0, 2]),
        Err(BundleAdjustError::SubsetIndexOutOfRange {
            block: 0,
            index: 2,
            tangent: 2
        })
    );
    problem.set_constant_subset(x, &[0, 1]).unwrap();
    problem
        .add_residual_block(
            Linear {
                a: vec![DMatrix::identity(2, 2)],
                b: DVector::from_vec(vec![5.0, 5.0]),
                sizes: vec![2],
            },
            RobustLoss::Trivial,
            &[x],
        )
        .unwrap();
    let summary = problem.solve(&SolverOptions::default()).unwrap();
    assert_eq!(summary.termination, Termination::NoFreeParameters);
    assert_eq!(problem.parameter_block(x).unwrap(), &[1.0, 2.0]);
}

/// r = T pₖ − qₖ for a pose T on SE(3).
struct Transformed {
    p: Vector3<f64>,
    q: Vector3<f64>,
}

impl CostFunction for Transformed {
    fn num_residuals(&self) -> usize {
        3
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[7]
    }
    fn evaluate(&self, params: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let pose = Se3Manifold::pose(params[0]).unwrap();
        let v = pose * Point3::from(self.p) - Point3::from(self.q);
        r.copy_from_slice(v.as_slice());
        if let Some(j) = j {
            let rot: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
            let mut m = SMatrix::<f64, 3, 6>::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&rot);
            m.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&(-rot * self.p.cross_matrix()));
            j.set(0, &m);
        }
        true
    }
}

/// On a manifold block the indices are tangent coordinates: holding φ (3..6) of an SE(3)
/// block keeps the rotation, and the translation reaches its optimum for that rotation,
/// mean(qₖ − R pₖ).
#[test]
fn tangent_coordinates_of_a_manifold_block_are_held() {
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let truth = Isometry3::new(Vector3::new(0.5, -0.2, 1.0), Vector3::new(0.1, 0.3, -0.2));
    let start = Isometry3::new(Vector3::zeros(), Vector3::new(0.12, 0.28, -0.25));
    let mut problem = Problem::new();
    let pose = problem
        .add_manifold_block(&Se3Manifold::params(&start), Se3Manifold)
        .unwrap();
    let mut expected = Vector3::zeros();
    let n = 10;
    for _ in 0..n {
        let p = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let q = (truth * Point3::from(p)).coords;
        expected += (q - start.rotation * p) / n as f64;
        problem
            .add_residual_block(Transformed { p, q }, RobustLoss::Trivial, &[pose])
            .unwrap();
    }
    problem.set_constant_subset(pose, &[3, 4, 5]).unwrap();
    let summary = problem.solve(&tight()).unwrap();
    assert!(summary.termination.is_converged(), "{}", summary.report());
    let solved = Se3Manifold::pose(problem.parameter_block(pose).unwrap()).unwrap();
    assert!(solved.rotation.angle_to(&start.rotation) < 1e-14);
    assert!((solved.translation.vector - expected).norm() < 1e-10);
    assert!(solved.translation.vector.norm() > 0.5);
}

/// A residual r = exp(x) − 2 from x = 4: many iterations to converge.
struct Exp;

impl CostFunction for Exp {
    fn num_residuals(&self) -> usize {
        1
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[1]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        r[0] = p[0][0].exp() - 2.0;
        if let Some(j) = j {
            j.set(0, &SMatrix::<f64, 1, 1>::new(p[0][0].exp()));
        }
        true
    }
}

/// [`Exp`], sleeping on every evaluation so that iterations take measurable time.
struct SlowExp(std::time::Duration);

impl CostFunction for SlowExp {
    fn num_residuals(&self) -> usize {
        1
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[1]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        std::thread::sleep(self.0);
        Exp.evaluate(p, r, j)
    }
}

fn exp_problem(cost: impl CostFunction + 'static) -> (Problem, ParameterBlockId) {
    let mut problem = Problem::new();
    let x = problem.add_parameter_block(&[4.0]).unwrap();
    problem
        .add_residual_block(cost, RobustLoss::Trivial, &[x])
        .unwrap();
    (problem, x)
}

/// Tight tolerances so that only the budgets stop the solve early.
fn tight() -> SolverOptions {
    SolverOptions {
        function_tolerance: 1e-15,
        parameter_tolerance: 1e-15,
        gradient_tolerance: 1e-20,
        ..Default::default()
    }
}

#[test]
fn an_iteration_budget_stops_after_that_many_iterations() {
    let unbounded = exp_problem(Exp).0.solve(&tight()).unwrap();
    assert!(unbounded.iterations > 6, "{}", unbounded.report());
    for k in [1, 3, 5] {
        let (mut problem, _) = exp_problem(Exp);
        let summary = problem
            .solve(&SolverOptions {
                max_iterations: k,
                ..tight()
            })
            .unwrap();
        assert_eq!(summary.termination, Termination::MaxIterations);
        assert_eq!(summary.iterations, k);
        assert_eq!(summary.log.len(), k + 1);
        // The same first k iterations as the unbounded solve.
        for (s, u) in summary.log.iter().zip(&unbounded.log[..=k]) {
            assert_eq!(s.cost.to_bits(), u.cost.to_bits());
            assert_eq!(s.step_norm.to_bits(), u.step_norm.to_bits());
        }
        assert!(summary.final_cost > unbounded.final_cost);
    }
}

#[test]
fn a_time_budget_stops_the_solve() {
    let sleep = std::time::Duration::from_millis(3);
    // Every iteration evaluates at least twice (candidate cost and Jacobian): >= 6 ms each.
    let budget = 0.02;
    let start = std::time::Instant::now();
    let summary = exp_problem(SlowExp(sleep))
        .0
        .solve(&SolverOptions {
            max_solver_time_in_seconds: budget,
            ..tight()
        })
        .unwrap();
    let elapsed = start.elapsed().as_secs_f64();
    assert_eq!(summary.termination, Termination::MaxSolverTime);
    assert!(
        summary.iterations >= 1 && summary.iterations < 10,
        "{}",
        summary.report()
    );
    let last = summary.log.last().unwrap();
    assert!(last.cumulative_time >= budget);
    // Stopped within one iteration of the budget (an iteration is not interrupted).
    let before = summary.log[summary.log.len() - 2].cumulative_time;
    assert!(before < budget, "{before}");
    assert!(elapsed < budget + 0.2, "{elapsed}");
    // A budget too short for any iteration still makes one.
    let summary = exp_problem(Exp)
        .0
        .solve(&SolverOptions {
            max_solver_time_in_seconds: 1e-12,
            ..tight()
        })
        .unwrap();
    assert_eq!(summary.termination, Termination::MaxSolverTime);
    assert_eq!(summary.iterations, 1);
    assert!(matches!(
        exp_problem(Exp).0.solve(&SolverOptions {
            max_solver_time_in_seconds: 0.0,
            ..Default::default()
        }),
        Err(BundleAdjustError::InvalidOption {
            name: "max_solver_time_in_seconds",
            ..
        })
    ));
}

#[test]
fn a_callback_sees_every_iteration_and_can_stop_the_solve() {
    // Seeing everything: the callback gets exactly the log.
    let mut seen = Vec::new();
    let (mut problem, _) = exp_problem(Exp);
    let summary = problem
        .solve_with_callback(&tight(), |it| {
            seen.push(*it);
            IterationControl::Continue
        })
        .unwrap();
    assert!(summary.termination.is_converged());
    assert_eq!(seen, summary.log);
    // Stopping after the cost fell below 0.01: the returned point is the last accepted one.
    let (mut problem, x) = exp_problem(Exp);
    let summary = problem
        .solve_with_callback(&tight(), |it| {
            if it.cost < 0.01 {
                IterationControl::Stop
            } else {
                IterationControl::Continue
            }
        })
        .unwrap();
    assert_eq!(summary.termination, Termination::UserStop);
    let last = summary.log.last().unwrap();
    assert!(last.cost < 0.01 && last.step_is_successful);
    assert!(
        summary.log[..summary.log.len() - 1]
            .iter()
            .all(|l| l.cost >= 0.01)
    );
    let x = problem.parameter_block(x).unwrap()[0];
    assert!((0.5 * (x.exp() - 2.0).powi(2) - summary.final_cost).abs() < 1e-15);
    assert_eq!(summary.final_cost, last.cost);
    // Stopping at iteration 0 changes nothing.
    let (mut problem, x) = exp_problem(Exp);
    let summary = problem
        .solve_with_callback(&tight(), |_| IterationControl::Stop)
        .unwrap();
    assert_eq!(summary.termination, Termination::UserStop);
    assert_eq!(summary.iterations, 0);
    assert_eq!(problem.parameter_block(x).unwrap(), &[4.0]);
}

/// Removing residual blocks between solves: the next solve is the solve of a problem built
/// without them (bit for bit), and removed ids are refused.
#[test]
fn removed_residual_blocks_leave_the_next_solve() {
    let mut bal = synthetic_bal(31, 6, 60, 0.5);
    perturb(&mut bal, 32, 0.01, 0.05, 0.05);
    let options = SolverOptions {
        max_iterations: 100,
        ..Default::default()
    };
    let mut problem = Problem::new();
    let cameras: Vec<_> = bal
        .cameras
        .iter()
        .map(|c| problem.add_parameter_block(c).unwrap())
        .collect();
    let points: Vec<_> = bal
        .points
        .iter()
        .map(|p| problem.add_parameter_block(p).unwrap())
        .collect();
    for &p in &points {
        problem.set_eliminated(p, true).unwrap();
    }
    problem.set_constant(cameras[0], true).unwrap();
    let ids: Vec<_> = bal
        .observations
        .iter()
        .map(|o| {
            problem
                .add_residual_block(
                    BalReprojection::new(o.pixel),
                    RobustLoss::Trivial,
                    &[cameras[o.camera], points[o.point]],
                )
                .unwrap()
        })
        .collect();
    let first = problem.solve(&options).unwrap();
    assert!(first.termination.is_converged());
    // Drop every observation of camera 5 and every third of the others.
    let drop: Vec<usize> = (0..ids.len())
        .filter(|&i| bal.observations[i].camera == 5 || i % 3 == 0)
        .collect();
    for &i in &drop {
        problem.remove_residual_block(ids[i]).unwrap();
    }
    assert_eq!(problem.num_residual_blocks(), ids.len() - drop.len());
    assert!(!problem.has_residual_block(ids[drop[0]]));
    assert_eq!(
        problem.remove_residual_block(ids[drop[0]]),
        Err(BundleAdjustError::UnknownResidualBlock {
            residual: drop[0],
            count: ids.len() - drop.len()
        })
    );
    // The reference: the scene as the first solve left it, without those observations.
    let mut kept = bal.clone();
    for (c, &id) in kept.cameras.iter_mut().zip(&cameras) {
        c.copy_from_slice(problem.parameter_block(id).unwrap());
    }
    for (p, &id) in kept.points.iter_mut().zip(&points) {
        p.copy_from_slice(problem.parameter_block(id).unwrap());
    }
    kept.observations = (0..ids.len())
        .filter(|i| drop.binary_search(i).is_err())
        .map(|i| bal.observations[i])
        .collect();
    let (mut reference, blocks) = kept.to_problem(RobustLoss::Trivial).unwrap();
    reference.set_constant(blocks.cameras[0], true).unwrap();
    let expected = reference.solve(&options).unwrap();
    let second = problem.solve(&options).unwrap();
    assert_eq!(second.num_residual_blocks, kept.observations.len());
    assert!(second.initial_cost < 0.8 * first.final_cost);
    assert_eq!(
        second.initial_cost.to_bits(),
        expected.initial_cost.to_bits()
    );
    assert_eq!(second.final_cost.to_bits(), expected.final_cost.to_bits());
    assert_eq!(second.iterations, expected.iterations);
    // Camera 5 lost all its observations: it keeps its values.
    let c5 = problem.parameter_block(cameras[5]).unwrap();
    assert_eq!(c5, &kept.cameras[5][..]);
    for (&a, &b) in points.iter().zip(&blocks.points) {
        assert_eq!(
            problem.parameter_block(a).unwrap(),
            reference.parameter_block(b).unwrap()
        );
    }
    // Removing everything leaves an empty problem.
    for (i, &id) in ids.iter().enumerate() {
        if drop.binary_search(&i).is_err() {
            problem.remove_residual_block(id).unwrap();
        }
    }
    assert_eq!(
        problem.solve(&options),
        Err(BundleAdjustError::EmptyProblem)
    );
}
