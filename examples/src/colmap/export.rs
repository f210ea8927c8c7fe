//! ibc maps and calibrations written as COLMAP data: a text sparse model with rigs and frames,
//! a database with the map images' keypoints and descriptors, and a `rig_config.json` for
//! COLMAP's `rig_configurator` (<https://colmap.github.io/rigs.html>: a list of rigs, each a
//! list of cameras with `image_prefix`, `ref_sensor` for the reference camera, else
//! `cam_from_rig_rotation` `[w, x, y, z]` and `cam_from_rig_translation`, and optionally
//! `camera_model_name` and `camera_params`).
//!
//! COLMAP's rig frame is its reference sensor's, which has the identity `sensor_from_rig`;
//! ibc's rig frame may be any (the simulator's vehicle frame). The writer takes the first
//! camera as the reference: `sensor_from_rig` of camera `c` is
//! `rig_from_camera[c]^-1 * rig_from_camera[0]`, and a frame's `rig_from_world` is its
//! first camera's `camera_from_world`.

use std::path::{Path, PathBuf};

use ibc_camera_models::Rig;
use nalgebra::Isometry3;
use serde_json::json;

use super::camera::{ColmapCamera, PIXEL_SHIFT};
use super::database::{
    ColmapDescriptor, DatabaseContent, DatabaseFrame, DatabaseImage, database_to_bytes,
};
use super::error::{ColmapError, Result};
use super::model::{
    ColmapFrame, ColmapImage, ColmapModel, ColmapPoint2D, ColmapPoint3D, ColmapRig, NO_POINT3D,
    Sensor, SensorKind,
};
use super::text::model_to_text;
use crate::data::Map;
use crate::data::io::StagedFiles;

/// The file names [`write_colmap`] writes into its folder.
pub mod file_names {
    /// The text model's folder.
    pub const SPARSE: &str = "sparse";
    /// The database.
    pub const DATABASE: &str = "database.db";
    /// The rig configuration.
    pub const RIG_CONFIG: &str = "rig_config.json";
}

/// Where each image of a simulated survey comes from: image `i` is camera `i % cameras` of
/// keyframe `i / cameras` (the simulator's order), as `(frame, camera)` pairs.
pub fn survey_image_sources(images: usize, cameras: usize) -> Vec<(usize, usize)> {
    (0..images)
        .map(|i| (i / cameras.max(1), i % cameras.max(1)))
        .collect()
}

/// A COLMAP model and database content of an ibc map taken by `rig`.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapExport {
    /// The model: one camera per rig camera (ids from 1, in rig order), one rig (id 1, the
    /// first camera its reference), one frame per frame index used, one image per map image
    /// (`<camera name>/<frame:06>.png`, ids from 1 in map order), one 3D point per map point
    /// (ids from 1 in map order).
    pub model: ColmapModel,
    /// The database's images (the model's, with the same ids).
    pub images: Vec<DatabaseImage>,
    /// The database's frames (the model's, without poses).
    pub frames: Vec<DatabaseFrame>,
}

fn id(i: usize) -> u32 {
    u32::try_from(i + 1).unwrap_or(u32::MAX)
}

/// The COLMAP model of `map`, whose image `i` was taken by camera `sources[i].1` of `rig` in
/// frame `sources[i].0`.
///
/// # Errors
/// [`ColmapError::UnsupportedIbcModel`] for a camera COLMAP has no model of,
/// [`ColmapError::Invalid`] (naming `dir`) when `sources` does not have one entry per map
/// image, an entry's camera is not in the rig, two images share a frame and camera, a map
/// image has no pose, or the rig is empty.
pub fn colmap_from_map<D>(
    rig: &Rig,
    map: &Map<D>,
    sources: &[(usize, usize)],
    dir: &Path,
) -> Result<ColmapExport> {
    let invalid = |what: String| ColmapError::Invalid {
        path: dir.to_owned(),
        what,
    };
    if rig.cameras.is_empty() {
        return Err(invalid("the rig has no camera".to_owned()));
    }
    if sources.len() != map.images.len() {
        return Err(invalid(format!(
            "{} image sources for {} map images",
            sources.len(),
            map.images.len()
        )));
    }
    let cameras = colmap_cameras(rig.cameras.iter())?;
    let rig_from_ref = rig.cameras[0].rig_from_camera;
    let camera_from_ref: Vec<Isometry3<f64>> = rig
        .cameras
        .iter()
        .map(|c| c.rig_from_camera.inverse() * rig_from_ref)
        .collect();
    let colmap_rig = ColmapRig {
        rig_id: 1,
        ref_sensor: sensor(0),
        sensors: (1..rig.cameras.len())
            .map(|c| (sensor(c), Some(camera_from_ref[c])))
            .collect(),
    };
    let mut frame_ids: Vec<usize> = sources.iter().map(|s| s.0).collect();
    frame_ids.sort_unstable();
    frame_ids.dedup();
    let mut frames: Vec<ColmapFrame> = frame_ids
        .iter()
        .map(|&f| ColmapFrame {
            frame_id: id(f),
            rig_id: 1,
            rig_from_world: Isometry3::identity(),
            data: Vec::new(),
        })
        .collect();
    let mut images = Vec::with_capacity(map.images.len());
    let mut tracks: Vec<Vec<(u32, u32)>> = vec![Vec::new(); map.points.len()];
    for (i, (image, &(frame, camera))) in map.images.iter().zip(sources).enumerate() {
        let rig_camera = rig
            .cameras
            .get(camera)
            .ok_or_else(|| invalid(format!("map image {i}: camera {camera} is not in the rig")))?;
        let cam_from_world = image.camera_from_world.ok_or_else(|| {
            invalid(format!(
                "map image {i} has no pose: COLMAP models hold posed images"
            ))
        })?;
        let f = frame_ids.binary_search(&frame).unwrap_or(0);
        if frames[f].data.iter().any(|(s, _)| s.id == id(camera)) {
            return Err(invalid(format!(
                "two map images of camera {camera} in frame {frame}"
            )));
        }
        if frames[f].data.is_empty() || camera == 0 {
            // The reference camera's pose is the frame's; another camera's gives it until then.
            frames[f].rig_from_world = camera_from_ref[camera].inverse() * cam_from_world;
        }
        frames[f].data.push((sensor(camera), u64::from(id(i))));
        let mut points2d = Vec::with_capacity(image.features.len());
        for (k, (xy, point)) in image
            .features
            .keypoints
            .iter()
            .zip(&image.point_ids)
            .enumerate()
        {
            let point3d_id = match point {
                Some(p) if (*p as usize) < map.points.len() => {
                    tracks[*p as usize].push((id(i), k as u32));
                    u64::from(*p) + 1
                }
                Some(p) => {
                    return Err(invalid(format!(
                        "map image {i} observes point {p}, past the map's"
                    )));
                }
                None => NO_POINT3D,
            };
            points2d.push(ColmapPoint2D {
                xy: xy.add_scalar(PIXEL_SHIFT),
                point3d_id,
            });
        }
        images.push(ColmapImage {
            image_id: id(i),
            name: format!("{}/{:06}.png", rig_camera.name, frame),
            camera_id: id(camera),
            cam_from_world,
            points2d,
        });
    }
    let points3d = map
        .points
        .iter()
        .zip(tracks)
        .enumerate()
        .map(|(p, (xyz, track))| ColmapPoint3D {
            point3d_id: p as u64 + 1,
            xyz: *xyz,
            color: [128, 128, 128],
            error: 0.0,
            track,
        })
        .collect();
    let db_images = images
        .iter()
        .map(|i| DatabaseImage {
            image_id: i.image_id,
            name: i.name.clone(),
            camera_id: i.camera_id,
        })
        .collect();
    let db_frames = frames
        .iter()
        .map(|f| DatabaseFrame {
            frame_id: f.frame_id,
            rig_id: f.rig_id,
            data: f.data.clone(),
        })
        .collect();
    Ok(ColmapExport {
        model: ColmapModel {
            cameras,
            images,
            points3d,
            rigs: vec![colmap_rig],
            frames,
        },
        images: db_images,
        frames: db_frames,
    })
}

/// `rig_config.json` of `rig` for COLMAP's `rig_configurator`: one rig whose cameras are the
/// image folders `<camera name>/`, the first the reference, the others with their
/// `cam_from_rig` (see the module docs), each with its COLMAP model and parameters.
///
/// # Errors
/// [`ColmapError::UnsupportedIbcModel`] for a camera COLMAP has no model of.
pub fn rig_config_json(rig: &Rig) -> Result<String> {
    let Some(reference) = rig.cameras.first() else {
        return Ok("[]\n".to_owned());
    };
    let mut cameras = Vec::with_capacity(rig.cameras.len());
    for (i, c) in rig.cameras.iter().enumerate() {
        let colmap = ColmapCamera::from_ibc(id(i), &c.name, &c.camera)?;
        let mut entry = json!({
            "image_prefix": format!("{}/", c.name),
            "camera_model_name": colmap.model.name(),
            "camera_params": colmap.params,
        });
        if i == 0 {
            entry["ref_sensor"] = json!(true);
        } else {
            let cam_from_rig = c.rig_from_camera.inverse() * reference.rig_from_camera;
            let q = cam_from_rig.rotation.quaternion();
            let t = cam_from_rig.translation.vector;
            entry["cam_from_rig_rotation"] = json!([q.w, q.i, q.j, q.k]);
            entry["cam_from_rig_translation"] = json!([t.x, t.y, t.z]);
        }
        cameras.push(entry);
    }
    let text = serde_json::to_string_pretty(&json!([{ "cameras": cameras }]))
        .unwrap_or_else(|_| "[]".to_owned());
    Ok(text + "\n")
}

/// Writes `map` (taken by `rig`, image `i` in frame `sources[i].0` by camera `sources[i].1`;
/// [`survey_image_sources`] for a simulated survey) into `dir` as COLMAP data, all or nothing
/// ([`StagedFiles`]): the text model in `sparse/`, `database.db` with every image's keypoints
/// and descriptors, and `rig_config.json`. Returns the paths written.
///
/// # Errors
/// Those of [`colmap_from_map`] and [`rig_config_json`]; [`ColmapError::Database`];
/// [`ColmapError::Output`] when a file cannot be written (nothing is then left in `dir`).
pub fn write_colmap<D: ColmapDescriptor>(
    dir: impl AsRef<Path>,
    rig: &Rig,
    map: &Map<D>,
    sources: &[(usize, usize)],
) -> Result<Vec<PathBuf>> {
    let dir = dir.as_ref();
    let export = colmap_from_map(rig, map, sources, dir)?;
    let rig_config = rig_config_json(rig)?;
    let features: Vec<(DatabaseImage, &crate::data::ImageFeatures<D>)> = export
        .images
        .iter()
        .cloned()
        .zip(map.images.iter().map(|i| &i.features))
        .collect();
    let db_path = dir.join(file_names::DATABASE);
    let database = database_to_bytes(
        &db_path,
        &DatabaseContent {
            cameras: &export.model.cameras,
            rigs: &export.model.rigs,
            frames: &export.frames,
            images: &features,
        },
    )?;
    let mut staged = StagedFiles::new(dir)?;
    for (name, text) in model_to_text(&export.model) {
        staged.stage(dir.join(file_names::SPARSE).join(name), text.as_bytes())?;
    }
    staged.stage(&db_path, &database)?;
    staged.stage(dir.join(file_names::RIG_CONFIG), rig_config.as_bytes())?;
    Ok(staged.commit()?)
}

/// The COLMAP database of a rig log: the rig's cameras (matched to the log's cameras by name),
/// one rig (the log's first camera its reference), one frame per log frame, and per image
/// `<camera name>/<time stamp in nanoseconds, 19 digits>.png` with its keypoints and
/// descriptors. Read it back with [`super::log_from_database`] and
/// `seconds_per_unit: 1e-9`. Odometry is not written (COLMAP's database has no place for
/// it). `path` names the database in errors.
///
/// # Errors
/// [`ColmapError::Invalid`] when a log camera has no camera of its name in `rig`, or a time
/// stamp is negative or not finite; [`ColmapError::UnsupportedIbcModel`];
/// [`ColmapError::Database`].
pub fn log_database_bytes<D: ColmapDescriptor>(
    path: &Path,
    rig: &Rig,
    log: &crate::data::RigLog<D>,
) -> Result<Vec<u8>> {
    let invalid = |what: String| ColmapError::Invalid {
        path: path.to_owned(),
        what,
    };
    let mut rig_cameras = Vec::with_capacity(log.camera_names.len());
    for name in &log.camera_names {
        rig_cameras.push(
            rig.camera(name)
                .ok_or_else(|| invalid(format!("the rig has no camera {name:?} of the log")))?,
        );
    }
    let cameras = colmap_cameras(rig_cameras.iter().copied())?;
    let colmap_rig = ColmapRig {
        rig_id: 1,
        ref_sensor: sensor(0),
        sensors: (1..rig_cameras.len())
            .map(|c| {
                let pose =
                    rig_cameras[c].rig_from_camera.inverse() * rig_cameras[0].rig_from_camera;
                (sensor(c), Some(pose))
            })
            .collect(),
    };
    let mut images = Vec::new();
    let mut frames = Vec::with_capacity(log.frames.len());
    for (f, frame) in log.frames.iter().enumerate() {
        let ns = frame.timestamp * 1e9;
        if !(0.0..1e19).contains(&ns) {
            return Err(invalid(format!(
                "frame {f}: time stamp {} s",
                frame.timestamp
            )));
        }
        let mut data = Vec::new();
        for (c, features) in frame.images.iter().enumerate() {
            let Some(camera) = rig_cameras.get(c) else {
                return Err(invalid(format!(
                    "frame {f} has more images than the log has cameras"
                )));
            };
            let image_id = id(images.len());
            data.push((sensor(c), u64::from(image_id)));
            images.push((
                DatabaseImage {
                    image_id,
                    name: format!("{}/{:019}.png", camera.name, ns.round() as u64),
                    camera_id: id(c),
                },
                features,
            ));
        }
        frames.push(DatabaseFrame {
            frame_id: id(f),
            rig_id: 1,
            data,
        });
    }
    database_to_bytes(
        path,
        &DatabaseContent {
            cameras: &cameras,
            rigs: &[colmap_rig],
            frames: &frames,
            images: &images,
        },
    )
}

/// Writes the COLMAP database of a rig log ([`log_database_bytes`]) atomically.
///
/// # Errors
/// Those of [`log_database_bytes`]; [`ColmapError::Io`] when the file cannot be written.
pub fn write_colmap_log<D: ColmapDescriptor>(
    path: impl AsRef<Path>,
    rig: &Rig,
    log: &crate::data::RigLog<D>,
) -> Result<()> {
    let path = path.as_ref();
    let bytes = log_database_bytes(path, rig, log)?;
    Ok(ibc_camera_models::io::write_atomically(path, &bytes)?)
}

/// The COLMAP cameras of a rig's cameras, ids from 1 in order.
fn colmap_cameras<'a>(
    cameras: impl Iterator<Item = &'a ibc_camera_models::RigCamera>,
) -> Result<Vec<ColmapCamera>> {
    cameras
        .enumerate()
        .map(|(i, c)| ColmapCamera::from_ibc(id(i), &c.name, &c.camera))
        .collect()
}

/// Camera `c` of the rig (0-based) as a COLMAP sensor.
fn sensor(c: usize) -> Sensor {
    Sensor {
        kind: SensorKind::Camera,
        id: id(c),
    }
}
