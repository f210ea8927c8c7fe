//! `ibc map`: the survey phase, a map built from a calibrated rig's log.

use ibc_pipeline::calib::camera_matching::match_cameras;
use ibc_pipeline::data::io::{DescriptorLayout, read_descriptor_layout, read_log, write_map};
use ibc_pipeline::sfm::{SelfCalibrationOptions, build_map};
use ibc_vocab_tree::{Descriptor, DescriptorKind};

use super::calibrate::read_cameras;
use super::progress::Bars;
use super::{CliError, MapArgs, Outcome, print};

fn run_with<D: Descriptor>(args: &MapArgs, bars: &Bars) -> Result<Outcome, CliError> {
    let prior = read_cameras(&args.cameras)?;
    bars.step("reading the log");
    let log = read_log::<D>(&args.log).map_err(|source| CliError::Data {
        what: "rig log",
        source,
    });
    bars.done();
    let log = log?;
    let (rig, _) = match_cameras(&prior, &log.camera_names)?;
    bars.step("building the map (tracks, averaging, triangulation and bundle adjustment)");
    let built = build_map(&log, &rig, &SelfCalibrationOptions::default());
    bars.done();
    let built = built?;
    write_map(&args.out, &built.map).map_err(|source| CliError::Data {
        what: "map",
        source,
    })?;
    let posed = built.world_from_rig.iter().flatten().count();
    let summary = serde_json::json!({
        "format": "ibc-map-report",
        "version": 1,
        "map": args.out.display().to_string(),
        "frames": built.world_from_rig.len(),
        "frames_posed": posed,
        "images": built.map.images.len(),
        "points": built.map.points.len(),
        "mean_observations_per_point": built.mean_observations_per_point,
        "reprojection_error_px": built.rms_px,
        "rounds": built.rounds.len(),
        "verified_pairs": built.tracks.verified_pairs,
    });
    if args.json {
        print(&(serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n"))?;
    } else {
        print(&format!(
            "map of {} points ({:.1} observations per point, rms {:.3} px) from {} of {} frames, \
             {} images\nwrote {}\n",
            built.map.points.len(),
            built.mean_observations_per_point,
            built.rms_px,
            posed,
            built.world_from_rig.len(),
            built.map.images.len(),
            args.out.display()
        ))?;
    }
    Ok(Outcome::Done)
}

/// Runs `ibc map`.
pub fn run(args: &MapArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let layout = read_descriptor_layout(&args.log).map_err(|source| CliError::Data {
        what: "rig log",
        source,
    })?;
    match (layout.kind, layout.width) {
        (DescriptorKind::Binary, 4) => run_with::<[u64; 4]>(args, &bars),
        (DescriptorKind::Binary, 8) => run_with::<[u64; 8]>(args, &bars),
        (DescriptorKind::Float, 32) => run_with::<[f32; 32]>(args, &bars),
        (DescriptorKind::Float, 64) => run_with::<[f32; 64]>(args, &bars),
        (DescriptorKind::Float, 128) => run_with::<[f32; 128]>(args, &bars),
        _ => Err(CliError::UnsupportedDescriptor(DescriptorLayout {
            ..layout
        })),
    }
}
