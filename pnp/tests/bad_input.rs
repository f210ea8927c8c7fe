//! Bad input gives typed errors, never a panic: too few points, mismatched lengths, collinear
//! or coincident world points, identical bearings, NaN, non-unit bearings; and proptest
//! checks that arbitrary input never panics while random valid input is solved exactly.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod common;

use common::*;
use ibc_pnp::{
    Degeneracy, PnpError, RansacOptions, RefineOptions, epnp, p3p, refine_pose, robust_pose,
};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn scene(n: usize) -> Scene {
    pinhole_scene(&mut ChaCha8Rng::seed_from_u64(50), n, 0.0)
}

#[test]
fn too_few_points() {
    let s = scene(3);
    assert_eq!(
        epnp(&s.bearings, &s.points).unwrap_err(),
        PnpError::NotEnoughPoints {
            solver: "EPnP",
            needed: 4,
            got: 3
        }
    );
    assert!(matches!(
        epnp(&[], &[]),
        Err(PnpError::NotEnoughPoints { got: 0, .. })
    ));
    let pose = s.camera_from_world;
    assert!(matches!(
        refine_pose(
            &s.bearings[..2],
            &s.points[..2],
            &pose,
            &RefineOptions::default()
        ),
        Err(PnpError::NotEnoughPoints { needed: 3, .. })
    ));
    assert!(matches!(
        robust_pose(&[], &[], &RansacOptions::default()),
        Err(PnpError::NotEnoughPoints { needed: 3, .. })
    ));
}

#[test]
fn mismatched_lengths() {
    let s = scene(10);
    assert_eq!(
        epnp(&s.bearings, &s.points[..8]).unwrap_err(),
        PnpError::LengthMismatch {
            bearings: 10,
            points: 8
        }
    );
    assert!(matches!(
        robust_pose(&s.bearings[..9], &s.points, &RansacOptions::default()),
        Err(PnpError::LengthMismatch { .. })
    ));
}

#[test]
fn collinear_and_coincident_world_points() {
    let s = scene(10);
    let line: Vec<Point3<f64>> = (0..10)
        .map(|i| Point3::new(1.0, 2.0, 3.0) + Vector3::new(1.0, -2.0, 0.5) * i as f64)
        .collect();
    assert_eq!(
        epnp(&s.bearings, &line).unwrap_err(),
        PnpError::Degenerate(Degeneracy::CollinearPoints)
    );
    let same = vec![Point3::new(4.0, -1.0, 7.0); 10];
    assert_eq!(
        epnp(&s.bearings, &same).unwrap_err(),
        PnpError::Degenerate(Degeneracy::CoincidentPoints)
    );
    assert_eq!(
        robust_pose(&s.bearings, &same, &RansacOptions::default()).unwrap_err(),
        PnpError::Degenerate(Degeneracy::CoincidentPoints)
    );
    // Collinear up to round-off at a large offset is still collinear.
    let far_line: Vec<Point3<f64>> = (0..10)
        .map(|i| Point3::new(1e6, 1e6, 1e6) + Vector3::new(1.0, 1.0, 1.0) * (i as f64 * 0.1))
        .collect();
    assert!(matches!(
        epnp(&s.bearings, &far_line),
        Err(PnpError::Degenerate(
            Degeneracy::CollinearPoints | Degeneracy::CoincidentPoints
        ))
    ));
}

#[test]
fn identical_bearings() {
    let s = scene(10);
    let same = vec![s.bearings[0]; 10];
    assert_eq!(
        epnp(&same, &s.points).unwrap_err(),
        PnpError::Degenerate(Degeneracy::ParallelBearings)
    );
    let mut opposite = same.clone();
    for f in opposite.iter_mut().step_by(2) {
        *f = -*f;
    }
    assert_eq!(
        epnp(&opposite, &s.points).unwrap_err(),
        PnpError::Degenerate(Degeneracy::ParallelBearings)
    );
    assert_eq!(
        robust_pose(&same, &s.points, &RansacOptions::default()).unwrap_err(),
        PnpError::Degenerate(Degeneracy::ParallelBearings)
    );
    let y = [s.bearings[0], s.bearings[0], s.bearings[2]];
    let x = [s.points[0], s.points[1], s.points[2]];
    assert!(matches!(
        p3p(&y, &x),
        Err(PnpError::Degenerate(Degeneracy::ParallelPair { .. }))
    ));
}

#[test]
fn non_finite_and_non_unit_values() {
    let s = scene(10);
    let pose = s.camera_from_world;
    let refine = RefineOptions::default();
    let ransac = RansacOptions::default();
    for value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut bearings = s.bearings.clone();
        bearings[3].y = value;
        assert_eq!(
            epnp(&bearings, &s.points).unwrap_err(),
            PnpError::NonFiniteBearing { index: 3 }
        );
        assert_eq!(
            refine_pose(&bearings, &s.points, &pose, &refine).unwrap_err(),
            PnpError::NonFiniteBearing { index: 3 }
        );
        assert_eq!(
            robust_pose(&bearings, &s.points, &ransac).unwrap_err(),
            PnpError::NonFiniteBearing { index: 3 }
        );
        let mut points = s.points.clone();
        points[7].z = value;
        assert_eq!(
            epnp(&s.bearings, &points).unwrap_err(),
            PnpError::NonFinitePoint { index: 7 }
        );
    }
    for scale in [0.0, 0.5, 1.0 + 1e-5, 800.0] {
        let mut bearings = s.bearings.clone();
        bearings[5] *= scale;
        let error = epnp(&bearings, &s.points).unwrap_err();
        assert!(
            matches!(error, PnpError::NonUnitBearing { index: 5, .. }),
            "{error}"
        );
        // The message says what is wrong.
        assert!(error.to_string().contains("unit"));
    }
    // Within the documented tolerance a bearing is accepted.
    let mut bearings = s.bearings.clone();
    bearings[5] *= 1.0 + 1e-8;
    assert!(epnp(&bearings, &s.points).is_ok());
}

#[test]
fn error_messages_name_the_problem() {
    let s = scene(10);
    let message = epnp(&s.bearings, &s.points[..8]).unwrap_err().to_string();
    assert!(message.contains("10") && message.contains('8'), "{message}");
    let message = epnp(&s.bearings[..3], &s.points[..3])
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("EPnP") && message.contains('4'),
        "{message}"
    );
}

fn finite_or_not() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -1e3..1e3f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(0.0),
        1 => -1e300..1e300f64,
    ]
}

fn vector() -> impl Strategy<Value = Vector3<f64>> {
    (finite_or_not(), finite_or_not(), finite_or_not()).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Arbitrary input (unnormalized, normalized, NaN, huge, duplicated) never panics.
    #[test]
    fn arbitrary_input_never_panics(
        raw in prop::collection::vec((vector(), vector()), 0..12),
        normalize in any::<bool>(),
    ) {
        let bearings: Vec<Vector3<f64>> = raw
            .iter()
            .map(|(f, _)| if normalize { f.try_normalize(0.0).unwrap_or(*f) } else { *f })
            .collect();
        let points: Vec<Point3<f64>> = raw.iter().map(|(_, x)| Point3::from(*x)).collect();
        let _ = epnp(&bearings, &points);
        let _ = refine_pose(&bearings, &points, &Isometry3::identity(), &RefineOptions::default());
        let o = RansacOptions { max_iterations: 50, min_iterations: 10, ..Default::default() };
        let _ = robust_pose(&bearings, &points, &o);
        if bearings.len() >= 3 {
            let y = [bearings[0], bearings[1], bearings[2]];
            let x = [points[0], points[1], points[2]];
            let _ = p3p(&y, &x);
        }
    }

    /// Random poses and random points in front of (or anywhere around) the camera: EPnP is
    /// exact and P3P's solutions include the truth.
    #[test]
    fn random_valid_input_is_solved_exactly(
        axis in (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
        angle in 0.0..3.1f64,
        t in (-20.0..20.0f64, -20.0..20.0f64, -20.0..20.0f64),
        raw in prop::collection::vec((-3.0..3.0f64, -3.0..3.0f64, 0.5..10.0f64, any::<bool>()), 6..30),
    ) {
        let axis = Vector3::new(axis.0, axis.1, axis.2);
        prop_assume!(axis.norm() > 1e-3);
        let rotation = UnitQuaternion::from_scaled_axis(axis.normalize() * angle);
        let camera_from_world = Isometry3::from_parts(Translation3::new(t.0, t.1, t.2), rotation);
        let camera: Vec<Point3<f64>> = raw
            .iter()
            .map(|&(x, y, z, behind)| Point3::new(x, y, if behind { -z } else { z }))
            .collect();
        let bearings: Vec<Vector3<f64>> = camera.iter().map(|p| p.coords.normalize()).collect();
        let points: Vec<Point3<f64>> = camera.iter().map(|p| camera_from_world.inverse() * p).collect();
        let pose = epnp(&bearings, &points).unwrap();
        let error = pose.rotation.angle_to(&camera_from_world.rotation);
        prop_assert!(error < 1e-9, "EPnP rotation error {error:e}");
        prop_assert!((pose.translation.vector - camera_from_world.translation.vector).norm() < 1e-8);
        let y = [bearings[0], bearings[1], bearings[2]];
        let x = [points[0], points[1], points[2]];
        if let Ok(solutions) = p3p(&y, &x) {
            let best = solutions
                .iter()
                .map(|p| p.rotation.angle_to(&camera_from_world.rotation))
                .fold(f64::INFINITY, f64::min);
            prop_assert!(best < 1e-8, "P3P misses the truth by {best:e}");
        } else {
            // Only degenerate triples (near-collinear points, parallel rays) may fail.
            let u = x[1] - x[0];
            let v = x[2] - x[0];
            prop_assert!(u.cross(&v).norm() < 1e-6 * u.norm() * v.norm());
        }
    }
}
