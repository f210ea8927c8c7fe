//! Which sensor's noise `refine_trajectories` models, measured.
//!
//! OpenCV's hand-eye simulation (10 poses, all pairs, 300 trials per case; noise of the camera
//! 2 mrad / 5 mm per component of `camera_from_target`, of the robot 1 mrad / 1 mm of
//! `base_from_gripper`, each scaled by a level, zero for an exact sensor), with the camera as
//! sensor `a` (the pipeline's roles: `a` the rig) or as sensor `b` (OpenCV's roles:
//! `X = gripper_from_camera`, `a` the gripper); and a vehicle on a plane (10 poses, the rig
//! `a` with the camera's noise, the odometry `b` with 1 mrad of yaw and 1 mm in `x` and `y`).
//!
//! The default model (noise on `a_k_from_world_a`, `b` exact) improves on the linear solution
//! only when the camera is `a`; with the camera as `b`, or with the noise on the robot or the
//! odometry, it does no better or worse. The model that matches the data (`NoiseModel::A` or
//! `NoiseModel::B` with the `PoseFrame` of the noisy sensor, or `NoiseModel::Both` with the
//! true standard deviations) is at least as good as the linear solution in every case, and the
//! default fit's `likeliest_noise` names the matching single-sensor model in most trials. Run
//! with `--nocapture` for the figures (the crate README has them).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::collections::BTreeMap;

use common::{opencv_pose, percentile, perturb, rng, rotation_error, translation_error};
use ibc_hand_eye::nalgebra::{
    Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use ibc_hand_eye::{
    DaniilidisOptions, NoiseModel, Pairing, PlanarOptions, PoseFrame, PoseNoise, TrajectoryOptions,
    daniilidis, guo_planar, refine_trajectories, relative_motions,
};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const TRIALS: usize = 300;
const POSES: usize = 10;
const CAMERA: (f64, f64) = common::CAMERA_NOISE;
const ROBOT: (f64, f64) = common::ROBOT_NOISE;

/// Multiples of OpenCV's camera and robot (or odometry) noise, zero for an exact sensor: either
/// sensor alone at half, once and twice OpenCV's level, then both with the robot's noise once,
/// four times and a quarter of OpenCV's.
const LEVELS: [(f64, f64); 9] = [
    (0.5, 0.0),
    (1.0, 0.0),
    (2.0, 0.0),
    (0.0, 0.5),
    (0.0, 1.0),
    (0.0, 2.0),
    (1.0, 1.0),
    (1.0, 4.0),
    (1.0, 0.25),
];

/// Median errors (degrees, millimetres) of a list of estimates.
#[derive(Default)]
struct Errors {
    rotation_deg: Vec<f64>,
    translation_mm: Vec<f64>,
}

impl Errors {
    fn push(&mut self, rotation: f64, translation: f64) {
        self.rotation_deg.push(rotation.to_degrees());
        self.translation_mm.push(translation * 1e3);
    }

    fn median(&self) -> (f64, f64) {
        (
            percentile(&self.rotation_deg, 50.0),
            percentile(&self.translation_mm, 50.0),
        )
    }

    fn show(&self) -> String {
        let (r, t) = self.median();
        format!("{r:.3}° {t:.1} mm")
    }
}

/// `A(sensor from world)` and the like.
fn short(model: &NoiseModel) -> String {
    let frame = |f: &PoseFrame| {
        if *f == PoseFrame::SensorFromWorld {
            "sensor from world"
        } else {
            "world from sensor"
        }
    };
    match model {
        NoiseModel::A(f) => format!("A({})", frame(f)),
        NoiseModel::B(f) => format!("B({})", frame(f)),
        _ => "Both".to_owned(),
    }
}

/// The linear solution, the default refinement and the refinement with the matching model, and
/// what the default fit's `likeliest_noise` says.
#[derive(Default)]
struct Case {
    linear: Errors,
    default: Errors,
    matched: Errors,
    named: BTreeMap<String, usize>,
}

impl Case {
    /// Prints a table row and checks that the matching model is at least as good as the
    /// linear solution, and for noise on one sensor that `likeliest_noise` names it in at
    /// least 60 % of the trials.
    fn report(&self, name: &str, model: &NoiseModel) {
        let (most, count) = self
            .named
            .iter()
            .max_by_key(|(_, count)| **count)
            .map(|(name, count)| (name.clone(), *count))
            .unwrap();
        let share = 100.0 * count as f64 / TRIALS as f64;
        eprintln!(
            "| {name} | {} | {} | {} | {} | {most} {share:.0} % |",
            self.linear.show(),
            self.default.show(),
            short(model),
            self.matched.show(),
        );
        let (linear, matched) = (self.linear.median(), self.matched.median());
        assert!(
            matched.0 <= linear.0 && matched.1 <= linear.1,
            "{name}: {model:?} {matched:?} worse than linear {linear:?}"
        );
        if !matches!(model, NoiseModel::Both { .. }) {
            let named = self.named.get(&short(model)).copied().unwrap_or(0);
            assert!(
                5 * named >= 3 * TRIALS,
                "{name}: {model:?} named {named} times"
            );
        }
    }

    fn record(&mut self, likeliest: &NoiseModel) {
        *self.named.entry(short(likeliest)).or_insert(0) += 1;
    }
}

/// The model that matches the data: the camera's errors are those of `camera_from_target`
/// (sensor from world), the robot's or the odometry's those of its pose in its world.
fn matching_model((camera, robot): (f64, f64), camera_is_a: bool) -> NoiseModel {
    let sensor_from_world = PoseFrame::SensorFromWorld;
    let world_from_sensor = PoseFrame::WorldFromSensor;
    let camera_noise = PoseNoise::new(sensor_from_world, CAMERA.0 * camera, CAMERA.1 * camera);
    let robot_noise = PoseNoise::new(world_from_sensor, ROBOT.0 * robot, ROBOT.1 * robot);
    match (camera > 0.0, robot > 0.0, camera_is_a) {
        (true, false, true) => NoiseModel::A(sensor_from_world),
        (true, false, false) => NoiseModel::B(sensor_from_world),
        (false, true, true) => NoiseModel::B(world_from_sensor),
        (false, true, false) => NoiseModel::A(world_from_sensor),
        (_, _, true) => NoiseModel::Both {
            a: camera_noise,
            b: robot_noise,
        },
        (_, _, false) => NoiseModel::Both {
            a: robot_noise,
            b: camera_noise,
        },
    }
}

/// OpenCV's `simulateData` with the noise of each sensor scaled by its level:
/// `(target_from_camera, base_from_gripper, gripper_from_camera)`.
fn opencv_simulation(
    rng: &mut ChaCha8Rng,
    (camera_level, robot_level): (f64, f64),
) -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>, Isometry3<f64>) {
    let deg = std::f64::consts::PI / 180.0;
    let gripper_from_camera = opencv_pose(rng, (10.0 * deg, 50.0 * deg), (0.05, 0.5));
    let base_from_target = opencv_pose(rng, (5.0 * deg, 85.0 * deg), (0.5, 3.5));
    let (mut target_from_camera, mut base_from_gripper) = (Vec::new(), Vec::new());
    for _ in 0..POSES {
        let mut gripper = opencv_pose(rng, (5.0 * deg, 45.0 * deg), (0.5, 1.5));
        let mut camera = gripper_from_camera.inverse() * gripper.inverse() * base_from_target;
        if camera_level > 0.0 {
            let sigma = (CAMERA.0 * camera_level, CAMERA.1 * camera_level);
            camera = perturb(rng, &camera, sigma);
        }
        if robot_level > 0.0 {
            let sigma = (ROBOT.0 * robot_level, ROBOT.1 * robot_level);
            gripper = perturb(rng, &gripper, sigma);
        }
        target_from_camera.push(camera.inverse());
        base_from_gripper.push(gripper);
    }
    (target_from_camera, base_from_gripper, gripper_from_camera)
}

/// `camera x1, robot x0.5` and the like.
fn level_name((camera, robot): (f64, f64), robot_name: &str) -> String {
    match (camera > 0.0, robot > 0.0) {
        (true, false) => format!("camera x{camera}"),
        (false, true) => format!("{robot_name} x{robot}"),
        _ => format!("camera x{camera}, {robot_name} x{robot}"),
    }
}

#[test]
fn six_dof_noise_on_either_sensor() {
    eprintln!(
        "| sensor a: noise | linear | default model | matching model | refined with it | diagnosis |"
    );
    eprintln!("|---|---|---|---|---|---|");
    for camera_is_a in [true, false] {
        for levels in LEVELS {
            let model = matching_model(levels, camera_is_a);
            let mut case = Case::default();
            let mut r = rng(40);
            for _ in 0..TRIALS {
                let (camera, gripper, gripper_from_camera) = opencv_simulation(&mut r, levels);
                let (world_from_a, world_from_b, truth) = if camera_is_a {
                    (camera, gripper, gripper_from_camera.inverse())
                } else {
                    (gripper, camera, gripper_from_camera)
                };
                let motions = relative_motions(&world_from_a, &world_from_b, Pairing::All).unwrap();
                let linear = daniilidis(&motions, &DaniilidisOptions::default())
                    .unwrap()
                    .a_from_b;
                let refine = |noise| {
                    let options = TrajectoryOptions {
                        noise,
                        ..Default::default()
                    };
                    refine_trajectories(&world_from_a, &world_from_b, &linear, &options).unwrap()
                };
                let default = refine(NoiseModel::default());
                let matched = refine(model);
                case.record(&default.likeliest_noise);
                for (errors, x) in [
                    (&mut case.linear, linear),
                    (&mut case.default, default.a_from_b),
                    (&mut case.matched, matched.a_from_b),
                ] {
                    errors.push(rotation_error(&x, &truth), translation_error(&x, &truth));
                }
            }
            let a = if camera_is_a { "camera" } else { "gripper" };
            case.report(&format!("{a}: {}", level_name(levels, "robot")), &model);
        }
    }
}

/// A vehicle on a plane (as `common::planar`, forward mount, known scale, the planar options
/// of the refinement): the rig is `a`, with the camera's noise (that of `rig_from_map`), the
/// odometry `b`, with noise on its yaw and position in its world; translation errors in the
/// plane.
#[test]
fn planar_noise_on_either_sensor() {
    let deg = std::f64::consts::PI / 180.0;
    eprintln!("| noise | linear | default model | matching model | refined with it | diagnosis |");
    eprintln!("|---|---|---|---|---|---|");
    for levels in LEVELS {
        let (camera_level, odometry_level) = levels;
        let model = matching_model(levels, true);
        let yaw_noise = Normal::new(0.0, ROBOT.0 * odometry_level).unwrap();
        let xy_noise = Normal::new(0.0, ROBOT.1 * odometry_level).unwrap();
        let mut case = Case::default();
        let mut r = rng(41);
        for _ in 0..TRIALS {
            let axes = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
            let axes = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&axes));
            let tilt = opencv_pose(&mut r, (10.0 * deg, 50.0 * deg), (0.05, 0.5)).rotation;
            let lever = Vector3::new(
                r.random_range(0.05..2.0),
                r.random_range(-2.0..2.0),
                r.random_range(0.5..1.5),
            );
            let odometry_from_rig = Isometry3::from_parts(Translation3::from(lever), tilt * axes);
            let map_from_world = opencv_pose(&mut r, (5.0 * deg, 85.0 * deg), (0.5, 3.5));
            let (mut world_from_rig, mut world_from_odometry) = (Vec::new(), Vec::new());
            for _ in 0..POSES {
                let (x, y) = (r.random_range(-3.5..3.5), r.random_range(-3.5..3.5));
                let yaw = r.random_range(-3.1..3.1);
                let odometry = Isometry3::new(Vector3::new(x, y, 0.0), Vector3::z() * yaw);
                let mut rig = map_from_world * odometry * odometry_from_rig;
                if camera_level > 0.0 {
                    let sigma = (CAMERA.0 * camera_level, CAMERA.1 * camera_level);
                    rig = perturb(&mut r, &rig.inverse(), sigma).inverse();
                }
                let odometry = if odometry_level > 0.0 {
                    let (dx, dy) = (xy_noise.sample(&mut r), xy_noise.sample(&mut r));
                    let noisy_yaw = yaw + yaw_noise.sample(&mut r);
                    Isometry3::new(Vector3::new(x + dx, y + dy, 0.0), Vector3::z() * noisy_yaw)
                } else {
                    odometry
                };
                world_from_rig.push(rig);
                world_from_odometry.push(odometry);
            }
            let motions =
                relative_motions(&world_from_rig, &world_from_odometry, Pairing::All).unwrap();
            let linear = guo_planar(&motions, &PlanarOptions::default()).unwrap();
            let refine = |noise| {
                let options = TrajectoryOptions {
                    noise,
                    ..TrajectoryOptions::planar(false, 1.0)
                };
                let start = &linear.a_from_b;
                refine_trajectories(&world_from_rig, &world_from_odometry, start, &options).unwrap()
            };
            let default = refine(NoiseModel::default());
            let matched = refine(model);
            case.record(&default.likeliest_noise);
            for (errors, y) in [
                (&mut case.linear, linear.b_from_a),
                (&mut case.default, default.b_from_a),
                (&mut case.matched, matched.b_from_a),
            ] {
                let in_plane =
                    y.translation.vector.xy() - odometry_from_rig.translation.vector.xy();
                errors.push(rotation_error(&y, &odometry_from_rig), in_plane.norm());
            }
        }
        case.report(&level_name(levels, "odometry"), &model);
    }
}
