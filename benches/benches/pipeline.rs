//! Benchmarks of the calibration pipeline's stages (`ibc_pipeline::calib`) on the default
//! garage scenario at a fifth of its size (100 frames x 4 fisheyes, 80 map images), with
//! same-run baselines:
//!
//! - matching one image to the map: the pipeline's matcher (the candidates' map points pooled
//!   per direct-index node) against matching each of the 10 candidate images in turn with
//!   `ibc_vocab_tree::match_by_nodes` (DBoW2's way) and by brute force (`match_brute_force`,
//!   as CamOdoCal does);
//! - refinement on two threads (the pipeline's fixed count) against one thread;
//! - the quality gates (per-camera residual statistics and pattern) against the refinement
//!   whose residuals they judge.
//!
//! Run with `cargo bench -p ibc-benches --bench pipeline`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_bundle_adjust::{IntrinsicsSelection, RigObservation, RigRefinement, RigRefinementOptions};
use ibc_camera_models::CameraModel;
use ibc_pipeline::calib::localization::match_to_map;
use ibc_pipeline::calib::quality::{RefinementFacts, assess};
use ibc_pipeline::calib::refinement::reprojection_residuals;
use ibc_pipeline::calib::{
    CalibrationOptions, MapIndex, RefinementOptions, calibrate, calibrate_hand_eye, initialize,
    localize_image, localize_log, refine, select_frame_sets,
};
use ibc_pipeline::calib::{HandEyeSolver, NoProgress};
use ibc_pipeline::data::{BinaryDescriptor, Map};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};
use ibc_vocab_tree::{MatchOptions, QueryOptions, match_brute_force, match_by_nodes};

/// The correspondences of one image matched to each candidate in turn (the baselines):
/// `by_nodes` with the direct index, else brute force.
fn match_each_candidate(
    index: &MapIndex<BinaryDescriptor>,
    map: &Map<BinaryDescriptor>,
    descriptors: &[BinaryDescriptor],
    by_nodes: bool,
) -> usize {
    let (bow, fv) = index
        .vocabulary
        .transform_with_features(descriptors, index.direct_index_levels)
        .unwrap();
    let mut n = 0;
    for r in index.database.query(&bow, &QueryOptions::default()) {
        let image = &map.images[r.image as usize];
        let matches = if by_nodes {
            match_by_nodes(
                descriptors,
                &fv,
                &image.features.descriptors,
                index.database.features(r.image).unwrap(),
                &MatchOptions::default(),
            )
        } else {
            match_brute_force(
                descriptors,
                &image.features.descriptors,
                &MatchOptions::default(),
            )
        }
        .unwrap();
        n += matches
            .iter()
            .filter(|m| image.point_ids[m.train as usize].is_some())
            .count();
    }
    n
}

fn stages(c: &mut Criterion) {
    let scenario = Scenario::builtin("garage").unwrap().with_scale(0.2);
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let options = CalibrationOptions::default();
    let cameras: Vec<_> = world
        .map_rig
        .cameras
        .iter()
        .map(|c| c.camera.clone())
        .collect();
    let index = MapIndex::train(&world.map, &options.vocabulary).unwrap();
    let images: Vec<(usize, usize)> = (0..8).map(|i| (i * 11 % 100, i % 4)).collect();

    let mut g = c.benchmark_group("pipeline");
    g.sample_size(10);
    g.bench_function("vocabulary: train and index (80 map images)", |b| {
        b.iter(|| MapIndex::train(black_box(&world.map), &options.vocabulary).unwrap())
    });
    g.bench_function("match 8 images: pooled per node (pipeline)", |b| {
        b.iter(|| {
            images
                .iter()
                .map(|&(f, k)| {
                    let features = &world.log.frames[f].images[k];
                    match_to_map(&index, &world.map, features, &options.localization)
                        .unwrap()
                        .len()
                })
                .sum::<usize>()
        })
    });
    g.bench_function("match 8 images: each candidate by nodes (baseline)", |b| {
        b.iter(|| {
            images
                .iter()
                .map(|&(f, k)| {
                    let d = &world.log.frames[f].images[k].descriptors;
                    match_each_candidate(&index, &world.map, d, true)
                })
                .sum::<usize>()
        })
    });
    g.bench_function(
        "match 8 images: each candidate brute force (baseline)",
        |b| {
            b.iter(|| {
                images
                    .iter()
                    .map(|&(f, k)| {
                        let d = &world.log.frames[f].images[k].descriptors;
                        match_each_candidate(&index, &world.map, d, false)
                    })
                    .sum::<usize>()
            })
        },
    );
    g.bench_function("localize 8 images (match + RANSAC PnP)", |b| {
        b.iter(|| {
            images
                .iter()
                .map(|&(f, k)| {
                    let features = &world.log.frames[f].images[k];
                    localize_image(
                        &index,
                        &world.map,
                        &cameras[k],
                        features,
                        &options.localization,
                        1,
                    )
                    .unwrap()
                    .inliers
                    .len()
                })
                .sum::<usize>()
        })
    });
    g.bench_function("localize the log (400 images, rayon)", |b| {
        b.iter(|| {
            localize_log(
                &index,
                &world.map,
                &cameras,
                &world.log,
                &options.localization,
                &NoProgress,
            )
            .unwrap()
        })
    });
    let localizations = localize_log(
        &index,
        &world.map,
        &cameras,
        &world.log,
        &options.localization,
        &NoProgress,
    )
    .unwrap();
    let sets = select_frame_sets(&localizations, &options.frame_sets);
    g.bench_function("frame sets + initialization (100 sets)", |b| {
        b.iter(|| {
            let sets = select_frame_sets(&localizations, &options.frame_sets);
            initialize(
                &sets,
                &localizations,
                &world.map,
                &world.log,
                &cameras,
                &options.initialization,
            )
            .unwrap()
        })
    });
    let init = initialize(
        &sets,
        &localizations,
        &world.map,
        &world.log,
        &cameras,
        &options.initialization,
    )
    .unwrap();
    let calibration = calibrate(&world.map, &world.log, &world.map_rig, &options).unwrap();
    let observations = calibration.observations.clone();
    g.bench_function(
        "refinement (100 sets, 40k correspondences), 2 threads",
        |b| {
            b.iter(|| {
                refine(
                    &cameras,
                    &init.rig_from_camera,
                    &init.world_from_rig,
                    &observations,
                    &options.refinement,
                )
                .unwrap()
            })
        },
    );
    // The same problem solved by `ibc_bundle_adjust` directly on one thread.
    let problem = RigRefinement {
        cameras: cameras.clone(),
        rig_from_camera: init.rig_from_camera.clone(),
        world_from_rig: init.world_from_rig.clone(),
        observations: observations
            .iter()
            .map(|o| RigObservation {
                frame: o.set as usize,
                camera: o.camera as usize,
                world_point: o.point.coords,
                pixel: o.pixel,
            })
            .collect(),
    };
    let one_thread = RigRefinementOptions {
        solver: ibc_bundle_adjust::SolverOptions {
            num_threads: 1,
            ..Default::default()
        },
        ..Default::default()
    };
    g.bench_function("refinement, 1 thread (baseline)", |b| {
        b.iter(|| problem.refine(&one_thread).unwrap())
    });
    // The quality gates on the refinement's residuals, as the pipeline computes them.
    let initial = reprojection_residuals(
        &cameras,
        &init.rig_from_camera,
        &init.world_from_rig,
        &observations,
    );
    let refined = reprojection_residuals(
        &cameras,
        &calibration.refinement.rig_from_camera,
        &calibration.refinement.world_from_rig,
        &observations,
    );
    let prior = calibration.prior_rig_from_camera();
    let facts = RefinementFacts {
        names: &calibration.camera_names,
        image_sizes: cameras.iter().map(|c| (c.width(), c.height())).collect(),
        localization: calibration
            .quality
            .cameras
            .iter()
            .map(|q| (q.images, q.images_localized, q.inliers))
            .collect(),
        observations: observations
            .iter()
            .map(|o| (o.camera as usize, o.pixel))
            .collect(),
        initial: &initial,
        refined: &refined,
        cauchy_scale_px: options.refinement.cauchy_scale_px,
        converged: (true, "function_tolerance", 5),
        covariance: true,
        prior_rig_from_camera: &prior,
        rig_from_camera: &calibration.refinement.rig_from_camera,
        intrinsics: (
            &calibration.refinement.cameras,
            &calibration.refinement.intrinsics,
        ),
    };
    assert_eq!(assess(&facts).warnings, calibration.quality.warnings);
    g.bench_function("quality gates (40k correspondences)", |b| {
        b.iter(|| assess(black_box(&facts)))
    });
    let poses: Vec<_> = calibration
        .rig_trajectory()
        .map(|(f, p)| (*p, world.log.frames[f].world_from_odometry.unwrap()))
        .collect();
    g.bench_function("hand-eye, planar (100 poses, window 8)", |b| {
        b.iter(|| calibrate_hand_eye(HandEyeSolver::Planar, &poses, &options.hand_eye).unwrap())
    });
    g.bench_function("calibrate: everything (100 frames x 4 cameras)", |b| {
        b.iter(|| calibrate(&world.map, &world.log, &world.map_rig, &options).unwrap())
    });
    // The same with the intrinsics refined too (`--refine-intrinsics`): against the line above.
    for (name, selection) in [
        ("focal+center", IntrinsicsSelection::FocalAndCenter),
        ("all", IntrinsicsSelection::All),
    ] {
        let with = CalibrationOptions {
            refinement: RefinementOptions {
                intrinsics: selection,
                ..Default::default()
            },
            ..Default::default()
        };
        g.bench_function(
            format!("calibrate: everything, --refine-intrinsics {name}"),
            |b| b.iter(|| calibrate(&world.map, &world.log, &world.map_rig, &with).unwrap()),
        );
    }
    g.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);
