//! Helpers shared by the simulation tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_pipeline::data::io::xxh64;
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

/// Scale of the small worlds the tests simulate (a 40 m garage, 25 frames).
pub const SMALL: f64 = 0.05;

/// A built-in scenario at the small scale.
pub fn small(name: &str) -> Scenario {
    Scenario::builtin(name).unwrap().with_scale(SMALL)
}

/// A small world of a built-in scenario.
pub fn world(name: &str, seed: u64) -> SimulatedWorld {
    SimulatedWorld::simulate(&small(name).with_seed(seed)).unwrap()
}

/// Rewrites the checksum of a map or log file after its content was edited, so the content
/// checks (not the checksum) are what rejects it.
pub fn reseal(bytes: &mut [u8]) {
    let n = bytes.len();
    let sum = xxh64(&bytes[..n - 8]);
    bytes[n - 8..].copy_from_slice(&sum.to_le_bytes());
}

/// Sets the file length in the header to the buffer's length, then reseals.
pub fn reseal_with_length(bytes: &mut [u8]) {
    let n = bytes.len() as u64;
    bytes[24..32].copy_from_slice(&n.to_le_bytes());
    reseal(bytes);
}
