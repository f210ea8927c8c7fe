//! Helpers shared by the `intrinsics_*` integration tests.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_pipeline::ibc_camera_models::{Camera, CameraModel};
use ibc_pipeline::intrinsics::simulate::{
    BoardSimulationOptions, SimulatedBoards, preset_camera, simulate_boards,
};
use ibc_pipeline::intrinsics::{IntrinsicModel, PlanarTarget};
use ibc_pipeline::nalgebra::Vector2;

/// The simulated views of a `rows x cols` board (4 cm squares) by the model's preset
/// camera: 20 views, 0.2 px noise per coordinate, the model's default geometry.
pub fn simulated(model: IntrinsicModel, rows: u32, cols: u32, seed: u64) -> SimulatedBoards {
    let options = BoardSimulationOptions {
        seed,
        ..BoardSimulationOptions::for_model(model)
    };
    simulated_with(model, rows, cols, &options)
}

/// Simulated views with explicit options.
pub fn simulated_with(
    model: IntrinsicModel,
    rows: u32,
    cols: u32,
    options: &BoardSimulationOptions,
) -> SimulatedBoards {
    let camera = preset_camera(model).unwrap();
    let target = PlanarTarget::new(rows, cols, 0.04).unwrap();
    simulate_boards(&camera, &target, options).unwrap()
}

/// Largest pixel difference between two cameras over a grid of pixels of `truth`'s image
/// (each pixel unprojected by `truth`, projected by `estimate`), where `truth` sees within
/// `max_deg` of its axis.
pub fn max_projection_difference(truth: &Camera, estimate: &Camera, max_deg: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..=32 {
        for j in 0..=24 {
            let px = Vector2::new(
                f64::from(i) / 32.0 * f64::from(truth.width() - 1),
                f64::from(j) / 24.0 * f64::from(truth.height() - 1),
            );
            let Ok(ray) = truth.unproject(&px) else {
                continue;
            };
            if ray.z.clamp(-1.0, 1.0).acos().to_degrees() > max_deg {
                continue;
            }
            if let Ok(p) = estimate.project(&ray.into_inner()) {
                worst = worst.max((p - px).norm());
            }
        }
    }
    worst
}
