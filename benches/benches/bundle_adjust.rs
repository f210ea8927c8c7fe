//! ibc-bundle-adjust: BAL problem-49 (Ceres's figures in issue 6) and rig refinement.
//!
//! Same-run baseline: one residual-only cost evaluation of problem-49 (`bal49/cost_pass`), so
//! solve times can be read as a ratio to a fixed unit of work on a noisy machine.
//!
//! `cargo bench -p ibc-benches --bench bundle_adjust`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use ibc_bundle_adjust::{
    BalProblem, LinearSolverType, OnlineCalibrator, OnlineEvent, OnlineFrameSet, OnlineObservation,
    OnlineOptions, RigObservation, RigRefinement, RigRefinementOptions, RobustLoss, SolverOptions,
};
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, PinholeRadtan, Rig, RigCamera};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The BAL problem-49 kept in the bundle adjuster's test data.
fn problem49() -> BalProblem {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../bundle-adjust/tests/data/problem-49-7776-pre.txt");
    let mut bal = BalProblem::from_file(&path).expect("the BAL file in bundle-adjust/tests/data");
    bal.normalize();
    bal
}

fn options(solver: LinearSolverType, threads: usize, full_budget: bool) -> SolverOptions {
    let o = SolverOptions {
        linear_solver: solver,
        num_threads: threads,
        ..Default::default()
    };
    if full_budget {
        SolverOptions {
            function_tolerance: 0.0,
            gradient_tolerance: 0.0,
            parameter_tolerance: 0.0,
            ..o
        }
    } else {
        o
    }
}

fn bal49(c: &mut Criterion) {
    let bal = problem49();
    let mut g = c.benchmark_group("bal49");
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(12));
    g.bench_function("cost_pass", |b| {
        b.iter(|| black_box(bal.cost(RobustLoss::Trivial).unwrap()))
    });
    let cases = [
        ("dense_50it_1t", LinearSolverType::DenseSchur, 1, true),
        ("sparse_50it_1t", LinearSolverType::SparseSchur, 1, true),
        (
            "iterative_50it_1t",
            LinearSolverType::IterativeSchur,
            1,
            true,
        ),
        ("dense_default_1t", LinearSolverType::DenseSchur, 1, false),
        ("dense_50it_2t", LinearSolverType::DenseSchur, 2, true),
        ("sparse_50it_2t", LinearSolverType::SparseSchur, 2, true),
        (
            "iterative_50it_2t",
            LinearSolverType::IterativeSchur,
            2,
            true,
        ),
        ("dense_default_2t", LinearSolverType::DenseSchur, 2, false),
    ];
    for (name, solver, threads, full) in cases {
        let o = options(solver, threads, full);
        g.bench_function(name, |b| {
            b.iter_batched(
                || bal.clone(),
                |mut p| black_box(p.solve(RobustLoss::Trivial, &o).unwrap().final_cost),
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

fn random_rotation(rng: &mut ChaCha8Rng, angle: f64) -> UnitQuaternion<f64> {
    let axis = Vector3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    UnitQuaternion::from_scaled_axis(axis.normalize() * angle)
}

/// 4 cameras x `frames` frame sets x `per_image` points per image (500 x 20: 40,000
/// observations), 0.5 px noise, 2 % wrong matches, perturbed extrinsics and rig poses.
fn rig_scene(frames: usize, per_image: usize) -> RigRefinement {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let cams = 4;
    let mut cameras: Vec<Camera> = Vec::new();
    let mut rig_from_camera = Vec::new();
    for c in 0..cams {
        cameras.push(if c % 2 == 0 {
            PinholeRadtan::new(
                752,
                480,
                [-0.28, 0.07, 1e-4, -2e-4, 460.0, 458.0, 370.0, 245.0],
            )
            .unwrap()
            .into()
        } else {
            KannalaBrandt::new(
                1280,
                800,
                [0.01, -0.002, 0.0005, -0.0001, 350.0, 350.0, 640.0, 400.0],
            )
            .unwrap()
            .into()
        });
        let yaw = UnitQuaternion::from_axis_angle(
            &Vector3::y_axis(),
            c as f64 * std::f64::consts::TAU / cams as f64,
        );
        let t = Vector3::new(
            rng.random_range(-0.5..0.5),
            0.0,
            rng.random_range(-0.5..0.5),
        );
        rig_from_camera.push(Isometry3::from_parts(Translation3::from(t), yaw));
    }
    let reference = rig_from_camera[0].inverse();
    for p in &mut rig_from_camera {
        *p = reference * *p;
    }
    let world_from_rig: Vec<Isometry3<f64>> = (0..frames)
        .map(|f| {
            let s = f as f64 * 0.05;
            Isometry3::from_parts(
                Translation3::new(30.0 * s.cos(), 0.0, 30.0 * s.sin()),
                random_rotation(&mut rng, 0.5),
            )
        })
        .collect();
    let mut observations = Vec::new();
    for (f, w) in world_from_rig.iter().enumerate() {
        for (c, cam) in cameras.iter().enumerate() {
            for _ in 0..per_image {
                let px = Vector2::new(
                    rng.random_range(20.0..f64::from(cam.width()) - 20.0),
                    rng.random_range(20.0..f64::from(cam.height()) - 20.0),
                );
                let p_cam = cam.unproject(&px).unwrap().into_inner() * rng.random_range(2.0..15.0);
                let world_point = (w * rig_from_camera[c])
                    .transform_point(&p_cam.into())
                    .coords;
                let pixel = if rng.random_range(0.0..1.0) < 0.02 {
                    Vector2::new(rng.random_range(0.0..700.0), rng.random_range(0.0..450.0))
                } else {
                    px + Vector2::new(rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5))
                };
                observations.push(RigObservation {
                    frame: f,
                    camera: c,
                    world_point,
                    pixel,
                });
            }
        }
    }
    let perturb = |rng: &mut ChaCha8Rng, p: &Isometry3<f64>, a: f64, t: f64| {
        Isometry3::from_parts(
            Translation3::from(p.translation.vector + Vector3::new(t, -t, t)),
            p.rotation * random_rotation(rng, a),
        )
    };
    let rig_from_camera = std::iter::once(rig_from_camera[0])
        .chain(
            rig_from_camera[1..]
                .iter()
                .map(|p| perturb(&mut rng, p, 0.02, 0.03)),
        )
        .collect();
    let world_from_rig = world_from_rig
        .iter()
        .map(|p| perturb(&mut rng, p, 0.01, 0.03))
        .collect();
    RigRefinement {
        cameras,
        rig_from_camera,
        world_from_rig,
        observations,
    }
}

fn rig(c: &mut Criterion) {
    let scene = rig_scene(500, 20);
    assert_eq!(scene.observations.len(), 40_000);
    let mut g = c.benchmark_group("rig_4x500x40000");
    g.sample_size(20).measurement_time(Duration::from_secs(8));
    for threads in [1, 2] {
        let o = RigRefinementOptions {
            covariance: false,
            solver: SolverOptions {
                num_threads: threads,
                ..Default::default()
            },
            ..Default::default()
        };
        g.bench_function(format!("refine_{threads}t"), |b| {
            b.iter(|| black_box(scene.refine(&o).unwrap().final_rms))
        });
    }
    g.finish();
}

/// An online update (`OnlineCalibrator`, focal lengths and extrinsics, PCG, one thread) of a
/// 50-frame-set window of 4 cameras x 50 or 100 correspondences, warm-started by the update ten
/// frame sets before (the calibrator's rhythm), against the extrinsics-only rig refinement of
/// the same window from the same start with the same solver.
fn online(c: &mut Criterion) {
    for per_image in [50, 100] {
        online_window(c, per_image);
    }
}

fn online_window(c: &mut Criterion, per_image: usize) {
    let scene = rig_scene(60, per_image);
    let rig = Rig::new(
        scene
            .cameras
            .iter()
            .zip(&scene.rig_from_camera)
            .enumerate()
            .map(|(i, (camera, pose))| RigCamera::new(format!("cam{i}"), camera.clone(), *pose))
            .collect(),
    );
    let options = OnlineOptions::default();
    let mut calibrator = OnlineCalibrator::new(&rig, options.clone()).unwrap();
    let mut sets: Vec<OnlineFrameSet> = scene
        .world_from_rig
        .iter()
        .map(|&world_from_rig| OnlineFrameSet {
            world_from_rig,
            observations: Vec::new(),
        })
        .collect();
    for o in &scene.observations {
        sets[o.frame].observations.push(OnlineObservation {
            camera: o.camera,
            world_point: o.world_point,
            pixel: o.pixel,
        });
    }
    let last = sets.pop().unwrap();
    for (i, set) in sets.into_iter().enumerate() {
        let event = calibrator.push(set).unwrap();
        assert_eq!(
            matches!(event, OnlineEvent::Updated(_)),
            i == 49,
            "{event:?}"
        );
    }
    // The baseline: the same window, from the same start.
    let mut window = scene.clone();
    window.world_from_rig.drain(..10);
    window.observations.retain(|o| o.frame >= 10);
    for o in &mut window.observations {
        o.frame -= 10;
    }
    window.cameras = calibrator.cameras().to_vec();
    window.rig_from_camera = calibrator.rig_from_camera().to_vec();
    let mut g = c.benchmark_group(format!("online_50x4x{per_image}"));
    g.sample_size(20);
    g.bench_function("update (focal + extrinsics, PCG, 1 thread)", |b| {
        b.iter_batched(
            || (calibrator.clone(), last.clone()),
            |(mut calibrator, last)| {
                let event = calibrator.push(last).unwrap();
                assert!(matches!(event, OnlineEvent::Updated(_)), "{event:?}");
            },
            BatchSize::LargeInput,
        )
    });
    let extrinsics_only = RigRefinementOptions {
        covariance: false,
        ..options.refinement.clone()
    };
    g.bench_function("rig refinement, extrinsics only (baseline)", |b| {
        b.iter(|| black_box(window.refine(&extrinsics_only).unwrap().final_rms))
    });
    g.finish();
}

criterion_group!(benches, bal49, rig, online);
criterion_main!(benches);
