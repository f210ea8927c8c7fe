//! Runs one solver many times on the inputs of `benches/benches/pnp.rs`, for instruction
//! counts under `valgrind --tool=callgrind` (repeatable whatever the load of the machine,
//! unlike wall-clock timings) and for CPU-time loops.
//!
//! ```text
//! cargo build --release -p ibc-pnp --example instruction_counts
//! valgrind --tool=callgrind target/release/examples/instruction_counts epnp 6 1000
//! valgrind --tool=callgrind target/release/examples/instruction_counts epnp 6 0
//! ```
//!
//! The difference of the two totals over 1000 is the count per call (the second run measures
//! the set-up alone). Solvers: `epnp` (default options), `epnp-single-pass`, `p3p`; the second
//! argument is the number of correspondences (ignored by `p3p`, which uses 3). Adding
//! `--toggle-collect='*smallest_eigenpairs*'` (or another function name) to valgrind counts
//! one stage alone.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use ibc_pnp::{EpnpOptions, epnp_with, p3p};
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const FOCAL: f64 = 800.0;

/// The seed of `ibc_benches::bench_rng`: the same scenes as the criterion benches.
const BENCH_SEED: u64 = 0x1bc_5eed;

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// The EPnP paper's setup with 1 px noise, as `scene(n, 0, n)` of the pnp bench.
fn scene(n: usize) -> (Vec<Vector3<f64>>, Vec<Point3<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(BENCH_SEED.wrapping_add(n as u64));
    let q = Quaternion::new(
        gaussian(&mut rng),
        gaussian(&mut rng),
        gaussian(&mut rng),
        gaussian(&mut rng),
    );
    let t = Vector3::from_fn(|_, _| rng.random_range(-10.0..10.0));
    let camera_from_world: Isometry3<f64> =
        Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_quaternion(q));
    let world_from_camera = camera_from_world.inverse();
    let mut bearings = Vec::with_capacity(n);
    let mut points = Vec::with_capacity(n);
    for _ in 0..n {
        let p = Point3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(4.0..8.0),
        );
        let u = FOCAL * p.x / p.z + 320.0 + gaussian(&mut rng);
        let v = FOCAL * p.y / p.z + 240.0 + gaussian(&mut rng);
        bearings.push(Vector3::new((u - 320.0) / FOCAL, (v - 240.0) / FOCAL, 1.0).normalize());
        points.push(world_from_camera * p);
    }
    (bearings, points)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: instruction_counts epnp|epnp-single-pass|p3p N CALLS";
    let solver = args.get(1).expect(usage).as_str();
    let n: usize = args.get(2).expect(usage).parse().expect(usage);
    let calls: usize = args.get(3).expect(usage).parse().expect(usage);
    let mut checksum = 0.0;
    match solver {
        "epnp" | "epnp-single-pass" => {
            let (bearings, points) = scene(n);
            let options = EpnpOptions {
                depth_reweighting: solver == "epnp",
                ..Default::default()
            };
            for _ in 0..calls {
                let pose = epnp_with(black_box(&bearings), black_box(&points), &options).unwrap();
                checksum += pose.translation.vector.x;
            }
        }
        "p3p" => {
            let (bearings, points) = scene(3);
            let y = [bearings[0], bearings[1], bearings[2]];
            let x = [points[0], points[1], points[2]];
            for _ in 0..calls {
                checksum += p3p(black_box(&y), black_box(&x)).unwrap().len() as f64;
            }
        }
        _ => panic!("{usage}"),
    }
    println!("{checksum}");
}
