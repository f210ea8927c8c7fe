//! `ibc simulate`: a scenario's map, rig log, cameras and ground truth written to a folder.

use std::path::Path;

use ibc_pipeline::colmap::{survey_image_sources, write_colmap, write_colmap_log};
use ibc_pipeline::sim::{SimulatedWorld, simulate_to_dir};

use super::progress::Bars;
use super::{CliError, SimulateArgs, print};

/// Runs `ibc simulate`.
pub fn run(args: &SimulateArgs) -> Result<(), CliError> {
    let bars = Bars::new(args.quiet);
    bars.step("simulating");
    let result = simulate_to_dir(&args.scenario, args.seed, &args.out);
    bars.done();
    let (world, files) = result?;
    let colmap_dir = args.out.join("colmap");
    if args.colmap {
        bars.step("writing COLMAP data");
        let written = write_world_colmap(&world, &colmap_dir);
        bars.done();
        written?;
    }
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
    ))?;
    if args.colmap {
        print(&format!(
            "      {} (sparse/, database.db, rig_config.json, log.db)\n",
            colmap_dir.display()
        ))?;
    }
    Ok(())
}

/// The world's map and log as COLMAP data in `dir` (see [`SimulateArgs::colmap`]).
fn write_world_colmap(world: &SimulatedWorld, dir: &Path) -> Result<(), CliError> {
    let error = |source| CliError::Colmap {
        what: "COLMAP output",
        source,
    };
    let sources = survey_image_sources(world.map.images.len(), world.map_rig.cameras.len());
    write_colmap(dir, &world.map_rig, &world.map, &sources).map_err(error)?;
    write_colmap_log(dir.join("log.db"), &world.map_rig, &world.log).map_err(error)
}
