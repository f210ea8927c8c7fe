//! `ibc demo`: a scenario simulated in memory, calibrated and reported.

use ibc_pipeline::calib::calibrate_with;
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

use super::progress::Bars;
use super::{CliError, DemoArgs, Outcome, calibrate::finish};

/// Runs `ibc demo`.
pub fn run(args: &DemoArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let mut scenario = Scenario::resolve(&args.scenario)?;
    if let Some(seed) = args.seed {
        scenario = scenario.with_seed(seed);
    }
    bars.step("simulating");
    let world = SimulatedWorld::simulate(&scenario)?;
    bars.done();
    let calibration = calibrate_with(
        &world.map,
        &world.log,
        &world.map_rig,
        &args.hand_eye.options(),
        None,
        &bars,
    )?;
    finish(
        &calibration,
        Some(&world.truth),
        args.out.as_deref(),
        args.json,
        args.quiet,
    )
}
