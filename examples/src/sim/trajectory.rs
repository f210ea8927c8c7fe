//! Trajectories: rig poses sampled along an environment's path.
//!
//! - [`Motion::Drive`]: a ground vehicle. The rig (vehicle) frame's origin follows the path on
//!   the ground, x along the direction of travel, z up: planar motion.
//! - [`Motion::Handheld`]: a person walking the path with the rig in hand (or a drone
//!   following it). On top of the walk the rig's height swings by ±0.15 m about 1.45 m, its
//!   heading by ±20 degrees, pitch by ±12 and roll by ±10, each a sinusoid of the distance
//!   walked with its own period (13, 6.7, 5.3 and 4.1 m), so rotations about every axis are
//!   observed, as Daniilidis' hand-eye method needs.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};

use super::path::Path2;

/// How the rig moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Planar driving (car, ground robot).
    Drive,
    /// 6-DoF handheld or aerial motion.
    Handheld,
}

impl Motion {
    /// Its name in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Drive => "drive",
            Self::Handheld => "handheld",
        }
    }

    /// The motion of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Drive, Self::Handheld]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// The calibration drive and the survey of a scenario.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct TrajectorySpec {
    /// How the rig moves.
    pub motion: Motion,
    /// Synchronized frames of the calibration loop at scale 1 (the paper: 500).
    pub frames: usize,
    /// Distance between survey keyframes at scale 1, metres (each keyframe gives one map
    /// image per camera).
    pub survey_spacing_m: f64,
    /// Speed along the path, metres per second (sets the time stamps).
    pub speed_m_s: f64,
}

impl Default for TrajectorySpec {
    /// The paper's car: driving, 500 frames, survey keyframes every 1.5 m, 5 m/s.
    fn default() -> Self {
        Self {
            motion: Motion::Drive,
            frames: 500,
            survey_spacing_m: 1.5,
            speed_m_s: 5.0,
        }
    }
}

/// Fewest frames of a calibration drive or a survey, whatever the scale.
pub const MIN_FRAMES: usize = 10;
/// Fewest survey keyframes, whatever the scale.
pub const MIN_SURVEY_FRAMES: usize = 20;

/// Time stamps and rig poses.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Timed {
    pub timestamps: Vec<f64>,
    pub world_from_rig: Vec<Isometry3<f64>>,
}

/// `frames` poses evenly spaced along `path` (a closed path is not sampled twice at its
/// start), starting at time `t0`. `phase` shifts the handheld sinusoids, so two walks differ.
pub(crate) fn sample(
    path: &Path2,
    frames: usize,
    speed: f64,
    motion: Motion,
    phase: f64,
    t0: f64,
) -> Timed {
    let len = path.length();
    let step = match (path.is_closed(), frames) {
        (_, 0 | 1) => 0.0,
        (true, n) => len / n as f64,
        (false, n) => len / (n - 1) as f64,
    };
    let mut out = Timed::default();
    for i in 0..frames {
        let s = step * i as f64;
        let (p, heading) = path.at(s);
        let pose = match motion {
            Motion::Drive => Isometry3::from_parts(
                Translation3::new(p.x, p.y, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, heading),
            ),
            Motion::Handheld => {
                let wave = |amplitude: f64, period: f64, k: f64| {
                    amplitude * (std::f64::consts::TAU * s / period + phase * k).sin()
                };
                let z = 1.45 + wave(0.15, 4.1, 1.0);
                let yaw = heading + wave(20f64.to_radians(), 13.0, 2.0);
                let pitch = wave(12f64.to_radians(), 6.7, 3.0);
                let roll = wave(10f64.to_radians(), 5.3, 5.0);
                Isometry3::from_parts(
                    Translation3::new(p.x, p.y, z),
                    UnitQuaternion::from_euler_angles(roll, pitch, yaw),
                )
            }
        };
        out.timestamps.push(t0 + s / speed);
        out.world_from_rig.push(pose);
    }
    out
}
