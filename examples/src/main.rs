//! `ibc`: infrastructure-based calibration of multi-camera rigs from the command line. A thin
//! layer over the `ibc_pipeline` library; see the crate README for the commands.

mod cli;

use clap::Parser;

fn main() {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(cli::Outcome::Done) => {}
        Ok(cli::Outcome::Poor) => {
            eprintln!(
                "warning: the result did not pass its quality gates (status `poor`; the \
                 warnings in the report say why)"
            );
            std::process::exit(cli::EXIT_POOR);
        }
        Err(e) => {
            eprintln!("error: {}", e.one_line());
            std::process::exit(1);
        }
    }
}
