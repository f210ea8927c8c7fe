//! ibc-camera-models: projection, unprojection and Jacobians per point, single thread.
//!
//! Same-run baselines: an ideal pinhole projection (`fx x / z + cx`, the cheapest possible
//! camera) for the projections, and CamOdoCal's radial-tangential inverse (8 fixed-point steps,
//! `m = md - (D(m) - m)`) for the unprojections. Each benchmark runs over 1024 points spread over
//! the image, so the figures are per 1024 points; divide by 1024 for per point.
//!
//! The machine these run on is shared, and the load inflates wall time several-fold; so before
//! the criterion runs, the bench prints the *CPU time* of its thread per point for each path
//! (over spans of a quarter second or more). Instruction counts, which no load changes, come
//! from `camera-models/examples/callgrind_paths.rs` under valgrind.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group};
use ibc_benches::thread_cpu_ns;
use ibc_camera_models::{CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use nalgebra::{Vector2, Vector3};

const N: usize = 1024;

fn kb() -> KannalaBrandt {
    // CamOdoCal's Kannala-Brandt test camera.
    KannalaBrandt::new(
        1280,
        800,
        [
            -0.01648, -0.00203, 0.00069, -0.00048, 419.22826, 420.42160, 655.45487, 389.66377,
        ],
    )
    .unwrap()
}

fn euroc() -> PinholeRadtan {
    // EuRoC MAV cam0.
    PinholeRadtan::new(
        752,
        480,
        [
            -0.28340811,
            0.07395907,
            0.00019359,
            1.76187114e-05,
            458.654,
            457.296,
            367.215,
            248.375,
        ],
    )
    .unwrap()
}

fn mei() -> Unified {
    // CamOdoCal's Mei test camera.
    Unified::new(
        1280,
        800,
        [
            0.894975,
            -0.344504,
            0.0984552,
            -0.00403995,
            0.00610364,
            758.355,
            757.615,
            646.72,
            395.001,
        ],
    )
    .unwrap()
}

/// N pixels on a grid over the image that have rays, and their rays scaled to points.
fn samples<C: CameraModel>(camera: &C) -> (Vec<Vector2<f64>>, Vec<Vector3<f64>>) {
    let (w, h) = (f64::from(camera.width()), f64::from(camera.height()));
    let mut pixels = Vec::with_capacity(N);
    let mut points = Vec::with_capacity(N);
    let mut i = 0usize;
    while pixels.len() < N {
        let px = Vector2::new(
            (i % 41) as f64 * w / 41.0,
            ((i / 41) % 29) as f64 * h / 29.0,
        );
        i += 1;
        if let Ok(ray) = camera.unproject(&px) {
            pixels.push(px);
            points.push(ray.into_inner() * (1.0 + (i % 7) as f64));
        }
    }
    (pixels, points)
}

/// CamOdoCal's radtan inverse: 8 fixed-point steps m <- md - (D(m) - m).
fn camodocal_undistort(k: [f64; 4], md: Vector2<f64>) -> Vector2<f64> {
    let delta = |m: Vector2<f64>| {
        let r2 = m.norm_squared();
        let radial = k[0] * r2 + k[1] * r2 * r2;
        Vector2::new(
            m.x * radial + 2.0 * k[2] * m.x * m.y + k[3] * (r2 + 2.0 * m.x * m.x),
            m.y * radial + k[2] * (r2 + 2.0 * m.y * m.y) + 2.0 * k[3] * m.x * m.y,
        )
    };
    let mut m = md - delta(md);
    for _ in 1..8 {
        m = md - delta(m);
    }
    m
}

fn projections(c: &mut Criterion) {
    let kb = kb();
    let euroc = euroc();
    let mei = mei();
    let (_, kb_points) = samples(&kb);
    let (_, pin_points) = samples(&euroc);
    let (_, mei_points) = samples(&mei);
    let mut g = c.benchmark_group("camera_models/project");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("baseline_ideal_pinhole", |b| {
        b.iter(|| {
            for p in &pin_points {
                black_box(Vector2::new(
                    458.654 * p.x / p.z + 367.215,
                    457.296 * p.y / p.z + 248.375,
                ));
            }
        });
    });
    g.bench_function("kannala_brandt", |b| {
        b.iter(|| {
            for p in &kb_points {
                let _ = black_box(kb.project(black_box(p)));
            }
        });
    });
    g.bench_function("kannala_brandt_with_all_jacobians", |b| {
        b.iter(|| {
            for p in &kb_points {
                let _ = black_box(kb.project_with_jacobians(black_box(p)));
            }
        });
    });
    g.bench_function("pinhole_radtan", |b| {
        b.iter(|| {
            for p in &pin_points {
                let _ = black_box(euroc.project(black_box(p)));
            }
        });
    });
    g.bench_function("pinhole_radtan_with_all_jacobians", |b| {
        b.iter(|| {
            for p in &pin_points {
                let _ = black_box(euroc.project_with_jacobians(black_box(p)));
            }
        });
    });
    g.bench_function("unified", |b| {
        b.iter(|| {
            for p in &mei_points {
                let _ = black_box(mei.project(black_box(p)));
            }
        });
    });
    g.bench_function("unified_with_all_jacobians", |b| {
        b.iter(|| {
            for p in &mei_points {
                let _ = black_box(mei.project_with_jacobians(black_box(p)));
            }
        });
    });
    g.finish();
}

fn unprojections(c: &mut Criterion) {
    let kb = kb();
    let euroc = euroc();
    let mei = mei();
    let (kb_pixels, _) = samples(&kb);
    let (pin_pixels, _) = samples(&euroc);
    let (mei_pixels, _) = samples(&mei);
    let mut g = c.benchmark_group("camera_models/unproject");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("baseline_camodocal_radtan_8_steps", |b| {
        let k = [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05];
        b.iter(|| {
            for px in &pin_pixels {
                let md = Vector2::new((px.x - 367.215) / 458.654, (px.y - 248.375) / 457.296);
                let m = camodocal_undistort(k, black_box(md));
                black_box(Vector3::new(m.x, m.y, 1.0).normalize());
            }
        });
    });
    g.bench_function("kannala_brandt_fast", |b| {
        b.iter(|| {
            for px in &kb_pixels {
                let _ = black_box(kb.unproject_fast(black_box(px)));
            }
        });
    });
    g.bench_function("kannala_brandt_companion", |b| {
        b.iter(|| {
            for px in &kb_pixels {
                let _ = black_box(kb.unproject(black_box(px)));
            }
        });
    });
    g.bench_function("pinhole_radtan", |b| {
        b.iter(|| {
            for px in &pin_pixels {
                let _ = black_box(euroc.unproject(black_box(px)));
            }
        });
    });
    g.bench_function("unified", |b| {
        b.iter(|| {
            for px in &mei_pixels {
                let _ = black_box(mei.unproject(black_box(px)));
            }
        });
    });
    g.bench_function("kannala_brandt_with_all_jacobians", |b| {
        b.iter(|| {
            for px in &kb_pixels {
                let _ = black_box(kb.unproject_with_jacobians(black_box(px)));
            }
        });
    });
    g.finish();
}

fn set_params(c: &mut Criterion) {
    // Derived limits are recomputed once per parameter set (a bundle-adjustment step).
    let mut g = c.benchmark_group("camera_models/set_params");
    let mut kb = kb();
    let kp = kb.params().to_vec();
    g.bench_function("kannala_brandt_fold", |b| {
        b.iter(|| kb.set_params(black_box(&kp)).unwrap())
    });
    let mut mei = mei();
    let mp = mei.params().to_vec();
    g.bench_function("unified_injective_radius", |b| {
        b.iter(|| mei.set_params(black_box(&mp)).unwrap());
    });
    g.finish();
}

/// CPU time per item of `f` over `items`, repeated until a quarter second of CPU time has
/// passed (the clock, a file read, is read every 64 passes so its cost stays out of the
/// figure); the best of three such spans.
fn cpu_ns_per_item<T>(items: &[T], mut f: impl FnMut(&T)) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let (start, mut calls) = (thread_cpu_ns().unwrap_or(0.0), 0usize);
        let mut spent = 0.0;
        while spent < 2.5e8 {
            for _ in 0..64 {
                for item in items {
                    f(black_box(item));
                }
            }
            calls += 64 * items.len();
            spent = thread_cpu_ns().unwrap_or(0.0) - start;
        }
        best = best.min(spent / calls as f64);
    }
    best
}

/// Prints the CPU time per point of every path before the criterion runs. Runs only under
/// `cargo bench` (criterion's `--bench` flag), not when `cargo test` smoke-runs benches.
fn cpu_time_report() {
    if !std::env::args().any(|a| a == "--bench") || thread_cpu_ns().is_none() {
        return;
    }
    let (kb, euroc, mei) = (kb(), euroc(), mei());
    let (kb_pixels, kb_points) = samples(&kb);
    let (pin_pixels, pin_points) = samples(&euroc);
    let (mei_pixels, mei_points) = samples(&mei);
    let report =
        |name: &str, ns: f64| println!("cpu-time camera_models/{name}: {ns:.1} ns per point");
    report(
        "project/baseline_ideal_pinhole",
        cpu_ns_per_item(&pin_points, |p| {
            black_box(Vector2::new(
                458.654 * p.x / p.z + 367.215,
                457.296 * p.y / p.z + 248.375,
            ));
        }),
    );
    report(
        "project/kannala_brandt",
        cpu_ns_per_item(&kb_points, |p| {
            let _ = black_box(kb.project(p));
        }),
    );
    report(
        "project/kannala_brandt_with_all_jacobians",
        cpu_ns_per_item(&kb_points, |p| {
            let _ = black_box(kb.project_with_jacobians(p));
        }),
    );
    report(
        "project/pinhole_radtan",
        cpu_ns_per_item(&pin_points, |p| {
            let _ = black_box(euroc.project(p));
        }),
    );
    report(
        "project/pinhole_radtan_with_all_jacobians",
        cpu_ns_per_item(&pin_points, |p| {
            let _ = black_box(euroc.project_with_jacobians(p));
        }),
    );
    report(
        "project/unified",
        cpu_ns_per_item(&mei_points, |p| {
            let _ = black_box(mei.project(p));
        }),
    );
    report(
        "project/unified_with_all_jacobians",
        cpu_ns_per_item(&mei_points, |p| {
            let _ = black_box(mei.project_with_jacobians(p));
        }),
    );
    report(
        "unproject/kannala_brandt_fast",
        cpu_ns_per_item(&kb_pixels, |px| {
            let _ = black_box(kb.unproject_fast(px));
        }),
    );
    report(
        "unproject/kannala_brandt_companion",
        cpu_ns_per_item(&kb_pixels, |px| {
            let _ = black_box(kb.unproject(px));
        }),
    );
    report(
        "unproject/pinhole_radtan",
        cpu_ns_per_item(&pin_pixels, |px| {
            let _ = black_box(euroc.unproject(px));
        }),
    );
    report(
        "unproject/unified",
        cpu_ns_per_item(&mei_pixels, |px| {
            let _ = black_box(mei.unproject(px));
        }),
    );
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    targets = projections, unprojections, set_params
}

fn main() {
    cpu_time_report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
