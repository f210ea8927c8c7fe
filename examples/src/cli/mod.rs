//! The `ibc` command line: a thin layer over the library (see the crate README for usage).

mod calibrate;
mod demo;
mod error;
mod intrinsics;
mod progress;
mod simulate;

use std::io::Write as _;
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

pub use error::CliError;

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
    /// List the built-in scenarios.
    Scenarios,
    /// Calibrate one camera's intrinsics from chessboard corners (or simulated ones).
    Intrinsics(intrinsics::IntrinsicsArgs),
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
    /// No progress bars and no summary.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `ibc calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// The map file (`.ibcmap`).
    #[arg(long, value_name = "FILE")]
    pub map: PathBuf,
    /// The rig-log file (`.ibclog`).
    #[arg(long, value_name = "FILE")]
    pub log: PathBuf,
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
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
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
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        None => demo::run(&cli.demo),
        Some(Command::Demo(args)) => demo::run(&args),
        Some(Command::Simulate(args)) => simulate::run(&args),
        Some(Command::Calibrate(args)) => calibrate::run(&args),
        Some(Command::Scenarios) => print(&ibc_pipeline::sim::scenario_list()),
        Some(Command::Intrinsics(args)) => intrinsics::run_command(&args),
    }
}
