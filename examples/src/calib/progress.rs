//! Progress reports of the long pipeline stages, for a progress bar or a log.

/// A stage of the pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Stage {
    /// Training the vocabulary and indexing the map images.
    Vocabulary,
    /// Localizing every image of the log (counted in images).
    Localization,
    /// Selecting frame sets and initializing the rig.
    Initialization,
    /// The non-linear refinement.
    Refinement,
    /// The hand-eye calibration.
    HandEye,
}

impl Stage {
    /// A short human-readable name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Vocabulary => "vocabulary",
            Self::Localization => "localization",
            Self::Initialization => "initialization",
            Self::Refinement => "refinement",
            Self::HandEye => "hand-eye",
        }
    }
}

/// Receives progress from [`calibrate`](super::calibrate). Called from worker threads
/// (hence `Sync`); every method has an empty default.
pub trait Progress: Sync {
    /// A stage starts; `total` is its number of steps (0 when unknown).
    fn start(&self, stage: Stage, total: u64) {
        let _ = (stage, total);
    }
    /// `steps` more steps of the current stage are done.
    fn advance(&self, steps: u64) {
        let _ = steps;
    }
    /// The current stage is done.
    fn finish(&self, stage: Stage) {
        let _ = stage;
    }
}

/// Progress that goes nowhere.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}
