//! `ibc`: infrastructure-based calibration of multi-camera rigs from the command line. A thin
//! layer over the `ibc_pipeline` library; see the crate README for the commands.

mod cli;

use clap::Parser;

fn main() {
    let args = cli::Cli::parse();
    if let Err(e) = cli::run(args) {
        eprintln!("error: {}", e.one_line());
        std::process::exit(1);
    }
}
