//! Progress bars on standard error, drawn only when standard error is a terminal.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

use ibc_pipeline::calib::{Progress, Stage};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress sink: an indicatif bar per stage on a terminal, nothing otherwise.
pub struct Bars {
    enabled: bool,
    current: Mutex<Option<ProgressBar>>,
}

impl Bars {
    /// Bars when standard error is a terminal and `quiet` is false.
    pub fn new(quiet: bool) -> Self {
        Self {
            enabled: !quiet && std::io::stderr().is_terminal(),
            current: Mutex::new(None),
        }
    }

    /// Starts a spinner for a step outside the pipeline (simulation, file reading).
    pub fn step(&self, message: &str) {
        self.begin(message, 0);
    }

    /// Clears the current bar.
    pub fn done(&self) {
        if let Ok(mut current) = self.current.lock()
            && let Some(bar) = current.take()
        {
            bar.finish_and_clear();
        }
    }

    fn begin(&self, message: &str, total: u64) {
        if !self.enabled {
            return;
        }
        self.done();
        let bar = if total == 0 {
            let bar = ProgressBar::new_spinner();
            bar.enable_steady_tick(Duration::from_millis(100));
            bar
        } else {
            let bar = ProgressBar::new(total);
            if let Ok(style) =
                ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} {elapsed}")
            {
                bar.set_style(style.progress_chars("=> "));
            }
            bar
        };
        bar.set_draw_target(ProgressDrawTarget::stderr());
        bar.set_message(message.to_owned());
        if let Ok(mut current) = self.current.lock() {
            *current = Some(bar);
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: Stage, total: u64) {
        self.begin(stage.name(), total);
    }

    fn advance(&self, steps: u64) {
        if !self.enabled {
            return;
        }
        if let Ok(current) = self.current.lock()
            && let Some(bar) = current.as_ref()
        {
            bar.inc(steps);
        }
    }

    fn finish(&self, _stage: Stage) {
        self.done();
    }
}
