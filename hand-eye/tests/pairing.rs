//! `Pairing::Window` gives exactly the motions the ibc pipeline built by hand (each frame set
//! with each of the next `window` sets, `examples/src/calib/hand_eye.rs` before it used the
//! window), in the same order, for every window and trajectory length.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{Mount, planar, rng};
use ibc_hand_eye::nalgebra::Isometry3;
use ibc_hand_eye::{MotionPair, Pairing, relative_motions};

/// The pipeline's loop, as it was written there.
fn pipeline_motions(
    rig: &[Isometry3<f64>],
    odometry: &[Isometry3<f64>],
    window: usize,
) -> Vec<MotionPair> {
    let mut motions = Vec::with_capacity(rig.len() * window);
    for k in 0..rig.len() {
        for l in k + 1..rig.len().min(k + 1 + window) {
            motions.push(MotionPair::new(
                rig[k].inv_mul(&rig[l]),
                odometry[k].inv_mul(&odometry[l]),
            ));
        }
    }
    motions
}

#[test]
fn window_matches_the_pipeline_motions() {
    let mut r = rng(50);
    for poses in [0, 1, 2, 3, 9, 40] {
        // Noisy trajectories of a vehicle, as the pipeline has them.
        let sim = planar(&mut r, poses, true, 1.0, Mount::Forward);
        let (rig, odometry) = (&sim.world_from_rig, &sim.world_from_odometry);
        for size in (1..=12).chain([39, 40, 100]) {
            let window = relative_motions(rig, odometry, Pairing::Window { size }).unwrap();
            assert_eq!(
                window,
                pipeline_motions(rig, odometry, size),
                "{poses} poses, window {size}"
            );
        }
        let all = relative_motions(rig, odometry, Pairing::All).unwrap();
        let size = poses.max(1);
        assert_eq!(all, pipeline_motions(rig, odometry, size));
        let consecutive = relative_motions(rig, odometry, Pairing::Consecutive).unwrap();
        assert_eq!(consecutive, pipeline_motions(rig, odometry, 1));
    }
}
