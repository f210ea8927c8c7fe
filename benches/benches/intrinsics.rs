//! Benchmarks of `ibc intrinsics` (issue 9): the intrinsic calibration of 20 simulated views
//! of a 9x6 board (0.2 px noise) by the 190-degree Kannala-Brandt fisheye preset (target
//! <= 200 ms) and by the EuRoC pinhole preset, each against same-run baselines:
//! - one PnP pass: EPnP and the bearing refinement of all 20 board poses with the true camera
//!   (the unit of work the paper's initialization repeats once per focal hypothesis);
//! - the Kannala-Brandt initialization alone (vanishing points, hypotheses scored by PnP).
//!
//! Run: `cargo bench -p ibc-benches --bench intrinsics`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ibc_camera_models::{Camera, CameraModel};
use ibc_pipeline::intrinsics::kb_init::{KbInitOptions, kannala_brandt_initialization};
use ibc_pipeline::intrinsics::simulate::{
    BoardSimulationOptions, SimulatedBoards, preset_camera, simulate_boards,
};
use ibc_pipeline::intrinsics::{
    IntrinsicModel, IntrinsicsOptions, PlanarTarget, calibrate_intrinsics,
};
use ibc_pnp::{RefineOptions, epnp, refine_pose};
use nalgebra::{Point3, Vector3};

fn boards(model: IntrinsicModel) -> SimulatedBoards {
    let camera = preset_camera(model).unwrap();
    let target = PlanarTarget::new(6, 9, 0.04).unwrap();
    let options = BoardSimulationOptions::for_model(model);
    simulate_boards(&camera, &target, &options).unwrap()
}

/// EPnP + refinement of every board pose with the true camera.
fn pnp_pass(camera: &Camera, sim: &SimulatedBoards) -> f64 {
    let mut sum = 0.0;
    for image in &sim.corners.images {
        let points: Vec<Point3<f64>> = image
            .corners
            .iter()
            .map(|c| sim.target.point(c.row, c.col))
            .collect();
        let rays: Vec<Vector3<f64>> = image
            .corners
            .iter()
            .map(|c| camera.unproject_fast(&c.pixel()).unwrap().into_inner())
            .collect();
        let pose = epnp(&rays, &points).unwrap();
        let refined = refine_pose(&rays, &points, &pose, &RefineOptions::default()).unwrap();
        sum += refined.camera_from_world.translation.vector.z;
    }
    sum
}

fn intrinsics(c: &mut Criterion) {
    let mut g = c.benchmark_group("intrinsics");
    g.sample_size(20);
    for model in [IntrinsicModel::KannalaBrandt, IntrinsicModel::PinholeRadtan] {
        let sim = boards(model);
        let name = model.short_name();
        let options = IntrinsicsOptions::default();
        g.bench_function(format!("{name}_9x6_20_views/calibrate"), |b| {
            b.iter(|| {
                calibrate_intrinsics(black_box(&sim.corners), &sim.target, model, &options).unwrap()
            })
        });
        g.bench_function(format!("{name}_9x6_20_views/baseline_one_pnp_pass"), |b| {
            b.iter(|| pnp_pass(black_box(&sim.camera), &sim))
        });
        if model == IntrinsicModel::KannalaBrandt {
            let init = KbInitOptions::default();
            g.bench_function(
                format!("{name}_9x6_20_views/baseline_vp_initialization"),
                |b| {
                    b.iter(|| {
                        kannala_brandt_initialization(black_box(&sim.corners), &sim.target, &init)
                            .unwrap()
                    })
                },
            );
        }
    }
    g.finish();
}

criterion_group!(benches, intrinsics);
criterion_main!(benches);
