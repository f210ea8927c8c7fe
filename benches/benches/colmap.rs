//! Reading a large COLMAP reconstruction as an ibc map (issue 19's figure: a 2,000-image,
//! 200,000-point model with its database in at most 2 s, and no slower than ibc's own map
//! format by more than 3x), against the same map in ibc's format in the same run.
//!
//! The map is synthetic (random poses, keypoints and SIFT bytes; its size is what counts):
//! 2,000 images of a 4-camera rig in 500 frames, 200,000 points, 300 features per image (600,000
//! keypoints and 128-byte SIFT descriptors, 70% of them on a point), read as `[f32; 128]`.
//!
//! Run with `cargo bench -p ibc-benches --bench colmap`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_pipeline::colmap::{
    DatabaseContent, ModelFormat, colmap_from_map, database_to_bytes, read_colmap_map,
    survey_image_sources, write_model,
};
use ibc_pipeline::data::io::{read_map, write_map};
use ibc_pipeline::data::{ImageFeatures, Map, MapImage};
use ibc_pipeline::ibc_camera_models::{KannalaBrandt, Rig, RigCamera};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const IMAGES: usize = 2000;
const CAMERAS: usize = 4;
const POINTS: usize = 200_000;
const FEATURES: usize = 300;

fn large_map() -> (Rig, Map<[f32; 128]>) {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let camera = KannalaBrandt::new(
        1280,
        960,
        [-0.01, 0.002, -0.0005, 0.00005, 400.0, 400.0, 640.0, 480.0],
    )
    .unwrap();
    let rig = Rig::new(
        (0..CAMERAS)
            .map(|c| {
                let yaw = c as f64 * std::f64::consts::FRAC_PI_2;
                RigCamera::new(
                    format!("cam{c}"),
                    camera.clone().into(),
                    Isometry3::from_parts(
                        Translation3::new(yaw.cos(), yaw.sin(), 1.5),
                        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
                    ),
                )
            })
            .collect(),
    );
    let points = (0..POINTS)
        .map(|_| {
            Point3::new(
                rng.random_range(-50.0..50.0),
                rng.random_range(-50.0..50.0),
                rng.random_range(0.0..5.0),
            )
        })
        .collect();
    let sources = survey_image_sources(IMAGES, CAMERAS);
    let mut frames = Vec::new();
    for _ in 0..IMAGES / CAMERAS {
        frames.push(Isometry3::from_parts(
            Translation3::new(
                rng.random_range(-40.0..40.0),
                rng.random_range(-40.0..40.0),
                0.0,
            ),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rng.random_range(-3.0..3.0)),
        ));
    }
    let images = sources
        .iter()
        .map(|&(frame, c)| {
            let world_from_camera = frames[frame] * rig.cameras[c].rig_from_camera;
            let mut descriptors = Vec::with_capacity(FEATURES);
            let mut keypoints = Vec::with_capacity(FEATURES);
            let mut point_ids = Vec::with_capacity(FEATURES);
            for _ in 0..FEATURES {
                keypoints.push(Vector2::new(
                    rng.random_range(0.0..1279.0),
                    rng.random_range(0.0..959.0),
                ));
                let mut d = [0.0f32; 128];
                for x in &mut d {
                    *x = f32::from(rng.random::<u8>());
                }
                descriptors.push(d);
                point_ids.push(
                    rng.random_bool(0.7)
                        .then(|| rng.random_range(0..POINTS as u32)),
                );
            }
            // One observation per point and image at most (COLMAP's tracks allow more, but a
            // model built by COLMAP has none).
            let mut seen = std::collections::HashSet::new();
            for p in &mut point_ids {
                if let Some(id) = *p
                    && !seen.insert(id)
                {
                    *p = None;
                }
            }
            MapImage {
                camera_from_world: Some(world_from_camera.inverse()),
                features: ImageFeatures {
                    keypoints,
                    descriptors,
                },
                point_ids,
            }
        })
        .collect();
    (rig, Map { points, images })
}

fn bench_colmap(c: &mut Criterion) {
    let (rig, map) = large_map();
    let dir = tempfile::tempdir().unwrap();
    let sparse = dir.path().join("sparse");
    let text = dir.path().join("text");
    let database = dir.path().join("database.db");
    let native = dir.path().join("map.ibcmap");
    let sources = survey_image_sources(IMAGES, CAMERAS);
    let export = colmap_from_map(&rig, &map, &sources, dir.path()).unwrap();
    write_model(&sparse, &export.model, ModelFormat::Binary).unwrap();
    write_model(&text, &export.model, ModelFormat::Text).unwrap();
    let features: Vec<_> = export
        .images
        .iter()
        .cloned()
        .zip(map.images.iter().map(|i| &i.features))
        .collect();
    let bytes = database_to_bytes(
        &database,
        &DatabaseContent {
            cameras: &export.model.cameras,
            rigs: &export.model.rigs,
            frames: &export.frames,
            images: &features,
        },
    )
    .unwrap();
    std::fs::write(&database, bytes).unwrap();
    write_map(&native, &map).unwrap();
    let size = |p: &std::path::Path| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let model_bytes: u64 = [
        "cameras.bin",
        "images.bin",
        "points3D.bin",
        "rigs.bin",
        "frames.bin",
    ]
    .iter()
    .map(|n| size(&sparse.join(n)))
    .sum();
    eprintln!(
        "binary model {:.1} MB, database {:.1} MB, ibc map {:.1} MB",
        model_bytes as f64 / 1e6,
        size(&database) as f64 / 1e6,
        size(&native) as f64 / 1e6
    );
    drop(map);

    let mut group = c.benchmark_group("colmap");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(20));
    group.bench_function("read_binary_model_and_database_2000_images", |b| {
        b.iter(|| {
            let m =
                read_colmap_map::<[f32; 128]>(black_box(&sparse), black_box(&database)).unwrap();
            m.map.images.len()
        })
    });
    group.bench_function("read_text_model_and_database_2000_images", |b| {
        b.iter(|| {
            let m = read_colmap_map::<[f32; 128]>(black_box(&text), black_box(&database)).unwrap();
            m.map.images.len()
        })
    });
    group.bench_function("baseline_read_ibc_map_2000_images", |b| {
        b.iter(|| {
            read_map::<[f32; 128]>(black_box(&native))
                .unwrap()
                .images
                .len()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_colmap);
criterion_main!(benches);
