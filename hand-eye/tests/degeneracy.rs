//! What the motions cannot determine is reported, never returned as a number; invalid input is
//! an error, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::translation_error;
use common::{CAMERA_NOISE, Mount, ROBOT_NOISE, opencv_pose, percentile, perturb, planar, rng};
use ibc_hand_eye::{
    DaniilidisOptions, HandEyeError, MotionPair, MotionScreening, Pairing, PlanarOptions, Sensor,
    TrajectoryOptions, daniilidis, guo_planar, refine_trajectories, relative_motions,
};
use nalgebra::{Isometry3, Vector3};
use proptest::prelude::*;
use rand::RngExt;

/// Planar motion (a vehicle) given to Daniilidis: with and without noise, every trial reports
/// parallel rotation axes and names the axis, the odometry's z axis seen from the rig.
#[test]
fn daniilidis_reports_planar_motion() {
    let mut r = rng(30);
    let mut figures = Vec::new();
    for trial in 0..400 {
        let noise = trial % 2 == 0;
        let poses = if trial % 4 < 2 { 10 } else { 30 };
        let sim = planar(&mut r, poses, noise, 1.0, Mount::Forward);
        let pairs =
            relative_motions(&sim.world_from_rig, &sim.world_from_odometry, Pairing::All).unwrap();
        match daniilidis(&pairs, &DaniilidisOptions::default()) {
            Err(HandEyeError::ParallelRotationAxes {
                axis_a,
                signal_to_noise,
                ..
            }) => {
                let expected = sim.rig_from_odometry.rotation * Vector3::z();
                assert!(
                    axis_a.cross(&expected).norm() < 0.01,
                    "axis {axis_a:?} vs {expected:?}"
                );
                if noise {
                    figures.push(signal_to_noise);
                }
            }
            other => panic!("trial {trial}: planar motion not reported: {other:?}"),
        }
    }
    eprintln!(
        "signal-to-noise of planar motion with noise: median {:.2}, max {:.2} (threshold {})",
        percentile(&figures, 50.0),
        percentile(&figures, 100.0),
        ibc_hand_eye::DEFAULT_MIN_SIGNAL_TO_NOISE
    );
}

/// Ten consecutive motions rotating 0.5 to 3 degrees each, OpenCV's noise. By default every
/// trial ends in an error (the 2-degree filter leaves too few motions, or the singular values
/// say the translation is lost in the noise). Forced through (no filter, no threshold), the
/// estimate is off by decimetres, and its predicted standard deviation says so.
#[test]
fn small_rotations_are_flagged() {
    let deg = std::f64::consts::PI / 180.0;
    let mut r = rng(31);
    let (mut errors, mut stds, mut refused) = (Vec::new(), Vec::new(), 0);
    let trials = 300;
    for _ in 0..trials {
        let rig_from_odometry = opencv_pose(&mut r, (10.0 * deg, 50.0 * deg), (0.05, 0.5));
        let mut odometry = vec![Isometry3::identity()];
        for _ in 0..10 {
            let axis = Vector3::from_fn(|_, _| r.random_range(-1.0..1.0f64)).normalize();
            let angle = r.random_range(0.5..3.0) * deg;
            let step = Vector3::from_fn(|_, _| r.random_range(-0.5..0.5f64));
            let last = odometry[odometry.len() - 1];
            odometry.push(last * Isometry3::new(step, axis * angle));
        }
        let rig: Vec<_> = odometry
            .iter()
            .map(|o| {
                perturb(
                    &mut r,
                    &(o * rig_from_odometry.inverse()).inverse(),
                    CAMERA_NOISE,
                )
                .inverse()
            })
            .collect();
        let odometry: Vec<_> = odometry
            .iter()
            .map(|o| perturb(&mut r, o, ROBOT_NOISE))
            .collect();
        let pairs = relative_motions(&rig, &odometry, Pairing::Consecutive).unwrap();
        match daniilidis(&pairs, &DaniilidisOptions::default()) {
            Err(
                HandEyeError::Degenerate { .. }
                | HandEyeError::TooFewMotions { .. }
                | HandEyeError::NoRotation { .. },
            ) => refused += 1,
            Ok(solution) => assert!(solution.uncertainty.translation_std.norm() > 0.05),
            Err(other) => panic!("unexpected {other}"),
        }
        let forced = DaniilidisOptions {
            screening: MotionScreening::new(0.0, 3.0),
            min_signal_to_noise: 0.0,
            ..Default::default()
        };
        let solution = daniilidis(&pairs, &forced).unwrap();
        errors.push(translation_error(&solution.a_from_b, &rig_from_odometry));
        stds.push(solution.uncertainty.translation_std.norm());
    }
    let (median_error, median_std) = (percentile(&errors, 50.0), percentile(&stds, 50.0));
    eprintln!(
        "small rotations: {refused}/{trials} refused by default; forced: median error {:.0} mm, median predicted std {:.0} mm, smallest predicted std {:.0} mm",
        median_error * 1e3,
        median_std * 1e3,
        percentile(&stds, 0.0) * 1e3
    );
    assert!(refused >= trials * 9 / 10);
    assert!(
        median_error > 0.1,
        "small rotations should not determine the translation"
    );
    assert!(percentile(&stds, 0.0) > 0.05);
    assert!((0.5..2.0).contains(&(median_error / median_std)));
}

fn pair(t: [f64; 3], r: [f64; 3]) -> MotionPair {
    let m = Isometry3::new(Vector3::from(t), Vector3::from(r));
    MotionPair::new(m, m)
}

#[test]
fn invalid_and_insufficient_input_is_an_error() {
    let default = DaniilidisOptions::default();
    let planar_options = PlanarOptions::default();
    let good = [
        pair([1.0, 0.0, 0.0], [0.3, 0.0, 0.0]),
        pair([0.0, 1.0, 0.0], [0.0, 0.4, 0.1]),
    ];

    // No motion, one motion.
    assert!(matches!(
        daniilidis(&[], &default),
        Err(HandEyeError::NoRotation { .. })
    ));
    assert!(matches!(
        daniilidis(&good[..1], &default),
        Err(HandEyeError::TooFewMotions {
            usable: 1,
            needed: 2,
            ..
        })
    ));
    assert!(matches!(
        guo_planar(&[], &planar_options),
        Err(HandEyeError::TooFewMotions { .. })
    ));

    // Pure translations: no rotation at all.
    let translations = [
        pair([1.0, 0.0, 0.0], [0.0; 3]),
        pair([0.0, 2.0, 0.0], [0.0; 3]),
    ];
    for result in [
        daniilidis(&translations, &default).map(|s| s.a_from_b),
        guo_planar(&translations, &planar_options).map(|s| s.a_from_b),
    ] {
        assert!(
            matches!(result, Err(HandEyeError::NoRotation { largest_rotation, .. }) if largest_rotation == 0.0)
        );
    }

    // Non-finite values.
    let mut bad = good;
    bad[1].b.translation.vector.z = f64::INFINITY;
    let expected = Err(HandEyeError::NonFinite {
        index: 1,
        sensor: Sensor::B,
    });
    assert_eq!(daniilidis(&bad, &default).map(|s| s.a_from_b), expected);
    assert_eq!(
        guo_planar(&bad, &planar_options).map(|s| s.a_from_b),
        expected
    );

    // Mismatched trajectories.
    let poses = [Isometry3::identity(); 3];
    assert_eq!(
        refine_trajectories(
            &poses,
            &poses[..2],
            &Isometry3::identity(),
            &TrajectoryOptions::default()
        ),
        Err(HandEyeError::MismatchedLengths { a: 3, b: 2 })
    );

    // Sensor b leaving the plane.
    let tilted = [
        pair([1.0, 0.0, 0.0], [0.3, 0.0, 0.0]),
        pair([0.0, 1.0, 0.0], [0.0, 0.0, 0.4]),
    ];
    assert!(matches!(
        guo_planar(&tilted, &planar_options),
        Err(HandEyeError::NotPlanar { index: Some(0), .. })
    ));

    // Options outside their domain.
    let options = DaniilidisOptions {
        screening: MotionScreening::new(1.0, 0.5),
        ..Default::default()
    };
    assert!(matches!(
        daniilidis(&good, &options),
        Err(HandEyeError::InvalidOptions { .. })
    ));
    let options = PlanarOptions {
        height_prior: Some(f64::NAN),
        ..Default::default()
    };
    assert!(matches!(
        guo_planar(&good, &options),
        Err(HandEyeError::InvalidOptions { .. })
    ));
}

/// Motions of two unrelated sensors, forced through the degeneracy test: the dual-quaternion
/// constraint `q·q' = 0` often has no real root in the null space, and Daniilidis says so. The
/// planar roll-pitch constraint always has one (its null space is invariant under `q ↦ k ⊗ q`,
/// see `guo_planar`), whatever the data.
#[test]
fn inconsistent_motions_give_negative_discriminants() {
    let mut r = rng(32);
    let (mut daniilidis_count, mut planar_count) = (0, 0);
    for _ in 0..200 {
        let pairs: Vec<_> = (0..4)
            .map(|_| {
                let a = opencv_pose(&mut r, (0.3, 1.5), (0.5, 1.5));
                let yaw = r.random_range(0.3..1.5);
                let b = Isometry3::new(
                    Vector3::new(r.random_range(-1.0..1.0), 0.5, 0.0),
                    Vector3::z() * yaw,
                );
                MotionPair::new(a, b)
            })
            .collect();
        let options = DaniilidisOptions {
            min_signal_to_noise: 0.0,
            ..Default::default()
        };
        if let Err(HandEyeError::NegativeDiscriminant { .. }) = daniilidis(&pairs, &options) {
            daniilidis_count += 1;
        }
        let options = PlanarOptions {
            min_signal_to_noise: 0.0,
            ..Default::default()
        };
        if let Err(HandEyeError::NegativeDiscriminant { .. }) = guo_planar(&pairs, &options) {
            planar_count += 1;
        }
    }
    eprintln!(
        "negative discriminants in 200 inconsistent sets: Daniilidis {daniilidis_count}, planar {planar_count}"
    );
    assert!(daniilidis_count > 0);
    assert_eq!(planar_count, 0);
}

fn isometry() -> impl Strategy<Value = Isometry3<f64>> {
    (
        prop::array::uniform3(-10.0f64..10.0),
        prop::array::uniform3(-4.0f64..4.0),
    )
        .prop_map(|(t, r)| Isometry3::new(Vector3::from(t), Vector3::from(r)))
}

fn planar_isometry() -> impl Strategy<Value = Isometry3<f64>> {
    (-10.0f64..10.0, -10.0f64..10.0, -4.0f64..4.0)
        .prop_map(|(x, y, yaw)| Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw))
}

proptest! {
    #![proptest_config(common::proptest_config())]

    /// Arbitrary (mostly inconsistent) input never panics, and every answer is finite.
    #[test]
    fn arbitrary_input_never_panics(
        a in prop::collection::vec(isometry(), 0..8),
        b in prop::collection::vec(planar_isometry(), 0..8),
        c in prop::collection::vec(isometry(), 0..8),
    ) {
        let n = a.len().min(b.len()).min(c.len());
        let planar_pairs: Vec<_> = (0..n).map(|k| MotionPair::new(a[k], b[k])).collect();
        let general_pairs: Vec<_> = (0..n).map(|k| MotionPair::new(a[k], c[k])).collect();
        let finite = |x: &Isometry3<f64>| x.translation.vector.iter().chain(x.rotation.coords.iter()).all(|v| v.is_finite());
        for pairs in [&planar_pairs, &general_pairs] {
            if let Ok(s) = daniilidis(pairs, &DaniilidisOptions::default()) {
                prop_assert!(finite(&s.a_from_b));
            }
            if let Ok(s) = guo_planar(pairs, &PlanarOptions::default()) {
                prop_assert!(finite(&s.a_from_b) && s.scale.is_finite());
            }
        }
        let start = a.first().copied().unwrap_or_else(Isometry3::identity);
        if let Ok(fit) = refine_trajectories(&a[..n], &c[..n], &start, &TrajectoryOptions::default()) {
            prop_assert!(finite(&fit.a_from_b) && finite(&fit.world_a_from_world_b));
        }
        if let Ok(fit) = refine_trajectories(&a[..n], &b[..n], &start, &TrajectoryOptions::planar(true, 1.0)) {
            prop_assert!(finite(&fit.a_from_b) && fit.scale.is_finite());
        }
    }
}
