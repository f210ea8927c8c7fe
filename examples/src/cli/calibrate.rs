//! `ibc calibrate`: the pipeline on a user's files.

use std::path::Path;
use std::sync::Arc;

use ibc_camera_models::Rig;
use ibc_pipeline::calib::{Calibration, Status, calibrate_with};
use ibc_pipeline::data::GroundTruth;
use ibc_pipeline::data::io::{
    DescriptorLayout, read_descriptor_layout, read_log, read_map, read_truth,
};
use ibc_pipeline::report::{Report, output_names, text_table, write_outputs};
use ibc_vocab_tree::{Descriptor, DescriptorKind, Vocabulary};

use super::progress::Bars;
use super::{CalibrateArgs, CliError, Outcome, print};

/// Reads the camera file: a CamOdoCal folder (or its `extrinsic.txt`), else a Kalibr camchain.
pub(super) fn read_cameras(path: &Path) -> Result<Rig, CliError> {
    let error = |source| CliError::Cameras {
        path: path.to_owned(),
        source: Box::new(source),
    };
    if path.is_dir() {
        Rig::read_camodocal_dir(path).map_err(error)
    } else if path.file_name().is_some_and(|n| n == "extrinsic.txt") {
        Rig::read_camodocal_dir(path.parent().unwrap_or(Path::new("."))).map_err(error)
    } else {
        Rig::read_kalibr(path).map_err(error)
    }
}

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
    let written = out
        .map(|dir| write_outputs(dir, calibration, &report).map(|_| dir))
        .transpose()?;
    let wrote = written.map(|dir| {
        format!(
            "wrote {} ({}, {}, {}, {}/, {}, {})\n",
            dir.display(),
            output_names::REPORT_JSON,
            output_names::REPORT_TEXT,
            output_names::CAMCHAIN,
            output_names::CAMODOCAL_DIR,
            output_names::TOP_VIEW,
            output_names::ERRORS
        )
    });
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

/// The calibration with descriptors of type `D`.
fn calibrate_files<D: Descriptor>(args: &CalibrateArgs, bars: &Bars) -> Result<Outcome, CliError> {
    let rig = read_cameras(&args.cameras)?;
    let truth = args
        .truth
        .as_ref()
        .map(|p| {
            read_truth(p).map_err(|source| CliError::Data {
                what: "ground truth",
                source,
            })
        })
        .transpose()?;
    bars.step("reading the map");
    let map = read_map::<D>(&args.map).map_err(|source| CliError::Data {
        what: "map",
        source,
    });
    bars.done();
    let map = map?;
    bars.step("reading the log");
    let log = read_log::<D>(&args.log).map_err(|source| CliError::Data {
        what: "rig log",
        source,
    });
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
    let vocabulary = args
        .vocabulary
        .as_ref()
        .map(|p| {
            Vocabulary::<D>::load(p)
                .map(Arc::new)
                .map_err(|source| CliError::Vocabulary { source })
        })
        .transpose()?;
    let calibration = calibrate_with(&map, &log, &rig, &args.hand_eye.options(), vocabulary, bars)?;
    finish(
        &calibration,
        truth.as_ref(),
        Some(&args.out),
        args.json,
        args.quiet,
    )
}

/// Runs `ibc calibrate`.
pub fn run(args: &CalibrateArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let data = |what| move |source| CliError::Data { what, source };
    let map = read_descriptor_layout(&args.map).map_err(data("map"))?;
    let log = read_descriptor_layout(&args.log).map_err(data("rig log"))?;
    if map != log {
        return Err(CliError::DescriptorMismatch { map, log });
    }
    match (map.kind, map.width) {
        (DescriptorKind::Binary, 4) => calibrate_files::<[u64; 4]>(args, &bars),
        (DescriptorKind::Binary, 8) => calibrate_files::<[u64; 8]>(args, &bars),
        (DescriptorKind::Float, 32) => calibrate_files::<[f32; 32]>(args, &bars),
        (DescriptorKind::Float, 64) => calibrate_files::<[f32; 64]>(args, &bars),
        (DescriptorKind::Float, 128) => calibrate_files::<[f32; 128]>(args, &bars),
        _ => Err(CliError::UnsupportedDescriptor(DescriptorLayout { ..map })),
    }
}
