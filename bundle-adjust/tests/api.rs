//! The crate as a user calls it: every options struct in one expression, rig refinement from
//! an `ibc_camera_models::Rig`, a cost function written with `Se3Manifold::params` and
//! `Se3Manifold::pose`, and `RobustLoss` in a `Problem`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::nalgebra::{Isometry3, Point3, SMatrix, UnitQuaternion, Vector3};
use ibc_bundle_adjust::{
    BundleAdjustError, BundleAdjustmentOptions, CostFunction, Jacobians, LinearSolverType, Problem,
    RigObservation, RigRefinement, RigRefinementOptions, RobustLoss, Se3Manifold, SolverOptions,
    UnitQuaternionManifold,
};
use ibc_camera_models::{Camera, CameraModel, PinholeRadtan, Rig, RigCamera};

#[test]
fn options_are_written_in_one_expression() {
    let solver = SolverOptions {
        max_iterations: 20,
        linear_solver: LinearSolverType::DenseSchur,
        ..Default::default()
    };
    assert_eq!(solver.max_iterations, 20);
    assert_eq!(solver.function_tolerance, 1e-6);
    let rig = RigRefinementOptions {
        loss: RobustLoss::Cauchy { scale: 1.0 },
        solver: SolverOptions {
            num_threads: 2,
            ..Default::default()
        },
        ..Default::default()
    };
    assert_eq!(rig.reference_camera, 0);
    assert_eq!(rig.solver.num_threads, 2);
    let ba = BundleAdjustmentOptions {
        optimize_intrinsics: true,
        loss: RobustLoss::Huber { scale: 2.0 },
        ..Default::default()
    };
    assert_eq!(ba.fixed_images, vec![0]);
    assert_eq!(
        RigRefinementOptions::default().loss,
        RobustLoss::Cauchy { scale: 1.0 }
    );
}

fn pinhole() -> Camera {
    PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0])
        .unwrap()
        .into()
}

#[test]
fn a_rig_is_refined_and_written_back() {
    // Two cameras looking forward, 0.3 m apart.
    let truth = Rig::new(vec![
        RigCamera::new("front_left", pinhole(), Isometry3::identity()),
        RigCamera::new(
            "front_right",
            pinhole(),
            Isometry3::new(Vector3::new(0.3, 0.0, 0.0), Vector3::new(0.0, 0.05, 0.0)),
        ),
    ]);
    let world_from_rig: Vec<Isometry3<f64>> = (0..6)
        .map(|f| {
            let f = f64::from(f);
            Isometry3::new(
                Vector3::new(0.2 * f, 0.0, 0.1 * f),
                Vector3::new(0.0, 0.05 * f, 0.0),
            )
        })
        .collect();
    let mut observations = Vec::new();
    for (frame, w) in world_from_rig.iter().enumerate() {
        for (camera, c) in truth.cameras.iter().enumerate() {
            for k in 0..30 {
                let k = f64::from(k);
                let p_cam = Vector3::new((k * 0.37).sin(), (k * 0.53).cos() * 0.7, 4.0 + k * 0.1);
                let world_point = (w * c.rig_from_camera * Point3::from(p_cam)).coords;
                observations.push(RigObservation {
                    frame,
                    camera,
                    world_point,
                    pixel: c.camera.project(&p_cam).unwrap(),
                });
            }
        }
    }
    // Start from a rig whose second extrinsic is off by 2 cm and 0.01 rad.
    let mut start = truth.clone();
    start.cameras[1].rig_from_camera *=
        Isometry3::new(Vector3::new(0.02, -0.01, 0.0), Vector3::new(0.0, 0.0, 0.01));
    let problem = RigRefinement::from_rig(&start, world_from_rig, observations);
    let result = problem.refine(&RigRefinementOptions::default()).unwrap();
    assert!(result.excluded_observations.is_empty());
    assert!(result.final_rms < 1e-6, "{}", result.final_rms);
    let refined: Rig = result.to_rig(&start).unwrap();
    assert_eq!(refined.cameras[1].name, "front_right");
    let (e, t) = (
        refined.cameras[1].rig_from_camera,
        truth.cameras[1].rig_from_camera,
    );
    assert!((e.translation.vector - t.translation.vector).norm() < 1e-6);
    assert!(e.rotation.angle_to(&t.rotation) < 1e-6);
    assert!(matches!(
        result.to_rig(&Rig::default()),
        Err(BundleAdjustError::LengthMismatch { .. })
    ));
}

/// r = camera_from_world · X − x_expected: a point prior through a pose, written as a user
/// would, with the manifold's conversions and the right-perturbation Jacobian
/// `R [I, −[X]×]` of `T Exp(δ)`, `δ = [ρ, φ]`.
struct PosedPoint {
    world_point: Vector3<f64>,
    expected: Vector3<f64>,
}

impl CostFunction for PosedPoint {
    fn num_residuals(&self) -> usize {
        3
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[7]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let Some(pose) = Se3Manifold::pose(p[0]) else {
            return false;
        };
        let x = pose * Point3::from(self.world_point);
        for k in 0..3 {
            r[k] = x[k] - self.expected[k];
        }
        if let Some(j) = j {
            let rotation = pose.rotation.to_rotation_matrix().into_inner();
            let mut d = SMatrix::<f64, 3, 6>::zeros();
            d.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
            d.fixed_view_mut::<3, 3>(0, 3)
                .copy_from(&(-rotation * self.world_point.cross_matrix()));
            j.set(0, &d);
        }
        true
    }
}

#[test]
fn a_cost_function_uses_the_manifold_conversions_and_a_robust_loss() {
    let truth = Isometry3::new(Vector3::new(0.5, -0.2, 1.0), Vector3::new(0.1, 0.4, -0.2));
    let start = Isometry3::new(Vector3::new(0.4, 0.0, 1.2), Vector3::new(0.0, 0.3, 0.0));
    let mut problem = Problem::new();
    let pose = problem
        .add_manifold_block(&Se3Manifold::params(&start), Se3Manifold)
        .unwrap();
    for k in 0..12 {
        let k = f64::from(k);
        let world_point = Vector3::new(k.sin(), (1.3 * k).cos(), 0.2 * k);
        let mut expected = (truth * Point3::from(world_point)).coords;
        if k == 5.0 {
            expected.x += 10.0; // a gross outlier
        }
        problem
            .add_residual_block(
                PosedPoint {
                    world_point,
                    expected,
                },
                RobustLoss::Cauchy { scale: 0.1 },
                &[pose],
            )
            .unwrap();
    }
    let summary = problem
        .solve(&SolverOptions {
            max_iterations: 100,
            ..Default::default()
        })
        .unwrap();
    assert!(summary.termination.is_converged(), "{}", summary.report());
    let solved = Se3Manifold::pose(problem.parameter_block(pose).unwrap()).unwrap();
    // The outlier's pull is a^2 / 10 m = 1 mm at most, where least squares moves by decimetres.
    let error = (solved.translation.vector - truth.translation.vector).norm();
    assert!(error < 2e-3, "{error} m");
    assert!(solved.rotation.angle_to(&truth.rotation) < 2e-3);
    assert_eq!(Se3Manifold::pose(&[1.0, 0.0]), None);
    // A robust loss with a bad scale is a typed error naming the scale.
    let bad: ibc_bundle_adjust::Result<_> = problem.add_residual_block(
        PosedPoint {
            world_point: Vector3::zeros(),
            expected: Vector3::zeros(),
        },
        RobustLoss::Huber { scale: 0.0 },
        &[pose],
    );
    assert_eq!(
        bad.unwrap_err(),
        BundleAdjustError::InvalidLossScale { scale: 0.0 }
    );
    // The quaternion manifold's conversions.
    let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.2, 0.3));
    let stored = UnitQuaternionManifold::params(&q);
    let read = UnitQuaternionManifold::rotation(&stored).unwrap();
    assert!(read.angle_to(&q) < 1e-15);
    assert_eq!(UnitQuaternionManifold::rotation(&stored[..3]), None);
}

/// The options of issue 16 (rig bundle adjustment, gauges, budgets), written as a caller
/// outside the crate writes them.
#[test]
fn issue_16_options_are_one_expression() {
    use ibc_bundle_adjust::{Gauge, RigBundleAdjustmentOptions, ScaleGauge};
    let rig = RigBundleAdjustmentOptions {
        optimize_intrinsics: true,
        held_intrinsics: vec![(0, 2), (0, 3)],
        scale: ScaleGauge::Odometry {
            frame: 10,
            distance_m: 3.2,
        },
        solver: SolverOptions {
            max_solver_time_in_seconds: 0.5,
            min_reciprocal_condition_number: 1e-12,
            ..Default::default()
        },
        ..Default::default()
    };
    assert_eq!(rig.reference_camera, 0);
    assert!(!rig.covariance);
    let ba = BundleAdjustmentOptions {
        gauge: Gauge::Similarity {
            reference_image: 0,
            scale_image: 4,
        },
        ..Default::default()
    };
    assert!(!ba.optimize_intrinsics);
    assert_eq!(
        SolverOptions::default().min_reciprocal_condition_number,
        1e-14
    );
}
