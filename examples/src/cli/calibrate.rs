//! `ibc calibrate`: the pipeline on a user's files.

use std::path::Path;
use std::sync::Arc;

use ibc_pipeline::calib::{Calibration, Status, calibrate_with};
use ibc_pipeline::data::GroundTruth;
use ibc_pipeline::data::io::{read_descriptor_layout, read_map};
use ibc_pipeline::report::{Report, output_names, text_table, write_outputs};
use ibc_vocab_tree::{Descriptor, Vocabulary};

use super::inputs::{read_cameras, read_log_checked, read_truth_arg, with_descriptor};
use super::progress::Bars;
use super::{CalibrateArgs, CliError, Outcome, print};

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
    let truth = read_truth_arg(args.truth.as_ref())?;
    bars.step("reading the map");
    let map = read_map::<D>(&args.map).map_err(|source| CliError::Data {
        what: "map",
        source,
    });
    bars.done();
    let map = map?;
    let log = read_log_checked::<D>(&args.log, truth.as_ref().zip(args.truth.as_ref()), bars)?;
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
    with_descriptor!(map, calibrate_files(args, &bars))
}
