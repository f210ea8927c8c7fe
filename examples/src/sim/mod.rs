//! Simulated calibration worlds with ground truth.
//!
//! # Usage
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use ibc_pipeline::sim::{Scenario, SimulatedWorld};
//!
//! // A built-in scenario by name (or a scenario file by path), shrunk for a quick run.
//! let scenario = Scenario::resolve("garage")?.with_seed(7).with_scale(0.05);
//! let world = SimulatedWorld::simulate(&scenario)?;
//! assert_eq!(world.log.camera_names, ["front", "left", "rear", "right"]);
//! assert_eq!(world.truth.world_from_rig.len(), world.log.frames.len());
//!
//! // map.ibcmap, log.ibclog, camchain.yaml (the map-building rig) and truth.json.
//! let dir = tempfile::tempdir()?;
//! let files = world.write(dir.path())?;
//! assert!(files.map.exists() && files.truth.exists());
//!
//! // `ibc scenarios` prints this table.
//! assert!(ibc_pipeline::sim::scenario_list().contains("garage-moved-cameras"));
//! # Ok(())
//! # }
//! ```
//!
//! - `ibc simulate --scenario NAME|FILE --seed N --out DIR` is [`simulate_to_dir`].
//! - `ibc scenarios` prints [`scenario_list`] ([`builtin_scenarios`] gives the pairs).
//! - `ibc demo` simulates in memory with [`SimulatedWorld::simulate`] and calibrates
//!   `world.map`, `world.log` and `world.map_rig`, scoring against `world.truth`.
//!
//! # What a world holds
//!
//! - [`SimulatedWorld::map`]: the map the survey built (points, map images with keypoints,
//!   descriptors and point ids); [`SimulatedWorld::log`]: the calibration drive
//!   (synchronized frames, odometry); [`SimulatedWorld::map_rig`]: the cameras as the map
//!   knows them, which is what the camera file holds; [`SimulatedWorld::truth`]: the true
//!   extrinsics, rig poses and `rig_from_odometry`.
//! - For tests and diagnostics: [`SimulatedWorld::log_point_ids`] (the map point behind every
//!   log feature), [`SimulatedWorld::true_map_points`], [`SimulatedWorld::rig`] (the true rig
//!   with its intrinsics), [`SimulatedWorld::stats`].
//!
//! # Conventions
//!
//! The world frame is the map's, z up, ground at z = 0. The vehicle (rig) frame is x forward,
//! y left, z up (REP-103); camera frames have z along the optical axis, x right, y down.
//! Poses are `a_from_b`. Everything is deterministic per seed, whatever the thread count.
//!
//! # Built-in scenarios
//!
//! See [`builtin_scenarios`]: the paper's garage (the default) and street with the car's four
//! fisheyes; its three experiments (cameras moved 9.7 and 10.0 cm forward, the left camera
//! turned 30 degrees about x, turned 15 degrees about z), map-point error and 30% spurious
//! features; the TrimBot2020 pentagon rig in a garden; a handheld 6-DoF rig with a pose
//! tracker. Scenario files are described in [`scenario_yaml`].

mod environment;
mod error;
mod garage;
mod garden;
mod grid;
mod mover;
mod odometry;
mod options;
mod path;
mod random;
mod render;
pub mod rigs;
mod scenario;
pub mod scenario_yaml;
mod street;
mod surface;
mod trajectory;
mod world;

pub use environment::{Environment, EnvironmentKind};
pub use error::SimError;
pub use mover::Mover;
pub use options::{DetectionOptions, NoiseOptions};
pub use path::Path2;
pub use rigs::{BuiltinRig, SimRig};
pub use scenario::{
    CameraChange, CameraFileFormat, DEFAULT_SCENARIO, RigSource, Scenario, builtin_scenarios,
    default_mount, scenario_list,
};
pub use surface::Landmarks;
pub use trajectory::{MIN_FRAMES, MIN_SURVEY_FRAMES, Motion, TrajectorySpec};
pub use world::{
    MIN_MAP_OBSERVATIONS, SimulatedWorld, WorldStats, WrittenFiles, simulate, simulate_to_dir,
};
