//! Helpers shared by the `intrinsics_*` integration tests.

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_pipeline::intrinsics::simulate::{
    BoardSimulationOptions, SimulatedBoards, preset_camera, simulate_boards,
};
use ibc_pipeline::intrinsics::{IntrinsicModel, PlanarTarget};

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
