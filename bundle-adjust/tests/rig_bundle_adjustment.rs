//! Rig bundle adjustment with free points on a small simulated garage: the car of the
//! pipeline's simulator (four 190-degree Kannala-Brandt fisheyes, 1280x960, front / left /
//! rear / right, lever arms 1-2.3 m, `examples/src/sim/rigs.rs`) driving a rounded loop in a
//! 50 x 24 x 2.6 m box of points (floor, ceiling, walls, pillars); keypoint noise σ = 0.5 px
//! (the simulator's); rays beyond 85 degrees dropped (as for COLMAP in issue 16). The start:
//! extrinsics of the three non-reference cameras 2 degrees / 10 cm off, points 5 cm off, rig
//! poses the truth plus 0.1 degree / 1 cm. The full-size comparison with COLMAP (4 x 500
//! frames, the pipeline's garage) is `examples/tests/rig_bundle_adjust.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::{
    BundleAdjustError, RigBaObservation, RigBundleAdjustment, RigBundleAdjustmentOptions,
    RigBundleAdjustmentResult, ScaleGauge,
};
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const SIGMA_PX: f64 = 0.5;

fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n: f64 = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

fn perturb(pose: &Isometry3<f64>, deg: f64, m: f64, rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    let turn = UnitQuaternion::from_scaled_axis(random_unit(rng) * deg.to_radians());
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + random_unit(rng) * m),
        pose.rotation * turn,
    )
}

/// The simulator's mounting: camera z along azimuth `yaw` tilted down by `pitch`, x right.
fn mount(p: Vector3<f64>, yaw: f64, pitch: f64, roll: f64) -> Isometry3<f64> {
    let forward = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
    ));
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch.to_radians())
        * forward
        * Rotation3::from_axis_angle(&Vector3::z_axis(), roll.to_radians());
    Isometry3::from_parts(
        Translation3::from(p),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

struct World {
    truth_cameras: Vec<Camera>,
    truth_rig_from_camera: Vec<Isometry3<f64>>,
    truth_world_from_rig: Vec<Isometry3<f64>>,
    truth_points: Vec<Vector3<f64>>,
    start: RigBundleAdjustment,
}

/// The car's rig (`examples/src/sim/rigs.rs`, `car_fisheye`).
fn car() -> (Vec<Camera>, Vec<Isometry3<f64>>) {
    let k = [-0.012, 0.0025, -0.0007, 0.00005];
    let cams = [
        (
            Vector3::new(2.30, 0.00, 0.65),
            0.6,
            14.0,
            -0.4,
            396.2,
            395.8,
            642.1,
            478.3,
        ),
        (
            Vector3::new(0.95, 0.98, 1.00),
            90.8,
            30.0,
            0.7,
            394.9,
            395.1,
            637.6,
            481.9,
        ),
        (
            Vector3::new(-2.30, 0.02, 0.90),
            179.4,
            22.0,
            0.3,
            395.5,
            395.3,
            640.8,
            476.4,
        ),
        (
            Vector3::new(0.95, -0.98, 1.00),
            -89.6,
            30.5,
            -0.6,
            396.8,
            396.5,
            643.2,
            482.7,
        ),
    ];
    let mut cameras = Vec::new();
    let mut poses = Vec::new();
    for (i, (p, yaw, pitch, roll, mu, mv, u0, v0)) in cams.into_iter().enumerate() {
        let s = 1.0 + 0.01 * i as f64;
        let params = [k[0] * s, k[1] * s, k[2], k[3], mu, mv, u0, v0];
        cameras.push(Camera::from(KannalaBrandt::new(1280, 960, params).unwrap()));
        poses.push(mount(p, yaw, pitch, roll));
    }
    (cameras, poses)
}

/// Points on the floor, ceiling, walls and pillars of a `length` x 24 x 2.6 m garage.
fn garage_points(length: f64, per_m2: f64, rng: &mut ChaCha8Rng) -> Vec<Vector3<f64>> {
    let (w, h) = (24.0, 2.6);
    let mut pts = Vec::new();
    let mut area =
        |n: f64, f: &mut dyn FnMut(&mut ChaCha8Rng) -> Vector3<f64>, rng: &mut ChaCha8Rng| {
            for _ in 0..(n * per_m2).round() as usize {
                pts.push(f(rng));
            }
        };
    area(
        length * w * 0.5,
        &mut |r| Vector3::new(r.random_range(0.0..length), r.random_range(0.0..w), 0.0),
        rng,
    );
    area(
        length * w * 0.5,
        &mut |r| Vector3::new(r.random_range(0.0..length), r.random_range(0.0..w), h),
        rng,
    );
    for y in [0.0, w] {
        area(
            length * h * 2.0,
            &mut |r| Vector3::new(r.random_range(0.0..length), y, r.random_range(0.0..h)),
            rng,
        );
    }
    for x in [0.0, length] {
        area(
            w * h * 2.0,
            &mut |r| Vector3::new(x, r.random_range(0.0..w), r.random_range(0.0..h)),
            rng,
        );
    }
    // Pillars every 7.5 m along the middle, 0.6 m square, busy with signs.
    let mut x = 7.5;
    while x < length - 5.0 {
        for y in [w / 2.0 - 3.0, w / 2.0 + 3.0] {
            area(
                2.4 * h * 4.0,
                &mut |r| {
                    let s = r.random_range(0.0..2.4);
                    let (dx, dy) = match (s / 0.6) as usize {
                        0 => (s - 0.3, -0.3),
                        1 => (0.3, s - 0.9),
                        2 => (1.5 - s, 0.3),
                        _ => (-0.3, 2.1 - s),
                    };
                    Vector3::new(x + dx, y + dy, r.random_range(0.0..h))
                },
                rng,
            );
        }
        x += 7.5;
    }
    pts
}

/// A world of `frames` rig poses around a rounded loop in a `length` m garage.
fn world(seed: u64, length: f64, frames: usize, per_m2: f64) -> World {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (cameras, rig_from_camera) = car();
    let points = garage_points(length, per_m2, &mut rng);
    // A loop: x from 6 to length - 6 at y = 6 and 18, joined by half circles.
    let (x0, x1, yc, r) = (6.0, length - 6.0, 12.0, 6.0);
    let straight = x1 - x0;
    let total = 2.0 * straight + 2.0 * std::f64::consts::PI * r;
    let world_from_rig: Vec<Isometry3<f64>> = (0..frames)
        .map(|i| {
            let s = total * i as f64 / frames as f64;
            let (x, y, heading) = if s < straight {
                (x0 + s, yc - r, 0.0)
            } else if s < straight + std::f64::consts::PI * r {
                let a = (s - straight) / r;
                (x1 + r * a.sin(), yc - r * a.cos(), a)
            } else if s < 2.0 * straight + std::f64::consts::PI * r {
                let d = s - straight - std::f64::consts::PI * r;
                (x1 - d, yc + r, std::f64::consts::PI)
            } else {
                let a = (s - 2.0 * straight - std::f64::consts::PI * r) / r;
                (x0 - r * a.sin(), yc + r * a.cos(), std::f64::consts::PI + a)
            };
            Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * heading)
        })
        .collect();
    let noise = Normal::new(0.0, SIGMA_PX).unwrap();
    let cos85 = 85f64.to_radians().cos();
    let mut observations = Vec::new();
    for (f, w) in world_from_rig.iter().enumerate() {
        for (c, (cam, e)) in cameras.iter().zip(&rig_from_camera).enumerate() {
            let camera_from_world = (w * e).inverse();
            for (j, x) in points.iter().enumerate() {
                let p = camera_from_world * nalgebra::Point3::from(*x);
                let d = p.coords.norm();
                if !(0.3..=30.0).contains(&d) || p.z < cos85 * d {
                    continue;
                }
                let Ok(px) = cam.project(&p.coords) else {
                    continue;
                };
                if !cam.in_image(&px) {
                    continue;
                }
                let pixel = px + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng));
                observations.push(RigBaObservation {
                    frame: f,
                    camera: c,
                    point: j,
                    pixel,
                });
            }
        }
    }
    // Keep the points seen at least twice, renumbered.
    let mut count = vec![0usize; points.len()];
    for o in &observations {
        count[o.point] += 1;
    }
    let mut remap = vec![usize::MAX; points.len()];
    let mut kept = Vec::new();
    for (j, x) in points.iter().enumerate() {
        if count[j] >= 2 {
            remap[j] = kept.len();
            kept.push(*x);
        }
    }
    observations.retain(|o| remap[o.point] != usize::MAX);
    for o in &mut observations {
        o.point = remap[o.point];
    }
    let start = RigBundleAdjustment {
        cameras: cameras.clone(),
        rig_from_camera: rig_from_camera
            .iter()
            .enumerate()
            .map(|(c, p)| {
                if c == 0 {
                    *p
                } else {
                    perturb(p, 2.0, 0.10, &mut rng)
                }
            })
            .collect(),
        world_from_rig: world_from_rig
            .iter()
            .map(|p| perturb(p, 0.1, 0.01, &mut rng))
            .collect(),
        points: kept
            .iter()
            .map(|x| x + random_unit(&mut rng) * 0.05)
            .collect(),
        observations,
    };
    World {
        truth_cameras: cameras,
        truth_rig_from_camera: rig_from_camera,
        truth_world_from_rig: world_from_rig,
        truth_points: kept,
        start,
    }
}

/// Worst rotation (degrees) and translation (mm) error of `front_from_camera`.
fn worst_error(truth: &[Isometry3<f64>], est: &[Isometry3<f64>]) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for c in 1..truth.len() {
        let t = truth[0].inverse() * truth[c];
        let e = est[0].inverse() * est[c];
        worst.0 = worst.0.max((t.inverse() * e).rotation.angle().to_degrees());
        worst.1 = worst
            .1
            .max((t.translation.vector - e.translation.vector).norm() * 1e3);
    }
    worst
}

fn baseline(w: &World, c: usize) -> f64 {
    (w.truth_rig_from_camera[c].translation.vector - w.truth_rig_from_camera[0].translation.vector)
        .norm()
}

/// The scale held by camera 2's true baseline, with the covariance.
fn baseline_gauge_with_covariance(w: &World) -> RigBundleAdjustmentOptions {
    RigBundleAdjustmentOptions {
        scale: ScaleGauge::Baseline {
            camera: 2,
            distance_m: baseline(w, 2),
        },
        covariance: true,
        ..Default::default()
    }
}

fn solve(w: &World, options: &RigBundleAdjustmentOptions) -> RigBundleAdjustmentResult {
    let r = w.start.solve(options).unwrap();
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );
    r
}

/// Points free, extrinsics 2 deg / 10 cm off: recovered to under 0.01 degree and 1 mm (this
/// world has 65k observations, 3.6 % of the pipeline garage's); the final rms is the noise's (σ √2 = 0.71 px); the baseline
/// gauge holds exactly; the covariance predicts the errors.
#[test]
fn points_free_recovers_the_extrinsics() {
    let w = world(16, 40.0, 40, 0.6);
    let options = baseline_gauge_with_covariance(&w);
    let r = solve(&w, &options);
    let (deg, mm) = worst_error(&w.truth_rig_from_camera, &r.rig_from_camera);
    eprintln!(
        "{} observations, {} points: worst {deg:.5} deg / {mm:.3} mm, rms {:.3} -> {:.3} px",
        w.start.observations.len(),
        w.start.points.len(),
        r.initial_rms,
        r.final_rms
    );
    assert!(r.initial_rms > 5.0);
    assert!(
        (r.final_rms - SIGMA_PX * 2f64.sqrt()).abs() < 0.03,
        "{}",
        r.final_rms
    );
    assert!(deg < 0.01 && mm < 1.0, "{deg} deg / {mm} mm");
    let b =
        (r.rig_from_camera[2].translation.vector - r.rig_from_camera[0].translation.vector).norm();
    assert!((b - baseline(&w, 2)).abs() < 1e-12);
    // The reference camera and rig pose did not move.
    assert_eq!(r.rig_from_camera[0], w.start.rig_from_camera[0]);
    assert_eq!(r.world_from_rig[0], w.start.world_from_rig[0]);
    // Covariance (σ² scaled): every free camera's errors within 5 of its standard deviations.
    for c in 1..4 {
        let cov = r.extrinsic_covariance[c].unwrap() * SIGMA_PX * SIGMA_PX;
        let d = w.truth_rig_from_camera[c].inverse() * r.rig_from_camera[c];
        let rot = d.rotation.scaled_axis();
        for k in 0..3 {
            assert!(
                rot[k].abs() < 5.0 * cov[(k + 3, k + 3)].sqrt() + 1e-7,
                "camera {c} phi {k}"
            );
        }
    }
    // Observability: all determined, the baseline camera's radial direction not a parameter.
    assert_eq!(r.observability.len(), 6 + 5 + 6);
    for p in &r.observability {
        assert!(p.std_dev.is_finite() && p.std_dev > 0.0, "{p:?}");
        assert!(p.observability > 0.0 && p.observability <= 1.0, "{p:?}");
    }
    // The points came back from 5 cm to millimetres (in the reference frame's gauge).
    let moved = r.world_from_rig[0] * w.truth_world_from_rig[0].inverse();
    let median = {
        let mut e: Vec<f64> = r
            .points
            .iter()
            .zip(&w.truth_points)
            .map(|(p, t)| (p - (moved * nalgebra::Point3::from(*t)).coords).norm())
            .collect();
        e.sort_by(f64::total_cmp);
        e[e.len() / 2]
    };
    assert!(median < 0.02, "median point error {median} m");
}

/// Intrinsics free too, focal lengths starting 1 px off: back within 0.1 px, extrinsics within
/// hundredths of a degree and a few millimetres; holding a parameter keeps it.
#[test]
fn intrinsics_free_recovers_the_focal_lengths() {
    let w = world(17, 40.0, 40, 0.6);
    let options = RigBundleAdjustmentOptions {
        scale: ScaleGauge::Baseline {
            camera: 2,
            distance_m: baseline(&w, 2),
        },
        optimize_intrinsics: true,
        held_intrinsics: vec![(3, 0)],
        ..Default::default()
    };
    // The focal lengths start 1 px off.
    let mut start = w.start.clone();
    for c in &mut start.cameras {
        let mut p = c.params().to_vec();
        p[4] += 1.0;
        p[5] -= 1.0;
        c.set_params(&p).unwrap();
    }
    let r = start.solve(&options).unwrap();
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );
    let (deg, mm) = worst_error(&w.truth_rig_from_camera, &r.rig_from_camera);
    let focal = r
        .cameras
        .iter()
        .zip(&w.truth_cameras)
        .map(|(c, t)| {
            (c.params()[4] - t.params()[4])
                .abs()
                .max((c.params()[5] - t.params()[5]).abs())
        })
        .fold(0.0, f64::max);
    eprintln!("intrinsics free: worst {deg:.5} deg / {mm:.3} mm, focal {focal:.4} px");
    // This world has 65k observations; the 0.05 px bar of issue 16 is asserted on the
    // pipeline's garage (1.8M observations) in `examples/tests/rig_bundle_adjust.rs`.
    assert!(focal < 0.1, "{focal} px");
    assert!(deg < 0.05 && mm < 3.0, "{deg} deg / {mm} mm");
    assert_eq!(r.cameras[3].params()[0], w.truth_cameras[3].params()[0]);
    assert_ne!(r.cameras[2].params()[0], w.truth_cameras[2].params()[0]);
}

/// The other gauges: the odometry distance holds exactly, the point distance within its σ;
/// with the scale free, the observability says the translations are not determined.
#[test]
fn scale_gauges_hold_and_a_free_scale_is_reported_unobservable() {
    let w = world(18, 40.0, 24, 0.3);
    let travel = (w.start.world_from_rig[15].translation.vector
        - w.start.world_from_rig[0].translation.vector)
        .norm();
    let r = solve(
        &w,
        &RigBundleAdjustmentOptions {
            scale: ScaleGauge::Odometry {
                frame: 15,
                distance_m: travel,
            },
            ..Default::default()
        },
    );
    let d =
        (r.world_from_rig[15].translation.vector - r.world_from_rig[0].translation.vector).norm();
    assert!((d - travel).abs() < 1e-12);

    let (a, b) = (0, w.start.points.len() / 2);
    let truth = (w.truth_points[a] - w.truth_points[b]).norm();
    let r = solve(
        &w,
        &RigBundleAdjustmentOptions {
            scale: ScaleGauge::PointDistance {
                points: [a, b],
                distance_m: truth,
                sigma_m: 1e-6,
            },
            ..Default::default()
        },
    );
    assert!(((r.points[a] - r.points[b]).norm() - truth).abs() < 1e-5);

    let r = solve(
        &w,
        &RigBundleAdjustmentOptions {
            scale: ScaleGauge::Free,
            covariance: true,
            ..Default::default()
        },
    );
    // The scale direction moves every translation together: no translation is determined
    // alone, the rotations are.
    let rho: Vec<_> = r
        .observability
        .iter()
        .filter(|p| p.name.starts_with("rho"))
        .collect();
    assert!(
        rho.iter()
            .any(|p| p.observability < 1e-6 || !p.std_dev.is_finite()),
        "{rho:?}"
    );
    assert!(r.extrinsic_covariance.iter().all(Option::is_none));
    let phi: Vec<_> = r
        .observability
        .iter()
        .filter(|p| p.name.starts_with("phi"))
        .collect();
    assert!(phi.iter().all(|p| p.std_dev.is_finite()), "{phi:?}");
}

#[test]
fn bad_input_is_a_typed_error() {
    let w = world(19, 40.0, 12, 0.4);
    let ok = RigBundleAdjustmentOptions::default();
    let err = |p: &RigBundleAdjustment, o: &RigBundleAdjustmentOptions| p.solve(o).unwrap_err();

    let mut p = w.start.clone();
    p.rig_from_camera.pop();
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::LengthMismatch {
            what: "rig_from_camera",
            ..
        }
    ));

    let mut p = w.start.clone();
    p.points[3].x = f64::NAN;
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::NonFiniteInput {
            what: "points",
            index: 3
        }
    ));

    let mut p = w.start.clone();
    p.observations[5].pixel.y = f64::INFINITY;
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::NonFiniteObservation { index: 5 }
    ));

    let mut p = w.start.clone();
    p.observations[7].point = p.points.len();
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::IndexOutOfRange {
            target: "point",
            ..
        }
    ));

    // A point seen once, and one not seen at all.
    let mut p = w.start.clone();
    let extra = p.points.len();
    p.points.push(Vector3::new(1.0, 2.0, 1.0));
    assert!(
        matches!(err(&p, &ok), BundleAdjustError::PointWithoutObservations { point, .. } if point == extra)
    );
    let mut o = p.observations[0];
    o.point = extra;
    p.observations.push(o);
    assert!(
        matches!(err(&p, &ok), BundleAdjustError::PointSeenOnce { point, .. } if point == extra)
    );

    // A frame without observations.
    let mut p = w.start.clone();
    p.world_from_rig.push(Isometry3::identity());
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::FrameWithoutObservations { frame: 12, .. }
    ));

    // Options that do not fit the problem.
    let bad = [
        RigBundleAdjustmentOptions {
            reference_camera: 4,
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            reference_frame: 12,
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            scale: ScaleGauge::Baseline {
                camera: 0,
                distance_m: 1.0,
            },
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            scale: ScaleGauge::Baseline {
                camera: 1,
                distance_m: -1.0,
            },
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            scale: ScaleGauge::Odometry {
                frame: 0,
                distance_m: 1.0,
            },
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            scale: ScaleGauge::PointDistance {
                points: [1, 1],
                distance_m: 1.0,
                sigma_m: 1e-6,
            },
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            scale: ScaleGauge::PointDistance {
                points: [1, 2],
                distance_m: 1.0,
                sigma_m: 0.0,
            },
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            optimize_intrinsics: true,
            held_intrinsics: vec![(0, 8)],
            ..Default::default()
        },
        RigBundleAdjustmentOptions {
            held_extrinsics: vec![9],
            ..Default::default()
        },
    ];
    for o in &bad {
        assert!(
            matches!(err(&w.start, o), BundleAdjustError::InvalidOption { .. }),
            "{o:?}"
        );
    }
    // A one-camera rig has no baseline to fix the scale with.
    let mut p = w.start.clone();
    p.cameras.truncate(1);
    p.rig_from_camera.truncate(1);
    p.observations.retain(|o| o.camera == 0);
    assert!(matches!(
        err(&p, &ok),
        BundleAdjustError::InvalidOption { name: "scale", .. }
    ));
}

/// A point that the observations do not place (seen twice along one ray: no parallax, its
/// depth free) makes the marginal covariance of the cameras undefined: the adjustment is
/// still returned, as accurate as without that point, with the reason instead of the
/// covariance.
#[test]
fn an_undetermined_point_loses_the_covariance_not_the_adjustment() {
    let w = world(18, 40.0, 24, 0.3);
    let options = baseline_gauge_with_covariance(&w);
    let full = solve(&w, &options);
    assert!(full.covariance_error.is_none());
    assert!(
        full.extrinsic_covariance
            .iter()
            .skip(1)
            .all(Option::is_some)
    );

    // A point 4 m in front of the front camera at frame 5, seen by it twice.
    let mut p = w.start.clone();
    let camera = &w.truth_cameras[0];
    let world_from_camera = w.truth_world_from_rig[5] * w.truth_rig_from_camera[0];
    let x = world_from_camera * nalgebra::Point3::new(0.3, -0.2, 4.0);
    let pixel = camera
        .project(&(world_from_camera.inverse() * x).coords)
        .unwrap();
    let point = p.points.len();
    p.points.push(x.coords);
    for _ in 0..2 {
        p.observations.push(RigBaObservation {
            frame: 5,
            camera: 0,
            point,
            pixel,
        });
    }
    let r = p.solve(&options).unwrap();
    assert!(
        matches!(
            r.covariance_error,
            Some(BundleAdjustError::SingularInformation)
        ),
        "{:?}",
        r.covariance_error
    );
    assert!(r.extrinsic_covariance.iter().all(Option::is_none));
    assert!(r.observability.is_empty());
    // The rest determines the extrinsics as before.
    for (a, b) in r.rig_from_camera.iter().zip(&full.rig_from_camera) {
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-6);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-7);
    }
}
