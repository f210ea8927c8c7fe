//! COLMAP data in and out: sparse models and databases as ibc maps and rig logs, and ibc maps
//! and rigs as COLMAP models, databases and rig configurations.
//!
//! Formats implemented from COLMAP's documentation: the sparse model
//! (<https://colmap.github.io/format.html>: text and binary `cameras`, `images`, `points3D`,
//! and `rigs`, `frames` since COLMAP 3.12), the database schema
//! (<https://colmap.github.io/database.html>), camera models
//! (<https://colmap.github.io/cameras.html>), rigs and frames
//! (<https://colmap.github.io/rigs.html>, <https://colmap.github.io/concepts.html>).
//!
//! Conventions at the boundary:
//! - **Pixels**: COLMAP puts pixel centres at `+0.5`, ibc at integers. The model types
//!   ([`ColmapModel`], [`ColmapCamera`]) keep COLMAP's numbers; conversions to ibc
//!   ([`ColmapCamera::to_ibc`], [`map_from_colmap`], [`log_from_database`],
//!   [`ColmapDatabase::keypoints`]) subtract 0.5 and the writers add it back.
//! - **Poses**: COLMAP's `cam_from_world`, `rig_from_world`, `sensor_from_rig` are ibc's
//!   `camera_from_world`, `rig_from_world` (of COLMAP's rig, whose frame is its reference
//!   camera's), `camera_from_rig`; quaternions `[w, x, y, z]` in both.
//! - **Descriptors**: 128-byte SIFT rows go through the vocabulary tree's float path as
//!   `[f32; 128]`; binary descriptors `[u64; W]` are stored as their `8 W` bytes
//!   ([`ColmapDescriptor`]).
//!
//! # Example
//!
//! ```
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use ibc_pipeline::colmap::{read_colmap_map, survey_image_sources, write_colmap};
//! use ibc_pipeline::sim::{Scenario, SimulatedWorld};
//!
//! let world = SimulatedWorld::simulate(&Scenario::builtin("garage")?.with_scale(0.02))?;
//! let dir = tempfile::tempdir()?;
//! let sources = survey_image_sources(world.map.images.len(), world.map_rig.cameras.len());
//! write_colmap(dir.path(), &world.map_rig, &world.map, &sources)?;
//! let (sparse, database) = (dir.path().join("sparse"), dir.path().join("database.db"));
//! let read = read_colmap_map::<[u64; 4]>(sparse, database)?;
//! assert_eq!(read.map.points.len(), world.map.points.len());
//! # Ok(())
//! # }
//! ```

mod binary;
mod camera;
mod database;
mod error;
mod export;
mod map;
mod model;
mod text;

pub use binary::{
    cameras_from_bytes, frames_from_bytes, images_from_bytes, model_to_binary, points_from_bytes,
    rigs_from_bytes,
};
pub use camera::{ColmapCamera, ColmapCameraModel, PIXEL_SHIFT};
pub use database::{
    ColmapDatabase, ColmapDescriptor, DatabaseContent, DatabaseFrame, DatabaseImage, SIFT_TYPE,
    UNDEFINED_TYPE, database_to_bytes,
};
pub use error::{ColmapError, Result};
pub use export::{
    ColmapExport, colmap_from_map, file_names, log_database_bytes, rig_config_json,
    survey_image_sources, write_colmap, write_colmap_log,
};
pub use map::{
    ColmapLogOptions, ColmapMap, ibc_cameras, log_from_database, map_from_colmap, read_colmap_log,
    read_colmap_map,
};
pub use model::{
    ColmapFrame, ColmapImage, ColmapModel, ColmapPoint2D, ColmapPoint3D, ColmapRig, ModelFormat,
    NO_POINT3D, Sensor, SensorKind, UNIT_QUATERNION_TOLERANCE, read_model, write_model,
};
pub use text::{
    cameras_from_text, frames_from_text, images_from_text, model_to_text, points_from_text,
    rigs_from_text,
};
