//! Benchmarks of triangulation on bearings (`ibc-pnp`): batches of 100 points, each seen by
//! cameras 4 to 8 m away in a 0.4 rad cone, oriented at random (rays at any incidence), with
//! 1 px of noise at f = 800 as an angle, against same-run baselines:
//! - two views: `triangulate_two_view` refined (the default) and linear only, and the 2 x 2
//!   depths of `depths_along_bearings` (the cheirality kernel of relative pose);
//! - 2 and 10 views: `triangulate` refined and linear only;
//! - baseline: the textbook DLT of Hartley and Zisserman (section 12.2) on bearings, nalgebra's
//!   SVD of the 3n x 4 cross-product matrix `[f_i]x [R_i | t_i]`, dehomogenized (no checks).
//!
//! Run: `cargo bench -p ibc-benches --bench triangulation`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ibc_benches::bench_rng;
use ibc_pnp::{TriangulationOptions, depths_along_bearings, triangulate, triangulate_two_view};
use nalgebra::{
    DMatrix, Isometry3, Point3, Quaternion, Translation3, Unit, UnitQuaternion, Vector3,
};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

const FOCAL: f64 = 800.0;

/// Points per batch.
const BATCH: usize = 100;

struct Views {
    cameras_from_world: Vec<Isometry3<f64>>,
    bearings: Vec<Vector3<f64>>,
    /// `cameras_from_world[1] * cameras_from_world[0]^-1`.
    b_from_a: Isometry3<f64>,
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller; enough for bench inputs.
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::from_fn(|_, _| gaussian(rng)).normalize()
}

/// `f` rotated by tangent-plane Gaussian noise of `sigma` radians per axis.
fn perturb(rng: &mut ChaCha8Rng, f: &Vector3<f64>, sigma: f64) -> Vector3<f64> {
    let e1 = f.cross(&unit(rng)).normalize();
    let e2 = f.cross(&e1);
    let tangent = (e1 * gaussian(rng) + e2 * gaussian(rng)) * sigma;
    UnitQuaternion::from_axis_angle(&Unit::new_normalize(f.cross(&tangent)), tangent.norm()) * f
}

/// A point seen by `n` cameras with at least 3 degrees of parallax between the first two.
fn views(rng: &mut ChaCha8Rng, n: usize) -> Views {
    loop {
        let truth = Point3::from(Vector3::from_fn(|_, _| rng.random_range(-5.0..5.0)));
        let axis = unit(rng);
        let cameras_from_world: Vec<Isometry3<f64>> = (0..n)
            .map(|_| {
                let offset = (axis + unit(rng) * 0.4).normalize() * rng.random_range(4.0..8.0);
                let centre = truth + offset;
                let q = Quaternion::new(gaussian(rng), gaussian(rng), gaussian(rng), gaussian(rng));
                let rotation = UnitQuaternion::from_quaternion(q);
                Isometry3::from_parts(Translation3::from(-(rotation * centre.coords)), rotation)
            })
            .collect();
        let rays: Vec<Vector3<f64>> = cameras_from_world
            .iter()
            .map(|c| (c * truth).coords.normalize())
            .collect();
        let (d0, d1) = (
            cameras_from_world[0].inverse_transform_vector(&rays[0]),
            cameras_from_world[1].inverse_transform_vector(&rays[1]),
        );
        if d0.cross(&d1).norm().atan2(d0.dot(&d1).abs()) < 3f64.to_radians() {
            continue;
        }
        let bearings = rays.iter().map(|f| perturb(rng, f, 1.0 / FOCAL)).collect();
        let b_from_a = cameras_from_world[1] * cameras_from_world[0].inverse();
        return Views {
            cameras_from_world,
            bearings,
            b_from_a,
        };
    }
}

/// Baseline: the textbook DLT on bearings, the right singular vector of the smallest singular
/// value of the 3n x 4 matrix `[f_i]x [R_i | t_i]`, dehomogenized.
fn textbook_dlt(v: &Views) -> Point3<f64> {
    let n = v.bearings.len();
    let mut m = DMatrix::zeros(3 * n, 4);
    for (i, (pose, f)) in v.cameras_from_world.iter().zip(&v.bearings).enumerate() {
        let skew = f.cross_matrix();
        let r = pose.rotation.to_rotation_matrix().into_inner();
        m.fixed_view_mut::<3, 3>(3 * i, 0).copy_from(&(skew * r));
        m.fixed_view_mut::<3, 1>(3 * i, 3)
            .copy_from(&(skew * pose.translation.vector));
    }
    let svd = m.svd(false, true);
    let v_t = svd.v_t.unwrap();
    let smallest = svd.singular_values.imin();
    let h = v_t.row(smallest);
    Point3::new(h[0] / h[3], h[1] / h[3], h[2] / h[3])
}

fn bench_two_view(c: &mut Criterion) {
    let mut group = c.benchmark_group("triangulation_two_view");
    group.throughput(Throughput::Elements(BATCH as u64));
    let mut rng = bench_rng(16);
    let scenes: Vec<Views> = (0..BATCH).map(|_| views(&mut rng, 2)).collect();
    let refined = TriangulationOptions::default();
    let linear = TriangulationOptions {
        refine: false,
        ..Default::default()
    };
    for (name, options) in [("refined", &refined), ("linear", &linear)] {
        group.bench_function(name, |b| {
            b.iter(|| {
                for s in &scenes {
                    black_box(
                        triangulate_two_view(
                            black_box(&s.b_from_a),
                            &s.bearings[0],
                            &s.bearings[1],
                            options,
                        )
                        .unwrap(),
                    );
                }
            })
        });
    }
    group.bench_function("depths_along_bearings", |b| {
        b.iter(|| {
            for s in &scenes {
                black_box(
                    depths_along_bearings(black_box(&s.b_from_a), &s.bearings[0], &s.bearings[1])
                        .unwrap(),
                );
            }
        })
    });
    group.bench_function("baseline_dlt_svd", |b| {
        b.iter(|| {
            for s in &scenes {
                black_box(textbook_dlt(black_box(s)));
            }
        })
    });
    group.finish();
}

fn bench_multi_view(c: &mut Criterion) {
    let mut group = c.benchmark_group("triangulation_multi_view");
    group.throughput(Throughput::Elements(BATCH as u64));
    let refined = TriangulationOptions::default();
    let linear = TriangulationOptions {
        refine: false,
        ..Default::default()
    };
    for n in [2usize, 10] {
        let mut rng = bench_rng(16 + n as u64);
        let scenes: Vec<Views> = (0..BATCH).map(|_| views(&mut rng, n)).collect();
        for (name, options) in [("refined", &refined), ("linear", &linear)] {
            group.bench_with_input(BenchmarkId::new(name, n), &scenes, |b, scenes| {
                b.iter(|| {
                    for s in scenes {
                        black_box(
                            triangulate(black_box(&s.cameras_from_world), &s.bearings, options)
                                .unwrap(),
                        );
                    }
                })
            });
        }
        group.bench_with_input(
            BenchmarkId::new("baseline_dlt_svd", n),
            &scenes,
            |b, scenes| {
                b.iter(|| {
                    for s in scenes {
                        black_box(textbook_dlt(black_box(s)));
                    }
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, bench_two_view, bench_multi_view);
criterion_main!(benches);
