//! `ibc simulate`: a scenario's map, rig log, cameras and ground truth written to a folder.

use ibc_pipeline::sim::simulate_to_dir;

use super::progress::Bars;
use super::{CliError, SimulateArgs, print};

/// Runs `ibc simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), CliError> {
    let bars = Bars::new(args.quiet);
    bars.step("simulating");
    let result = simulate_to_dir(&args.scenario, args.seed, &args.out);
    bars.done();
    let (world, files) = result?;
    if args.quiet {
        return Ok(());
    }
    let stats = world.stats();
    print(&format!(
        "scenario `{}` (seed {}): {} map points, {} map images, {} frames x {} cameras\n\
         wrote {}\n      {}\n      {}\n      {}\n",
        world.scenario.name,
        world.scenario.seed,
        stats.map_points,
        stats.map_images,
        stats.frames,
        world.log.camera_names.len(),
        files.map.display(),
        files.log.display(),
        files.cameras.display(),
        files.truth.display()
    ))
}
