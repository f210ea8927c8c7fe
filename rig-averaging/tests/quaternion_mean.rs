//! Markley averaging: agreement with the SVD chordal mean, sign invariance, statistical
//! efficiency under isotropic noise, the conditioning figure and input errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::{assert_abs_diff_eq, assert_relative_eq};
use common::{chordal_svd_mean, random_sign, rng, rotation_noise, uniform_rotation};
use ibc_rig_averaging::{MarkleyAccumulator, RigAveragingError, pose_mean, quaternion_mean};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use rand::RngExt;

/// Rotations clustered within about 1.2 rad of a random centre (the chordal mean is then
/// well conditioned), each with a random quaternion sign, and random weights in [0.1, 10].
fn clustered(seed: u64, n: usize) -> (Vec<UnitQuaternion<f64>>, Vec<f64>) {
    let mut rng = rng(seed);
    let centre = uniform_rotation(&mut rng);
    let mut rotations = Vec::with_capacity(n);
    let mut weights = Vec::with_capacity(n);
    for _ in 0..n {
        let q = centre * rotation_noise(&mut rng, 0.4);
        rotations.push(random_sign(&mut rng, q));
        weights.push(rng.random_range(0.1..10.0));
    }
    (rotations, weights)
}

#[test]
fn equals_the_svd_projection_of_the_weighted_rotation_sum() {
    let mut worst: f64 = 0.0;
    for seed in 0..2000 {
        let n = 1 + (seed as usize % 30);
        let (rotations, weights) = clustered(seed, n);
        let markley = quaternion_mean(&rotations, Some(&weights)).unwrap();
        let svd = chordal_svd_mean(&rotations, &weights);
        worst = worst.max(markley.mean.angle_to(&svd));
    }
    println!("Markley vs SVD projection, 2000 clustered cases: worst {worst:.2e} rad");
    assert!(worst < 1e-12, "largest disagreement {worst:e} rad");
}

#[test]
fn equals_the_svd_projection_on_uniform_rotations_when_well_conditioned() {
    // Uniformly random rotations, no clustering: compare whenever the mean is unique enough
    // that rounding (about 1e-16 / conditioning) stays far below the 1e-12 tolerance.
    let mut compared = 0;
    let mut worst: f64 = 0.0;
    let mut r = rng(99);
    for _ in 0..3000 {
        let n = r.random_range(2..8);
        let rotations: Vec<_> = (0..n).map(|_| uniform_rotation(&mut r)).collect();
        let weights: Vec<f64> = (0..n).map(|_| r.random_range(0.5..2.0)).collect();
        let markley = quaternion_mean(&rotations, Some(&weights)).unwrap();
        if markley.conditioning < 1e-2 {
            continue;
        }
        compared += 1;
        let svd = chordal_svd_mean(&rotations, &weights);
        worst = worst.max(markley.mean.angle_to(&svd));
    }
    println!("Markley vs SVD projection, {compared} uniform cases: worst {worst:.2e} rad");
    assert!(worst < 1e-12, "largest disagreement {worst:e} rad");
    assert!(compared > 2000, "only {compared} cases compared");
}

#[test]
fn independent_of_input_signs_and_deterministic_output_sign() {
    for seed in 0..500 {
        let (rotations, weights) = clustered(1000 + seed, 7);
        let base = quaternion_mean(&rotations, Some(&weights)).unwrap();
        let mut r = rng(seed);
        let flipped: Vec<_> = rotations
            .iter()
            .map(|q| UnitQuaternion::new_unchecked(-q.into_inner()))
            .map(|q| random_sign(&mut r, q))
            .collect();
        let other = quaternion_mean(&flipped, Some(&weights)).unwrap();
        // q q^T is bitwise the same for -q, so the whole result is bitwise identical.
        assert_eq!(base, other);
        assert!(base.mean.w >= 0.0);
    }
    // w == 0 exactly: the first non-zero of (x, y, z) is positive.
    let about_minus_y = UnitQuaternion::new_unchecked(Quaternion::new(0.0, 0.0, -1.0, 0.0));
    let mean = quaternion_mean(&[about_minus_y], None).unwrap();
    assert_eq!(mean.mean.coords, Vector3::new(0.0, 1.0, 0.0).push(0.0));
}

#[test]
fn rms_error_under_isotropic_noise_matches_sqrt3_sigma_over_sqrt_n() {
    // R_i = R exp(n_i), n_i ~ N(0, sigma^2 I): to first order the mean's error vector is the
    // average of the n_i, whose squared norm has expectation 3 sigma^2 / N. With T trials the
    // relative standard error of the RMS is sqrt(2/3) / (2 sqrt(T)) ~ 0.65 % at T = 4000, so the
    // 5 % band is about 7 standard errors wide.
    let trials = 4000;
    for (n, sigma, seed) in [(5, 0.005, 1), (10, 0.01, 2), (40, 0.02, 3)] {
        let mut r = rng(seed);
        let mut sum_sq = 0.0;
        for _ in 0..trials {
            let truth = uniform_rotation(&mut r);
            let rotations: Vec<_> = (0..n)
                .map(|_| {
                    let q = truth * rotation_noise(&mut r, sigma);
                    random_sign(&mut r, q)
                })
                .collect();
            let mean = quaternion_mean(&rotations, None).unwrap();
            sum_sq += mean.mean.angle_to(&truth).powi(2);
        }
        let rms = (sum_sq / trials as f64).sqrt();
        let expected = 3.0f64.sqrt() * sigma / (n as f64).sqrt();
        println!(
            "N = {n}, sigma = {sigma}: RMS {rms:.4e}, expected {expected:.4e}, ratio {:.4}",
            rms / expected
        );
        assert_relative_eq!(rms, expected, max_relative = 0.05);
    }
}

#[test]
fn inverse_variance_weights_reach_the_weighted_bound() {
    // Noise sigma_i per input and weights 1 / sigma_i^2: E[err^2] = 3 / sum_i sigma_i^-2.
    let trials = 4000;
    let sigmas = [0.002, 0.004, 0.008, 0.016, 0.002, 0.01];
    let weights: Vec<f64> = sigmas.iter().map(|s| 1.0 / (s * s)).collect();
    let expected = (3.0 / weights.iter().sum::<f64>()).sqrt();
    let mut r = rng(5);
    let mut sum_sq = 0.0;
    for _ in 0..trials {
        let truth = uniform_rotation(&mut r);
        let rotations: Vec<_> = sigmas
            .iter()
            .map(|&s| truth * rotation_noise(&mut r, s))
            .collect();
        let mean = quaternion_mean(&rotations, Some(&weights)).unwrap();
        sum_sq += mean.mean.angle_to(&truth).powi(2);
    }
    let rms = (sum_sq / trials as f64).sqrt();
    assert_relative_eq!(rms, expected, max_relative = 0.05);
}

#[test]
fn naive_sign_unaligned_mean_is_far_off_where_markley_is_not() {
    // The naive average normalizes sum_i q_i without aligning signs. With random signs the
    // inputs partly cancel; Markley is unaffected.
    let mut r = rng(11);
    let mut naive_sq = 0.0;
    let mut markley_sq = 0.0;
    let trials = 1000;
    for _ in 0..trials {
        let truth = uniform_rotation(&mut r);
        let rotations: Vec<_> = (0..10)
            .map(|_| {
                let q = truth * rotation_noise(&mut r, 0.05);
                random_sign(&mut r, q)
            })
            .collect();
        let sum = rotations
            .iter()
            .fold(Quaternion::new(0.0, 0.0, 0.0, 0.0), |acc, q| {
                acc + q.into_inner()
            });
        if sum.norm() > 1e-9 {
            naive_sq += UnitQuaternion::from_quaternion(sum)
                .angle_to(&truth)
                .powi(2);
        } else {
            naive_sq += std::f64::consts::PI.powi(2);
        }
        markley_sq += quaternion_mean(&rotations, None)
            .unwrap()
            .mean
            .angle_to(&truth)
            .powi(2);
    }
    let naive = (naive_sq / trials as f64).sqrt().to_degrees();
    let markley = (markley_sq / trials as f64).sqrt().to_degrees();
    println!("RMS error: naive {naive:.3} deg, Markley {markley:.3} deg");
    assert!(naive > 10.0 * markley);
}

#[test]
fn two_rotations_conditioning_is_cos_half_angle_and_flags_the_half_turn() {
    // M = q1 q1^T + q2 q2^T has eigenvalues 1 +- |q1 . q2| = 1 +- cos(theta/2), so the
    // conditioning figure (gap over weight sum 2) is cos(theta/2).
    let axis = Vector3::new(0.3, -0.5, 0.8);
    let axis = nalgebra::Unit::new_normalize(axis);
    let base = UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1);
    for k in 0..=100 {
        let theta = std::f64::consts::PI * k as f64 / 100.0;
        let other = base * UnitQuaternion::from_axis_angle(&axis, theta);
        let mean = quaternion_mean(&[base, other], None).unwrap();
        assert_abs_diff_eq!(mean.conditioning, (theta / 2.0).cos(), epsilon = 1e-14);
        if k < 100 {
            // The mean is the midpoint.
            assert_abs_diff_eq!(mean.mean.angle_to(&base), theta / 2.0, epsilon = 1e-12);
        }
    }
    let half_turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI);
    let degenerate = quaternion_mean(&[UnitQuaternion::identity(), half_turn], None).unwrap();
    assert!(degenerate.conditioning < 1e-15);
    assert!(!degenerate.is_well_conditioned(1e-6));
    assert_abs_diff_eq!(degenerate.eigenvalues[0], 0.5, epsilon = 1e-15);
    assert_abs_diff_eq!(degenerate.eigenvalues[1], 0.5, epsilon = 1e-15);
    // Unequal weights make the heavier rotation the unique mean: gap 1/3 of the weight sum.
    let weighted =
        quaternion_mean(&[UnitQuaternion::identity(), half_turn], Some(&[2.0, 1.0])).unwrap();
    assert_abs_diff_eq!(weighted.conditioning, 1.0 / 3.0, epsilon = 1e-15);
    assert_abs_diff_eq!(weighted.mean.angle(), 0.0, epsilon = 1e-15);
    // Identity and the three half turns about the axes: M = I / 4 . W, all eigenvalues equal.
    let quads = [
        UnitQuaternion::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI),
        half_turn,
    ];
    assert!(quaternion_mean(&quads, None).unwrap().conditioning < 1e-15);
    // A single rotation is perfectly conditioned.
    let single = quaternion_mean(&[base], None).unwrap();
    assert_abs_diff_eq!(single.conditioning, 1.0, epsilon = 1e-15);
    assert!(single.mean.angle_to(&base) < 1e-15);
}

#[test]
fn accumulator_matches_the_slice_function() {
    let (rotations, weights) = clustered(42, 12);
    let mut acc = MarkleyAccumulator::new();
    assert!(acc.is_empty());
    for (q, w) in rotations.iter().zip(&weights) {
        acc.add(q, *w).unwrap();
    }
    assert_eq!(acc.len(), 12);
    let streamed = acc.finish().unwrap();
    let sliced = quaternion_mean(&rotations, Some(&weights)).unwrap();
    assert!(streamed.mean.angle_to(&sliced.mean) < 1e-14);
    assert_abs_diff_eq!(streamed.conditioning, sliced.conditioning, epsilon = 1e-14);
}

#[test]
fn extreme_but_valid_weights_work_in_the_slice_function() {
    let a = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1);
    let b = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3);
    for scale in [1e-310, 1e-300, 1.0, 1e300, f64::MAX] {
        let mean = quaternion_mean(&[a, b], Some(&[scale, scale])).unwrap();
        assert_abs_diff_eq!(mean.mean.angle(), 0.2, epsilon = 1e-14);
    }
    // The streaming accumulator uses weights as given and reports an overflowing sum.
    let mut acc = MarkleyAccumulator::new();
    acc.add(&a, f64::MAX).unwrap();
    acc.add(&b, f64::MAX).unwrap();
    assert!(matches!(
        acc.finish(),
        Err(RigAveragingError::WeightsOutOfRange { .. })
    ));
}

#[test]
fn invalid_inputs_are_typed_errors() {
    let q = UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3);
    assert_eq!(
        quaternion_mean(&[], None),
        Err(RigAveragingError::EmptyInput)
    );
    assert_eq!(
        MarkleyAccumulator::new().finish(),
        Err(RigAveragingError::EmptyInput)
    );
    assert_eq!(
        quaternion_mean(&[q, q], Some(&[1.0])),
        Err(RigAveragingError::WeightCountMismatch {
            inputs: 2,
            weights: 1
        })
    );
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, -0.0] {
        let err = quaternion_mean(&[q, q], Some(&[1.0, bad])).unwrap_err();
        assert!(
            matches!(err, RigAveragingError::InvalidWeight { index: 1, .. }),
            "{err}"
        );
    }
    let not_unit = UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0));
    assert!(matches!(
        quaternion_mean(&[q, not_unit], None),
        Err(RigAveragingError::NotUnitQuaternion { index: 1, norm }) if norm == 2.0
    ));
    let nan = UnitQuaternion::new_unchecked(Quaternion::new(f64::NAN, 0.0, 0.0, 0.0));
    assert!(matches!(
        quaternion_mean(&[nan], None),
        Err(RigAveragingError::NotUnitQuaternion { index: 0, .. })
    ));
    let mut acc = MarkleyAccumulator::new();
    assert!(acc.add(&not_unit, 1.0).is_err());
    assert!(acc.add(&q, 0.0).is_err());
    assert!(acc.is_empty());
    // Rounding-level drift from unit norm is accepted.
    let drifted = UnitQuaternion::new_unchecked(q.into_inner() * (1.0 + 1e-9));
    assert!(quaternion_mean(&[drifted], None).is_ok());
    // Messages say what was wrong.
    let message = quaternion_mean(&[not_unit], None).unwrap_err().to_string();
    assert!(message.contains("norm 2"), "{message}");
}

#[test]
fn pose_mean_averages_rotation_and_translation() {
    let (rotations, weights) = clustered(7, 9);
    let mut r = rng(8);
    let poses: Vec<Isometry3<f64>> = rotations
        .iter()
        .map(|q| {
            let t = Vector3::new(
                r.random_range(-5.0..5.0),
                r.random_range(-5.0..5.0),
                r.random_range(-5.0..5.0),
            );
            Isometry3::from_parts(Translation3::from(t), *q)
        })
        .collect();
    let mean = pose_mean(&poses, Some(&weights)).unwrap();
    let w_sum: f64 = weights.iter().sum();
    let expected_t = poses
        .iter()
        .zip(&weights)
        .fold(Vector3::zeros(), |acc, (p, w)| {
            acc + *w * p.translation.vector
        })
        / w_sum;
    assert_abs_diff_eq!(mean.mean.translation.vector, expected_t, epsilon = 1e-12);
    let rotation = quaternion_mean(&rotations, Some(&weights)).unwrap();
    assert!(mean.mean.rotation.angle_to(&rotation.mean) < 1e-15);
    assert_eq!(mean.rotation.conditioning, rotation.conditioning);

    let mut bad = poses.clone();
    bad[3].translation.vector.y = f64::NAN;
    assert_eq!(
        pose_mean(&bad, None),
        Err(RigAveragingError::NonFiniteTranslation { index: 3 })
    );
    assert_eq!(pose_mean(&[], None), Err(RigAveragingError::EmptyInput));
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: Some(Box::new(
            proptest::test_runner::FileFailurePersistence::WithSource("proptest-regressions"),
        )),
        ..ProptestConfig::default()
    })]

    #[test]
    fn prop_markley_is_the_chordal_mean(
        centre in (-3.0..3.0f64, -3.0..3.0f64, -3.0..3.0f64),
        spread in prop::collection::vec(
            ((-0.6..0.6f64, -0.6..0.6f64, -0.6..0.6f64), 0.1..10.0f64, any::<bool>()),
            1..20,
        ),
    ) {
        let centre = UnitQuaternion::from_scaled_axis(Vector3::new(centre.0, centre.1, centre.2));
        let mut rotations = Vec::new();
        let mut weights = Vec::new();
        for ((x, y, z), w, flip) in spread {
            let q = centre * UnitQuaternion::from_scaled_axis(Vector3::new(x, y, z));
            rotations.push(if flip { UnitQuaternion::new_unchecked(-q.into_inner()) } else { q });
            weights.push(w);
        }
        let markley = quaternion_mean(&rotations, Some(&weights)).unwrap();
        let svd = chordal_svd_mean(&rotations, &weights);
        prop_assert!(markley.mean.angle_to(&svd) < 1e-12);
        prop_assert!(markley.mean.w >= 0.0);
        prop_assert!((0.0..=1.0).contains(&markley.conditioning));
        let eigen_sum: f64 = markley.eigenvalues.iter().sum();
        prop_assert!((eigen_sum - 1.0).abs() < 1e-12);
    }

    #[test]
    fn prop_mean_is_equivariant_under_left_and_right_rotation(
        seed in any::<u64>(),
        n in 1usize..12,
        left in (-3.0..3.0f64, -3.0..3.0f64, -3.0..3.0f64),
        right in (-3.0..3.0f64, -3.0..3.0f64, -3.0..3.0f64),
    ) {
        // The chordal mean of {A R_i B} is A mean(R_i) B.
        let (rotations, weights) = clustered(seed, n);
        let a = UnitQuaternion::from_scaled_axis(Vector3::new(left.0, left.1, left.2));
        let b = UnitQuaternion::from_scaled_axis(Vector3::new(right.0, right.1, right.2));
        let moved: Vec<_> = rotations.iter().map(|q| a * q * b).collect();
        let m = quaternion_mean(&rotations, Some(&weights)).unwrap();
        let m_moved = quaternion_mean(&moved, Some(&weights)).unwrap();
        prop_assert!((a * m.mean * b).angle_to(&m_moved.mean) < 1e-12);
        prop_assert!((m.conditioning - m_moved.conditioning).abs() < 1e-12);
    }
}
