//! Shared helpers for the criterion benchmarks of the ibc workspace.
//!
//! The benchmarks themselves live in `benches/benches/<topic>.rs`, one file per crate, and
//! their recorded figures in the workspace's `BENCHMARKS.md`. Every bench input is generated
//! from a fixed seed, so two runs measure the same work.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The seed every bench input is generated from unless a bench says otherwise.
pub const BENCH_SEED: u64 = 0x1bc_5eed;

/// A deterministic random number generator for bench inputs, seeded with `BENCH_SEED + stream`
/// so that separate inputs of one bench can draw from independent streams.
pub fn bench_rng(stream: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(BENCH_SEED.wrapping_add(stream))
}

/// CPU time of the calling thread in nanoseconds, from `/proc/thread-self/schedstat` (Linux);
/// `None` where unavailable. Updated at scheduler ticks, so only long spans are meaningful.
/// On the shared machines parallel builds inflate wall time, and a thread's CPU time moves far
/// less with the load, so benches print it beside criterion's wall-clock figures.
pub fn thread_cpu_ns() -> Option<f64> {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}
