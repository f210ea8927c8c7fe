//! COLMAP model + database as an ibc map, a COLMAP database as an ibc rig log.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use ibc_camera_models::Camera;

use super::camera::PIXEL_SHIFT;
use super::database::{ColmapDatabase, ColmapDescriptor, DatabaseImage};
use super::error::{ColmapError, Result};
use super::model::{ColmapModel, NO_POINT3D, SensorKind};
use crate::NonExhaustive;
use crate::data::{Frame, ImageFeatures, Map, MapImage, OdometryKind, PointId, RigLog};

/// An ibc map read from a COLMAP model and its database, with what links it back to COLMAP.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapMap<D> {
    /// The map: every registered image of the model (by image id) with its pose, its
    /// database features (index for index with the model's 2D points) and the map points
    /// they observe; the model's 3D points (by point id).
    pub map: Map<D>,
    /// For each map image, COLMAP's image id.
    pub image_ids: Vec<u32>,
    /// For each map image, its name.
    pub image_names: Vec<String>,
    /// For each map image, its COLMAP camera id.
    pub image_camera_ids: Vec<u32>,
    /// For each map point, COLMAP's 3D point id.
    pub point3d_ids: Vec<u64>,
}

/// Reads a model's images and points as an ibc map, with the features of each image from the
/// database (matched by image name). Keypoints are the model's 2D points moved to ibc's pixel
/// convention (`- 0.5`); the database must hold as many keypoints and descriptors for each
/// image as the model has 2D points.
///
/// # Errors
/// [`ColmapError::ImageNotInDatabase`] naming a model image the database lacks,
/// [`ColmapError::MissingFeatures`] for an image without keypoints or descriptors,
/// [`ColmapError::BadFeatures`] when the counts differ, [`ColmapError::DescriptorMismatch`]
/// when the descriptors are not of `D`'s kind, [`ColmapError::Invalid`] for a model with
/// more than `u32::MAX - 1` points.
pub fn map_from_colmap<D: ColmapDescriptor>(
    model: &ColmapModel,
    database: &ColmapDatabase,
) -> Result<ColmapMap<D>> {
    let db_images: HashMap<String, DatabaseImage> = database
        .images()?
        .into_iter()
        .map(|i| (i.name.clone(), i))
        .collect();
    let too_many = model.points3d.len() >= PointId::MAX as usize;
    if too_many {
        return Err(ColmapError::Invalid {
            path: database.path().to_owned(),
            what: format!(
                "{} 3D points: ibc maps hold fewer than 2^32 - 1",
                model.points3d.len()
            ),
        });
    }
    let point_index: HashMap<u64, PointId> = model
        .points3d
        .iter()
        .enumerate()
        .map(|(i, p)| (p.point3d_id, i as PointId))
        .collect();
    let mut out = ColmapMap {
        map: Map {
            points: model.points3d.iter().map(|p| p.xyz).collect(),
            images: Vec::with_capacity(model.images.len()),
        },
        image_ids: Vec::with_capacity(model.images.len()),
        image_names: Vec::with_capacity(model.images.len()),
        image_camera_ids: Vec::with_capacity(model.images.len()),
        point3d_ids: model.points3d.iter().map(|p| p.point3d_id).collect(),
    };
    for image in &model.images {
        let db_image =
            db_images
                .get(&image.name)
                .ok_or_else(|| ColmapError::ImageNotInDatabase {
                    path: database.path().to_owned(),
                    image: image.name.clone(),
                })?;
        let descriptors = database.descriptors::<D>(db_image)?;
        let n = image.points2d.len();
        let keypoints = database.keypoints(db_image)?;
        if keypoints.len() != n || descriptors.len() != n {
            return Err(ColmapError::BadFeatures {
                path: database.path().to_owned(),
                image: image.name.clone(),
                what: format!(
                    "the model has {n} 2D points but the database {} keypoints and {} \
                     descriptors",
                    keypoints.len(),
                    descriptors.len()
                ),
            });
        }
        let point_ids = image
            .points2d
            .iter()
            .map(|p| {
                (p.point3d_id != NO_POINT3D)
                    .then(|| point_index.get(&p.point3d_id).copied())
                    .flatten()
            })
            .collect();
        out.map.images.push(MapImage {
            camera_from_world: Some(image.cam_from_world),
            features: ImageFeatures {
                keypoints: image
                    .points2d
                    .iter()
                    .map(|p| p.xy.add_scalar(-PIXEL_SHIFT))
                    .collect(),
                descriptors,
            },
            point_ids,
        });
        out.image_ids.push(image.image_id);
        out.image_names.push(image.name.clone());
        out.image_camera_ids.push(image.camera_id);
    }
    Ok(out)
}

/// Reads the model in `model_dir` ([`super::read_model`]) and its database at
/// `database_path` as an ibc map ([`map_from_colmap`]).
///
/// # Errors
/// Those of the three.
pub fn read_colmap_map<D: ColmapDescriptor>(
    model_dir: impl AsRef<Path>,
    database_path: impl AsRef<Path>,
) -> Result<ColmapMap<D>> {
    let model = super::read_model(model_dir)?;
    let database = ColmapDatabase::open(database_path)?;
    map_from_colmap(&model, &database)
}

/// The ibc cameras of a model, by COLMAP camera id ([`super::ColmapCamera::to_ibc`]).
///
/// # Errors
/// [`ColmapError::UnsupportedCameraModel`] naming the first camera whose model ibc does not
/// represent exactly, [`ColmapError::CameraParameters`].
pub fn ibc_cameras(model: &ColmapModel) -> Result<BTreeMap<u32, Camera>> {
    model
        .cameras
        .iter()
        .map(|c| Ok((c.camera_id, c.to_ibc()?)))
        .collect()
}

/// How [`log_from_database`] turns a database into a rig log.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapLogOptions {
    /// The rig whose frames make the log, when the database's frame table is used. Default
    /// `None`: the rig with the most cameras (the lowest id among equals).
    pub rig_id: Option<u32>,
    /// Seconds per unit of the number in the file names (`front/1403636579763555584.png`:
    /// nanoseconds, `1e-9`). Default 1: a frame number or seconds. Names that are not
    /// numbers give their frame's index as the time stamp.
    pub seconds_per_unit: f64,
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for ColmapLogOptions {
    fn default() -> Self {
        Self {
            rig_id: None,
            seconds_per_unit: 1.0,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// The folder part of an image name (`front` of `front/000001.png`), and its file name.
fn split_name(name: &str) -> (&str, &str) {
    match name.rfind('/') {
        Some(i) => (&name[..i], &name[i + 1..]),
        None => ("", name),
    }
}

/// The number in a file name without its extension (`000123.png` is 123).
fn name_number(file: &str) -> Option<f64> {
    let stem = file.rsplit_once('.').map_or(file, |(s, _)| s);
    stem.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// A rig log from a COLMAP database of the rig's images.
///
/// - **Frames**: from COLMAP's frame table where a rig of two or more cameras has frames
///   (the rig [`ColmapLogOptions::rig_id`], or the one with the most cameras); its cameras
///   are the rig's reference camera, then the others by camera id. Else, by name pattern as
///   COLMAP's rig support lays images out (`camera_folder/image_name`): images with the same
///   file name in different folders are one frame; the cameras are the folders, sorted.
/// - **Camera names**: a camera's folder when all its images lie in one folder that no other
///   camera uses, else `camera<id>`. ibc matches them to the camera file's cameras by name.
/// - **Time stamps**: the number in the reference image's file name times
///   [`ColmapLogOptions::seconds_per_unit`], else the frame's index; frames are sorted by
///   time (then by name).
/// - Each image's keypoints (ibc's pixel convention) and descriptors; a camera without an
///   image in a frame has no features there. No odometry.
///
/// # Errors
/// [`ColmapError::Invalid`] when the database has no images, a frame names an image or
/// camera that is not there, or `seconds_per_unit` is not finite and positive;
/// [`ColmapError::MissingFeatures`], [`ColmapError::BadFeatures`],
/// [`ColmapError::DescriptorMismatch`] for an image's features, [`ColmapError::Database`].
pub fn log_from_database<D: ColmapDescriptor>(
    database: &ColmapDatabase,
    options: &ColmapLogOptions,
) -> Result<RigLog<D>> {
    let invalid = |what: String| ColmapError::Invalid {
        path: database.path().to_owned(),
        what,
    };
    if !(options.seconds_per_unit.is_finite() && options.seconds_per_unit > 0.0) {
        return Err(invalid(format!(
            "seconds per unit of the image names must be finite and positive, not {}",
            options.seconds_per_unit
        )));
    }
    let images = database.images()?;
    if images.is_empty() {
        return Err(invalid("the database holds no image".to_owned()));
    }
    let by_id: HashMap<u32, &DatabaseImage> = images.iter().map(|i| (i.image_id, i)).collect();
    // The rig whose frames make the log: the one asked for, else the one with the most cameras.
    let rigs = database.rigs()?;
    let frames = database.frames()?;
    let camera_count = |rig: &super::ColmapRig| {
        1 + rig
            .sensors
            .iter()
            .filter(|(s, _)| s.kind == SensorKind::Camera)
            .count()
    };
    let rig = match options.rig_id {
        Some(id) => Some(
            rigs.iter()
                .find(|r| r.rig_id == id)
                .ok_or_else(|| invalid(format!("the database has no rig {id}")))?,
        ),
        None => rigs
            .iter()
            .filter(|r| camera_count(r) >= 2 && frames.iter().any(|f| f.rig_id == r.rig_id))
            .fold(None, |best: Option<&super::ColmapRig>, r| match best {
                Some(b) if camera_count(b) >= camera_count(r) => Some(b),
                _ => Some(r),
            }),
    };
    let (camera_ids, grouped): (Vec<u32>, Vec<Vec<Option<&DatabaseImage>>>) = match rig {
        Some(rig) if rig.ref_sensor.kind == SensorKind::Camera => {
            let mut cameras = vec![rig.ref_sensor.id];
            let mut others: Vec<u32> = rig
                .sensors
                .iter()
                .filter(|(s, _)| s.kind == SensorKind::Camera)
                .map(|(s, _)| s.id)
                .collect();
            others.sort_unstable();
            cameras.extend(others);
            let mut grouped = Vec::new();
            for f in frames.iter().filter(|f| f.rig_id == rig.rig_id) {
                let mut row = vec![None; cameras.len()];
                for (s, data) in &f.data {
                    if s.kind != SensorKind::Camera {
                        continue;
                    }
                    let Some(c) = cameras.iter().position(|&c| c == s.id) else {
                        return Err(invalid(format!(
                            "frame {} has camera {}, which its rig {} does not hold",
                            f.frame_id, s.id, rig.rig_id
                        )));
                    };
                    let image = u32::try_from(*data)
                        .ok()
                        .and_then(|id| by_id.get(&id))
                        .ok_or_else(|| {
                            invalid(format!(
                                "frame {} has image {data}, which images does not hold",
                                f.frame_id
                            ))
                        })?;
                    row[c] = Some(*image);
                }
                grouped.push(row);
            }
            (cameras, grouped)
        }
        Some(rig) => {
            return Err(invalid(format!(
                "rig {}'s reference sensor is not a camera",
                rig.rig_id
            )));
        }
        None => {
            // By name pattern: folder = camera, file name = frame.
            let mut folders: Vec<&str> = images.iter().map(|i| split_name(&i.name).0).collect();
            folders.sort_unstable();
            folders.dedup();
            let mut by_file: BTreeMap<&str, Vec<Option<&DatabaseImage>>> = BTreeMap::new();
            for image in &images {
                let (folder, file) = split_name(&image.name);
                let c = folders.iter().position(|f| *f == folder).unwrap_or(0);
                by_file
                    .entry(file)
                    .or_insert_with(|| vec![None; folders.len()])[c] = Some(image);
            }
            // The log's cameras are the folders; a folder's camera id is its first image's.
            let cameras = folders
                .iter()
                .map(|f| {
                    images
                        .iter()
                        .find(|i| split_name(&i.name).0 == *f)
                        .map_or(0, |i| i.camera_id)
                })
                .collect();
            return build_log(
                database,
                options,
                cameras,
                folders.iter().map(|f| Some((*f).to_owned())).collect(),
                by_file.into_values().collect(),
            );
        }
    };
    // Camera names: the one folder of each camera's images, when no other camera uses it.
    let mut folder_of: Vec<Option<String>> = Vec::with_capacity(camera_ids.len());
    for &c in &camera_ids {
        let mut folders = images
            .iter()
            .filter(|i| i.camera_id == c)
            .map(|i| split_name(&i.name).0);
        let first = folders.next();
        let one = first.filter(|f| !f.is_empty() && folders.all(|g| g == *f));
        folder_of.push(one.map(str::to_owned));
    }
    build_log(database, options, camera_ids, folder_of, grouped)
}

/// A frame's images by camera, with its file name's number and the file name (sort keys).
type KeyedFrame<'a> = (Option<f64>, String, Vec<Option<&'a DatabaseImage>>);

fn build_log<D: ColmapDescriptor>(
    database: &ColmapDatabase,
    options: &ColmapLogOptions,
    camera_ids: Vec<u32>,
    folders: Vec<Option<String>>,
    grouped: Vec<Vec<Option<&DatabaseImage>>>,
) -> Result<RigLog<D>> {
    let mut names: Vec<String> = Vec::with_capacity(camera_ids.len());
    for (i, (&id, folder)) in camera_ids.iter().zip(&folders).enumerate() {
        let unique = folder.as_ref().filter(|f| {
            !f.is_empty()
                && folders
                    .iter()
                    .enumerate()
                    .all(|(j, g)| j == i || g.as_ref() != Some(f))
        });
        names.push(unique.cloned().unwrap_or_else(|| format!("camera{id}")));
    }
    // Sort frames by (time, name of the first image).
    let mut keyed: Vec<KeyedFrame<'_>> = grouped
        .into_iter()
        .filter_map(|row| {
            let first = row.iter().flatten().next()?;
            let file = split_name(&first.name).1;
            Some((name_number(file), file.to_owned(), row))
        })
        .collect();
    let all_numbered = keyed.iter().all(|k| k.0.is_some());
    keyed.sort_by(|a, b| {
        let t = if all_numbered {
            a.0.partial_cmp(&b.0)
        } else {
            None
        };
        t.unwrap_or(std::cmp::Ordering::Equal)
            .then_with(|| a.1.cmp(&b.1))
    });
    let mut frames = Vec::with_capacity(keyed.len());
    for (index, (number, _, row)) in keyed.into_iter().enumerate() {
        let timestamp = match number {
            Some(n) if all_numbered => n * options.seconds_per_unit,
            _ => index as f64,
        };
        let images = row
            .into_iter()
            .map(|image| match image {
                Some(image) => database.features::<D>(image),
                None => Ok(ImageFeatures {
                    keypoints: Vec::new(),
                    descriptors: Vec::new(),
                }),
            })
            .collect::<Result<Vec<_>>>()?;
        frames.push(Frame {
            timestamp,
            images,
            world_from_odometry: None,
        });
    }
    Ok(RigLog {
        camera_names: names,
        odometry: OdometryKind::None,
        frames,
    })
}

/// Opens the database at `path` and reads it as a rig log ([`log_from_database`]).
///
/// # Errors
/// Those of [`ColmapDatabase::open`] and [`log_from_database`].
pub fn read_colmap_log<D: ColmapDescriptor>(
    path: impl AsRef<Path>,
    options: &ColmapLogOptions,
) -> Result<RigLog<D>> {
    log_from_database(&ColmapDatabase::open(path)?, options)
}
