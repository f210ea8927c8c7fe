//! Robust averaging: one bad input among many is ignored, clean data is barely affected.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use approx::assert_abs_diff_eq;
use common::{random_sign, rng, rotation_noise, uniform_rotation};
use ibc_rig_averaging::{
    RobustOptions, pose_mean, quaternion_mean, robust_pose_mean, robust_quaternion_mean,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_distr::{Distribution, Normal};

const TRIALS: usize = 1000;

/// RMS errors (plain Markley, robust) over trials of `n - 1` noisy inliers plus one outlier
/// rotated `outlier_angle` away from the truth about a random axis; also the RMS error of
/// Markley on the inliers alone and the largest robust weight given to the outlier.
fn outlier_trials(seed: u64, n: usize, sigma: f64, outlier_angle: f64) -> [f64; 4] {
    let mut r = rng(seed);
    let (mut plain, mut robust, mut clean, mut max_outlier_weight) = (0.0, 0.0, 0.0, 0.0f64);
    for _ in 0..TRIALS {
        let truth = uniform_rotation(&mut r);
        let mut rotations: Vec<_> = (0..n - 1)
            .map(|_| {
                let q = truth * rotation_noise(&mut r, sigma);
                random_sign(&mut r, q)
            })
            .collect();
        let axis = uniform_rotation(&mut r) * Vector3::x_axis();
        let position = r.random_range(0..n);
        let clean_mean = quaternion_mean(&rotations, None).unwrap().mean;
        rotations.insert(
            position,
            truth * UnitQuaternion::from_axis_angle(&axis, outlier_angle),
        );
        let p = quaternion_mean(&rotations, None).unwrap().mean;
        let rb = robust_quaternion_mean(&rotations, None, &RobustOptions::default()).unwrap();
        assert!(rb.diagnostics.converged);
        plain += p.angle_to(&truth).powi(2);
        robust += rb.mean.mean.angle_to(&truth).powi(2);
        clean += clean_mean.angle_to(&truth).powi(2);
        max_outlier_weight = max_outlier_weight.max(rb.diagnostics.robust_weights[position]);
    }
    let rms = |s: f64| (s / TRIALS as f64).sqrt();
    [rms(plain), rms(robust), rms(clean), max_outlier_weight]
}

#[test]
fn one_outlier_among_many_is_ignored() {
    for (n, sigma, angle, seed) in [
        (10, 0.01, 0.5, 1),
        (20, 0.005, 1.6, 2),
        (6, 0.01, 1.0, 3),
        (20, 0.005, std::f64::consts::PI, 5),
        (30, 0.002, 0.1, 4),
    ] {
        let [plain, robust, clean, outlier_weight] = outlier_trials(seed, n, sigma, angle);
        println!(
            "N = {n}, sigma = {sigma}, outlier {angle} rad: RMS plain {plain:.2e}, robust \
             {robust:.2e}, inliers only {clean:.2e}, outlier weight <= {outlier_weight:.1e}"
        );
        // The robust mean is as good as the mean of the inliers alone (within 10 %), the plain
        // mean is not, except for a half-turn outlier: its quaternion is orthogonal to the
        // truth's, so q q^T leaves the top eigenvector (nearly) in place and the chordal mean
        // hardly moves.
        assert!(
            robust < 1.1 * clean,
            "robust {robust} vs inliers-only {clean}"
        );
        if angle < 3.0 {
            assert!(plain > 2.0 * robust);
        }
        assert!(outlier_weight < 0.02);
    }
}

#[test]
fn clean_data_loses_little_efficiency() {
    // Without outliers the Cauchy estimator should stay close to the optimal Markley mean.
    let mut r = rng(21);
    let (n, sigma) = (15, 0.01);
    let (mut plain, mut robust) = (0.0, 0.0);
    for _ in 0..TRIALS {
        let truth = uniform_rotation(&mut r);
        let rotations: Vec<_> = (0..n)
            .map(|_| truth * rotation_noise(&mut r, sigma))
            .collect();
        plain += quaternion_mean(&rotations, None)
            .unwrap()
            .mean
            .angle_to(&truth)
            .powi(2);
        robust += robust_quaternion_mean(&rotations, None, &RobustOptions::default())
            .unwrap()
            .mean
            .mean
            .angle_to(&truth)
            .powi(2);
    }
    let ratio = (robust / plain).sqrt();
    println!("clean data: robust / plain RMS = {ratio:.4}");
    assert!(ratio < 1.08, "{ratio}");
}

#[test]
fn exact_inliers_are_recovered_exactly() {
    let truth = UnitQuaternion::from_euler_angles(0.4, -0.2, 1.0);
    let mut rotations = vec![truth; 8];
    rotations.push(UnitQuaternion::from_euler_angles(2.0, 1.0, -1.0));
    let rb = robust_quaternion_mean(&rotations, None, &RobustOptions::default()).unwrap();
    assert!(rb.mean.mean.angle_to(&truth) < 1e-12);
    assert!(rb.diagnostics.robust_weights[8] < 1e-20);
}

#[test]
fn fewer_than_three_inputs_give_the_plain_mean() {
    let a = UnitQuaternion::from_euler_angles(0.1, 0.0, 0.0);
    let b = UnitQuaternion::from_euler_angles(1.1, 0.0, 0.0);
    let rb = robust_quaternion_mean(&[a, b], Some(&[1.0, 2.0]), &RobustOptions::default()).unwrap();
    let plain = quaternion_mean(&[a, b], Some(&[1.0, 2.0])).unwrap();
    assert_eq!(rb.mean, plain);
    assert_eq!(rb.diagnostics.robust_weights, vec![1.0, 1.0]);
    assert!(rb.diagnostics.rotation_scale.is_infinite());
}

#[test]
fn fixed_scale_and_weights_are_honoured() {
    // With a fixed scale of 1 degree, a 10 degree outlier gets weight about 1 / 101.
    let truth = UnitQuaternion::identity();
    let mut rotations = vec![truth; 5];
    rotations.push(UnitQuaternion::from_axis_angle(
        &Vector3::z_axis(),
        10f64.to_radians(),
    ));
    let options = RobustOptions::default().with_rotation_scale(1f64.to_radians());
    let rb = robust_quaternion_mean(&rotations, None, &options).unwrap();
    assert_eq!(rb.diagnostics.rotation_scale, 1f64.to_radians());
    let w = rb.diagnostics.robust_weights[5];
    assert!((1.0 / 102.0..1.0 / 100.0).contains(&w), "{w}");
    // Caller weights multiply the robust weights: a tiny caller weight on the outlier moves
    // the mean even less.
    let heavy =
        robust_quaternion_mean(&rotations, Some(&[1.0, 1.0, 1.0, 1.0, 1.0, 1e-6]), &options)
            .unwrap();
    assert!(heavy.mean.mean.angle() < rb.mean.mean.angle());
}

#[test]
fn robust_pose_mean_rejects_a_translation_outlier() {
    let mut r = rng(31);
    let normal = Normal::new(0.0, 0.01).unwrap();
    let truth = Isometry3::new(Vector3::new(1.0, 2.0, 3.0), Vector3::new(0.1, 0.2, 0.3));
    let mut poses: Vec<Isometry3<f64>> = (0..12)
        .map(|_| {
            let dt = Vector3::new(
                normal.sample(&mut r),
                normal.sample(&mut r),
                normal.sample(&mut r),
            );
            Isometry3::from_parts(
                Translation3::from(truth.translation.vector + dt),
                truth.rotation * rotation_noise(&mut r, 0.002),
            )
        })
        .collect();
    let clean = pose_mean(&poses, None).unwrap().mean;
    // Right rotation, translation 2 m off.
    poses.push(Isometry3::from_parts(
        Translation3::from(truth.translation.vector + Vector3::new(2.0, 0.0, 0.0)),
        truth.rotation,
    ));
    let plain = pose_mean(&poses, None).unwrap().mean;
    let rb = robust_pose_mean(&poses, None, &RobustOptions::default()).unwrap();
    let t_err = |p: &Isometry3<f64>| (p.translation.vector - truth.translation.vector).norm();
    println!(
        "translation error: clean {:.3e}, plain {:.3e}, robust {:.3e}",
        t_err(&clean),
        t_err(&plain),
        t_err(&rb.mean.mean)
    );
    assert!(t_err(&plain) > 0.1);
    assert!(t_err(&rb.mean.mean) < 0.02);
    assert!(rb.diagnostics.robust_weights[12] < 1e-3);
    assert!(rb.diagnostics.translation_scale.unwrap() > 0.0);
    assert!(rb.diagnostics.converged);
    assert_abs_diff_eq!(
        rb.mean.mean.rotation.angle_to(&truth.rotation),
        0.0,
        epsilon = 3e-3
    );
}
