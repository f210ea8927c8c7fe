//! Benchmarks of averaging over a viewing graph (`ibc-rig-averaging`): rotation averaging of a
//! 500-view graph of mean degree 20 (5000 edges, 2 degrees of noise, 30 % outlier edges) and
//! translation averaging of the same graph's directions, each against a same-run baseline: the
//! chordal initialization alone (rotations, the first stage of the robust solve) and the
//! least-squares solve (translations, `robust: false`: BATA's alternation then least-squares
//! Gauss-Newton). Also the rig form (125 times x 4 cameras), and a survey-like drive (500 times x
//! 2 cameras: straights and four turns, each camera's images linked up to five frames apart, the
//! cameras linked at every tenth frame, 0.1 degree of noise) averaged from its directions alone
//! against the same with the distances between consecutive frames of one heading (1 % noise):
//! the distances' system is factored directly, the directions' alone solved by conjugate
//! gradients.
//!
//! Run: `cargo bench -p ibc-benches --bench viewing_graph`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group};
use ibc_benches::{bench_rng, thread_cpu_ns};
use ibc_rig_averaging::{
    DirectionEdge, RigLayout, RigView, RotationAveragingOptions, RotationEdge, TimeDistance,
    TranslationAveragingOptions, rig_rotation_averaging, rig_translation_averaging,
    rig_translation_averaging_with_distances, rotation_averaging, translation_averaging,
};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

const VIEWS: usize = 500;
const EDGES: usize = 5000;
const OUTLIERS: f64 = 0.3;

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box-Muller: rand_distr is not a dependency of the benches.
    let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn uniform_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(
        gaussian(rng),
        gaussian(rng),
        gaussian(rng),
        gaussian(rng),
    ))
}

fn unit_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)).normalize()
}

fn pairs(rng: &mut ChaCha8Rng) -> Vec<(usize, usize)> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    while out.len() < EDGES {
        let (i, j) = (rng.random_range(0..VIEWS), rng.random_range(0..VIEWS));
        if i != j && seen.insert((i.min(j), i.max(j))) {
            out.push((i, j));
        }
    }
    out
}

/// Relative rotations between `camera_from_world` rotations: 2 degrees RMS noise, 30 % random.
fn rotation_edges(rng: &mut ChaCha8Rng, truth: &[UnitQuaternion<f64>]) -> Vec<RotationEdge> {
    let sigma = (2.0 / 3f64.sqrt()).to_radians();
    pairs(rng)
        .into_iter()
        .map(|(i, j)| {
            let q = if rng.random::<f64>() < OUTLIERS {
                uniform_rotation(rng)
            } else {
                let noise = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma;
                UnitQuaternion::from_scaled_axis(noise) * truth[j] * truth[i].inverse()
            };
            RotationEdge::new(i, j, q)
        })
        .collect()
}

/// World directions between positions: 2 degrees RMS noise, 30 % random.
fn direction_edges(rng: &mut ChaCha8Rng, positions: &[Vector3<f64>]) -> Vec<DirectionEdge> {
    let sigma = (2.0 / 2f64.sqrt()).to_radians();
    pairs(rng)
        .into_iter()
        .map(|(i, j)| {
            let v = if rng.random::<f64>() < OUTLIERS {
                unit_vector(rng)
            } else {
                let noise = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma;
                ((positions[j] - positions[i]).normalize() + noise).normalize()
            };
            DirectionEdge::new(i, j, v)
        })
        .collect()
}

struct Problems {
    rotations: Vec<RotationEdge>,
    directions: Vec<DirectionEdge>,
    layout: RigLayout,
    rig_rotations: Vec<RotationEdge>,
    rig_directions: Vec<DirectionEdge>,
    world_from_rig: Vec<Option<UnitQuaternion<f64>>>,
    drive: Drive,
}

/// The survey-like drive of the module documentation.
struct Drive {
    layout: RigLayout,
    world_from_rig: Vec<Option<UnitQuaternion<f64>>>,
    directions: Vec<DirectionEdge>,
    distances: Vec<TimeDistance>,
}

fn drive(rng: &mut ChaCha8Rng) -> Drive {
    let (times, cameras) = (500, 2);
    let views: Vec<RigView> = (0..times)
        .flat_map(|time| (0..cameras).map(move |camera| RigView { time, camera }))
        .collect();
    let layout = RigLayout::new(times, cameras, views.clone()).unwrap();
    // Heading: straights, and a quarter turn over 20 frames four times.
    let heading = |t: usize| {
        let turned = [100, 225, 350, 475]
            .iter()
            .map(|&start| (t.saturating_sub(start)).min(20) as f64 / 20.0)
            .sum::<f64>();
        turned * std::f64::consts::FRAC_PI_2
    };
    let rotations: Vec<UnitQuaternion<f64>> = (0..times)
        .map(|t| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading(t)))
        .collect();
    let lever_arms = [Vector3::zeros(), Vector3::new(-1.4, 0.5, 0.1)];
    let mut positions = vec![Vector3::zeros()];
    let mut distances = Vec::new();
    for t in 1..times {
        let step = 0.4 + 0.4 * rng.random::<f64>();
        positions.push(positions[t - 1] + rotations[t] * Vector3::x() * step);
        if heading(t) == heading(t - 1) {
            let measured = step * (1.0 + 0.01 * gaussian(rng));
            distances.push(TimeDistance::new(t - 1, t, measured, 0.01 * measured));
        }
    }
    let truth: Vec<Vector3<f64>> = views
        .iter()
        .map(|v| positions[v.time] + rotations[v.time] * lever_arms[v.camera])
        .collect();
    let sigma = 0.1_f64.to_radians();
    let mut directions = Vec::new();
    for (i, a) in views.iter().enumerate() {
        for (j, b) in views.iter().enumerate().skip(i + 1) {
            let linked = a.camera == b.camera || a.time % 10 == 0;
            if b.time - a.time <= 5 && b.time != a.time && linked {
                let noise = Vector3::new(gaussian(rng), gaussian(rng), gaussian(rng)) * sigma;
                let d = (truth[j] - truth[i]).normalize() + noise;
                directions.push(DirectionEdge::new(i, j, d.normalize()));
            }
        }
    }
    Drive {
        layout,
        world_from_rig: rotations.into_iter().map(Some).collect(),
        directions,
        distances,
    }
}

fn problems() -> Problems {
    let mut rng = bench_rng(16);
    let truth: Vec<_> = (0..VIEWS).map(|_| uniform_rotation(&mut rng)).collect();
    let rotations = rotation_edges(&mut rng, &truth);
    let positions: Vec<_> = (0..VIEWS)
        .map(|_| Vector3::new(rng.random(), rng.random(), rng.random()) * 20.0)
        .collect();
    let directions = direction_edges(&mut rng, &positions);
    // Rig: 125 times x 4 cameras, lever arms of about 0.5 m, a random walk of 1 m steps.
    let (times, cameras) = (125, 4);
    let views: Vec<RigView> = (0..times)
        .flat_map(|time| (0..cameras).map(move |camera| RigView { time, camera }))
        .collect();
    let layout = RigLayout::new(times, cameras, views.clone()).unwrap();
    let world_from_rig: Vec<_> = (0..times).map(|_| uniform_rotation(&mut rng)).collect();
    let rig_from_camera: Vec<_> = (0..cameras).map(|_| uniform_rotation(&mut rng)).collect();
    let lever_arms: Vec<_> = (0..cameras)
        .map(|c| {
            if c == 0 {
                Vector3::zeros()
            } else {
                unit_vector(&mut rng) * 0.5
            }
        })
        .collect();
    let mut rig_positions = vec![Vector3::zeros()];
    for _ in 1..times {
        let last = *rig_positions.last().unwrap();
        rig_positions.push(last + unit_vector(&mut rng) * 2.0);
    }
    let view_truth: Vec<_> = views
        .iter()
        .map(|v| (world_from_rig[v.time] * rig_from_camera[v.camera]).inverse())
        .collect();
    let view_positions: Vec<_> = views
        .iter()
        .map(|v| rig_positions[v.time] + world_from_rig[v.time] * lever_arms[v.camera])
        .collect();
    Problems {
        rotations,
        directions,
        rig_rotations: rotation_edges(&mut rng, &view_truth),
        rig_directions: direction_edges(&mut rng, &view_positions),
        layout,
        world_from_rig: world_from_rig.into_iter().map(Some).collect(),
        drive: drive(&mut rng),
    }
}

fn bench_viewing_graph(c: &mut Criterion) {
    let p = problems();
    let chordal = RotationAveragingOptions {
        l1_iterations: 0,
        irls_iterations: 0,
        ..Default::default()
    };
    let least_squares = TranslationAveragingOptions {
        robust: false,
        ..Default::default()
    };
    let mut group = c.benchmark_group("viewing_graph");
    group.sample_size(20);
    group.bench_function("rotation/chordal_init/500", |b| {
        b.iter(|| rotation_averaging(VIEWS, black_box(&p.rotations), &chordal).unwrap())
    });
    group.bench_function("rotation/robust/500", |b| {
        b.iter(|| rotation_averaging(VIEWS, black_box(&p.rotations), &Default::default()).unwrap())
    });
    group.bench_function("rotation/rig_robust/125x4", |b| {
        b.iter(|| {
            rig_rotation_averaging(&p.layout, black_box(&p.rig_rotations), &Default::default())
                .unwrap()
        })
    });
    group.bench_function("translation/least_squares/500", |b| {
        b.iter(|| translation_averaging(VIEWS, black_box(&p.directions), &least_squares).unwrap())
    });
    group.bench_function("translation/robust/500", |b| {
        b.iter(|| {
            translation_averaging(VIEWS, black_box(&p.directions), &Default::default()).unwrap()
        })
    });
    group.bench_function("translation/rig_robust/125x4", |b| {
        b.iter(|| {
            rig_translation_averaging(
                &p.layout,
                &p.world_from_rig,
                black_box(&p.rig_directions),
                &Default::default(),
            )
            .unwrap()
        })
    });
    let d = &p.drive;
    group.bench_function("translation/drive_directions/500x2", |b| {
        b.iter(|| {
            rig_translation_averaging(
                &d.layout,
                &d.world_from_rig,
                black_box(&d.directions),
                &Default::default(),
            )
            .unwrap()
        })
    });
    group.bench_function("translation/drive_distances/500x2", |b| {
        b.iter(|| {
            rig_translation_averaging_with_distances(
                &d.layout,
                &d.world_from_rig,
                black_box(&d.directions),
                &d.distances,
                &Default::default(),
            )
            .unwrap()
        })
    });
    group.finish();
}

/// CPU time of the calling thread for the main solves, beside criterion's wall clock. Runs
/// only under `cargo bench`.
fn cpu_time_report() {
    if !std::env::args().any(|a| a == "--bench") || thread_cpu_ns().is_none() {
        return;
    }
    let p = problems();
    for _ in 0..3 {
        let (cpu0, wall0) = (thread_cpu_ns(), std::time::Instant::now());
        let r = black_box(rotation_averaging(VIEWS, &p.rotations, &Default::default()).unwrap());
        let cpu = (thread_cpu_ns().unwrap_or(0.0) - cpu0.unwrap_or(0.0)) / 1e6;
        let wall = wall0.elapsed().as_secs_f64() * 1e3;
        println!(
            "cpu-time rotation_averaging 500 views: {cpu:.1} ms CPU, {wall:.1} ms wall \
             ({} iterations, {} CG iterations)",
            r.report.iterations, r.report.linear_iterations
        );
        let (cpu0, wall0) = (thread_cpu_ns(), std::time::Instant::now());
        let t =
            black_box(translation_averaging(VIEWS, &p.directions, &Default::default()).unwrap());
        let cpu = (thread_cpu_ns().unwrap_or(0.0) - cpu0.unwrap_or(0.0)) / 1e6;
        let wall = wall0.elapsed().as_secs_f64() * 1e3;
        println!(
            "cpu-time translation_averaging 500 views: {cpu:.1} ms CPU, {wall:.1} ms wall \
             ({} iterations, {} CG iterations)",
            t.report.iterations, t.report.linear_iterations
        );
    }
}

criterion_group!(benches, bench_viewing_graph);

fn main() {
    cpu_time_report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
