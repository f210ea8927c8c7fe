//! `ibc calibrate`: the pipeline on a user's files.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use ibc_bundle_adjust::nalgebra::DMatrix;
use ibc_bundle_adjust::{OnlineEvent, OnlineOptions};
use ibc_camera_models::Rig;
use ibc_camera_models::{Camera, CameraModel};
use ibc_pipeline::calib::{Calibration, Status, calibrate_with, replay_online};
use ibc_pipeline::colmap::{
    ColmapDatabase, ColmapDescriptor, ColmapLogOptions, read_colmap_log, read_colmap_map,
};
use ibc_pipeline::data::io::{read_descriptor_layout, read_map};
use ibc_pipeline::data::{GroundTruth, Map, RigLog};
use ibc_pipeline::report::{Report, text_table, write_outputs};
use ibc_vocab_tree::{Descriptor, Vocabulary};

use super::inputs::{
    is_sqlite, read_cameras, read_log_checked, read_truth_arg, with_colmap_descriptor,
    with_descriptor,
};
use super::progress::Bars;
use super::{CalibrateArgs, CliError, Outcome, print, wrote_line};

/// Builds the report, writes the output files when `out` is given, prints the table (or the
/// JSON report), says where the files went (after the table; on standard error with `json`
/// unless `quiet`), and returns whether the calibration passed its quality gates.
pub fn finish(
    calibration: &Calibration,
    truth: Option<&GroundTruth>,
    out: Option<&Path>,
    json: bool,
    quiet: bool,
) -> Result<Outcome, CliError> {
    let report = Report::new(calibration, truth)?;
    let wrote = out
        .map(|dir| {
            write_outputs(dir, calibration, &report).map(|written| wrote_line(dir, &written))
        })
        .transpose()?;
    if json {
        print(&(report.to_json() + "\n"))?;
        if let (Some(line), false) = (&wrote, quiet) {
            eprint!("{line}");
        }
    } else {
        print(&(text_table(&report) + wrote.as_deref().unwrap_or("")))?;
    }
    Ok(match report.status {
        Status::Ok => Outcome::Done,
        Status::Poor => Outcome::Poor,
    })
}

/// The calibration of `map` and `log` (read by the caller) with the cameras and options of
/// `args`.
fn calibrate_inputs<D: Descriptor>(
    args: &CalibrateArgs,
    rig: &Rig,
    map: &Map<D>,
    log: &RigLog<D>,
    truth: Option<&GroundTruth>,
    bars: &Bars,
) -> Result<Outcome, CliError> {
    let vocabulary = args
        .vocabulary
        .as_ref()
        .map(|p| {
            Vocabulary::<D>::load(p)
                .map(Arc::new)
                .map_err(|source| CliError::Vocabulary { source })
        })
        .transpose()?;
    let mut options = args.hand_eye.options();
    options.refinement.intrinsics = args.refine_intrinsics.selection();
    let calibration = calibrate_with(map, log, rig, &options, vocabulary, bars)?;
    let online = args
        .online
        .then(|| online_lines(&calibration, map, log, truth))
        .transpose()?;
    let outcome = finish(&calibration, truth, Some(&args.out), args.json, args.quiet)?;
    if let Some(lines) = online {
        // After the table on standard output; beside the JSON on standard error.
        if args.json {
            if !args.quiet {
                eprint!("{lines}");
            }
        } else {
            print(&lines)?;
        }
    }
    Ok(outcome)
}

/// The online calibrator's running estimate over the log ([`replay_online`]), a line per due
/// update: each camera's focal lengths with their standard deviations and, with `truth`,
/// their errors against the truth at the window's middle frame; or why the update was
/// skipped.
fn online_lines<D: Descriptor>(
    calibration: &Calibration,
    map: &Map<D>,
    log: &RigLog<D>,
    truth: Option<&GroundTruth>,
) -> Result<String, CliError> {
    let options = OnlineOptions::default();
    let steps = replay_online(calibration, map, log, &options)?;
    let mut out = String::new();
    for step in &steps {
        let line = match &step.event {
            OnlineEvent::Updated(update) => {
                // The window's middle frame set, and its log frame.
                let middle = step.set + 1 - options.window / 2;
                let frame = calibration
                    .frame_sets
                    .get(middle)
                    .map_or(step.frame, |s| s.frame);
                let cameras: Vec<String> = update
                    .cameras
                    .iter()
                    .enumerate()
                    .map(|(c, camera)| {
                        let name = calibration.camera_names.get(c).map_or("?", String::as_str);
                        let cov = update.intrinsic_covariance.get(c).and_then(Option::as_ref);
                        let truth = truth.and_then(|t| t.camera_at(c, frame, camera));
                        focal_lengths(name, camera, cov, truth.as_ref())
                    })
                    .collect();
                format!("updated: {}", cameras.join("; "))
            }
            OnlineEvent::Skipped(reason) => format!("skipped: {reason}"),
            _ => continue,
        };
        out.push_str(&format!(
            "online, frame set {} (frame {}): {line}\n",
            step.set, step.frame
        ));
    }
    if steps.is_empty() {
        out.push_str(&format!(
            "online: no update was due ({} frame sets, the window is {})\n",
            calibration.frame_sets.len(),
            options.window
        ));
    }
    Ok(out)
}

/// `name mu 396.606 (std 0.016, error +0.048) mv ...`: a camera's focal lengths with their
/// standard deviations (from `cov`, the covariance of its intrinsics) and, with `truth`, their
/// errors.
fn focal_lengths(
    name: &str,
    camera: &Camera,
    cov: Option<&DMatrix<f64>>,
    truth: Option<&Camera>,
) -> String {
    let focal: Vec<String> = camera
        .focal_length_indices()
        .iter()
        .map(|&i| {
            let value = camera.params()[i];
            let std = cov.map_or(f64::NAN, |m| m[(i, i)].max(0.0).sqrt());
            let error = truth.map_or(String::new(), |t| {
                format!(", error {:+.3}", value - t.params()[i])
            });
            format!(
                "{} {value:.3} (std {std:.3}{error})",
                camera.param_names()[i]
            )
        })
        .collect();
    format!("{name} {}", focal.join(" "))
}

/// The calibration with descriptors of type `D`, from ibc files.
fn calibrate_files<D: Descriptor>(args: &CalibrateArgs, bars: &Bars) -> Result<Outcome, CliError> {
    // The camera file first: its errors are the cheapest to find.
    let rig = read_cameras(&args.cameras)?;
    let truth = read_truth_arg(args.truth.as_ref())?;
    bars.step("reading the map");
    let map = read_map::<D>(&args.map).map_err(|source| CliError::Data {
        what: "map",
        source,
    });
    bars.done();
    let map = map?;
    let log = read_log_checked::<D>(&args.log, truth.as_ref().zip(args.truth.as_ref()), bars)?;
    calibrate_inputs(args, &rig, &map, &log, truth.as_ref(), bars)
}

/// The COLMAP database of a COLMAP map (`--map` a folder), or `None` for an ibc map.
fn colmap_map_database(args: &CalibrateArgs) -> Result<Option<&PathBuf>, CliError> {
    if !args.map.is_dir() {
        return Ok(None);
    }
    args.database
        .as_ref()
        .map(Some)
        .ok_or_else(|| CliError::ColmapDatabaseMissing {
            path: args.map.clone(),
        })
}

/// The calibration with descriptors of type `D`, when the map or the log (or both) are COLMAP
/// data.
fn calibrate_colmap<D: ColmapDescriptor>(
    args: &CalibrateArgs,
    bars: &Bars,
) -> Result<Outcome, CliError> {
    let rig = read_cameras(&args.cameras)?;
    let truth = read_truth_arg(args.truth.as_ref())?;
    let colmap = |what| move |source| CliError::Colmap { what, source };
    bars.step("reading the map");
    let map = match colmap_map_database(args)? {
        Some(database) => read_colmap_map::<D>(&args.map, database)
            .map(|m| m.map)
            .map_err(colmap("map")),
        None => read_map::<D>(&args.map).map_err(|source| CliError::Data {
            what: "map",
            source,
        }),
    };
    bars.done();
    let map = map?;
    let log = if is_sqlite(&args.log) {
        bars.step("reading the log");
        let options = ColmapLogOptions {
            seconds_per_unit: args.colmap_seconds_per_unit,
            ..Default::default()
        };
        let log = read_colmap_log::<D>(&args.log, &options).map_err(colmap("rig log"));
        bars.done();
        let log = log?;
        if let (Some(truth), Some(path)) = (&truth, &args.truth) {
            truth
                .check_log(&log.camera_names, log.frames.len())
                .map_err(|source| CliError::TruthMismatch {
                    path: path.clone(),
                    source,
                })?;
        }
        log
    } else {
        read_log_checked::<D>(&args.log, truth.as_ref().zip(args.truth.as_ref()), bars)?
    };
    calibrate_inputs(args, &rig, &map, &log, truth.as_ref(), bars)
}

/// Runs `ibc calibrate`.
pub fn run(args: &CalibrateArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let data = |what| move |source| CliError::Data { what, source };
    let colmap = |what| move |source| CliError::Colmap { what, source };
    let map_database = colmap_map_database(args)?;
    let log_is_colmap = is_sqlite(&args.log);
    let map = match map_database {
        Some(db) => ColmapDatabase::open(db)
            .and_then(|db| db.descriptor_layout())
            .map_err(colmap("map"))?,
        None => read_descriptor_layout(&args.map).map_err(data("map"))?,
    };
    let log = if log_is_colmap {
        ColmapDatabase::open(&args.log)
            .and_then(|db| db.descriptor_layout())
            .map_err(colmap("rig log"))?
    } else {
        read_descriptor_layout(&args.log).map_err(data("rig log"))?
    };
    if map != log {
        return Err(CliError::DescriptorMismatch { map, log });
    }
    if map_database.is_some() || log_is_colmap {
        with_colmap_descriptor!(map, calibrate_colmap(args, &bars))
    } else {
        with_descriptor!(map, calibrate_files(args, &bars))
    }
}
