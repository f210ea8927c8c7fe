//! `ibc selfcalib`: a rig's extrinsics from its own log, without a map.

use ibc_pipeline::calib::camera_matching::match_cameras;
use ibc_pipeline::report::{SelfCalibrationReport, self_calibrated_rig, write_selfcalib_outputs};
use ibc_pipeline::sfm::{ScaleSource, SelfCalibrationOptions, self_calibrate};
use ibc_vocab_tree::Descriptor;

use super::inputs::{log_layout, read_cameras, read_log_checked, read_truth_arg, with_descriptor};
use super::progress::Bars;
use super::{CliError, Outcome, SelfCalibArgs, print, wrote_line};

/// Parses `--baseline CAM_A:CAM_B=METRES` against the log's camera names.
fn baseline(text: &str, names: &[String]) -> Result<ScaleSource, CliError> {
    let bad = |reason: String| CliError::Baseline {
        value: text.to_owned(),
        reason,
    };
    let (cameras, metres) = text
        .split_once('=')
        .ok_or_else(|| bad("expected CAM_A:CAM_B=METRES".into()))?;
    let (a, b) = cameras
        .split_once(':')
        .ok_or_else(|| bad("expected CAM_A:CAM_B=METRES".into()))?;
    let index = |name: &str| {
        names.iter().position(|n| n == name).ok_or_else(|| {
            bad(format!(
                "the log has no camera `{name}` (it has {})",
                names.join(", ")
            ))
        })
    };
    let distance_m: f64 = metres
        .trim()
        .parse()
        .map_err(|_| bad(format!("`{metres}` is not a number of metres")))?;
    if !(distance_m > 0.0 && distance_m.is_finite()) {
        return Err(bad(
            "the distance must be a finite positive number of metres".into(),
        ));
    }
    let (a, b) = (index(a.trim())?, index(b.trim())?);
    if a == b {
        return Err(bad("the two cameras must differ".into()));
    }
    Ok(ScaleSource::Baseline { a, b, distance_m })
}

fn run_with<D: Descriptor>(args: &SelfCalibArgs, bars: &Bars) -> Result<Outcome, CliError> {
    let prior = read_cameras(&args.cameras)?;
    let truth = read_truth_arg(args.truth.as_ref())?;
    let log = read_log_checked::<D>(&args.log, truth.as_ref().zip(args.truth.as_ref()), bars)?;
    let (rig, _) = match_cameras(&prior, &log.camera_names)?;
    let scale = match &args.baseline {
        Some(text) => baseline(text, &log.camera_names)?,
        None => ScaleSource::Auto,
    };
    let cameras: Vec<_> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    bars.step("self-calibrating (tracks, averaging, triangulation and bundle adjustment)");
    let result = self_calibrate(
        &log,
        &cameras,
        &SelfCalibrationOptions {
            scale,
            ..Default::default()
        },
    );
    bars.done();
    let result = result?;
    let report = SelfCalibrationReport::new(&result, &log.camera_names, &cameras, truth.as_ref());
    let written = write_selfcalib_outputs(
        &args.out,
        &report,
        &result,
        &self_calibrated_rig(&rig, &log.camera_names, &result),
    )?;
    let wrote = wrote_line(&args.out, &written);
    if args.json {
        print(&(report.to_json() + "\n"))?;
        if !args.quiet {
            eprint!("{wrote}");
        }
    } else {
        print(&(report.text_table() + &wrote))?;
    }
    Ok(if report.is_ok() {
        Outcome::Done
    } else {
        Outcome::Poor
    })
}

/// Runs `ibc selfcalib`.
pub fn run(args: &SelfCalibArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let layout = log_layout(&args.log)?;
    with_descriptor!(layout, run_with(args, &bars))
}
