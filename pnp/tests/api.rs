//! The crate as a caller outside it writes it: every options struct in one expression with
//! `..Default::default()`, the documented defaults, and the pixel-level entry point.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use ibc_camera_models::{CameraModel, PinholeRadtan};
use ibc_pnp::nalgebra::{Isometry3, Point3, Vector2, Vector3};
use ibc_pnp::{
    AbsolutePose, AbsolutePoseOptions, DEFAULT_MAX_ERROR_PX, DEFAULT_MIN_INLIERS,
    DEFAULT_THRESHOLD, EpnpOptions, PnpError, RansacOptions, RefineOptions, RobustLoss,
    absolute_pose,
};

#[test]
fn every_options_struct_is_one_expression() {
    let epnp = EpnpOptions {
        depth_reweighting: false,
        ..Default::default()
    };
    let refine = RefineOptions {
        max_iterations: 20,
        loss: RobustLoss::SoftL1 { scale: 1e-3 },
        step_tolerance: 1e-10,
        cost_tolerance: 1e-12,
        ..Default::default()
    };
    let ransac = RansacOptions {
        threshold: 2e-3,
        confidence: 0.99,
        min_iterations: 10,
        max_iterations: 1_000,
        min_inliers: 12,
        local_optimization: false,
        final_refinement: true,
        refine: refine.clone(),
        seed: 3,
        ..Default::default()
    };
    let options = AbsolutePoseOptions {
        ransac: ransac.clone(),
        max_error_px: 1.5,
        ..Default::default()
    };
    assert!(!epnp.depth_reweighting);
    assert_eq!(refine.loss, RobustLoss::SoftL1 { scale: 1e-3 });
    assert_eq!(ransac.seed, 3);
    assert_eq!(options.ransac, ransac);
    assert_eq!(options.max_error_px, 1.5);
    // Struct update from another value, not only from the default.
    let again = RansacOptions {
        seed: 4,
        ..ransac.clone()
    };
    assert_eq!(again.min_inliers, 12);
}

#[test]
fn defaults_are_the_documented_ones() {
    assert!(EpnpOptions::default().depth_reweighting);
    let refine = RefineOptions::default();
    assert_eq!(refine.max_iterations, 50);
    assert_eq!(refine.loss, RobustLoss::Trivial);
    assert_eq!(refine.step_tolerance, 1e-12);
    assert_eq!(refine.cost_tolerance, 1e-14);
    let ransac = RansacOptions::default();
    assert_eq!(ransac.threshold, DEFAULT_THRESHOLD);
    assert_eq!(ransac.confidence, 0.999);
    assert_eq!(ransac.min_iterations, 50);
    assert_eq!(ransac.max_iterations, 10_000);
    assert_eq!(ransac.min_inliers, DEFAULT_MIN_INLIERS);
    assert!(ransac.local_optimization && ransac.final_refinement);
    assert_eq!(ransac.refine, refine);
    assert_eq!(ransac.seed, 0);
    let options = AbsolutePoseOptions::default();
    assert_eq!(options.ransac, ransac);
    assert_eq!(options.max_error_px, DEFAULT_MAX_ERROR_PX);
    assert_eq!(DEFAULT_MAX_ERROR_PX, 2.0);
    assert_eq!(RobustLoss::default(), RobustLoss::Trivial);
}

/// What a robotics user writes: a camera, detected pixels, map points, one call.
fn localize(
    camera: &impl CameraModel,
    pixels: &[Vector2<f64>],
    map: &[Point3<f64>],
) -> Result<AbsolutePose, PnpError> {
    let options = AbsolutePoseOptions {
        max_error_px: 1.5,
        ..Default::default()
    };
    absolute_pose(camera, pixels, map, &options)
}

#[test]
fn absolute_pose_as_a_user_calls_it() {
    let camera =
        PinholeRadtan::new(640, 480, [-0.1, 0.01, 0.0, 0.0, 600.0, 600.0, 320.0, 240.0]).unwrap();
    let camera_from_world =
        Isometry3::new(Vector3::new(0.3, -0.1, 6.0), Vector3::new(0.1, -0.2, 0.05));
    let map: Vec<Point3<f64>> = (0..60)
        .map(|i| {
            Point3::new(
                (i % 10) as f64 * 0.4 - 2.0,
                (i / 10) as f64 * 0.5 - 1.5,
                ((i * 7) % 5) as f64 * 0.3,
            )
        })
        .collect();
    let pixels: Vec<Vector2<f64>> = map
        .iter()
        .map(|x| camera.project(&(camera_from_world * x).coords).unwrap())
        .collect();
    let pose = localize(&camera, &pixels, &map).unwrap();
    assert_eq!(pose.inliers, (0..60).collect::<Vec<_>>());
    assert_eq!(pose.unprojection_failures, 0);
    assert!(pose.iterations >= 50);
    assert!(pose.inlier_rms < 1e-9);
    assert!(
        pose.camera_from_world
            .rotation
            .angle_to(&camera_from_world.rotation)
            < 1e-9
    );
    // 1.5 px at the principal point of a 600 px focal length (the distortion changes the
    // angle by about 1e-9 rad within 1.5 px of the centre).
    assert!((pose.threshold - (1.5f64 / 600.0).atan()).abs() < 1e-8);
}

/// The two-view options of issue 16, written as a caller outside the crate writes them.
#[test]
fn two_view_options_are_one_expression() {
    use ibc_pnp::{
        RELATIVE_POSE_MAX_ITERATIONS, RELATIVE_POSE_MIN_PARALLAX, RelativePoseOptions,
        TRIANGULATION_MIN_PARALLAX, TriangulationOptions,
    };
    let defaults = RelativePoseOptions::default();
    assert_eq!(defaults.ransac.max_iterations, RELATIVE_POSE_MAX_ITERATIONS);
    assert_eq!(defaults.min_parallax, RELATIVE_POSE_MIN_PARALLAX);
    assert!(defaults.model_selection);
    let relative = RelativePoseOptions {
        ransac: RansacOptions {
            threshold: 1e-3,
            seed: 9,
            ..defaults.ransac.clone()
        },
        model_selection: false,
        ..defaults
    };
    assert_eq!(relative.ransac.max_iterations, RELATIVE_POSE_MAX_ITERATIONS);
    assert_eq!(relative.ransac.seed, 9);
    let triangulation = TriangulationOptions {
        min_parallax: 2f64.to_radians(),
        max_iterations: 5,
        ..Default::default()
    };
    assert!(triangulation.refine);
    assert_eq!(
        TriangulationOptions::default().min_parallax,
        TRIANGULATION_MIN_PARALLAX
    );
}
