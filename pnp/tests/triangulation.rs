//! Triangulation on bearings: exact recovery (rays beyond 90 degrees from the optical axis
//! included), accuracy under noise against the maximum-likelihood point, and typed errors for
//! every bad input.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod common;

use common::{FOCAL, median, perturb_bearing, random_pose};
use ibc_pnp::{
    TRIANGULATION_MIN_PARALLAX, TRIANGULATION_MIN_VIEWS, TriangulationError, TriangulationOptions,
    UNIT_NORM_TOLERANCE, depths_along_bearings, refine_point, triangulate, triangulate_two_view,
};
use nalgebra::{
    Isometry3, Matrix3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3,
};
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Views of one point: `bearings[i]` is the (possibly noisy) bearing of `truth` in camera `i`.
struct Views {
    cameras_from_world: Vec<Isometry3<f64>>,
    bearings: Vec<Vector3<f64>>,
    truth: Point3<f64>,
}

impl Views {
    /// Distance from the point to the nearest camera centre: the scale of relative errors.
    fn nearest(&self) -> f64 {
        self.cameras_from_world
            .iter()
            .map(|c| (c * self.truth).coords.norm())
            .fold(f64::INFINITY, f64::min)
    }

    /// The largest angle between two lines from the centres to the true point, folded into
    /// [0, 90] degrees (COLMAP's triangulation angle).
    fn true_parallax(&self) -> f64 {
        let rays: Vec<Vector3<f64>> = self
            .cameras_from_world
            .iter()
            .map(|c| c.inverse_transform_vector(&(c * self.truth).coords.normalize()))
            .collect();
        let mut best: f64 = 0.0;
        for (i, u) in rays.iter().enumerate() {
            for v in &rays[i + 1..] {
                best = best.max(u.cross(v).norm().atan2(u.dot(v).abs()));
            }
        }
        best
    }
}

fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        if (0.01..=1.0).contains(&v.norm_squared()) {
            return v.normalize();
        }
    }
}

/// A unit vector within `half_angle` of `axis`, uniform over the cap.
fn in_cone(rng: &mut ChaCha8Rng, axis: &Vector3<f64>, half_angle: f64) -> Vector3<f64> {
    let z = rng.random_range(half_angle.cos()..1.0);
    let phi = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let e1 = axis.cross(&unit(rng)).normalize();
    let e2 = axis.cross(&e1);
    axis * z + (e1 * phi.cos() + e2 * phi.sin()) * r
}

/// `camera_from_world` of a camera at `centre` oriented uniformly at random: the point's
/// bearing may be anywhere on the sphere, behind the image plane (z < 0) included.
fn random_orientation(rng: &mut ChaCha8Rng, centre: &Point3<f64>) -> Isometry3<f64> {
    let rotation = random_pose(rng).rotation;
    Isometry3::from_parts(Translation3::from(-(rotation * centre.coords)), rotation)
}

/// `camera_from_world` of a camera at `centre` whose optical axis makes `off_axis` radians
/// with the direction to `target`, rolled at random.
fn looking_off_axis(
    rng: &mut ChaCha8Rng,
    centre: &Point3<f64>,
    target: &Point3<f64>,
    off_axis: f64,
) -> Isometry3<f64> {
    let u = (target - centre).normalize();
    let w = u.cross(&unit(rng)).normalize();
    let z = u * off_axis.cos() + w * off_axis.sin();
    let x = z.cross(&unit(rng)).normalize();
    let y = z.cross(&x);
    let rows = Matrix3::from_rows(&[x.transpose(), y.transpose(), z.transpose()]);
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(rows));
    Isometry3::from_parts(Translation3::from(-(rotation * centre.coords)), rotation)
}

/// `n` cameras 4 to 8 m from a point, in a cone of `cone` radians around a random axis,
/// oriented at random; bearings with tangent-plane noise `sigma` radians. Scenes whose true
/// parallax is below 3 degrees are drawn again.
fn views(rng: &mut ChaCha8Rng, n: usize, cone: f64, sigma: f64) -> Views {
    loop {
        let truth = Point3::from(Vector3::from_fn(|_, _| rng.random_range(-5.0..5.0)));
        let axis = unit(rng);
        let cameras_from_world: Vec<Isometry3<f64>> = (0..n)
            .map(|_| {
                let centre = truth + in_cone(rng, &axis, cone) * rng.random_range(4.0..8.0);
                random_orientation(rng, &centre)
            })
            .collect();
        let bearings = cameras_from_world
            .iter()
            .map(|c| perturb_bearing(rng, &(c * truth).coords.normalize(), sigma))
            .collect();
        let v = Views {
            cameras_from_world,
            bearings,
            truth,
        };
        if v.true_parallax() >= 3f64.to_radians() {
            return v;
        }
    }
}

/// The pose of camera `b` relative to camera `a`.
fn b_from_a(v: &Views) -> Isometry3<f64> {
    v.cameras_from_world[1] * v.cameras_from_world[0].inverse()
}

#[test]
fn exact_views_are_triangulated_to_round_off_at_any_incidence() {
    let mut rng = ChaCha8Rng::seed_from_u64(1600);
    let (mut behind_image_plane, mut total) = (0, 0);
    let mut worst: f64 = 0.0;
    for trial in 0..600 {
        let n = 2 + trial % 7;
        let v = views(&mut rng, n, 0.6, 0.0);
        behind_image_plane += v.bearings.iter().filter(|f| f.z < 0.0).count();
        total += n;
        let scale = v.nearest();
        for refine in [true, false] {
            let options = TriangulationOptions {
                refine,
                ..Default::default()
            };
            let t = triangulate(&v.cameras_from_world, &v.bearings, &options).unwrap();
            let error = (t.point - v.truth).norm() / scale;
            worst = worst.max(error);
            assert!(error <= 1e-10, "trial {trial}, refine {refine}: {error:e}");
            assert!(t.max_residual <= 1e-10, "{:e}", t.max_residual);
            for (c, depth) in v.cameras_from_world.iter().zip(&t.depths) {
                let distance = (c * v.truth).coords.norm();
                assert!((depth - distance).abs() <= 1e-10 * distance);
            }
            assert!((t.parallax - v.true_parallax()).abs() <= 1e-9);
            assert_eq!(t.converged, refine, "trial {trial}");
            assert!(t.final_cost <= t.initial_cost);
        }
    }
    // Uniformly random orientations: about half the bearings point behind the image plane.
    assert!(
        behind_image_plane * 3 > total,
        "{behind_image_plane} of {total}"
    );
    println!("exact multi-view: worst relative error {worst:.2e}");
}

#[test]
fn fisheye_rays_beyond_90_degrees_two_view() {
    // Both bearings between 90 and 95 degrees from their optical axes (z < 0): a 190 degree
    // fisheye's edge.
    let mut rng = ChaCha8Rng::seed_from_u64(1601);
    let mut worst: f64 = 0.0;
    for trial in 0..300 {
        let truth = Point3::from(Vector3::from_fn(|_, _| rng.random_range(-5.0..5.0)));
        let centre_a = truth + unit(&mut rng) * rng.random_range(2.0..8.0);
        let centre_b = centre_a + unit(&mut rng) * rng.random_range(0.5..2.0);
        let off_a = rng.random_range(90.0f64..95.0).to_radians();
        let off_b = rng.random_range(90.0f64..95.0).to_radians();
        let v = Views {
            cameras_from_world: vec![
                looking_off_axis(&mut rng, &centre_a, &truth, off_a),
                looking_off_axis(&mut rng, &centre_b, &truth, off_b),
            ],
            bearings: vec![],
            truth,
        };
        let fa = (v.cameras_from_world[0] * truth).coords.normalize();
        let fb = (v.cameras_from_world[1] * truth).coords.normalize();
        assert!(fa.z < 0.0 && fb.z < 0.0);
        if v.true_parallax() < 2f64.to_radians() {
            continue;
        }
        let t = triangulate_two_view(&b_from_a(&v), &fa, &fb, &Default::default()).unwrap();
        let truth_a = v.cameras_from_world[0] * truth;
        let error = (t.point_a - truth_a).norm() / v.nearest();
        worst = worst.max(error);
        assert!(error <= 1e-10, "trial {trial}: {error:e}");
        assert!(
            t.point_a.z < 0.0,
            "the point is behind camera a's image plane"
        );
        assert!((t.depth_a - truth_a.coords.norm()).abs() <= 1e-10 * truth_a.coords.norm());
        let truth_b = v.cameras_from_world[1] * truth;
        assert!((t.depth_b - truth_b.coords.norm()).abs() <= 1e-10 * truth_b.coords.norm());
        assert!(t.residual_a <= 1e-10 && t.residual_b <= 1e-10);
        assert!((t.parallax - v.true_parallax()).abs() <= 1e-9);
        // The 2 x 2 depths agree.
        let (la, lb) = depths_along_bearings(&b_from_a(&v), &fa, &fb).unwrap();
        assert!((la - t.depth_a).abs() <= 1e-9 * la && (lb - t.depth_b).abs() <= 1e-9 * lb);
    }
    println!("exact fisheye two-view: worst relative error {worst:.2e}");
}

#[test]
fn two_view_agrees_with_multi_view() {
    let mut rng = ChaCha8Rng::seed_from_u64(1602);
    for _ in 0..200 {
        let v = views(&mut rng, 2, 0.5, 1.0 / FOCAL);
        let relative = b_from_a(&v);
        let two = triangulate_two_view(
            &relative,
            &v.bearings[0],
            &v.bearings[1],
            &Default::default(),
        )
        .unwrap();
        let many = triangulate(
            &[Isometry3::identity(), relative],
            &v.bearings,
            &Default::default(),
        )
        .unwrap();
        assert!((two.point_a - many.point).norm() <= 1e-12 * many.depths[0]);
        assert_eq!(two.iterations, many.iterations);
        assert!(two.converged && many.converged);
        assert!((two.residual_b - many.residuals[1]).abs() <= 1e-12);
    }
}

/// Median 3D errors over seeded noisy trials of the triangulated point and of the
/// maximum-likelihood point (the same cost refined from the true point), and of the linear
/// estimate; also the median distance between the triangulated and the ML points.
struct NoiseFigures {
    refined: f64,
    maximum_likelihood: f64,
    linear: f64,
    to_maximum_likelihood: f64,
    mean_iterations: f64,
    max_iterations: usize,
}

fn noise_trials(seed: u64, n: usize, trials: usize) -> NoiseFigures {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // One pixel on a pinhole camera of f = 800 px as an angle, per tangent axis.
    let sigma = (1.0 / FOCAL).atan();
    let linear_options = TriangulationOptions {
        refine: false,
        ..Default::default()
    };
    let (mut refined, mut ml, mut linear, mut gap) = (vec![], vec![], vec![], vec![]);
    let mut iterations = vec![];
    for trial in 0..trials {
        let v = views(&mut rng, n, 0.4, sigma);
        let point = if n == 2 {
            let t = triangulate_two_view(
                &b_from_a(&v),
                &v.bearings[0],
                &v.bearings[1],
                &Default::default(),
            )
            .unwrap();
            assert!(t.converged, "trial {trial}");
            iterations.push(t.iterations);
            v.cameras_from_world[0].inverse() * t.point_a
        } else {
            let t = triangulate(&v.cameras_from_world, &v.bearings, &Default::default()).unwrap();
            assert!(t.converged, "trial {trial}");
            iterations.push(t.iterations);
            t.point
        };
        let reference = refine_point(
            &v.cameras_from_world,
            &v.bearings,
            &v.truth,
            &Default::default(),
        )
        .unwrap();
        assert!(reference.converged);
        let first = triangulate(&v.cameras_from_world, &v.bearings, &linear_options).unwrap();
        refined.push((point - v.truth).norm());
        ml.push((reference.point - v.truth).norm());
        linear.push((first.point - v.truth).norm());
        gap.push((point - reference.point).norm());
    }
    NoiseFigures {
        refined: median(&refined),
        maximum_likelihood: median(&ml),
        linear: median(&linear),
        to_maximum_likelihood: median(&gap),
        mean_iterations: iterations.iter().sum::<usize>() as f64 / trials as f64,
        max_iterations: iterations.iter().copied().max().unwrap_or(0),
    }
}

#[test]
fn noisy_points_match_the_maximum_likelihood_point() {
    for (n, seed) in [(2, 1603), (5, 1604), (10, 1605)] {
        let f = noise_trials(seed, n, 400);
        println!(
            "{n} views, 1 px at f = 800, 400 trials: median 3D error refined {:.3} mm, ML {:.3} mm, linear {:.3} mm; median distance refined to ML {:.2e} mm; iterations mean {:.2}, max {}",
            f.refined * 1e3,
            f.maximum_likelihood * 1e3,
            f.linear * 1e3,
            f.to_maximum_likelihood * 1e3,
            f.mean_iterations,
            f.max_iterations
        );
        assert!(
            f.refined <= 1.05 * f.maximum_likelihood,
            "{n} views: {} vs {}",
            f.refined,
            f.maximum_likelihood
        );
        // The same minimum, not merely as good on average.
        assert!(f.to_maximum_likelihood <= 1e-6 * f.maximum_likelihood);
    }
}

#[test]
fn too_few_views_and_mismatched_lengths() {
    let v = views(&mut ChaCha8Rng::seed_from_u64(1606), 3, 0.5, 0.0);
    let options = TriangulationOptions::default();
    for n in 0..TRIANGULATION_MIN_VIEWS {
        assert_eq!(
            triangulate(&v.cameras_from_world[..n], &v.bearings[..n], &options).unwrap_err(),
            TriangulationError::TooFewViews { needed: 2, got: n }
        );
        assert!(matches!(
            refine_point(
                &v.cameras_from_world[..n],
                &v.bearings[..n],
                &v.truth,
                &options
            ),
            Err(TriangulationError::TooFewViews { got, .. }) if got == n
        ));
    }
    assert_eq!(
        triangulate(&v.cameras_from_world, &v.bearings[..2], &options).unwrap_err(),
        TriangulationError::LengthMismatch {
            poses: 3,
            bearings: 2
        }
    );
    assert!(matches!(
        refine_point(&v.cameras_from_world[..1], &v.bearings, &v.truth, &options),
        Err(TriangulationError::LengthMismatch {
            poses: 1,
            bearings: 3
        })
    ));
}

#[test]
fn non_finite_and_non_unit_input() {
    let v = views(&mut ChaCha8Rng::seed_from_u64(1607), 3, 0.5, 0.0);
    let options = TriangulationOptions::default();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut bearings = v.bearings.clone();
        bearings[2].y = bad;
        assert_eq!(
            triangulate(&v.cameras_from_world, &bearings, &options).unwrap_err(),
            TriangulationError::NonFiniteBearing { view: 2 }
        );
        let mut cameras = v.cameras_from_world.clone();
        cameras[1].translation.vector.x = bad;
        assert_eq!(
            triangulate(&cameras, &v.bearings, &options).unwrap_err(),
            TriangulationError::NonFinitePose { view: 1 }
        );
        assert_eq!(
            triangulate_two_view(&cameras[1], &v.bearings[0], &v.bearings[1], &options)
                .unwrap_err(),
            TriangulationError::NonFinitePose { view: 1 }
        );
        assert_eq!(
            triangulate_two_view(&b_from_a(&v), &bearings[2], &v.bearings[1], &options)
                .unwrap_err(),
            TriangulationError::NonFiniteBearing { view: 0 }
        );
        assert!(matches!(
            refine_point(
                &v.cameras_from_world,
                &v.bearings,
                &Point3::new(0.0, bad, 0.0),
                &options
            ),
            Err(TriangulationError::InvalidOption {
                name: "initial",
                ..
            })
        ));
        assert!(depths_along_bearings(&cameras[1], &v.bearings[0], &v.bearings[1]).is_none());
    }
    // An unnormalized image point (x, y, 1) is refused, and so is a bearing just outside
    // the tolerance; one just inside is accepted.
    let mut bearings = v.bearings.clone();
    let z = bearings[1].z;
    bearings[1] /= z;
    assert!(matches!(
        triangulate(&v.cameras_from_world, &bearings, &options),
        Err(TriangulationError::NonUnitBearing { view: 1, .. })
    ));
    let outside = v.bearings[1] * (1.0 + 2.0 * UNIT_NORM_TOLERANCE);
    assert!(matches!(
        triangulate_two_view(&b_from_a(&v), &v.bearings[0], &outside, &options),
        Err(TriangulationError::NonUnitBearing { view: 1, norm, tolerance })
            if (norm - 1.0 - 2.0 * UNIT_NORM_TOLERANCE).abs() < 1e-12 && tolerance == UNIT_NORM_TOLERANCE
    ));
    let inside = v.bearings[1] * (1.0 + 0.5 * UNIT_NORM_TOLERANCE);
    assert!(triangulate_two_view(&b_from_a(&v), &v.bearings[0], &inside, &options).is_ok());
}

#[test]
fn too_little_parallax() {
    let mut rng = ChaCha8Rng::seed_from_u64(1608);
    let options = TriangulationOptions::default();
    for trial in 0..100 {
        // A point 100 m away seen over a 1 m baseline: at most about 0.6 degrees.
        let truth = Point3::from(unit(&mut rng) * 100.0);
        let centre_b = Point3::from(unit(&mut rng));
        let cameras = vec![
            random_orientation(&mut rng, &Point3::origin()),
            random_orientation(&mut rng, &centre_b),
        ];
        let bearings: Vec<Vector3<f64>> = cameras
            .iter()
            .map(|c| (c * truth).coords.normalize())
            .collect();
        let error = triangulate(&cameras, &bearings, &options).unwrap_err();
        let TriangulationError::TooLittleParallax {
            parallax,
            min_parallax,
        } = error
        else {
            panic!("trial {trial}: {error:?}");
        };
        assert_eq!(min_parallax, TRIANGULATION_MIN_PARALLAX);
        assert!(parallax < 0.6f64.to_radians());
        let relative = cameras[1] * cameras[0].inverse();
        assert!(matches!(
            triangulate_two_view(&relative, &bearings[0], &bearings[1], &options),
            Err(TriangulationError::TooLittleParallax { .. })
        ));
        // With the check relaxed, the exact point is found.
        let relaxed = TriangulationOptions {
            min_parallax: 0.1f64.to_radians(),
            ..Default::default()
        };
        if let Ok(t) = triangulate(&cameras, &bearings, &relaxed) {
            assert!((t.point - truth).norm() <= 1e-8 * 100.0);
        } else {
            assert!(parallax < 0.1f64.to_radians(), "trial {trial}");
        }
        // A pure rotation: the same centre for both cameras, whatever the noise.
        let rotated = random_orientation(&mut rng, &Point3::origin());
        let same_centre = [cameras[0], rotated];
        let noisy: Vec<Vector3<f64>> = same_centre
            .iter()
            .map(|c| perturb_bearing(&mut rng, &(c * truth).coords.normalize(), 1.0 / FOCAL))
            .collect();
        assert!(matches!(
            triangulate(&same_centre, &noisy, &options),
            Err(TriangulationError::TooLittleParallax { .. })
        ));
        // Identical bearings of exactly parallel rays are refused even with no minimum.
        let none = TriangulationOptions {
            min_parallax: 0.0,
            ..Default::default()
        };
        let parallel = [Isometry3::identity(), Isometry3::translation(1.0, 0.0, 0.0)];
        assert!(matches!(
            triangulate(&parallel, &[Vector3::z(), Vector3::z()], &none),
            Err(TriangulationError::TooLittleParallax { parallax, .. }) if parallax == 0.0
        ));
    }
}

#[test]
fn point_behind_a_camera() {
    let mut rng = ChaCha8Rng::seed_from_u64(1609);
    let options = TriangulationOptions::default();
    for trial in 0..200 {
        let n = 2 + trial % 4;
        let v = views(&mut rng, n, 0.5, 0.0);
        // One bearing reversed: its line still passes through the point, its ray does not.
        let flipped = trial % n;
        let mut bearings = v.bearings.clone();
        bearings[flipped] = -bearings[flipped];
        let error = triangulate(&v.cameras_from_world, &bearings, &options).unwrap_err();
        let TriangulationError::BehindCamera { view, depth } = error else {
            panic!("trial {trial}: {error:?}");
        };
        assert_eq!(view, flipped);
        assert!(depth < 0.0);
        if n == 2 {
            let relative = b_from_a(&v);
            assert!(matches!(
                triangulate_two_view(&relative, &bearings[0], &bearings[1], &options),
                Err(TriangulationError::BehindCamera { view, .. }) if view == flipped
            ));
            let (la, lb) = depths_along_bearings(&relative, &bearings[0], &bearings[1]).unwrap();
            assert!((la < 0.0) == (flipped == 0) && (lb < 0.0) == (flipped == 1));
        }
        // Refining from the true point is refused too: it is behind that camera.
        assert!(matches!(
            refine_point(&v.cameras_from_world, &bearings, &v.truth, &options),
            Err(TriangulationError::BehindCamera { view, .. }) if view == flipped
        ));
    }
    // Rays that diverge: both cameras look away from where their lines meet.
    let cameras = [
        Isometry3::identity(),
        Isometry3::translation(-1.0, 0.0, 0.0),
    ];
    let a = Vector3::new(-0.1, 0.0, -1.0).normalize();
    let target = Point3::from(a * -5.0);
    let b = -(cameras[1] * target).coords.normalize();
    assert!(matches!(
        triangulate(&cameras, &[a, b], &options),
        Err(TriangulationError::BehindCamera { view: 0, .. })
    ));
}

#[test]
fn invalid_options() {
    let v = views(&mut ChaCha8Rng::seed_from_u64(1610), 3, 0.5, 0.0);
    for min_parallax in [-0.1, f64::NAN, std::f64::consts::FRAC_PI_2, 4.0] {
        let options = TriangulationOptions {
            min_parallax,
            ..Default::default()
        };
        assert!(matches!(
            triangulate(&v.cameras_from_world, &v.bearings, &options),
            Err(TriangulationError::InvalidOption {
                name: "min_parallax",
                ..
            })
        ));
    }
    for step_tolerance in [-1.0, f64::NAN, f64::INFINITY] {
        let options = TriangulationOptions {
            step_tolerance,
            ..Default::default()
        };
        assert!(matches!(
            triangulate_two_view(&b_from_a(&v), &v.bearings[0], &v.bearings[1], &options),
            Err(TriangulationError::InvalidOption {
                name: "step_tolerance",
                ..
            })
        ));
    }
    // No iterations allowed: the linear estimate, reported as not converged.
    let options = TriangulationOptions {
        max_iterations: 0,
        ..Default::default()
    };
    let t = triangulate(&v.cameras_from_world, &v.bearings, &options).unwrap();
    assert_eq!(t.iterations, 0);
    assert!(!t.converged);
}

#[test]
fn defaults_and_messages() {
    let options = TriangulationOptions::default();
    assert_eq!(options.min_parallax, 1.5f64.to_radians());
    assert!(options.refine);
    assert_eq!(options.max_iterations, 20);
    assert_eq!(options.step_tolerance, 1e-10);
    let message = TriangulationError::TooLittleParallax {
        parallax: 0.5f64.to_radians(),
        min_parallax: TRIANGULATION_MIN_PARALLAX,
    }
    .to_string();
    assert!(
        message.contains("0.5000 degrees") && message.contains("1.5000 degrees"),
        "{message}"
    );
    let message = TriangulationError::BehindCamera {
        view: 3,
        depth: -2.0,
    }
    .to_string();
    assert!(
        message.contains("view 3") && message.contains("-2"),
        "{message}"
    );
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -10.0..10.0f64,
        1 => prop::num::f64::ANY,
        1 => Just(0.0),
    ]
}

fn any_vector() -> impl Strategy<Value = Vector3<f64>> {
    (any_f64(), any_f64(), any_f64()).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

fn any_pose() -> impl Strategy<Value = Isometry3<f64>> {
    (any_vector(), any_vector()).prop_map(|(t, r)| Isometry3::new(t, r))
}

/// Nearly unit bearings half of the time (so the solver itself runs), anything otherwise.
fn any_bearing() -> impl Strategy<Value = Vector3<f64>> {
    prop_oneof![
        any_vector().prop_map(|v| {
            let n = v.norm();
            if n > 1e-3 && n.is_finite() {
                v / n
            } else {
                Vector3::z()
            }
        }),
        any_vector(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Arbitrary input never panics; whatever is returned as a point is in front of every
    /// camera and seen at the minimum parallax or more.
    #[test]
    fn arbitrary_input_never_panics(
        cameras in prop::collection::vec(any_pose(), 0..6),
        bearings in prop::collection::vec(any_bearing(), 0..6),
        initial in any_vector(),
        min_parallax in prop_oneof![Just(TRIANGULATION_MIN_PARALLAX), Just(0.0), any_f64()],
    ) {
        let options = TriangulationOptions { min_parallax, ..Default::default() };
        if let Ok(t) = triangulate(&cameras, &bearings, &options) {
            prop_assert!(t.depths.iter().all(|&d| d > 0.0));
            prop_assert!(t.parallax >= min_parallax);
            prop_assert!(t.final_cost <= t.initial_cost);
        }
        if let Ok(t) = refine_point(&cameras, &bearings, &Point3::from(initial), &options) {
            prop_assert!(t.depths.iter().all(|&d| d > 0.0));
        }
        if let (Some(pose), [a, b, ..]) = (cameras.first(), bearings.as_slice()) {
            if let Ok(t) = triangulate_two_view(pose, a, b, &options) {
                prop_assert!(t.depth_a > 0.0 && t.depth_b > 0.0);
            }
            let _ = depths_along_bearings(pose, a, b);
        }
    }
}

#[test]
fn rotation_invariance_of_the_bearing_frame() {
    // Rotating a camera about its centre and its bearing with it changes nothing: the angles
    // are measured on the sphere, not on an image plane.
    let mut rng = ChaCha8Rng::seed_from_u64(1611);
    for _ in 0..100 {
        let v = views(&mut rng, 4, 0.5, 1.0 / FOCAL);
        let t = triangulate(&v.cameras_from_world, &v.bearings, &Default::default()).unwrap();
        let spin = UnitQuaternion::from_axis_angle(
            &Unit::new_normalize(unit(&mut rng)),
            rng.random_range(0.0..std::f64::consts::PI),
        );
        let mut cameras = v.cameras_from_world.clone();
        let mut bearings = v.bearings.clone();
        cameras[0] = Isometry3::from_parts(Translation3::identity(), spin) * cameras[0];
        bearings[0] = spin * bearings[0];
        let s = triangulate(&cameras, &bearings, &Default::default()).unwrap();
        assert!((s.point - t.point).norm() <= 1e-9 * t.depths[0]);
    }
}
