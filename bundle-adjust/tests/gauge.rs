//! Gauges of a bundle adjustment and the covariance they make defined: a free scale makes the
//! information singular up to rounding (a typed error naming it), the 7-degree-of-freedom
//! similarity gauge gives a covariance that matches a Monte-Carlo run, and it is more accurate
//! than holding two whole image poses (12 degrees of freedom).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::{
    BaObservation, BundleAdjustError, BundleAdjustment, BundleAdjustmentOptions, Gauge, RobustLoss,
    SolverOptions,
};
use ibc_camera_models::{Camera, CameraModel, PinholeRadtan};
use nalgebra::{Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// `images` pinhole images on a ring of radius 6 m around a 4 m cloud of `points` points,
/// every point seen by every image; noise-free pixels.
fn scene(seed: u64, images: usize, points: usize) -> BundleAdjustment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let camera: Camera = PinholeRadtan::new(
        752,
        480,
        [-0.05, 0.01, 1e-4, -2e-4, 460.0, 458.0, 370.0, 245.0],
    )
    .unwrap()
    .into();
    let camera_from_world: Vec<Isometry3<f64>> = (0..images)
        .map(|i| {
            let a = i as f64 * 0.5;
            let center = Vector3::new(6.0 * a.cos(), rng.random_range(-0.5..0.5), 6.0 * a.sin());
            Isometry3::face_towards(&Point3::from(center), &Point3::origin(), &Vector3::y())
                .inverse()
        })
        .collect();
    let pts: Vec<Vector3<f64>> = (0..points)
        .map(|_| {
            Vector3::new(
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
                rng.random_range(-1.5..1.5),
            )
        })
        .collect();
    let mut observations = Vec::new();
    for (i, pose) in camera_from_world.iter().enumerate() {
        for (j, x) in pts.iter().enumerate() {
            let px = camera.project(&(pose * Point3::from(*x)).coords).unwrap();
            assert!(camera.in_image(&px));
            observations.push(BaObservation {
                image: i,
                point: j,
                pixel: px,
            });
        }
    }
    BundleAdjustment {
        cameras: vec![camera],
        image_camera: vec![0; images],
        camera_from_world,
        points: pts,
        observations,
    }
}

/// `truth` with Gaussian pixel noise `sigma`.
fn noisy(truth: &BundleAdjustment, seed: u64, sigma: f64) -> BundleAdjustment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, sigma).unwrap();
    let mut s = truth.clone();
    for o in &mut s.observations {
        o.pixel += Vector2::new(normal.sample(&mut rng), normal.sample(&mut rng));
    }
    s
}

/// Every image pose (image 0 too) and point perturbed: an estimate from an earlier stage.
fn perturbed(scene: &BundleAdjustment, seed: u64) -> BundleAdjustment {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = scene.clone();
    let mut v = |scale: f64| {
        Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * scale
    };
    for pose in &mut s.camera_from_world {
        let (w, t) = (v(0.01), v(0.05));
        *pose = Isometry3::from_parts(
            Translation3::from(pose.translation.vector + t),
            pose.rotation * UnitQuaternion::from_scaled_axis(w),
        );
    }
    for x in &mut s.points {
        *x += v(0.03);
    }
    s
}

fn options(gauge: Gauge, fixed_images: Vec<usize>) -> BundleAdjustmentOptions {
    BundleAdjustmentOptions {
        gauge,
        fixed_images,
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

fn similarity() -> Gauge {
    Gauge::Similarity {
        reference_image: 0,
        scale_image: 1,
    }
}

fn centre(pose: &Isometry3<f64>) -> Vector3<f64> {
    pose.inverse().translation.vector
}

/// RMS distance of `estimate` to `truth` after the best similarity
/// (Umeyama, "Least-squares estimation of transformation parameters between two point
/// patterns", 1991): an error that does not depend on the gauge.
fn aligned_rms(estimate: &[Vector3<f64>], truth: &[Vector3<f64>]) -> f64 {
    let n = estimate.len() as f64;
    let me = estimate.iter().sum::<Vector3<f64>>() / n;
    let mt = truth.iter().sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    let mut var = 0.0;
    for (e, t) in estimate.iter().zip(truth) {
        cov += (t - mt) * (e - me).transpose() / n;
        var += (e - me).norm_squared() / n;
    }
    let svd = cov.svd(true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut d = Matrix3::identity();
    if (u * vt).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = u * d * vt;
    let s = (svd.singular_values.component_mul(&d.diagonal())).sum() / var;
    let t = mt - s * r * me;
    let sum: f64 = estimate
        .iter()
        .zip(truth)
        .map(|(e, x)| (s * r * e + t - x).norm_squared())
        .sum();
    (sum / n).sqrt()
}

/// Defect 1: with one fixed image the scale is free; the information is singular up to
/// rounding and the covariance is a typed error with the reciprocal condition number, naming a
/// free pose. With the similarity gauge the same scene has a covariance.
#[test]
fn a_free_scale_makes_the_covariance_a_typed_error() {
    let truth = scene(1, 8, 60);
    let one_image = options(Gauge::FixedImages, vec![0]);
    // Six noisy scenes solved, and the noise-free one: in exact arithmetic the information is
    // singular in all of them; in floating point its Cholesky factorization succeeds in some
    // (the old covariance then returned rounding noise as an answer).
    let mut worst = 0.0f64;
    for seed in 0..7 {
        let start = if seed == 6 {
            truth.clone()
        } else {
            perturbed(&noisy(&truth, 40 + seed, 0.5), 50 + seed)
        };
        let mut ba = start.to_problem(&one_image).unwrap();
        let summary = ba.problem.solve(&one_image.solver).unwrap();
        assert!(summary.termination.is_converged(), "{}", summary.report());
        let free = &ba.camera_from_world[1..];
        let err = ba.problem.covariance(free, &one_image.solver).unwrap_err();
        let BundleAdjustError::CovarianceRankDeficient {
            reciprocal_condition_number,
            min_reciprocal_condition_number,
            block,
        } = err
        else {
            panic!("{err}");
        };
        eprintln!(
            "free scale, scene {seed}: reciprocal condition number {reciprocal_condition_number:.3e}, block {block}"
        );
        assert_eq!(min_reciprocal_condition_number, 1e-14);
        worst = worst.max(reciprocal_condition_number.abs());
        assert!(free.iter().any(|b| b.index() == block), "{block}");
        assert!(err.to_string().contains("reciprocal condition number"));
    }
    // Rounding level: 1e-16 to 1e-17 measured.
    assert!(worst < 1e-15, "{worst}");

    // The same scene, scale held: defined, and the scale image has one degree of freedom
    // less (5 × 5).
    let start = perturbed(&noisy(&truth, 2, 0.5), 3);
    let gauge = options(similarity(), vec![]);
    let mut ba = start.to_problem(&gauge).unwrap();
    ba.problem.solve(&gauge.solver).unwrap();
    let cov = ba
        .problem
        .covariance(&ba.camera_from_world[1..], &gauge.solver)
        .unwrap();
    assert_eq!(cov.matrix().nrows(), 5 + 6 * 6);
    let rcond = {
        let m = cov.matrix();
        let d = m.diagonal().map(|v| 1.0 / v.sqrt());
        let e = m.component_mul(&(&d * d.transpose()));
        let eig = e.symmetric_eigen().eigenvalues;
        eig.min() / eig.max()
    };
    eprintln!("similarity gauge: reciprocal condition number of the covariance {rcond:.3e}");
    assert!(rcond > 1e-8, "{rcond}");
    // A threshold above the problem's own condition refuses it too.
    let strict = SolverOptions {
        min_reciprocal_condition_number: 0.5,
        ..gauge.solver.clone()
    };
    assert!(matches!(
        ba.problem.covariance(&ba.camera_from_world[1..], &strict),
        Err(BundleAdjustError::CovarianceRankDeficient { .. })
    ));
}

/// Defect 1, the well-posed side: the covariance of a point (taken out of the eliminated
/// group) under the similarity gauge matches the scatter of the solutions of 300 noisy
/// copies of the scene.
#[test]
fn the_covariance_matches_a_monte_carlo_run() {
    let truth = scene(5, 8, 40);
    let sigma = 0.5;
    let gauge = options(similarity(), vec![]);
    let point = 7;
    // Predicted: σ² times the covariance at the noise-free solution (the truth).
    let mut ba = truth.to_problem(&gauge).unwrap();
    ba.problem.set_eliminated(ba.points[point], false).unwrap();
    let cov = ba
        .problem
        .covariance(&[ba.points[point]], &gauge.solver)
        .unwrap();
    let predicted = Matrix3::from_iterator(cov.matrix().iter().copied()) * (sigma * sigma);
    let samples = 300;
    let mut sum = Vector3::zeros();
    let mut sum_sq = Matrix3::zeros();
    for k in 0..samples {
        let r = noisy(&truth, 100 + k, sigma).solve(&gauge).unwrap();
        let d = r.points[point] - truth.points[point];
        sum += d;
        sum_sq += d * d.transpose();
    }
    let n = samples as f64;
    let mean = sum / n;
    let empirical = (sum_sq - mean * mean.transpose() * n) / (n - 1.0);
    // Whitened: tr(P⁻¹ E)/3 is 1 for a match; its sampling error over 300 draws is about
    // sqrt(2/(3·300)) = 4.7 %.
    let whitened = predicted.try_inverse().unwrap() * empirical;
    let ratio = whitened.trace() / 3.0;
    let std_pred = predicted.diagonal().map(f64::sqrt);
    let std_emp = empirical.diagonal().map(f64::sqrt);
    eprintln!(
        "point {point}: predicted std {:.3e} {:.3e} {:.3e} m, Monte-Carlo {:.3e} {:.3e} {:.3e} m, tr(P^-1 E)/3 = {ratio:.3}",
        std_pred.x, std_pred.y, std_pred.z, std_emp.x, std_emp.y, std_emp.z
    );
    assert!((ratio - 1.0).abs() < 0.15, "{ratio}");
    for k in 0..3 {
        assert!(
            (std_emp[k] / std_pred[k] - 1.0).abs() < 0.15,
            "axis {k}: {} vs {}",
            std_emp[k],
            std_pred[k]
        );
    }
}

/// Defect 2: with noisy pixels and a noisy second pose, holding two whole poses (12 degrees
/// of freedom) biases the solution; the similarity gauge (7) reaches a lower cost and a
/// smaller point error (after a similarity alignment to the truth, which removes the gauge),
/// holds the reference pose and the distance exactly, and the scale-only gauge reaches the same
/// optimum.
#[test]
fn the_similarity_gauge_beats_two_fixed_images() {
    // Four images 0.5 rad apart on the ring: the held second pose carries much weight.
    let truth = scene(9, 4, 80);
    let mut cost_ratios = Vec::new();
    let mut error_ratios = Vec::new();
    for seed in 0..4 {
        let start = perturbed(&noisy(&truth, 20 + seed, 0.5), 30 + seed);
        let fixed = start
            .solve(&options(Gauge::FixedImages, vec![0, 1]))
            .unwrap();
        let sim = start.solve(&options(similarity(), vec![])).unwrap();
        let scale = start
            .solve(&options(
                Gauge::ScaleOnly {
                    first_image: 0,
                    second_image: 1,
                },
                vec![],
            ))
            .unwrap();
        for r in [&fixed, &sim, &scale] {
            assert!(
                r.summary.termination.is_converged(),
                "{}",
                r.summary.report()
            );
        }
        // The similarity gauge holds image 0 and the distance of image 1's centre.
        assert!(
            sim.camera_from_world[0]
                .rotation
                .angle_to(&start.camera_from_world[0].rotation)
                < 1e-15
        );
        assert_eq!(
            sim.camera_from_world[0].translation,
            start.camera_from_world[0].translation
        );
        let d0 = (centre(&start.camera_from_world[1]) - centre(&start.camera_from_world[0])).norm();
        let d = (centre(&sim.camera_from_world[1]) - centre(&sim.camera_from_world[0])).norm();
        assert!((d / d0 - 1.0).abs() < 1e-13, "{}", d / d0 - 1.0);
        // Image 1 moved (its pose is not held): by more than the noise would allow otherwise.
        let moved =
            (centre(&sim.camera_from_world[1]) - centre(&start.camera_from_world[1])).norm();
        assert!(moved > 1e-3, "{moved}");
        // The scale-only gauge: the distance held by its prior, the same optimum.
        let ds = (centre(&scale.camera_from_world[1]) - centre(&scale.camera_from_world[0])).norm();
        // Measured: 5e-14 at most (the prior pulls along a pure gauge direction).
        assert!((ds / d0 - 1.0).abs() < 1e-10, "{}", ds / d0 - 1.0);
        let (c_fixed, c_sim, c_scale) = (
            fixed.summary.final_cost,
            sim.summary.final_cost,
            scale.summary.final_cost,
        );
        assert!((c_scale / c_sim - 1.0).abs() < 1e-6, "{c_scale} vs {c_sim}");
        eprintln!(
            "seed {seed}: similarity gauge distance error {:.1e}, scale-only {:.1e} (relative); scale-only cost / similarity cost - 1 = {:.1e}",
            d / d0 - 1.0,
            ds / d0 - 1.0,
            c_scale / c_sim - 1.0
        );
        let e_fixed = aligned_rms(&fixed.points, &truth.points);
        let e_sim = aligned_rms(&sim.points, &truth.points);
        let e_scale = aligned_rms(&scale.points, &truth.points);
        assert!((e_scale / e_sim - 1.0).abs() < 1e-4, "{e_scale} vs {e_sim}");
        eprintln!(
            "seed {seed}: final cost 12-DoF {c_fixed:.4} vs 7-DoF {c_sim:.4} (+{:.1} %), aligned point RMS 12-DoF {:.3} mm vs 7-DoF {:.3} mm (+{:.1} %)",
            100.0 * (c_fixed / c_sim - 1.0),
            1e3 * e_fixed,
            1e3 * e_sim,
            100.0 * (e_fixed / e_sim - 1.0)
        );
        cost_ratios.push(c_fixed / c_sim);
        error_ratios.push(e_fixed / e_sim);
    }
    for (&c, &e) in cost_ratios.iter().zip(&error_ratios) {
        // The 7-DoF optimum is the unconstrained one: never above the 12-DoF cost.
        assert!(c >= 1.0, "{c}");
        // Measured: the 12-DoF cost is 49 % to 698 % higher and its point error 15 % to
        // 142 % larger over the four seeds; asserted with a margin.
        assert!(c > 1.3, "{c}");
        assert!(e > 1.1, "{e}");
    }
    let mean_error_ratio = error_ratios.iter().sum::<f64>() / error_ratios.len() as f64;
    assert!(mean_error_ratio > 1.3, "{mean_error_ratio}");
}

/// Bad gauges are named.
#[test]
fn bad_gauges_are_rejected() {
    let truth = scene(13, 4, 20);
    for gauge in [
        Gauge::Similarity {
            reference_image: 0,
            scale_image: 9,
        },
        Gauge::Similarity {
            reference_image: 2,
            scale_image: 2,
        },
        Gauge::ScaleOnly {
            first_image: 1,
            second_image: 1,
        },
    ] {
        assert!(matches!(
            truth.solve(&options(gauge, vec![])),
            Err(BundleAdjustError::InvalidOption { name: "gauge", .. })
        ));
    }
}

/// Online use of a bundle adjustment's problem: hold the principal point and the distortion
/// of the camera (`set_constant_subset`) while refining the focal lengths with the poses and
/// points; the held entries stay bit-identical, the focal lengths return to the truth.
#[test]
fn some_intrinsics_are_held_in_a_bundle_adjustment() {
    let truth = scene(17, 8, 60);
    let mut start = perturbed(&truth, 18);
    let mut params = start.cameras[0].params().to_vec();
    params[4] *= 1.01;
    params[5] *= 0.99;
    start.cameras[0].set_params(&params).unwrap();
    let options = BundleAdjustmentOptions {
        optimize_intrinsics: true,
        ..options(similarity(), vec![])
    };
    let mut ba = start.to_problem(&options).unwrap();
    let intrinsics = ba.intrinsics[0];
    // [k1, k2, p1, p2, fx, fy, cx, cy]: all but the focal lengths held.
    ba.problem
        .set_constant_subset(intrinsics, &[0, 1, 2, 3, 6, 7])
        .unwrap();
    let summary = ba.problem.solve(&options.solver).unwrap();
    assert!(summary.termination.is_converged(), "{}", summary.report());
    let solved = ba.problem.parameter_block(intrinsics).unwrap();
    for k in [0, 1, 2, 3, 6, 7] {
        assert_eq!(solved[k].to_bits(), params[k].to_bits(), "entry {k}");
    }
    let true_params = truth.cameras[0].params();
    for k in [4, 5] {
        // Up to the scene's similarity, which leaves focal lengths alone.
        assert!(
            (solved[k] - true_params[k]).abs() < 1e-6,
            "{k}: {} vs {}",
            solved[k],
            true_params[k]
        );
        assert!((params[k] - true_params[k]).abs() > 4.0);
    }
    assert!(summary.final_cost < 1e-15, "{}", summary.final_cost);
}

/// The new options are written in one expression, with documented defaults.
#[test]
fn the_new_options_are_written_in_one_expression() {
    let o = BundleAdjustmentOptions {
        gauge: Gauge::ScaleOnly {
            first_image: 0,
            second_image: 3,
        },
        solver: SolverOptions {
            max_solver_time_in_seconds: 0.5,
            min_reciprocal_condition_number: 1e-12,
            ..Default::default()
        },
        ..Default::default()
    };
    assert_eq!(o.fixed_images, vec![0]);
    assert_eq!(BundleAdjustmentOptions::default().gauge, Gauge::FixedImages);
    let d = SolverOptions::default();
    assert_eq!(d.max_solver_time_in_seconds, 1e9);
    assert_eq!(d.min_reciprocal_condition_number, 1e-14);
    assert!(o.solver.validate().is_ok());
    let bad = SolverOptions {
        min_reciprocal_condition_number: 1.0,
        ..Default::default()
    };
    assert!(matches!(
        bad.validate(),
        Err(BundleAdjustError::InvalidOption {
            name: "min_reciprocal_condition_number",
            ..
        })
    ));
}
