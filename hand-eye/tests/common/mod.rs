//! Simulated hand-eye data shared by the integration tests.
//!
//! `general` reproduces the simulation of OpenCV's hand-eye regression test
//! (`modules/calib3d/test/test_calibration_hand_eye.cpp`, `simulateData` and `generatePose`):
//! the same pose distributions and the same noise, Gaussian per component added to the
//! rotation vector and to the translation of `camera_from_target` (2 mrad, 5 mm) and of
//! `base_from_gripper` (1 mrad, 1 mm). In this crate's terms the camera is sensor `a` (the rig),
//! the gripper sensor `b` (the odometry), and `X = rig_from_odometry = camera_from_gripper`.
//!
//! `planar` is the same for a vehicle whose odometry moves in its `xy` plane.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_hand_eye::MotionPair;
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use proptest::test_runner::{Config, RngSeed};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// OpenCV's camera-side noise: rotation vector and translation, per component.
pub const CAMERA_NOISE: (f64, f64) = (0.002, 0.005);
/// OpenCV's robot-side noise: rotation vector and translation, per component.
pub const ROBOT_NOISE: (f64, f64) = (0.001, 0.001);

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

fn random_sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.random::<bool>() { 1.0 } else { -1.0 }
}

/// OpenCV's `generatePose` with `random_sign`: rotation vector `θ · axis` with every axis
/// component uniform in [-1, 1] (not normalized) and `θ` uniform in the range with a random
/// sign; every translation component uniform in the range with a random sign.
pub fn opencv_pose(rng: &mut ChaCha8Rng, theta: (f64, f64), t: (f64, f64)) -> Isometry3<f64> {
    let axis = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0));
    let angle = rng.random_range(theta.0..theta.1) * random_sign(rng);
    let translation = Vector3::from_fn(|_, _| rng.random_range(t.0..t.1) * random_sign(rng));
    Isometry3::new(translation, axis * angle)
}

/// OpenCV's noise: Gaussian added to each component of the rotation vector and translation.
pub fn perturb(rng: &mut ChaCha8Rng, pose: &Isometry3<f64>, sigma: (f64, f64)) -> Isometry3<f64> {
    let rotation = Normal::new(0.0, sigma.0).unwrap();
    let translation = Normal::new(0.0, sigma.1).unwrap();
    let rvec = pose.rotation.scaled_axis() + Vector3::from_fn(|_, _| rotation.sample(rng));
    let t = pose.translation.vector + Vector3::from_fn(|_, _| translation.sample(rng));
    Isometry3::new(t, rvec)
}

/// Two synchronized trajectories and the transform that links them.
pub struct Simulation {
    pub world_from_rig: Vec<Isometry3<f64>>,
    pub world_from_odometry: Vec<Isometry3<f64>>,
    pub rig_from_odometry: Isometry3<f64>,
}

/// OpenCV's `simulateData` (see the module docs).
pub fn general(rng: &mut ChaCha8Rng, poses: usize, noise: bool) -> Simulation {
    let deg = std::f64::consts::PI / 180.0;
    let gripper_from_camera = opencv_pose(rng, (10.0 * deg, 50.0 * deg), (0.05, 0.5));
    let base_from_target = opencv_pose(rng, (5.0 * deg, 85.0 * deg), (0.5, 3.5));
    let mut world_from_rig = Vec::with_capacity(poses);
    let mut world_from_odometry = Vec::with_capacity(poses);
    for _ in 0..poses {
        let base_from_gripper = opencv_pose(rng, (5.0 * deg, 45.0 * deg), (0.5, 1.5));
        let camera_from_target =
            gripper_from_camera.inverse() * base_from_gripper.inverse() * base_from_target;
        let (camera_from_target, base_from_gripper) = if noise {
            (
                perturb(rng, &camera_from_target, CAMERA_NOISE),
                perturb(rng, &base_from_gripper, ROBOT_NOISE),
            )
        } else {
            (camera_from_target, base_from_gripper)
        };
        world_from_rig.push(camera_from_target.inverse());
        world_from_odometry.push(base_from_gripper);
    }
    Simulation {
        world_from_rig,
        world_from_odometry,
        rig_from_odometry: gripper_from_camera.inverse(),
    }
}

/// How the rig is mounted on the vehicle in [`planar`].
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Mount {
    /// Camera axes (x right, y down, z forward) on vehicle axes (x forward, y left, z up),
    /// then rotated by up to 50 degrees about a random axis (OpenCV's hand-eye distribution).
    Forward,
    /// The camera x axis exactly vertical: the zero-yaw constraint of Guo et al. degenerates.
    XAxisVertical,
}

/// A vehicle whose odometry moves in its xy plane: poses with x, y uniform in ±[0.5, 3.5] m
/// and yaw uniform in [-π, π); the map frame of the rig trajectory is an OpenCV-style random
/// pose of the odometry's world frame. The rig's translations are divided by `rig_scale` (the
/// metric translation is `rig_scale` times the measured one). Noise: camera as OpenCV (2 mrad,
/// 5 mm per component of `rig_from_world`), odometry in the plane only (1 mrad yaw, 1 mm in x
/// and y).
pub fn planar(
    rng: &mut ChaCha8Rng,
    poses: usize,
    noise: bool,
    rig_scale: f64,
    mount: Mount,
) -> Simulation {
    let deg = std::f64::consts::PI / 180.0;
    let camera_axes = match mount {
        // Columns: camera x, y, z in vehicle coordinates.
        Mount::Forward => Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0),
        Mount::XAxisVertical => Matrix3::new(0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0),
    };
    let camera_axes = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&camera_axes));
    let tilt = match mount {
        Mount::Forward => opencv_pose(rng, (10.0 * deg, 50.0 * deg), (0.05, 0.5)).rotation,
        Mount::XAxisVertical => UnitQuaternion::from_axis_angle(
            &Vector3::z_axis(),
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
        ),
    };
    let lever = Vector3::new(
        rng.random_range(0.05..2.0) * random_sign(rng),
        rng.random_range(0.05..2.0) * random_sign(rng),
        rng.random_range(0.5..1.5) * random_sign(rng),
    );
    let odometry_from_rig = Isometry3::from_parts(Translation3::from(lever), tilt * camera_axes);
    let map_from_odometry_world = opencv_pose(rng, (5.0 * deg, 85.0 * deg), (0.5, 3.5));
    let yaw_noise = Normal::new(0.0, ROBOT_NOISE.0).unwrap();
    let xy_noise = Normal::new(0.0, ROBOT_NOISE.1).unwrap();
    let mut world_from_rig = Vec::with_capacity(poses);
    let mut world_from_odometry = Vec::with_capacity(poses);
    for _ in 0..poses {
        let x = rng.random_range(0.5..3.5) * random_sign(rng);
        let y = rng.random_range(0.5..3.5) * random_sign(rng);
        let yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
        let odometry = Isometry3::new(Vector3::new(x, y, 0.0), Vector3::new(0.0, 0.0, yaw));
        let mut rig = map_from_odometry_world * odometry * odometry_from_rig;
        rig.translation.vector /= rig_scale;
        if noise {
            rig = perturb(rng, &rig.inverse(), CAMERA_NOISE).inverse();
            let noisy = Vector3::new(x + xy_noise.sample(rng), y + xy_noise.sample(rng), 0.0);
            let noisy_yaw = yaw + yaw_noise.sample(rng);
            world_from_odometry.push(Isometry3::new(noisy, Vector3::new(0.0, 0.0, noisy_yaw)));
        } else {
            world_from_odometry.push(odometry);
        }
        world_from_rig.push(rig);
    }
    Simulation {
        world_from_rig,
        world_from_odometry,
        rig_from_odometry: odometry_from_rig.inverse(),
    }
}

/// The same motions with every quaternion negated with probability one half (the same
/// rotations, the other sign).
pub fn flip_signs(rng: &mut ChaCha8Rng, pairs: &[MotionPair]) -> Vec<MotionPair> {
    let mut flip = |pose: Isometry3<f64>| {
        if rng.random::<bool>() {
            let q = UnitQuaternion::new_unchecked(-pose.rotation.into_inner());
            Isometry3::from_parts(pose.translation, q)
        } else {
            pose
        }
    };
    pairs
        .iter()
        .map(|p| MotionPair::new(flip(p.a), flip(p.b)))
        .collect()
}

/// Rotation angle between two poses, radians.
pub fn rotation_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
    a.rotation.angle_to(&b.rotation)
}

/// Distance between the translations of two poses.
pub fn translation_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> f64 {
    (a.translation.vector - b.translation.vector).norm()
}

/// The `p`-th percentile (0 to 100, nearest rank) of `values`.
pub fn percentile(values: &[f64], p: f64) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// The property tests' configuration: 256 cases from a fixed seed (same seed, same cases), no
/// regression files.
pub fn proptest_config() -> Config {
    Config {
        cases: 256,
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(0x1bc_4a9d),
        ..Config::default()
    }
}
