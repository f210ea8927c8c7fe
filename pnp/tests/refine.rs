//! Pose refinement: convergence from far starts, rays beyond 90 degrees, robust losses,
//! information weighting, invalid options.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod common;

use common::*;
use ibc_pnp::{
    PnpError, RefineOptions, RobustLoss, angle_from_pixels, epnp, pinhole_information, refine_pose,
    refine_pose_weighted,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The truth moved by about `angle` radians and `shift` metres in random directions.
fn perturbed(
    rng: &mut ChaCha8Rng,
    truth: &Isometry3<f64>,
    angle: f64,
    shift: f64,
) -> Isometry3<f64> {
    let axis = direction_in_cap(rng, std::f64::consts::PI);
    let offset = direction_in_cap(rng, std::f64::consts::PI) * shift;
    Isometry3::from_parts(
        Translation3::from(offset),
        UnitQuaternion::from_scaled_axis(axis * angle),
    ) * truth
}

#[test]
fn converges_to_the_exact_pose_from_far_starts() {
    let mut rng = ChaCha8Rng::seed_from_u64(30);
    for trial in 0..200 {
        let s = if trial % 2 == 0 {
            pinhole_scene(&mut rng, 20, 0.0)
        } else {
            // Rays up to 95 degrees from the axis.
            wide_scene(&mut rng, 20, 190f64.to_radians(), 0.0)
        };
        let start = perturbed(&mut rng, &s.camera_from_world, 0.2, 0.5);
        let refined =
            refine_pose(&s.bearings, &s.points, &start, &RefineOptions::default()).unwrap();
        let rotation = rotation_error_deg(&refined.camera_from_world, &s.camera_from_world);
        let translation = translation_error(&refined.camera_from_world, &s.camera_from_world);
        assert!(
            rotation.to_radians() <= 1e-10,
            "trial {trial}: {rotation:e} deg"
        );
        assert!(translation <= 1e-9, "trial {trial}: {translation:e} m");
        assert!(refined.final_cost <= refined.initial_cost);
        assert!(refined.final_cost <= 1e-20);
    }
}

#[test]
fn rays_behind_the_image_plane_are_refined() {
    // All rays between 100 and 180 degrees from the optical axis (z < 0): a residual on
    // x / z would be undefined here.
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    for _ in 0..100 {
        let mut s = wide_scene(&mut rng, 15, 160f64.to_radians(), 1.0 / FOCAL);
        let flip = Isometry3::rotation(Vector3::x() * std::f64::consts::PI);
        for f in &mut s.bearings {
            *f = flip * *f;
        }
        s.camera_from_world = flip * s.camera_from_world;
        let start = perturbed(&mut rng, &s.camera_from_world, 0.05, 0.1);
        let refined =
            refine_pose(&s.bearings, &s.points, &start, &RefineOptions::default()).unwrap();
        assert!(rotation_error_deg(&refined.camera_from_world, &s.camera_from_world) < 0.5);
        assert!(refined.final_cost < refined.initial_cost);
    }
}

#[test]
fn robust_losses_resist_gross_outliers() {
    let mut rng = ChaCha8Rng::seed_from_u64(32);
    let scale = angle_from_pixels(2.0, FOCAL).unwrap();
    let (mut plain, mut huber, mut cauchy, mut clean) = (vec![], vec![], vec![], vec![]);
    for _ in 0..100 {
        let mut s = pinhole_scene(&mut rng, 100, 1.0);
        let start = epnp(&s.bearings, &s.points).unwrap();
        let reference =
            refine_pose(&s.bearings, &s.points, &start, &RefineOptions::default()).unwrap();
        clean.push(rotation_error_deg(
            &reference.camera_from_world,
            &s.camera_from_world,
        ));
        // 20 % of the bearings replaced by random pixels.
        for f in s.bearings.iter_mut().take(20) {
            *f = bearing_of_pixel(rng.random_range(0.0..640.0), rng.random_range(0.0..480.0));
        }
        for (loss, out) in [
            (RobustLoss::Trivial, &mut plain),
            (RobustLoss::Huber { scale }, &mut huber),
            (RobustLoss::Cauchy { scale }, &mut cauchy),
        ] {
            let options = RefineOptions {
                loss,
                ..Default::default()
            };
            let refined = refine_pose(&s.bearings, &s.points, &start, &options).unwrap();
            out.push(rotation_error_deg(
                &refined.camera_from_world,
                &s.camera_from_world,
            ));
        }
    }
    let (plain, huber, cauchy, clean) = (
        median(&plain),
        median(&huber),
        median(&cauchy),
        median(&clean),
    );
    println!(
        "median rotation error: clean {clean:.4}, squared {plain:.4}, Huber {huber:.4}, Cauchy {cauchy:.4}"
    );
    assert!(plain > 5.0 * clean);
    assert!(huber < 0.5 * plain);
    assert!(cauchy < 1.5 * clean);
}

#[test]
fn pixel_information_weighting_is_the_pinhole_maximum_likelihood() {
    // With pinhole information the cost is exactly the squared pixel error to first order:
    // at the optimum its value is that of pixel-space least squares, about 2 (n - 3) sigma^2.
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let mut costs = Vec::new();
    for _ in 0..300 {
        let s = pinhole_scene(&mut rng, 50, 1.0);
        let start = epnp(&s.bearings, &s.points).unwrap();
        let information: Vec<_> = s
            .bearings
            .iter()
            .map(|f| pinhole_information(f, FOCAL))
            .collect();
        let refined = refine_pose_weighted(
            &s.bearings,
            &s.points,
            &information,
            &start,
            &RefineOptions::default(),
        )
        .unwrap();
        costs.push(refined.final_cost);
    }
    let mean = costs.iter().sum::<f64>() / costs.len() as f64;
    // Chi-square with 2 n - 6 = 94 degrees of freedom.
    println!("mean weighted cost {mean:.2} (expected 94)");
    assert!((mean - 94.0).abs() < 3.0);
}

#[test]
fn invalid_options_and_input_are_typed_errors() {
    let mut rng = ChaCha8Rng::seed_from_u64(34);
    let s = pinhole_scene(&mut rng, 10, 0.0);
    let start = s.camera_from_world;
    for loss in [
        RobustLoss::Huber { scale: 0.0 },
        RobustLoss::Cauchy { scale: -1.0 },
        RobustLoss::Cauchy { scale: f64::NAN },
    ] {
        let options = RefineOptions {
            loss,
            ..Default::default()
        };
        assert!(matches!(
            refine_pose(&s.bearings, &s.points, &start, &options),
            Err(PnpError::InvalidLossScale { .. })
        ));
    }
    let options = RefineOptions {
        step_tolerance: -1.0,
        ..Default::default()
    };
    assert!(matches!(
        refine_pose(&s.bearings, &s.points, &start, &options),
        Err(PnpError::InvalidOption {
            name: "step_tolerance",
            ..
        })
    ));
    let options = RefineOptions::default();
    assert!(matches!(
        refine_pose(&s.bearings[..2], &s.points[..2], &start, &options),
        Err(PnpError::NotEnoughPoints {
            needed: 3,
            got: 2,
            ..
        })
    ));
    assert!(matches!(
        refine_pose(&s.bearings, &s.points[..9], &start, &options),
        Err(PnpError::LengthMismatch {
            bearings: 10,
            points: 9
        })
    ));
    let information = vec![nalgebra::Matrix3::identity(); 9];
    assert!(matches!(
        refine_pose_weighted(&s.bearings, &s.points, &information, &start, &options),
        Err(PnpError::InvalidOption {
            name: "information",
            ..
        })
    ));
    let mut information = vec![nalgebra::Matrix3::identity(); 10];
    information[4][(1, 1)] = f64::NAN;
    assert!(matches!(
        refine_pose_weighted(&s.bearings, &s.points, &information, &start, &options),
        Err(PnpError::InvalidOption {
            name: "information",
            ..
        })
    ));
    let bad = Isometry3::from_parts(
        Translation3::new(f64::NAN, 0.0, 0.0),
        UnitQuaternion::identity(),
    );
    assert!(matches!(
        refine_pose(&s.bearings, &s.points, &bad, &options),
        Err(PnpError::InvalidOption {
            name: "initial",
            ..
        })
    ));
    // A start that puts a point at the camera centre still refines (that point's error is
    // the largest possible, 180 degrees, and it has no gradient).
    let mut at_centre = s.camera_from_world;
    at_centre.translation.vector -= (s.camera_from_world * s.points[0]).coords;
    assert!(refine_pose(&s.bearings, &s.points, &at_centre, &options).is_ok());
}
