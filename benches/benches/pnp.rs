//! Benchmarks of `ibc-pnp` on the EPnP paper's synthetic setup (f = 800, 640 x 480, points
//! uniform in [-2, 2] x [-2, 2] x [4, 8] in the camera frame, 1 px noise), each against a
//! same-run baseline:
//! - EPnP at n = 6 and n = 100 (default, and the paper's single pass) against the textbook
//!   core, nalgebra's SVD of the 3n x 12 cross-product matrix;
//! - P3P (Lambda Twist) against nalgebra's SVD of a 3 x 3 matrix;
//! - refinement at n = 100 and the robust solve at 50 % outliers (n = 200) and 80 % outliers
//!   (n = 500) against one scoring pass of a pose over the same correspondences (the inner
//!   loop of RANSAC).
//!
//! Run: `cargo bench -p ibc-benches --bench pnp`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use ibc_benches::bench_rng;
use ibc_pnp::{
    EpnpOptions, RansacOptions, RefineOptions, angle_from_pixels, epnp, epnp_with, p3p,
    refine_pose, robust_pose,
};
use nalgebra::{
    DMatrix, Isometry3, Matrix3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3,
};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

const FOCAL: f64 = 800.0;

struct Scene {
    bearings: Vec<Vector3<f64>>,
    points: Vec<Point3<f64>>,
    camera_from_world: Isometry3<f64>,
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller; enough for bench inputs.
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn bearing_of_pixel(u: f64, v: f64) -> Vector3<f64> {
    Vector3::new((u - 320.0) / FOCAL, (v - 240.0) / FOCAL, 1.0).normalize()
}

/// The EPnP paper's setup with `outliers` of the `n` bearings replaced by random pixels.
fn scene(n: usize, outliers: usize, stream: u64) -> Scene {
    let mut rng = bench_rng(stream);
    let q = Quaternion::new(
        gaussian(&mut rng),
        gaussian(&mut rng),
        gaussian(&mut rng),
        gaussian(&mut rng),
    );
    let t = Vector3::from_fn(|_, _| rng.random_range(-10.0..10.0));
    let camera_from_world =
        Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_quaternion(q));
    let world_from_camera = camera_from_world.inverse();
    let mut bearings = Vec::with_capacity(n);
    let mut points = Vec::with_capacity(n);
    for i in 0..n {
        let p = Point3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(4.0..8.0),
        );
        let (u, v) = if i < outliers {
            (rng.random_range(0.0..640.0), rng.random_range(0.0..480.0))
        } else {
            (
                FOCAL * p.x / p.z + 320.0 + gaussian(&mut rng),
                FOCAL * p.y / p.z + 240.0 + gaussian(&mut rng),
            )
        };
        bearings.push(bearing_of_pixel(u, v));
        points.push(world_from_camera * p);
    }
    Scene {
        bearings,
        points,
        camera_from_world,
    }
}

/// Baseline: the textbook EPnP core, the SVD of the 3n x 12 cross-product matrix built from
/// barycentric weights (here: the world coordinates and 1, which costs the same).
fn textbook_svd(scene: &Scene) -> f64 {
    let n = scene.bearings.len();
    let mut m = DMatrix::zeros(3 * n, 12);
    for (i, (f, x)) in scene.bearings.iter().zip(&scene.points).enumerate() {
        let skew = f.cross_matrix();
        let w = [x.x, x.y, x.z, 1.0];
        for (j, wj) in w.iter().enumerate() {
            m.fixed_view_mut::<3, 3>(3 * i, 3 * j)
                .copy_from(&(skew * *wj));
        }
    }
    let svd = m.svd(false, true);
    svd.singular_values.min()
}

/// Baseline: count the inliers of one pose (the inner loop of RANSAC).
fn scoring_pass(scene: &Scene, pose: &Isometry3<f64>, tan2: f64) -> usize {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let t = pose.translation.vector;
    scene
        .bearings
        .iter()
        .zip(&scene.points)
        .filter(|(f, x)| {
            let p = r * x.coords + t;
            let along = f.dot(&p);
            along > 0.0 && p.norm_squared() - along * along <= tan2 * along * along
        })
        .count()
}

fn bench_epnp(c: &mut Criterion) {
    let mut group = c.benchmark_group("epnp");
    let paper = EpnpOptions {
        depth_reweighting: false,
        ..Default::default()
    };
    for n in [6usize, 100] {
        let s = scene(n, 0, n as u64);
        group.bench_with_input(BenchmarkId::new("default", n), &s, |b, s| {
            b.iter(|| epnp(black_box(&s.bearings), black_box(&s.points)).unwrap())
        });
        group.bench_with_input(BenchmarkId::new("single_pass", n), &s, |b, s| {
            b.iter(|| epnp_with(black_box(&s.bearings), black_box(&s.points), &paper).unwrap())
        });
        group.bench_with_input(BenchmarkId::new("baseline_svd_3nx12", n), &s, |b, s| {
            b.iter(|| textbook_svd(black_box(s)))
        });
    }
    group.finish();
}

fn bench_p3p(c: &mut Criterion) {
    let mut group = c.benchmark_group("p3p");
    let s = scene(3, 0, 3);
    let y = [s.bearings[0], s.bearings[1], s.bearings[2]];
    let x = [s.points[0], s.points[1], s.points[2]];
    group.bench_function("lambda_twist", |b| {
        b.iter(|| p3p(black_box(&y), black_box(&x)).unwrap())
    });
    let m = Matrix3::from_columns(&[y[0], y[1], y[2]]);
    group.bench_function("baseline_svd_3x3", |b| {
        b.iter(|| black_box(m).svd(true, true).singular_values)
    });
    group.finish();
}

fn bench_robust(c: &mut Criterion) {
    let mut group = c.benchmark_group("robust");
    group.sample_size(20);
    let threshold = angle_from_pixels(3.0, FOCAL).unwrap();
    let tan2 = threshold.tan().powi(2);
    let options = RansacOptions {
        threshold,
        ..Default::default()
    };
    for (n, outlier_ratio) in [(200usize, 0.5), (500, 0.8)] {
        let s = scene(n, (outlier_ratio * n as f64) as usize, 7 + n as u64);
        let label = format!("n{n}_outliers{}", (outlier_ratio * 100.0) as usize);
        group.bench_function(BenchmarkId::new("robust_pose", &label), |b| {
            b.iter(|| robust_pose(black_box(&s.bearings), black_box(&s.points), &options).unwrap())
        });
        group.bench_function(BenchmarkId::new("baseline_one_scoring_pass", &label), |b| {
            b.iter(|| scoring_pass(black_box(&s), &s.camera_from_world, tan2))
        });
    }
    let s = scene(100, 0, 100);
    let start = epnp(&s.bearings, &s.points).unwrap();
    group.bench_function("refine_pose_n100", |b| {
        b.iter(|| {
            refine_pose(
                black_box(&s.bearings),
                black_box(&s.points),
                &start,
                &RefineOptions::default(),
            )
            .unwrap()
        })
    });
    group.bench_function("baseline_one_scoring_pass_n100", |b| {
        b.iter(|| scoring_pass(black_box(&s), &s.camera_from_world, tan2))
    });
    group.finish();
}

criterion_group!(benches, bench_epnp, bench_p3p, bench_robust);
criterion_main!(benches);
