//! Robust relative pose: accuracy against the maximum-likelihood estimate under noise,
//! success at 50, 70 and 80 % outliers, model selection for planes and pure rotations,
//! too little parallax, rays beyond 90 degrees, bad input.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

#[path = "common/two_view.rs"]
mod two_view;

use ibc_pnp::nalgebra::{Isometry3, Matrix3, Point3, UnitQuaternion, Vector3};
use ibc_pnp::{
    RansacOptions, RefineOptions, RelativePoseError, RelativePoseOptions, TwoViewModel,
    angle_from_pixels, refine_relative_pose, relative_pose,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use two_view::*;

fn options(seed: u64) -> RelativePoseOptions {
    RelativePoseOptions {
        ransac: RansacOptions {
            seed,
            ..RelativePoseOptions::default().ransac
        },
        ..Default::default()
    }
}

#[test]
fn noise_refined_pose_matches_the_maximum_likelihood_estimate() {
    // f = 800 equivalent, 1 px noise, n = 100, 300 trials: the robust solve (no outliers)
    // against refining the same cost from the true pose.
    let sigma = 1.0 / FOCAL;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut rot, mut trans, mut rot_ml, mut trans_ml) = (vec![], vec![], vec![], vec![]);
    for trial in 0..300 {
        let s = pinhole_pair(&mut rng, 100, sigma, 0);
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        assert!(matches!(result.model, TwoViewModel::Essential { .. }));
        let ml = refine_relative_pose(&s.a, &s.b, &s.b_from_a, &RefineOptions::default()).unwrap();
        rot.push(rotation_error(&result.b_from_a, &s.b_from_a));
        trans.push(translation_direction_error(&result.b_from_a, &s.b_from_a));
        rot_ml.push(rotation_error(&ml.b_from_a, &s.b_from_a));
        trans_ml.push(translation_direction_error(&ml.b_from_a, &s.b_from_a));
    }
    let (r, t, r_ml, t_ml) = (
        median(&rot),
        median(&trans),
        median(&rot_ml),
        median(&trans_ml),
    );
    eprintln!(
        "median rotation error {:.5} deg (ML {:.5}), translation direction {:.4} deg (ML {:.4})",
        r.to_degrees(),
        r_ml.to_degrees(),
        t.to_degrees(),
        t_ml.to_degrees()
    );
    assert!(r <= 1.05 * r_ml, "rotation {r} vs ML {r_ml}");
    assert!(t <= 1.05 * t_ml, "translation {t} vs ML {t_ml}");
}

/// Success: the essential model; at least 95 % of the true inliers found and at most 3 % of
/// the outliers accepted (a random match within the threshold of its epipolar line and in
/// front of both cameras cannot be told apart: about 1.5 % of the outliers here); the pose the
/// optimum of its inliers (within 1e-6 rad of the refinement from the true pose on the same
/// inliers, so the search did not stop in another basin); and no wrong solution: rotation
/// within 2 degrees and translation direction within 10 degrees of the truth (the noise alone
/// gives medians of 0.18 and 0.6 degree at n = 100, with a tail to about 1 and 4 degrees
/// from the rotation-translation ambiguity of a narrow field of view).
///
/// With `progressive`, the correspondences are ordered by a quality that favours the inliers
/// without telling them apart (a score uniform on [0, 1] for an inlier, on [0.3, 1.3] for an
/// outlier, as a descriptor distance would) and sampled progressively (PROSAC). Returns the
/// successes, the wrong solutions (rotation or translation direction off by more than 2 or
/// 10 degrees) and the median iteration count; asserts every trial a success without
/// `progressive`.
fn robust_success(
    outlier_ratio: f64,
    trials: u64,
    seed: u64,
    progressive: bool,
) -> (usize, usize, f64) {
    let n = 500;
    let outliers = (n as f64 * outlier_ratio) as usize;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut successes, mut wrong) = (0, 0);
    let (mut rot, mut trans, mut iterations, mut false_ratio) = (vec![], vec![], vec![], vec![]);
    for trial in 0..trials {
        let mut s = pinhole_pair(&mut rng, n, 1.0 / FOCAL, outliers);
        let mut o = options(trial);
        if progressive {
            let mut order_rng = ChaCha8Rng::seed_from_u64(1000 + trial);
            let mut order: Vec<(f64, usize)> = (0..n)
                .map(|i| {
                    let shift = if s.outlier[i] { 0.3 } else { 0.0 };
                    (order_rng.random::<f64>() + shift, i)
                })
                .collect();
            order.sort_by(|x, y| x.0.total_cmp(&y.0));
            s.a = order.iter().map(|&(_, i)| s.a[i]).collect();
            s.b = order.iter().map(|&(_, i)| s.b[i]).collect();
            s.outlier = order.iter().map(|&(_, i)| s.outlier[i]).collect();
            o.progressive = true;
        }
        let result = relative_pose(&s.a, &s.b, &o).unwrap();
        let (ia, ib): (Vec<_>, Vec<_>) = result.inliers.iter().map(|&i| (s.a[i], s.b[i])).unzip();
        let optimum = refine_relative_pose(&ia, &ib, &s.b_from_a, &o.ransac.refine).unwrap();
        let r = rotation_error(&result.b_from_a, &s.b_from_a);
        let t = translation_direction_error(&result.b_from_a, &s.b_from_a);
        let from_optimum = rotation_error(&result.b_from_a, &optimum.b_from_a).max(
            translation_direction_error(&result.b_from_a, &optimum.b_from_a),
        );
        let true_inliers = result.inliers.iter().filter(|&&i| !s.outlier[i]).count();
        let false_inliers = result.inliers.len() - true_inliers;
        rot.push(r);
        trans.push(t);
        iterations.push(result.iterations as f64);
        false_ratio.push(false_inliers as f64 / result.inliers.len() as f64);
        let ok = matches!(result.model, TwoViewModel::Essential { .. })
            && true_inliers * 100 >= (n - outliers) * 95
            && false_inliers * 100 <= outliers * 3
            && from_optimum < 1e-6
            && r < 2f64.to_radians()
            && t < 10f64.to_radians();
        if !ok {
            eprintln!(
                "  trial {trial} failed: r {:.3} t {:.3} deg, {from_optimum:e} from the optimum, {true_inliers} true and {false_inliers} false inliers",
                r.to_degrees(),
                t.to_degrees(),
            );
        }
        successes += usize::from(ok);
        wrong += usize::from(r >= 2f64.to_radians() || t >= 10f64.to_radians());
    }
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "{:.0} % outliers{}: {successes}/{trials} successes; error median rotation {:.3} deg, translation direction {:.3} deg, max {:.3} / {:.3} deg; outliers among the inliers median {:.1} %, max {:.1} %; median iterations {}",
        outlier_ratio * 100.0,
        if progressive { ", progressive" } else { "" },
        median(&rot).to_degrees(),
        median(&trans).to_degrees(),
        max(&rot).to_degrees(),
        max(&trans).to_degrees(),
        median(&false_ratio) * 100.0,
        max(&false_ratio) * 100.0,
        median(&iterations)
    );
    if !progressive {
        assert_eq!(successes, trials as usize);
    }
    (successes, wrong, median(&iterations))
}

#[test]
fn robust_at_50_percent_outliers() {
    robust_success(0.5, 30, 12, false);
}

#[test]
fn robust_at_70_percent_outliers() {
    robust_success(0.7, 25, 13, false);
}

#[test]
fn robust_at_80_percent_outliers() {
    robust_success(0.8, 20, 14, false);
}

/// Progressive sampling (PROSAC) on matches ordered by a quality that favours the inliers,
/// on the same data as uniform sampling: no wrong solution, at most one trial in ten short
/// of the success criteria (PROSAC's guarantee covers the best model within the prefix of
/// the order it stopped at, not over all matches: on a narrow field of view a second pose
/// with almost as many inliers can win there), in at most half the samples.
#[test]
fn progressive_sampling_succeeds_in_fewer_samples() {
    for (ratio, trials, seed) in [(0.5, 30, 12), (0.7, 25, 13), (0.8, 20, 14)] {
        let (_, _, uniform) = robust_success(ratio, trials, seed, false);
        let (successes, wrong, progressive) = robust_success(ratio, trials, seed, true);
        assert_eq!(wrong, 0, "{ratio}");
        assert!(
            successes * 10 >= trials as usize * 9,
            "{ratio}: {successes}/{trials}"
        );
        assert!(
            progressive <= 0.5 * uniform,
            "{ratio}: {progressive} against {uniform} iterations"
        );
    }
}

#[test]
fn rays_over_190_degrees_with_outliers() {
    let mut rng = ChaCha8Rng::seed_from_u64(15);
    for trial in 0..10 {
        let s = wide_pair(&mut rng, 300, 1.0 / FOCAL, 100);
        assert!(s.a.iter().any(|f| f.z < 0.0));
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        assert!(matches!(result.model, TwoViewModel::Essential { .. }));
        assert!(rotation_error(&result.b_from_a, &s.b_from_a) < 0.2f64.to_radians());
        assert!(translation_direction_error(&result.b_from_a, &s.b_from_a) < 1f64.to_radians());
    }
}

#[test]
fn a_planar_scene_is_a_homography() {
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let mut correct = 0;
    for trial in 0..20 {
        let s = planar_pair(&mut rng, 300, 1.0 / FOCAL, 100);
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        let TwoViewModel::Homography { alternative, .. } = &result.model else {
            panic!(
                "trial {trial}: {:?} for a planar scene ({:?})",
                result.model, result.gric
            );
        };
        let true_inliers = result.inliers.iter().filter(|&&i| !s.outlier[i]).count();
        assert!(true_inliers >= 180, "{true_inliers} true inliers");
        let r = rotation_error(&result.b_from_a, &s.b_from_a);
        let t = translation_direction_error(&result.b_from_a, &s.b_from_a);
        // The decomposition's twofold ambiguity: the truth is the pose or the alternative.
        let alternative_ok = alternative.as_ref().is_some_and(|p| {
            rotation_error(&p.b_from_a, &s.b_from_a) < 1f64.to_radians()
                && translation_direction_error(&p.b_from_a, &s.b_from_a) < 5f64.to_radians()
        });
        let pose_ok = r < 1f64.to_radians() && t < 5f64.to_radians();
        assert!(pose_ok || alternative_ok, "trial {trial}: errors {r} {t}");
        correct += usize::from(pose_ok);
    }
    eprintln!("planar: the selected decomposition is the truth in {correct}/20");
}

#[test]
fn a_pure_rotation_is_reported_as_such() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let mut worst = 0.0f64;
    for trial in 0..20 {
        let s = rotation_pair(&mut rng, 300, 1.0 / FOCAL, 100);
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        assert!(
            matches!(result.model, TwoViewModel::PureRotation),
            "trial {trial}: {:?} ({:?})",
            result.model,
            result.gric
        );
        assert_eq!(result.b_from_a.translation.vector, Vector3::zeros());
        let r = rotation_error(&result.b_from_a, &s.b_from_a);
        // The least-squares rotation of the true inliers (Kabsch, by SVD).
        let mut h = Matrix3::zeros();
        for i in (0..300).filter(|&i| !s.outlier[i]) {
            h += s.b[i] * s.a[i].transpose();
        }
        let svd = h.svd(true, true);
        let clean = UnitQuaternion::from_matrix(&(svd.u.unwrap() * svd.v_t.unwrap()));
        worst = worst.max(r);
        // 1 px noise on 200 rays of a 60 degree camera: about 0.05 degree.
        assert!(
            r < 0.2f64.to_radians(),
            "rotation error {} deg",
            r.to_degrees()
        );
        assert!(result.b_from_a.rotation.angle_to(&clean) < 0.05f64.to_radians());
        let true_inliers = result.inliers.iter().filter(|&&i| !s.outlier[i]).count();
        assert!(true_inliers >= 190 && result.inliers.len() <= true_inliers + 4);
    }
    eprintln!(
        "pure rotation: worst rotation error {:.4} deg",
        worst.to_degrees()
    );
}

#[test]
fn too_little_parallax_is_an_error_that_keeps_the_rotation() {
    // A 5 cm baseline to points 4 to 8 m away: a median triangulation angle near 0.5 deg.
    let mut rng = ChaCha8Rng::seed_from_u64(18);
    let mut s = pinhole_pair(&mut rng, 200, 0.0, 0);
    let truth = s.b_from_a;
    let scaled = Isometry3::from_parts((truth.translation.vector * 0.05).into(), truth.rotation);
    // Re-render view b with the short baseline.
    let depths: Vec<f64> = (0..200).map(|i| 4.0 + (i % 40) as f64 * 0.1).collect();
    for (i, (fa, fb)) in s.a.iter().zip(s.b.iter_mut()).enumerate() {
        *fb = (scaled * Point3::from(fa * depths[i])).coords.normalize();
    }
    let error = relative_pose(
        &s.a,
        &s.b,
        &RelativePoseOptions {
            model_selection: false,
            ..options(0)
        },
    )
    .unwrap_err();
    let RelativePoseError::InsufficientParallax {
        median_parallax_deg,
        rotation,
        inliers,
        ..
    } = error
    else {
        panic!("{error:?}");
    };
    assert!(median_parallax_deg < 1.0);
    assert_eq!(inliers.len(), 200);
    assert!(rotation.angle_to(&truth.rotation) < 1e-8);
}

#[test]
fn threshold_from_pixels_and_determinism() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let s = pinhole_pair(&mut rng, 200, 1.0 / FOCAL, 60);
    let opts = RelativePoseOptions {
        ransac: RansacOptions {
            threshold: angle_from_pixels(2.0, FOCAL).unwrap(),
            seed: 3,
            ..RelativePoseOptions::default().ransac
        },
        ..Default::default()
    };
    let first = relative_pose(&s.a, &s.b, &opts).unwrap();
    let second = relative_pose(&s.a, &s.b, &opts).unwrap();
    assert_eq!(first, second);
    assert!(first.inliers.iter().all(|&i| i < 200));
    assert!(first.inlier_rms < angle_from_pixels(2.0, FOCAL).unwrap());
}

#[test]
fn bad_input_is_a_typed_error() {
    let mut rng = ChaCha8Rng::seed_from_u64(20);
    let s = pinhole_pair(&mut rng, 50, 0.0, 0);
    let o = RelativePoseOptions::default();
    assert_eq!(
        relative_pose(&s.a[..4], &s.b[..4], &o).unwrap_err(),
        RelativePoseError::NotEnoughPoints {
            solver: "relative pose",
            needed: 5,
            got: 4
        }
    );
    assert_eq!(
        relative_pose(&s.a, &s.b[..49], &o).unwrap_err(),
        RelativePoseError::LengthMismatch { a: 50, b: 49 }
    );
    let mut a = s.a.clone();
    a[17] = Vector3::new(0.0, f64::NAN, 1.0);
    assert_eq!(
        relative_pose(&a, &s.b, &o).unwrap_err(),
        RelativePoseError::NonFiniteBearing {
            view: 'a',
            index: 17
        }
    );
    a[17] = Vector3::new(0.0, 0.3, 1.0);
    assert!(matches!(
        relative_pose(&a, &s.b, &o).unwrap_err(),
        RelativePoseError::NonUnitBearing {
            view: 'a',
            index: 17,
            ..
        }
    ));
    let bad = RelativePoseOptions {
        min_parallax: -1.0,
        ..Default::default()
    };
    assert!(matches!(
        relative_pose(&s.a, &s.b, &bad).unwrap_err(),
        RelativePoseError::InvalidOption {
            name: "min_parallax",
            ..
        }
    ));
    let bad = RelativePoseOptions {
        ransac: RansacOptions {
            threshold: f64::NAN,
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(matches!(
        relative_pose(&s.a, &s.b, &bad).unwrap_err(),
        RelativePoseError::InvalidOption {
            name: "threshold",
            ..
        }
    ));
    // All correspondences the same: no pose, and no panic.
    let a = vec![s.a[0]; 30];
    let b = vec![s.b[0]; 30];
    assert!(relative_pose(&a, &b, &o).is_err());
    // Pure noise: too few inliers.
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let a: Vec<_> = (0..100).map(|_| random_unit(&mut rng)).collect();
    let b: Vec<_> = (0..100).map(|_| random_unit(&mut rng)).collect();
    let o = RelativePoseOptions {
        ransac: RansacOptions {
            max_iterations: 2000,
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(matches!(
        relative_pose(&a, &b, &o).unwrap_err(),
        RelativePoseError::TooFewInliers { .. }
    ));
    // Refinement from a pose without translation.
    assert!(matches!(
        refine_relative_pose(
            &s.a,
            &s.b,
            &Isometry3::identity(),
            &RefineOptions::default()
        ),
        Err(RelativePoseError::InvalidOption {
            name: "initial",
            ..
        })
    ));
}

#[test]
fn exact_pure_rotation_and_exact_plane() {
    // Noise-free data, where the five-point problem of a pure rotation or a plane is exactly
    // degenerate: the models are still found, exactly, with exactly the true inliers.
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    for trial in 0..5 {
        let s = rotation_pair(&mut rng, 100, 0.0, 30);
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        assert!(matches!(result.model, TwoViewModel::PureRotation));
        assert!(rotation_error(&result.b_from_a, &s.b_from_a) < 1e-10);
        assert_eq!(result.inliers, (30..100).collect::<Vec<_>>());

        let s = planar_pair(&mut rng, 100, 0.0, 30);
        let result = relative_pose(&s.a, &s.b, &options(trial)).unwrap();
        let TwoViewModel::Homography { alternative, .. } = &result.model else {
            panic!("{:?}", result.model);
        };
        assert_eq!(result.inliers, (30..100).collect::<Vec<_>>());
        let exact = |p: &Isometry3<f64>| {
            rotation_error(p, &s.b_from_a) < 1e-9
                && translation_direction_error(p, &s.b_from_a) < 1e-9
        };
        let alternative = alternative.as_ref().map(|p| {
            let t = p.b_from_a.translation.vector.normalize();
            Isometry3::from_parts(t.into(), p.b_from_a.rotation)
        });
        assert!(exact(&result.b_from_a) || alternative.as_ref().is_some_and(exact));
    }
}

/// A known relative pose (two cameras of a calibrated rig) picks the consistent
/// correspondences without a search: on a 190-degree pair with 30 % outliers it keeps at
/// least 97 % of the true inliers and at most 3 % of the outliers; the translation's norm
/// does not matter; with no translation the rotation alone decides; bad input is typed.
#[test]
fn inliers_of_a_known_pose() {
    use ibc_pnp::relative_pose_inliers;
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let threshold = RelativePoseOptions::default().ransac.threshold;
    let (n, outliers) = (500, 150);
    let s = wide_pair(&mut rng, n, 1.0 / FOCAL, outliers);
    let inliers = relative_pose_inliers(&s.a, &s.b, &s.b_from_a, threshold).unwrap();
    let true_inliers = inliers.iter().filter(|&&i| !s.outlier[i]).count();
    let false_inliers = inliers.len() - true_inliers;
    eprintln!(
        "known pose: {true_inliers} of {} inliers, {false_inliers} of {outliers} outliers",
        n - outliers
    );
    assert!(true_inliers * 100 >= (n - outliers) * 97, "{true_inliers}");
    assert!(false_inliers * 100 <= outliers * 3, "{false_inliers}");
    assert!(inliers.windows(2).all(|w| w[0] < w[1]));
    let longer = Isometry3::from_parts(
        (s.b_from_a.translation.vector * 2.5).into(),
        s.b_from_a.rotation,
    );
    assert_eq!(
        relative_pose_inliers(&s.a, &s.b, &longer, threshold).unwrap(),
        inliers
    );

    let r = rotation_pair(&mut rng, n, 1.0 / FOCAL, outliers);
    let inliers = relative_pose_inliers(&r.a, &r.b, &r.b_from_a, threshold).unwrap();
    let true_inliers = inliers.iter().filter(|&&i| !r.outlier[i]).count();
    assert!(true_inliers * 100 >= (n - outliers) * 97, "{true_inliers}");
    assert!((inliers.len() - true_inliers) * 100 <= outliers * 3);

    let err = |a: &[Vector3<f64>], b: &[Vector3<f64>], pose: &Isometry3<f64>, t: f64| {
        relative_pose_inliers(a, b, pose, t).unwrap_err()
    };
    assert!(matches!(
        err(&s.a, &s.b[1..], &s.b_from_a, threshold),
        RelativePoseError::LengthMismatch { .. }
    ));
    for bad in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            err(&s.a, &s.b, &s.b_from_a, bad),
            RelativePoseError::InvalidOption {
                name: "threshold",
                ..
            }
        ));
    }
    let mut not_finite = s.b_from_a;
    not_finite.translation.vector.x = f64::INFINITY;
    assert!(matches!(
        err(&s.a, &s.b, &not_finite, threshold),
        RelativePoseError::InvalidOption {
            name: "b_from_a",
            ..
        }
    ));
    let mut a = s.a.clone();
    a[3] *= 2.0;
    assert!(matches!(
        err(&a, &s.b, &s.b_from_a, threshold),
        RelativePoseError::NonUnitBearing {
            view: 'a',
            index: 3,
            ..
        }
    ));
    assert_eq!(
        relative_pose_inliers(&[], &[], &s.b_from_a, threshold).unwrap(),
        Vec::<usize>::new()
    );
}
