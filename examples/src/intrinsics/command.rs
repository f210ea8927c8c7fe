//! The work of `ibc intrinsics`: load (or simulate) corners, calibrate, write the outputs and
//! print a summary. The command line maps its arguments onto an [`IntrinsicsJob`].

use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use ibc_camera_models::{Camera, camodocal};

use super::calibrate::{
    IntrinsicCalibration, IntrinsicModel, IntrinsicsOptions, calibrate_intrinsics,
};
use super::corners::CornerSet;
use super::error::IntrinsicsError;
use super::output::{OutputFiles, write_outputs};
use super::report::IntrinsicsReport;
use super::simulate::{BoardSimulationOptions, SimulatedBoards, preset_camera, simulate_boards};
use super::target::PlanarTarget;

/// The board of `ibc intrinsics --simulate` when none is given: 6 x 9 inner corners (a 7 x 10
/// chessboard, OpenCV's sample "9x6" pattern), 4 cm apart.
pub const DEFAULT_SIMULATED_BOARD: (u32, u32, f64) = (6, 9, 0.04);

/// Where the corners come from.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum CornerSource {
    /// A corner file (see [`crate::intrinsics`] for the format).
    File(PathBuf),
    /// Simulated views of the board.
    Simulate {
        /// A CamOdoCal camera YAML with the true camera; `None` uses the model's preset
        /// ([`preset_camera`]).
        true_camera: Option<PathBuf>,
        /// The simulation's options.
        options: BoardSimulationOptions,
    },
}

/// Everything `ibc intrinsics` needs.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct IntrinsicsJob {
    /// The corners.
    pub source: CornerSource,
    /// The model to calibrate.
    pub model: IntrinsicModel,
    /// The board; `None` takes it from the corner file (or [`DEFAULT_SIMULATED_BOARD`]).
    pub board: Option<PlanarTarget>,
    /// Folder of the output files (created if needed).
    pub out: PathBuf,
    /// Print the JSON report instead of the text summary.
    pub json: bool,
    /// Print nothing (but the JSON report when `json` is set).
    pub quiet: bool,
    /// The camera's name in the output files (`<name>_camera_calib.yaml`, camchain).
    pub camera_name: String,
    /// The calibration's options.
    pub options: IntrinsicsOptions,
}

impl IntrinsicsJob {
    /// A job with default options: camera name `cam0`, the text summary.
    pub fn new(source: CornerSource, model: IntrinsicModel, out: impl Into<PathBuf>) -> Self {
        Self {
            source,
            model,
            board: None,
            out: out.into(),
            json: false,
            quiet: false,
            camera_name: "cam0".to_owned(),
            options: IntrinsicsOptions::default(),
        }
    }

    /// The same job with a board.
    pub fn with_board(mut self, board: PlanarTarget) -> Self {
        self.board = Some(board);
        self
    }

    /// The same job printing JSON (`true`) or text.
    pub fn with_json(mut self, json: bool) -> Self {
        self.json = json;
        self
    }

    /// The same job printing nothing but the JSON report (if asked for).
    pub fn with_quiet(mut self, quiet: bool) -> Self {
        self.quiet = quiet;
        self
    }
}

/// What [`run_job`] produced.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct IntrinsicsOutcome {
    /// The calibration.
    pub calibration: IntrinsicCalibration,
    /// Its report.
    pub report: IntrinsicsReport,
    /// The files written.
    pub files: OutputFiles,
    /// The simulated views, in simulated mode.
    pub simulated: Option<SimulatedBoards>,
}

/// The board to use: the job's, the corner file's, or (simulated) the default; a job's board
/// must agree with the file's.
fn resolve_board(
    job: &IntrinsicsJob,
    from_file: Option<PlanarTarget>,
    simulated: bool,
) -> Result<PlanarTarget, IntrinsicsError> {
    match (job.board, from_file) {
        (Some(b), Some(f)) if b != f => Err(IntrinsicsError::InvalidInput(format!(
            "--board {}x{} --square {} disagrees with the corner file's board {}x{} of {} m",
            b.rows, b.cols, b.square, f.rows, f.cols, f.square
        ))),
        (Some(b), _) => Ok(b),
        (None, Some(f)) => Ok(f),
        (None, None) if simulated => {
            let (r, c, s) = DEFAULT_SIMULATED_BOARD;
            PlanarTarget::new(r, c, s)
        }
        (None, None) => Err(IntrinsicsError::InvalidInput(
            "the corner file does not name its board: give --board ROWSxCOLS and --square M".into(),
        )),
    }
}

/// The true camera of a simulation: a CamOdoCal file of the job's model, or the preset.
fn true_camera(job: &IntrinsicsJob, path: Option<&PathBuf>) -> Result<Camera, IntrinsicsError> {
    let Some(path) = path else {
        return preset_camera(job.model);
    };
    let named = camodocal::read_camera(path)?;
    match IntrinsicModel::of(&named.camera) {
        Some(m) if m == job.model => Ok(named.camera),
        _ => Err(IntrinsicsError::InvalidInput(format!(
            "the true camera in {} is a {} camera, but --model is {}",
            path.display(),
            ibc_camera_models::CameraModel::model_name(&named.camera),
            job.model.short_name()
        ))),
    }
}

/// Runs a job: corners (read or simulated), calibration, output files (all or nothing), and
/// the summary or JSON report written to `stdout`.
///
/// # Errors
/// Any [`IntrinsicsError`]: unreadable or invalid corners, a failed calibration, an output
/// folder that cannot be written, or `stdout` failing ([`IntrinsicsError::Io`]).
pub fn run_job(
    job: &IntrinsicsJob,
    stdout: &mut dyn Write,
) -> Result<IntrinsicsOutcome, IntrinsicsError> {
    let (corners, board, simulated) = match &job.source {
        CornerSource::File(path) => {
            let corners = CornerSet::read(path)?;
            let board = resolve_board(job, corners.board, false)?;
            (corners, board, None)
        }
        CornerSource::Simulate {
            true_camera: path,
            options,
        } => {
            let board = resolve_board(job, None, true)?;
            let camera = true_camera(job, path.as_ref())?;
            let sim = simulate_boards(&camera, &board, options)?;
            (sim.corners.clone(), board, Some(sim))
        }
    };
    let start = Instant::now();
    let calibration = calibrate_intrinsics(&corners, &board, job.model, &job.options)?;
    let seconds = start.elapsed().as_secs_f64();
    let report = IntrinsicsReport::new(
        &calibration,
        &board,
        simulated.as_ref().map(|s| &s.camera),
        seconds,
    );
    let files = write_outputs(
        &job.out,
        &job.camera_name,
        &calibration,
        &corners,
        &report,
        simulated.as_ref(),
    )?;
    let text = if job.json {
        report.to_json_string()
    } else if job.quiet {
        String::new()
    } else {
        let mut t = report.to_text();
        t.push_str("wrote");
        for f in [
            &files.camodocal,
            &files.camchain,
            &files.report,
            &files.residuals_svg,
        ]
        .into_iter()
        .chain(files.corners.iter())
        .chain(files.truth.iter())
        {
            t.push_str(&format!(" {}", f.display()));
        }
        t.push('\n');
        t
    };
    let stdout_error = |source| {
        IntrinsicsError::Io(ibc_camera_models::io::IoError::os(
            std::path::Path::new("<standard output>"),
            source,
        ))
    };
    stdout.write_all(text.as_bytes()).map_err(stdout_error)?;
    stdout.flush().map_err(stdout_error)?;
    Ok(IntrinsicsOutcome {
        calibration,
        report,
        files,
        simulated,
    })
}
