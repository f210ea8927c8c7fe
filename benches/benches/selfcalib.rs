//! `ibc selfcalib`'s stages (issue 17) on the garage car rig at the size (100 frames,
//! 4 fisheyes): feature tracks (vocabulary retrieval, matching, verification) and the whole
//! self-calibration (tracks, averaging, triangulation and rig bundle adjustment rounds, scale).
//! Same-run baseline: the map-based calibration (`calib::calibrate`) of the same log against
//! the simulated map. Target: <= 25 s of CPU for the whole (COLMAP's global mapping: 237 s).
//!
//! `cargo bench -p ibc-benches --bench selfcalib -- --warm-up-time 1 --measurement-time 3`.
#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_pipeline::calib::{CalibrationOptions, calibrate};
use ibc_pipeline::sfm::{SelfCalibrationOptions, TrackOptions, build_tracks, self_calibrate};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

fn bench(c: &mut Criterion) {
    let scenario = Scenario::resolve("garage").unwrap().with_scale(0.2);
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let cameras: Vec<_> = world.rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let mut group = c.benchmark_group("selfcalib");
    group.sample_size(10);
    group.bench_function("baseline: map-based calibrate, same log", |b| {
        b.iter(|| {
            calibrate(
                &world.map,
                &world.log,
                &world.map_rig,
                &CalibrationOptions::default(),
            )
            .unwrap()
        })
    });
    group.bench_function("tracks", |b| {
        b.iter(|| build_tracks(&world.log, &cameras, &TrackOptions::default()).unwrap())
    });
    group.bench_function("whole", |b| {
        b.iter(|| self_calibrate(&world.log, &cameras, &SelfCalibrationOptions::default()).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
