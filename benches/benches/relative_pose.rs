//! Benchmarks of relative pose in `ibc-pnp` (issue 16), each against a same-run baseline, on
//! two pinhole-like views (f = 800 equivalent) of points uniform in [-2, 2] x [-2, 2] x [4, 8],
//! the second camera rotated by up to 15 degrees and moved 1 m, 1 px of angular noise:
//! - the five-point minimal solve (every real essential matrix, polished) against the first
//!   step of any five-point solver, nalgebra's SVD of the 5 x 9 epipolar matrix (its null
//!   space);
//! - the four-point homography against the same SVD of its 8 x 9 matrix;
//! - the robust solve at n = 500 with 50 % outliers (five-point LO-RANSAC, refinement, model
//!   selection) against one scoring pass of an essential matrix over the same correspondences
//!   (the tangent-plane Sampson error, the inner loop of RANSAC);
//! - the rejection of a pair that holds no model (60 random correspondences, 30 inliers
//!   required, 2000 iterations at most, as `ibc selfcalib` verifies candidate pairs) against
//!   the same search with 5 required, which runs to the 2000 (how every failing pair was
//!   searched before the floor `min_inliers / n` on the adaptive count);
//! - progressive sampling (PROSAC) of the n = 500, 50 % outliers pair with its
//!   correspondences ordered by a quality that favours the inliers without telling them apart
//!   (uniform on [0, 1] for an inlier, on [0.3, 1.3] for an outlier, as a descriptor distance
//!   would) against the uniform search on the same ordered correspondences.
//!
//! Run: `cargo bench -p ibc-benches --bench relative_pose`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_benches::bench_rng;
use ibc_pnp::{
    RansacOptions, RelativePoseOptions, essential_from_pose, five_point, homography, relative_pose,
};
use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

const FOCAL: f64 = 800.0;

struct Pair {
    a: Vec<Vector3<f64>>,
    b: Vec<Vector3<f64>>,
    b_from_a: Isometry3<f64>,
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller; enough for bench inputs.
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)).normalize()
}

fn noisy(rng: &mut ChaCha8Rng, f: Vector3<f64>, sigma: f64) -> Vector3<f64> {
    (f + Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma).normalize()
}

/// `n` correspondences, the first `outliers` with a random direction in view b (within 30
/// degrees of the axis).
fn pair(n: usize, outliers: usize, sigma: f64, stream: u64) -> Pair {
    let mut rng = bench_rng(stream);
    let axis = Unit::new_normalize(unit(&mut rng));
    let rotation = UnitQuaternion::from_axis_angle(&axis, rng.random_range(0.0..0.26));
    let b_from_a = Isometry3::from_parts(Translation3::from(unit(&mut rng)), rotation);
    let (mut a, mut b) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let p = Point3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(4.0..8.0),
        );
        a.push(noisy(&mut rng, p.coords.normalize(), sigma));
        if i < outliers {
            let z: f64 = rng.random_range(30f64.to_radians().cos()..1.0);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let r = (1.0 - z * z).sqrt();
            b.push(Vector3::new(r * phi.cos(), r * phi.sin(), z));
        } else {
            b.push(noisy(&mut rng, (b_from_a * p).coords.normalize(), sigma));
        }
    }
    Pair { a, b, b_from_a }
}

/// The null space of the epipolar (or homography) constraint matrix by nalgebra's SVD.
fn baseline_svd(rows: &DMatrix<f64>) -> f64 {
    let svd = rows.clone().svd(false, true);
    svd.v_t.unwrap()[(rows.nrows() - 1, 0)]
}

/// One scoring pass: the number of correspondences within the threshold of the tangent-plane
/// Sampson error of `e`.
fn scoring_pass(p: &Pair, e: &Matrix3<f64>, thr2: f64) -> usize {
    p.a.iter()
        .zip(&p.b)
        .filter(|(a, b)| {
            let ea = e * *a;
            let etb = e.tr_mul(b);
            let c = b.dot(&ea);
            c * c <= thr2 * (ea.norm_squared() + etb.norm_squared() - 2.0 * c * c)
        })
        .count()
}

/// The five bearings of each view of a minimal problem.
type FiveBearings = ([Vector3<f64>; 5], [Vector3<f64>; 5]);

fn bench_minimal(c: &mut Criterion) {
    let mut group = c.benchmark_group("relative_minimal");
    // A batch of 64 instances, cycled, so one lucky configuration does not set the figure.
    let instances: Vec<Pair> = (0..64).map(|k| pair(5, 0, 0.0, 100 + k)).collect();
    let five: Vec<FiveBearings> = instances
        .iter()
        .map(|p| {
            (
                core::array::from_fn(|i| p.a[i]),
                core::array::from_fn(|i| p.b[i]),
            )
        })
        .collect();
    let rows5: Vec<DMatrix<f64>> = instances
        .iter()
        .map(|p| DMatrix::from_fn(5, 9, |r, k| p.b[r][k / 3] * p.a[r][k % 3]))
        .collect();
    let mut k = 0;
    group.bench_function("five_point", |bench| {
        bench.iter(|| {
            k = (k + 1) % five.len();
            let (a, b) = &five[k];
            black_box(five_point(black_box(a), black_box(b)).unwrap().len())
        })
    });
    let mut k = 0;
    group.bench_function("baseline_svd_5x9", |bench| {
        bench.iter(|| {
            k = (k + 1) % rows5.len();
            black_box(baseline_svd(black_box(&rows5[k])))
        })
    });
    let four: Vec<Pair> = (0..64).map(|k| pair(4, 0, 0.0, 200 + k)).collect();
    let rows8: Vec<DMatrix<f64>> = four
        .iter()
        .map(|p| {
            DMatrix::from_fn(8, 9, |r, k| {
                let (i, row) = (r / 2, r % 2);
                let cross = p.b[i].cross_matrix();
                cross[(row, k / 3)] * p.a[i][k % 3]
            })
        })
        .collect();
    let mut k = 0;
    group.bench_function("homography_4pt", |bench| {
        bench.iter(|| {
            k = (k + 1) % four.len();
            black_box(homography(black_box(&four[k].a), black_box(&four[k].b)).unwrap())
        })
    });
    let mut k = 0;
    group.bench_function("baseline_svd_8x9", |bench| {
        bench.iter(|| {
            k = (k + 1) % rows8.len();
            black_box(baseline_svd(black_box(&rows8[k])))
        })
    });
    group.finish();
}

fn bench_robust(c: &mut Criterion) {
    let mut group = c.benchmark_group("relative_robust");
    group.sample_size(20);
    let p = pair(500, 250, 1.0 / FOCAL, 300);
    let options = RelativePoseOptions {
        ransac: RansacOptions {
            seed: 1,
            ..RelativePoseOptions::default().ransac
        },
        ..Default::default()
    };
    let result = relative_pose(&p.a, &p.b, &options).unwrap();
    eprintln!(
        "n = 500, 50 % outliers: {} inliers, {} iterations, rotation error {:.3} deg",
        result.inliers.len(),
        result.iterations,
        result
            .b_from_a
            .rotation
            .angle_to(&p.b_from_a.rotation)
            .to_degrees()
    );
    group.bench_function("relative_pose_n500_50pct", |bench| {
        bench.iter(|| black_box(relative_pose(black_box(&p.a), black_box(&p.b), &options).unwrap()))
    });
    let without_selection = RelativePoseOptions {
        model_selection: false,
        ..options.clone()
    };
    group.bench_function("relative_pose_n500_50pct_no_selection", |bench| {
        bench.iter(|| {
            black_box(relative_pose(black_box(&p.a), black_box(&p.b), &without_selection).unwrap())
        })
    });
    let e = essential_from_pose(&p.b_from_a);
    let thr2 = options.ransac.threshold.powi(2);
    group.bench_function("baseline_one_scoring_pass_n500", |bench| {
        bench.iter(|| black_box(scoring_pass(black_box(&p), black_box(&e), thr2)))
    });
    // The same pair ordered by a quality that favours the inliers (the first 250 are the
    // outliers).
    let mut rng = bench_rng(302);
    let mut order: Vec<(f64, usize)> = (0..p.a.len())
        .map(|i| (rng.random::<f64>() + if i < 250 { 0.3 } else { 0.0 }, i))
        .collect();
    order.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (oa, ob): (Vec<_>, Vec<_>) = order.iter().map(|&(_, i)| (p.a[i], p.b[i])).unzip();
    let progressive = RelativePoseOptions {
        progressive: true,
        ..options.clone()
    };
    for (label, o) in [("uniform", &options), ("progressive", &progressive)] {
        let r = relative_pose(&oa, &ob, o).unwrap();
        eprintln!(
            "ordered, {label}: {} inliers, {} iterations, rotation error {:.3} deg",
            r.inliers.len(),
            r.iterations,
            r.b_from_a
                .rotation
                .angle_to(&p.b_from_a.rotation)
                .to_degrees()
        );
    }
    group.bench_function("relative_pose_n500_50pct_ordered_progressive", |bench| {
        bench.iter(|| {
            black_box(relative_pose(black_box(&oa), black_box(&ob), &progressive).unwrap())
        })
    });
    group.bench_function(
        "baseline_relative_pose_n500_50pct_ordered_uniform",
        |bench| {
            bench.iter(|| {
                black_box(relative_pose(black_box(&oa), black_box(&ob), &options).unwrap())
            })
        },
    );
    group.finish();
}

fn bench_reject(c: &mut Criterion) {
    let mut group = c.benchmark_group("relative_reject");
    group.sample_size(20);
    let p = pair(60, 60, 1.0 / FOCAL, 301);
    let options = |min_inliers| RelativePoseOptions {
        ransac: RansacOptions {
            seed: 1,
            max_iterations: 2000,
            min_inliers,
            ..RelativePoseOptions::default().ransac
        },
        ..Default::default()
    };
    let (required, baseline) = (options(30), options(5));
    assert!(relative_pose(&p.a, &p.b, &required).is_err());
    group.bench_function("no_model_n60_30_required", |bench| {
        bench.iter(|| black_box(relative_pose(black_box(&p.a), black_box(&p.b), &required)))
    });
    group.bench_function("baseline_no_model_n60_5_required", |bench| {
        bench.iter(|| black_box(relative_pose(black_box(&p.a), black_box(&p.b), &baseline)))
    });
    group.finish();
}

criterion_group!(benches, bench_minimal, bench_robust, bench_reject);
criterion_main!(benches);
