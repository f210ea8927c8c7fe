//! The `ibc` command line: a thin layer over the library (see the crate README for usage).

mod calibrate;
mod demo;
mod error;
mod inputs;
mod intrinsics;
mod map;
mod progress;
mod selfcalib;
mod simulate;
mod target;

use std::io::Write as _;
use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand, ValueEnum};
use ibc_bundle_adjust::IntrinsicsSelection;
use ibc_pipeline::calib::{CalibrationOptions, HandEyeMethod, HandEyeOptions};

pub use error::CliError;

/// Exit code of a command whose result was computed and written but did not pass its quality
/// gates (status `poor`; the warnings say why). 1 is an input or computation error, 2 a usage
/// error.
pub const EXIT_POOR: i32 = 3;

/// How a command that did not fail ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// The result passed its quality gates (or the command judges nothing).
    Done,
    /// The result was written but did not pass its quality gates.
    Poor,
}

/// The hand-eye method, as the command line names it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum HandEyeArg {
    /// From the log's odometry: planar odometry uses Guo et al., 6-DoF odometry Daniilidis.
    #[default]
    Auto,
    /// Guo, Mirzaei and Roumeliotis's planar method (a ground vehicle's wheel odometry).
    Planar,
    /// Daniilidis's dual-quaternion method (6-DoF odometry).
    SixDof,
    /// No hand-eye calibration.
    None,
}

/// The intrinsics `ibc calibrate` refines, as the command line names them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum IntrinsicsArg {
    /// None: the camera file's intrinsics are held.
    #[default]
    None,
    /// The focal lengths.
    Focal,
    /// The focal lengths and the principal point.
    #[value(name = "focal+center")]
    FocalCenter,
    /// Every parameter of the model, distortion included.
    All,
}

impl IntrinsicsArg {
    /// The selection it names.
    pub fn selection(self) -> IntrinsicsSelection {
        match self {
            Self::None => IntrinsicsSelection::None,
            Self::Focal => IntrinsicsSelection::Focal,
            Self::FocalCenter => IntrinsicsSelection::FocalAndCenter,
            Self::All => IntrinsicsSelection::All,
        }
    }
}

impl HandEyeArg {
    /// The calibration options with this hand-eye method.
    fn options(self) -> CalibrationOptions {
        let method = match self {
            Self::Auto => HandEyeMethod::Auto,
            Self::Planar => HandEyeMethod::Planar,
            Self::SixDof => HandEyeMethod::Daniilidis,
            Self::None => HandEyeMethod::Skip,
        };
        CalibrationOptions {
            hand_eye: HandEyeOptions {
                method,
                ..Default::default()
            },
            ..Default::default()
        }
    }
}

/// Infrastructure-based calibration of multi-camera rigs.
///
/// With no command, `ibc` runs `ibc demo`: the default scenario simulated in memory,
/// calibrated, and the result printed as a table like the paper's Table I.
#[derive(Debug, Parser)]
#[command(name = "ibc", version, args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// The command (default: demo).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The demo's options, when no command is given.
    #[command(flatten)]
    pub demo: DemoArgs,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a scenario in memory, calibrate it and print the result (the default).
    Demo(DemoArgs),
    /// Simulate a scenario and write its map, rig log, cameras and ground truth.
    Simulate(SimulateArgs),
    /// Calibrate a rig from a map, a rig log and a camera file.
    Calibrate(CalibrateArgs),
    /// Calibrate a rig's extrinsics from its own log, without a map (structure from motion).
    Selfcalib(SelfCalibArgs),
    /// Build a map from a calibrated rig's survey log (structure from motion).
    Map(MapArgs),
    /// List the built-in scenarios.
    Scenarios,
    /// Calibrate one camera's intrinsics from chessboard corners (or simulated ones).
    Intrinsics(intrinsics::IntrinsicsArgs),
    /// Calibrate a rig's intrinsics and extrinsics from images of an AprilGrid.
    Target(target::TargetArgs),
}

/// Options of `ibc demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// A built-in scenario (see `ibc scenarios`) or a scenario YAML file.
    #[arg(long, value_name = "NAME|FILE", default_value = ibc_pipeline::sim::DEFAULT_SCENARIO)]
    pub scenario: String,
    /// The simulation's seed (default: the scenario's).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Also write every output file (report, camchain, CamOdoCal files, plots) into DIR.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the JSON report on standard output instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
    /// The hand-eye method between the rig and its odometry.
    #[arg(long, value_enum, value_name = "METHOD", default_value_t = HandEyeArg::Auto)]
    pub hand_eye: HandEyeArg,
}

/// Options of `ibc simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// A built-in scenario (see `ibc scenarios`) or a scenario YAML file.
    #[arg(long, value_name = "NAME|FILE", default_value = ibc_pipeline::sim::DEFAULT_SCENARIO)]
    pub scenario: String,
    /// The simulation's seed (default: the scenario's).
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Folder to write map.ibcmap, log.ibclog, camchain.yaml and truth.json into.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Also write the map and the log as COLMAP data into `DIR/colmap`: the map as a text
    /// model (`sparse/`) with `database.db` and `rig_config.json`, the log as `log.db`
    /// (image names in nanoseconds: calibrate with `--colmap-seconds-per-unit 1e-9`).
    #[arg(long)]
    pub colmap: bool,
    /// No progress bars and no summary.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `ibc calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// The map: an ibc map file (`.ibcmap`), or a COLMAP sparse model folder (`sparse/0`,
    /// text or binary) with `--database`.
    #[arg(long, value_name = "FILE|DIR")]
    pub map: PathBuf,
    /// The COLMAP database of a COLMAP map (`--map sparse/0`): its images' keypoints and
    /// descriptors.
    #[arg(long, value_name = "FILE")]
    pub database: Option<PathBuf>,
    /// The rig log: an ibc rig-log file (`.ibclog`), or a COLMAP database of the rig's
    /// images (frames from its frame table, else `camera/image` names: one frame per image
    /// name).
    #[arg(long, value_name = "FILE")]
    pub log: PathBuf,
    /// Seconds per unit of the numbers in a COLMAP log's image names (1e-9 for nanosecond
    /// names such as `cam0/1403636579763555584.png`).
    #[arg(long, value_name = "SECONDS", default_value_t = 1.0)]
    pub colmap_seconds_per_unit: f64,
    /// The cameras: a Kalibr camchain YAML or a CamOdoCal folder (or its extrinsic.txt).
    #[arg(long, value_name = "FILE")]
    pub cameras: PathBuf,
    /// Folder for the output files.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Ground truth (`truth.json`) to score the calibration against.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// A vocabulary file (ibc-vocab-tree format) to use instead of training one on the map.
    #[arg(long, value_name = "FILE")]
    pub vocabulary: Option<PathBuf>,
    /// Print the JSON report on standard output instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bars, and no line on standard error saying where the files went.
    #[arg(long)]
    pub quiet: bool,
    /// The hand-eye method between the rig and its odometry.
    #[arg(long, value_enum, value_name = "METHOD", default_value_t = HandEyeArg::Auto)]
    pub hand_eye: HandEyeArg,
    /// The intrinsics refined with the extrinsics against the map, for every camera (`focal`,
    /// `focal+center` or `all`, distortion included). Default `none`: the camera file's are
    /// held, which gives the most precise extrinsics when they are right (freeing the
    /// principal points costs the rotations ten times their precision, a shifted principal
    /// point being nearly a turned camera); a stale camera file is flagged by the quality
    /// gates, and this option then corrects it. Parameters the data does not determine are
    /// held and listed in the report.
    #[arg(long, value_enum, value_name = "SET", default_value_t = IntrinsicsArg::None)]
    pub refine_intrinsics: IntrinsicsArg,
    /// Also replay the log through the online calibrator (focal lengths and extrinsics over a
    /// sliding window of 50 frame sets, an update every 10 when the rig turned and moved) and
    /// print its running estimate, with the errors over time against `--truth`.
    #[arg(long)]
    pub online: bool,
}

/// Options of `ibc selfcalib`.
#[derive(Debug, Args)]
pub struct SelfCalibArgs {
    /// The rig-log file (`.ibclog`).
    #[arg(long, value_name = "FILE")]
    pub log: PathBuf,
    /// The cameras' intrinsics: a Kalibr camchain YAML or a CamOdoCal folder (its extrinsics
    /// are ignored).
    #[arg(long, value_name = "FILE")]
    pub cameras: PathBuf,
    /// Folder for the output files.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Ground truth (`truth.json`) to score the result against.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// A known distance between two cameras' centres, for the metric scale when the log has
    /// no odometry (it takes precedence over the odometry).
    #[arg(long, value_name = "CAM_A:CAM_B=METRES")]
    pub baseline: Option<String>,
    /// Print the JSON report on standard output instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bars, and no line on standard error saying where the files went.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `ibc map`.
#[derive(Debug, Args)]
pub struct MapArgs {
    /// The survey's rig-log file (`.ibclog`).
    #[arg(long, value_name = "FILE")]
    pub log: PathBuf,
    /// The calibrated rig: a Kalibr camchain YAML or a CamOdoCal folder (intrinsics used as
    /// they are; extrinsics too unless --refine-extrinsics).
    #[arg(long, value_name = "FILE")]
    pub cameras: PathBuf,
    /// The map file to write (`.ibcmap`), atomically.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Refine the extrinsics with the map, starting from the camera file's (the scale held by
    /// its longest baseline from the first camera); the summary says how far each moved.
    #[arg(long)]
    pub refine_extrinsics: bool,
    /// Also write the map as COLMAP data into DIR (a text model in `sparse/`, `database.db`,
    /// `rig_config.json`), all or nothing; for logs with binary or 128-float descriptors.
    #[arg(long, value_name = "DIR")]
    pub colmap: Option<PathBuf>,
    /// Print a JSON summary on standard output instead of the line.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// "wrote DIR (a, b, c/)": the entries of `dir` among the `written` paths, in the order
/// written, a folder once with a slash.
fn wrote_line(dir: &Path, written: &[PathBuf]) -> String {
    let mut names: Vec<String> = Vec::new();
    for path in written {
        let Ok(rest) = path.strip_prefix(dir) else {
            continue;
        };
        let mut parts = rest.components();
        let Some(first) = parts.next() else { continue };
        let name = first.as_os_str().to_string_lossy().into_owned()
            + if parts.next().is_some() { "/" } else { "" };
        if !names.contains(&name) {
            names.push(name);
        }
    }
    format!("wrote {} ({})\n", dir.display(), names.join(", "))
}

/// Writes `text` to standard output.
fn print(text: &str) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes()).map_err(CliError::Stdout)?;
    out.flush().map_err(CliError::Stdout)
}

/// Runs a parsed command line.
///
/// # Errors
/// [`CliError`] naming what failed.
pub fn run(cli: Cli) -> Result<Outcome, CliError> {
    match cli.command {
        None => demo::run(&cli.demo),
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Simulate(args)) => simulate::run(&args).map(|()| Outcome::Done),
        Some(Command::Calibrate(args)) => calibrate::run(&args),
        Some(Command::Selfcalib(args)) => selfcalib::run(&args),
        Some(Command::Map(args)) => map::run(&args),
        Some(Command::Scenarios) => {
            print(&ibc_pipeline::sim::scenario_list()).map(|()| Outcome::Done)
        }
        Some(Command::Intrinsics(args)) => intrinsics::run_command(&args),
        Some(Command::Target(args)) => target::run(&args),
    }
}
