//! Full bundle adjustment with camera models: poses and points, and intrinsics when asked.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::{
    BaObservation, BundleAdjustment, BundleAdjustmentOptions, RobustLoss, SolverOptions,
};
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, PinholeRadtan};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Two cameras (pinhole and fisheye), `images` images each on a circle around a point cloud.
fn scene(seed: u64, images: usize, points: usize) -> BundleAdjustment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let cameras: Vec<Camera> = vec![
        PinholeRadtan::new(
            752,
            480,
            [-0.28, 0.07, 1e-4, -2e-4, 460.0, 458.0, 370.0, 245.0],
        )
        .unwrap()
        .into(),
        KannalaBrandt::new(
            1280,
            800,
            [0.01, -0.002, 0.0005, -0.0001, 350.0, 350.0, 640.0, 400.0],
        )
        .unwrap()
        .into(),
    ];
    let mut camera_from_world = Vec::new();
    let mut image_camera = Vec::new();
    for i in 0..2 * images {
        let a = i as f64 * std::f64::consts::TAU / (2 * images) as f64;
        let center = Vector3::new(8.0 * a.cos(), rng.random_range(-0.5..0.5), 8.0 * a.sin());
        let world_from_camera =
            Isometry3::face_towards(&Point3::from(center), &Point3::origin(), &Vector3::y());
        camera_from_world.push(world_from_camera.inverse());
        image_camera.push(i % 2);
    }
    let pts: Vec<Vector3<f64>> = (0..points)
        .map(|_| {
            Vector3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            )
        })
        .collect();
    let mut observations = Vec::new();
    for (i, pose) in camera_from_world.iter().enumerate() {
        let cam = &cameras[image_camera[i]];
        for (j, x) in pts.iter().enumerate() {
            if let Ok(px) = cam.project(&(pose * Point3::from(*x)).coords)
                && cam.in_image(&px)
                && rng.random_range(0.0..1.0) < 0.6
            {
                observations.push(BaObservation {
                    image: i,
                    point: j,
                    pixel: px,
                });
            }
        }
    }
    BundleAdjustment {
        cameras,
        image_camera,
        camera_from_world,
        points: pts,
        observations,
    }
}

fn perturbed(truth: &BundleAdjustment, seed: u64, intrinsics: bool) -> BundleAdjustment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = truth.clone();
    for pose in s.camera_from_world.iter_mut().skip(2) {
        let w = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * 0.01;
        let t = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * 0.05;
        *pose = Isometry3::from_parts(
            Translation3::from(pose.translation.vector + t),
            pose.rotation * UnitQuaternion::from_scaled_axis(w),
        );
    }
    for x in &mut s.points {
        *x += Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * 0.03;
    }
    if intrinsics {
        for c in &mut s.cameras {
            let mut p = c.params().to_vec();
            let n = p.len();
            // Focal lengths +1.5 %, principal point 3 px off.
            p[n - 4] *= 1.015;
            p[n - 3] *= 1.015;
            p[n - 2] += 3.0;
            p[n - 1] -= 3.0;
            c.set_params(&p).unwrap();
        }
    }
    s
}

fn options(intrinsics: bool) -> BundleAdjustmentOptions {
    BundleAdjustmentOptions {
        optimize_intrinsics: intrinsics,
        // Two fixed images remove the whole similarity gauge.
        fixed_images: vec![0, 1],
        loss: RobustLoss::Trivial,
        solver: SolverOptions {
            function_tolerance: 1e-12,
            parameter_tolerance: 1e-12,
            max_iterations: 100,
            ..Default::default()
        },
        ..Default::default()
    }
}

#[test]
fn poses_and_points_are_recovered() {
    let truth = scene(1, 8, 150);
    let start = perturbed(&truth, 2, false);
    let r = start.solve(&options(false)).unwrap();
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );
    assert!(r.initial_rms > 1.0);
    assert!(r.final_rms < 1e-6, "{}", r.final_rms);
    for (e, t) in r.points.iter().zip(&truth.points) {
        assert!((e - t).norm() < 1e-6);
    }
}

#[test]
fn intrinsics_are_refined_when_asked() {
    let truth = scene(3, 8, 150);
    let start = perturbed(&truth, 4, true);
    // Without refining the intrinsics the wrong focal lengths leave an error.
    let fixed = start.solve(&options(false)).unwrap();
    assert!(fixed.final_rms > 0.05, "{}", fixed.final_rms);
    let refined = start.solve(&options(true)).unwrap();
    assert!(
        refined.summary.termination.is_converged(),
        "{}",
        refined.summary.report()
    );
    assert!(refined.final_rms < 1e-6, "{}", refined.final_rms);
    for (e, t) in refined.cameras.iter().zip(&truth.cameras) {
        for (a, b) in e.params().iter().zip(t.params()) {
            assert!((a - b).abs() < 1e-6 * (1.0 + b.abs()), "{a} vs {b}");
        }
    }
}

#[test]
fn bad_scenes_are_rejected() {
    let truth = scene(5, 3, 20);
    let mut bad = truth.clone();
    bad.observations[0].point = 1000;
    assert!(bad.solve(&options(false)).is_err());
    let mut bad = truth.clone();
    bad.image_camera[0] = 5;
    assert!(bad.solve(&options(false)).is_err());
    let mut bad = truth.clone();
    bad.observations[0].pixel = Vector2::new(f64::NAN, 0.0);
    assert!(bad.solve(&options(false)).is_err());
    let o = BundleAdjustmentOptions {
        fixed_images: vec![99],
        ..options(false)
    };
    assert!(truth.solve(&o).is_err());
}

#[test]
fn an_observation_behind_its_camera_at_the_start_is_left_out() {
    let truth = scene(7, 8, 100);
    let start = perturbed(&truth, 8, false);
    // A new point behind image 2 (a pinhole camera) but in front of images across the circle.
    let centre = truth.camera_from_world[2].inverse().translation.vector;
    let x = centre * 1.3;
    let mut bad = start.clone();
    bad.points.push(x);
    let point = bad.points.len() - 1;
    let first = bad.observations.len();
    for (i, pose) in truth.camera_from_world.iter().enumerate() {
        let cam = &truth.cameras[truth.image_camera[i]];
        if let Ok(px) = cam.project(&(pose * Point3::from(x)).coords)
            && cam.in_image(&px)
        {
            bad.observations.push(BaObservation {
                image: i,
                point,
                pixel: px,
            });
        }
    }
    assert!(bad.observations.len() - first >= 2);
    bad.observations.push(BaObservation {
        image: 2,
        point,
        pixel: Vector2::new(300.0, 200.0),
    });
    let result = bad.solve(&options(false)).unwrap();
    assert_eq!(
        result.excluded_observations,
        vec![bad.observations.len() - 1]
    );
    assert!(result.final_rms < 1e-6, "{}", result.final_rms);
    // The same solution as without that observation.
    let mut without = bad.clone();
    without.observations.pop();
    let reference = without.solve(&options(false)).unwrap();
    assert!(reference.excluded_observations.is_empty());
    for (a, b) in result.points.iter().zip(&reference.points) {
        assert!((a - b).norm() < 1e-12);
    }
    assert_eq!(
        result.summary.final_cost.to_bits(),
        reference.summary.final_cost.to_bits()
    );
    // A point seen only from behind is left out with its observation, and counted; the rest
    // of the scene is adjusted as without it (defect 3 of issue 16: it aborted the solve).
    let mut bad = start.clone();
    bad.points.push(x);
    bad.observations.push(BaObservation {
        image: 2,
        point: bad.points.len() - 1,
        pixel: Vector2::new(300.0, 200.0),
    });
    let result = bad.solve(&options(false)).unwrap();
    assert_eq!(result.excluded_points, vec![bad.points.len() - 1]);
    assert_eq!(
        result.excluded_observations,
        vec![bad.observations.len() - 1]
    );
    assert_eq!(result.points[bad.points.len() - 1], x);
    assert!(result.final_rms < 1e-6, "{}", result.final_rms);
    let reference = start.solve(&options(false)).unwrap();
    assert!(reference.excluded_points.is_empty());
    assert_eq!(
        result.summary.final_cost.to_bits(),
        reference.summary.final_cost.to_bits()
    );
    for (a, b) in result.points.iter().zip(&reference.points) {
        assert_eq!(a, b);
    }
    // A point no observation refers to is a mistake of the caller, named.
    let mut bad = start.clone();
    bad.points.push(x);
    assert_eq!(
        bad.solve(&options(false)).unwrap_err(),
        ibc_bundle_adjust::BundleAdjustError::PointWithoutObservations {
            point: bad.points.len() - 1,
            excluded: 0
        }
    );
}
