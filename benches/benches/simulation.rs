//! Benchmarks of the pipeline crate's simulated worlds: simulating the default scenario (the
//! paper's car, 4 fisheyes x 500 frames and the survey) and writing and reading its files,
//! against same-run baselines: the same simulation on a one-thread pool, and a bare
//! `std::fs::read` of the same map and log files.
//!
//! Run with `cargo bench -p ibc-benches --bench simulation`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_pipeline::data::BinaryDescriptor;
use ibc_pipeline::data::io::{read_log, read_map};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

fn bench_simulation(c: &mut Criterion) {
    let scenario = Scenario::builtin("garage").unwrap();
    let mut group = c.benchmark_group("simulation");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("simulate_default", |b| {
        b.iter(|| SimulatedWorld::simulate(black_box(&scenario)).unwrap())
    });
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    group.bench_function("baseline_simulate_default_1_thread", |b| {
        b.iter(|| one.install(|| SimulatedWorld::simulate(black_box(&scenario)).unwrap()))
    });
    let small = scenario.clone().with_scale(0.05);
    group.bench_function("simulate_scale_0.05", |b| {
        b.iter(|| SimulatedWorld::simulate(black_box(&small)).unwrap())
    });

    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = world.write(dir.path()).unwrap();
    group.bench_function("write_default", |b| {
        b.iter(|| world.write(black_box(dir.path())).unwrap())
    });
    group.bench_function("read_default_map_and_log", |b| {
        b.iter(|| {
            let map = read_map::<BinaryDescriptor>(black_box(&files.map)).unwrap();
            let log = read_log::<BinaryDescriptor>(black_box(&files.log)).unwrap();
            (map.points.len(), log.frames.len())
        })
    });
    group.bench_function("baseline_fs_read_map_and_log", |b| {
        b.iter(|| {
            let map = std::fs::read(black_box(&files.map)).unwrap();
            let log = std::fs::read(black_box(&files.log)).unwrap();
            (map.len(), log.len())
        })
    });
    group.finish();
}

criterion_group!(benches, bench_simulation);
criterion_main!(benches);
