//! Structure from motion on a rig's own log: feature tracks without a map, the rig's
//! extrinsics self-calibrated from them (TrimBot2020 D3.1 §3.3.3), and the survey's map built
//! by a calibrated rig (Heng et al. §IV-A, [`build_map`]), composing the geometry
//! crates: relative pose and triangulation (`ibc-pnp`), rotation and translation averaging
//! (`ibc-rig-averaging`), rig bundle adjustment with free points (`ibc-bundle-adjust`) and the
//! metric scale from odometry (`ibc-hand-eye`).
//!
//! ```no_run
//! use ibc_pipeline::sim::{Scenario, SimulatedWorld};
//! use ibc_pipeline::sfm::{SelfCalibrationOptions, extrinsic_errors, self_calibrate};
//!
//! let world = SimulatedWorld::simulate(&Scenario::builtin("garage")?.with_scale(0.2))?;
//! let cameras: Vec<_> = world.rig.cameras.iter().map(|c| c.camera.clone()).collect();
//! let result = self_calibrate(&world.log, &cameras, &SelfCalibrationOptions::default())?;
//! for (camera, (rotation, translation)) in
//!     extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, false)
//!         .iter()
//!         .enumerate()
//! {
//!     println!("camera {camera}: {:.4} deg, {:.2} mm", rotation.to_degrees(), translation * 1e3);
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod completion;
mod error;
mod map;
mod selfcalib;
mod tracks;

pub use completion::TrackCompletion;
pub use error::SelfCalibrationError;
pub use map::{BuiltMap, MapOptions, build_map};
pub use selfcalib::{
    OdometryDistances, Round, ScaleEstimate, ScaleSource, SelfCalibration, SelfCalibrationOptions,
    TrackStats, extrinsic_errors, self_calibrate,
};
pub use tracks::{
    ImageId, Track, TrackOptions, Tracks, VerifiedPair, build_tracks, build_tracks_with_rig,
};
