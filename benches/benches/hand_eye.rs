//! Benchmarks of `ibc-hand-eye` on OpenCV's hand-eye simulation (10 poses, all 45 pairs, and
//! 30 poses, 435 pairs; noise of 2 mrad / 5 mm on the camera, 1 mrad / 1 mm on the robot),
//! against a same-run baseline: nalgebra's SVD (right vectors only) of a `6m x 8` matrix, the
//! core of Daniilidis' method for `m` motions.
//!
//! Run with `cargo bench -p ibc-benches --bench hand_eye`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use ibc_benches::bench_rng;
use ibc_hand_eye::{
    DaniilidisOptions, MotionPair, Pairing, PlanarOptions, TrajectoryOptions, daniilidis,
    guo_planar, refine_trajectories, relative_motions,
};
use nalgebra::{DMatrix, Isometry3, Vector3, linalg::SVD};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

const DEG: f64 = std::f64::consts::PI / 180.0;

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random::<bool>() { 1.0 } else { -1.0 }
}

/// OpenCV's `generatePose` (random-sign ranges for the angle and each translation component).
fn pose(rng: &mut ChaCha8Rng, theta: (f64, f64), t: (f64, f64)) -> Isometry3<f64> {
    let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
    let angle = rng.random_range(theta.0..theta.1) * sign(rng);
    let translation = Vector3::from_fn(|_, _| rng.random_range(t.0..t.1) * sign(rng));
    Isometry3::new(translation, axis * angle)
}

/// Noise of standard deviation `sigma` (uniform, which is all a timing needs) on the rotation
/// vector and translation.
fn noisy(rng: &mut ChaCha8Rng, p: &Isometry3<f64>, sigma: (f64, f64)) -> Isometry3<f64> {
    let half = 3f64.sqrt();
    let mut draw = |s: f64| Vector3::from_fn(|_, _| rng.random_range(-half..half) * s);
    Isometry3::new(
        p.translation.vector + draw(sigma.1),
        p.rotation.scaled_axis() + draw(sigma.0),
    )
}

/// `(world_from_rig, world_from_odometry)`: OpenCV's eye-in-hand simulation, or a vehicle
/// moving in its plane.
fn trajectories(
    poses: usize,
    planar: bool,
    stream: u64,
) -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
    let mut rng = bench_rng(stream);
    let odometry_from_rig = pose(&mut rng, (10.0 * DEG, 50.0 * DEG), (0.05, 0.5));
    let map_from_world = pose(&mut rng, (5.0 * DEG, 85.0 * DEG), (0.5, 3.5));
    let (mut rig, mut odometry) = (Vec::new(), Vec::new());
    for _ in 0..poses {
        let o = if planar {
            let xy = Vector3::from_fn(|k, _| {
                if k < 2 {
                    rng.random_range(-3.5..3.5)
                } else {
                    0.0
                }
            });
            Isometry3::new(xy, Vector3::z() * rng.random_range(-3.1..3.1))
        } else {
            pose(&mut rng, (5.0 * DEG, 45.0 * DEG), (0.5, 1.5))
        };
        let camera_from_map = (map_from_world * o * odometry_from_rig).inverse();
        rig.push(noisy(&mut rng, &camera_from_map, (0.002, 0.005)).inverse());
        odometry.push(if planar {
            o
        } else {
            noisy(&mut rng, &o, (0.001, 0.001))
        });
    }
    (rig, odometry)
}

fn motions(rig: &[Isometry3<f64>], odometry: &[Isometry3<f64>]) -> Vec<MotionPair> {
    relative_motions(rig, odometry, Pairing::All).unwrap()
}

fn bench_hand_eye(c: &mut Criterion) {
    let mut group = c.benchmark_group("hand_eye");
    for poses in [10usize, 30] {
        let pairs = poses * (poses - 1) / 2;
        let (rig, odometry) = trajectories(poses, false, 1);
        let general = motions(&rig, &odometry);
        let (planar_rig, planar_odometry) = trajectories(poses, true, 2);
        let planar = motions(&planar_rig, &planar_odometry);
        let mut rng = bench_rng(3);
        let matrix = DMatrix::from_fn(6 * pairs, 8, |_, _| rng.random_range(-1.0..1.0));

        group.bench_function(BenchmarkId::new("baseline_svd_6m_x_8", pairs), |b| {
            b.iter(|| SVD::new(black_box(matrix.clone()), false, true).singular_values)
        });
        group.bench_function(BenchmarkId::new("relative_motions_all_pairs", pairs), |b| {
            b.iter(|| motions(black_box(&rig), black_box(&odometry)))
        });
        let options = DaniilidisOptions::default();
        group.bench_function(BenchmarkId::new("daniilidis", pairs), |b| {
            b.iter(|| daniilidis(black_box(&general), &options).unwrap().a_from_b)
        });
        let options = PlanarOptions::default();
        group.bench_function(BenchmarkId::new("guo_planar", pairs), |b| {
            b.iter(|| guo_planar(black_box(&planar), &options).unwrap().a_from_b)
        });
        let options = PlanarOptions {
            estimate_scale: true,
            ..Default::default()
        };
        group.bench_function(BenchmarkId::new("guo_planar_scale", pairs), |b| {
            b.iter(|| guo_planar(black_box(&planar), &options).unwrap().a_from_b)
        });
        let start = daniilidis(&general, &DaniilidisOptions::default())
            .unwrap()
            .a_from_b;
        let options = TrajectoryOptions::default();
        group.bench_function(BenchmarkId::new("refine_trajectories", poses), |b| {
            b.iter(|| {
                refine_trajectories(black_box(&rig), black_box(&odometry), &start, &options)
                    .unwrap()
                    .a_from_b
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_hand_eye);
criterion_main!(benches);
