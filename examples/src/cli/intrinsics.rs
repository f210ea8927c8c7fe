//! `ibc intrinsics`: a camera's intrinsics from chessboard corners (or simulated ones).
//!
//! A thin layer over [`ibc_pipeline::intrinsics::command`]: the arguments become an
//! [`IntrinsicsJob`], which [`run_job`] carries out (outputs written all or nothing).

use std::path::PathBuf;

use clap::Args;
use ibc_pipeline::intrinsics::command::{CornerSource, IntrinsicsJob, IntrinsicsOutcome, run_job};
use ibc_pipeline::intrinsics::simulate::BoardSimulationOptions;
use ibc_pipeline::intrinsics::{IntrinsicModel, IntrinsicsError, IntrinsicsStatus, PlanarTarget};

use super::CliError;

/// Options of `ibc intrinsics`.
///
/// Calibrates one camera from the corners of a planar target (a chessboard's inner corners,
/// or any grid) detected in several images. Writes `<name>_camera_calib.yaml` (CamOdoCal),
/// `camchain.yaml` (Kalibr), `intrinsics_report.json` and `residuals.svg` into `--out`.
#[derive(Debug, Clone, Args)]
pub struct IntrinsicsArgs {
    /// The corner file (JSON; the format is in the crate documentation, module
    /// `intrinsics`). Required unless --simulate.
    #[arg(long, value_name = "FILE", required_unless_present = "simulate")]
    pub corners: Option<PathBuf>,
    /// The camera model: `kb` (Kannala-Brandt, for fisheyes), `pinhole` (pinhole with
    /// radial-tangential distortion) or `mei` (unified, Kalibr's `omni` + `radtan`).
    #[arg(long, value_name = "kb|pinhole|mei", default_value = "kb", value_parser = parse_model)]
    pub model: IntrinsicModel,
    /// The board as ROWSxCOLS inner corners, e.g. 6x9 (default: the corner file's board, or
    /// 6x9 when simulating).
    #[arg(long, value_name = "ROWSxCOLS", requires = "square")]
    pub board: Option<String>,
    /// Distance between neighbouring corners, metres.
    #[arg(long, value_name = "M", requires = "board")]
    pub square: Option<f64>,
    /// Folder for the output files (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Print the JSON report on standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// No summary on standard output (the JSON report is still printed with --json).
    #[arg(long)]
    pub quiet: bool,
    /// The camera's name in the output files.
    #[arg(long, value_name = "NAME", default_value = "cam0")]
    pub name: String,
    /// Simulate the corners instead of reading them: views of the board seen by a true camera
    /// (the model's preset, or --true-camera), with noise and missing corners. The corners and
    /// the true camera are written next to the outputs, and the report compares with the truth.
    #[arg(long, conflicts_with = "corners")]
    pub simulate: bool,
    /// Simulation: the true camera, a CamOdoCal camera YAML of the --model (default: a 190
    /// degree Kannala-Brandt fisheye, or the EuRoC pinhole).
    #[arg(long, value_name = "FILE", requires = "simulate")]
    pub true_camera: Option<PathBuf>,
    /// Simulation: number of views [default: 20].
    #[arg(long, value_name = "N", requires = "simulate")]
    pub views: Option<usize>,
    /// Simulation: pixel noise per coordinate, pixels [default: 0.2].
    #[arg(long, value_name = "PX", requires = "simulate")]
    pub noise: Option<f64>,
    /// Simulation: probability that a visible corner is missing [default: 0].
    #[arg(long, value_name = "FRACTION", requires = "simulate")]
    pub missing: Option<f64>,
    /// Simulation: the seed of the views and the noise [default: 0].
    #[arg(long, value_name = "N", requires = "simulate")]
    pub seed: Option<u64>,
}

/// Parses `--model`.
fn parse_model(text: &str) -> Result<IntrinsicModel, String> {
    text.parse().map_err(|e: IntrinsicsError| e.to_string())
}

/// The job the arguments describe.
///
/// # Errors
/// [`IntrinsicsError::InvalidTarget`] for a malformed `--board` or `--square`.
pub fn job(args: &IntrinsicsArgs) -> Result<IntrinsicsJob, IntrinsicsError> {
    let source = if args.simulate {
        let preset = BoardSimulationOptions::for_model(args.model);
        let options = BoardSimulationOptions {
            views: args.views.unwrap_or(preset.views),
            noise_px: args.noise.unwrap_or(preset.noise_px),
            missing_fraction: args.missing.unwrap_or(preset.missing_fraction),
            seed: args.seed.unwrap_or(preset.seed),
            ..preset
        };
        CornerSource::Simulate {
            true_camera: args.true_camera.clone(),
            options,
        }
    } else {
        let path = args.corners.clone().ok_or_else(|| {
            IntrinsicsError::InvalidInput("give --corners FILE, or --simulate".into())
        })?;
        CornerSource::File(path)
    };
    let mut job = IntrinsicsJob::new(source, args.model, &args.out)
        .with_json(args.json)
        .with_quiet(args.quiet);
    job.camera_name.clone_from(&args.name);
    if let (Some(board), Some(square)) = (&args.board, args.square) {
        job = job.with_board(PlanarTarget::parse(board, square)?);
    }
    Ok(job)
}

/// Runs `ibc intrinsics`: prints the summary (or the JSON report with --json) and returns
/// what was computed and written.
///
/// # Errors
/// [`IntrinsicsError`] naming what was wrong: the arguments, the corner file, the views
/// (too few, degenerate), the calibration, or the output folder.
pub fn run(args: &IntrinsicsArgs) -> Result<IntrinsicsOutcome, IntrinsicsError> {
    let job = job(args)?;
    run_job(&job, &mut std::io::stdout().lock())
}

/// [`run`] for the command dispatch: its error becomes a [`CliError`], printed as one line by
/// `main`. Output files are written all or nothing, so none is left behind; a calibration
/// that fails its quality gates is written and reported as [`super::Outcome::Poor`].
///
/// # Errors
/// [`CliError::Intrinsics`] with [`run`]'s error.
pub fn run_command(args: &IntrinsicsArgs) -> Result<super::Outcome, CliError> {
    let outcome = run(args)?;
    Ok(match outcome.calibration.status() {
        IntrinsicsStatus::Ok => super::Outcome::Done,
        IntrinsicsStatus::Poor => super::Outcome::Poor,
    })
}
