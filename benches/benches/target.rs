//! Benchmarks of `ibc target` (issue 20): AprilGrid detection in a 752 x 480 image on one
//! thread (target <= 20 ms) against decoding the same image from PNG, and the four-camera car
//! rig calibrated from 4 x 100 image files, detection included (target <= 30 s), against
//! reading and decoding those files alone.
//!
//! Run: `cargo bench -p ibc-benches --bench target`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_pipeline::target::command::{calibrate_image_folders, scene_models, simulate_scene};
use ibc_pipeline::target::{
    TargetCalibrationOptions, detect_april_grid, list_camera_folders, read_gray_image,
};

fn detection(c: &mut Criterion) {
    let sim = simulate_scene("stereo", 1, Some(4)).unwrap();
    let image = sim.images[0].iter().flatten().next().unwrap().clone();
    let mut png = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut g = c.benchmark_group("target");
    g.bench_function("decode_png_752x480 (baseline)", |b| {
        b.iter(|| one.install(|| image::load_from_memory(black_box(&png)).unwrap()))
    });
    g.bench_function("detect_aprilgrid_752x480", |b| {
        b.iter(|| one.install(|| detect_april_grid(black_box(&image), &sim.grid, "bench").unwrap()))
    });
    // The left camera's 24 views of the stereo scene: boards near and far, whole and cut by
    // the image border (the single image above is among the slowest of them).
    let views = simulate_scene("stereo", 1, Some(24)).unwrap();
    let left: Vec<_> = views.images[0].iter().flatten().cloned().collect();
    g.bench_function(
        format!("detect_aprilgrid_752x480_{}_views", left.len()),
        |b| {
            b.iter(|| {
                one.install(|| {
                    left.iter()
                        .map(|i| {
                            detect_april_grid(black_box(i), &views.grid, "bench")
                                .unwrap()
                                .corners
                                .len()
                        })
                        .sum::<usize>()
                })
            })
        },
    );
    g.finish();
}

fn car_rig(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let sim = simulate_scene("car", 0, Some(100)).unwrap();
    sim.write(dir.path()).unwrap();
    let models = scene_models(&sim);
    let mut g = c.benchmark_group("target");
    g.sample_size(10);
    g.measurement_time(Duration::from_secs(60));
    g.bench_function("car_4x100_read_and_decode (baseline)", |b| {
        b.iter(|| {
            let folders = list_camera_folders(dir.path()).unwrap();
            let mut pixels = 0u64;
            for f in &folders {
                for (_, path) in &f.images {
                    pixels += u64::from(read_gray_image(path).unwrap().width());
                }
            }
            pixels
        })
    });
    g.bench_function("car_4x100_detect_and_calibrate", |b| {
        b.iter(|| {
            calibrate_image_folders(
                dir.path(),
                &sim.grid,
                &models,
                &TargetCalibrationOptions::default(),
                &|| {},
            )
            .unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, detection, car_rig);
criterion_main!(benches);
