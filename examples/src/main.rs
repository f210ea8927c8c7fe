//! `ibc`: infrastructure-based calibration of multi-camera rigs from the command line. A thin
//! layer over the `ibc_pipeline` library; see the crate README for the commands.

mod cli;

use clap::Parser;

/// Exit code after an interrupt: 128 + SIGINT, as shells report it.
const EXIT_INTERRUPTED: i32 = 130;

fn main() {
    // An interrupted run leaves no output: the staged files are removed (a write or commit in
    // progress finishes first), then the process exits.
    let handler = ctrlc::set_handler(|| {
        ibc_pipeline::data::io::remove_staged_outputs();
        eprintln!("error: interrupted (files not yet in place were removed)");
        std::process::exit(EXIT_INTERRUPTED);
    });
    if let Err(e) = handler {
        eprintln!(
            "warning: cannot handle interrupts ({e}); an interrupted run may leave a hidden staging folder in its output folder"
        );
    }
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
