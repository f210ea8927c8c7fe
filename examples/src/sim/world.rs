//! [`SimulatedWorld`]: a scenario simulated into a map, a rig log and their ground truth, and
//! written to a folder.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ibc_bundle_adjust::RigBaObservation;
use ibc_camera_models::{Camera, CameraModel, Rig};
use nalgebra::{Isometry3, Point3, Vector3};
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use super::environment::Environment;
use super::error::SimError;
use super::odometry::{self, OdometryNoise};
use super::random::{Purpose, stream};
use super::render::{Settings, View, render_image};
use super::rigs::SimRig;
use super::scenario::{Scenario, scaled};
use super::trajectory::{self, MIN_SURVEY_FRAMES, Timed};
use crate::data::io::{
    DataFileError, StagedFiles, file_names, log_to_bytes, map_to_bytes, truth_to_json,
};
use crate::data::{
    BinaryDescriptor, Frame, GroundTruth, ImageFeatures, Map, MapImage, OdometryKind, PointId,
    RigLog,
};

/// A landmark becomes a map point when this many survey images see it (two views
/// triangulate a point).
pub const MIN_MAP_OBSERVATIONS: u32 = 2;

/// Time of the first survey keyframe, seconds: far from the log's (which starts at 0), so the
/// moving objects are elsewhere during the survey.
const SURVEY_START_S: f64 = 1.0e5;

/// A simulated world: what the calibration reads (map, log, cameras) and the truth behind it.
///
/// The simulation runs in this order, every random step on its own seeded stream:
///
/// 1. the environment (landmarks, moving objects, the two paths);
/// 2. the survey: the map-building rig drives the survey path; every keyframe gives one map
///    image per camera;
/// 3. the map: every landmark seen in at least [`MIN_MAP_OBSERVATIONS`] survey images becomes
///    a map point (plus the map-point error, if any), in landmark order; survey features on
///    other landmarks, moving objects and clutter are map features with no point;
/// 4. the log: the calibrated (possibly changed) rig drives the calibration loop; every frame
///    gives one image per camera; odometry is dead-reckoned from noisy increments;
/// 5. the ground truth.
///
/// Images are rendered in parallel (rayon) and the result does not depend on the thread
/// count.
#[derive(Clone, Debug)]
pub struct SimulatedWorld {
    /// The scenario it was simulated from.
    pub scenario: Scenario,
    /// The rig that built the map: what the written camera file holds (its intrinsics are the
    /// true ones; its extrinsics are the calibration's prior configuration).
    pub map_rig: Rig,
    /// The true rig of the log, extrinsics in the vehicle frame.
    pub rig: Rig,
    /// The map (map points with the map-point error, if any).
    pub map: Map<BinaryDescriptor>,
    /// The rig log.
    pub log: RigLog<BinaryDescriptor>,
    /// The ground truth.
    pub truth: GroundTruth,
    /// The map points without error, index for index with `map.points`.
    pub true_map_points: Vec<Point3<f64>>,
    /// For every log feature (`[frame][camera][feature]`), the map point it is a noisy
    /// projection of, or `None` (a moving object, clutter, or a landmark not in the map).
    pub log_point_ids: Vec<Vec<Vec<Option<PointId>>>>,
    /// The survey's rig poses (`world_from_rig` of the map-building rig at each keyframe).
    pub survey_world_from_rig: Vec<Isometry3<f64>>,
}

/// The files [`SimulatedWorld::write`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WrittenFiles {
    /// `map.ibcmap`.
    pub map: PathBuf,
    /// `log.ibclog`.
    pub log: PathBuf,
    /// `camchain.yaml` (the map-building configuration, never the truth).
    pub cameras: PathBuf,
    /// `truth.json`.
    pub truth: PathBuf,
}

/// Summary figures of a world (see [`SimulatedWorld::stats`]).
#[derive(Clone, Debug, PartialEq)]
pub struct WorldStats {
    /// Map points.
    pub map_points: usize,
    /// Map images.
    pub map_images: usize,
    /// Mean features per map image.
    pub map_features_per_image: f64,
    /// Log frames.
    pub frames: usize,
    /// Mean features per log image.
    pub features_per_image: f64,
    /// Fraction of log features that are on map points.
    pub on_map_points: f64,
    /// Median distance from the camera to the map point of a log feature, metres.
    pub median_range_m: f64,
    /// 90th percentile of that distance, metres.
    pub p90_range_m: f64,
}

/// One rendered image: its features and the static landmark of each.
struct Rendered {
    features: ImageFeatures<BinaryDescriptor>,
    landmarks: Vec<Option<u32>>,
}

/// Renders every image of a drive: `[frame][camera]`.
/// `camera` with its focal lengths times `1 + change` (a change the model refuses, which the
/// scenario's validation rules out, leaves it as it is).
fn with_focal_change(camera: &Camera, change: f64) -> Camera {
    let mut out = camera.clone();
    let mut params = out.params().to_vec();
    for i in out.focal_length_indices() {
        params[i] *= 1.0 + change;
    }
    if out.set_params(&params).is_err() {
        return camera.clone();
    }
    out
}

/// Renders every frame of a drive. `focal_drift` (one per camera, or empty for none): the
/// relative change of each camera's focal lengths over the drive, reached linearly from 0 at
/// the first frame to its value at the last.
fn render_drive(
    env: &Environment,
    rig: &SimRig,
    poses: &Timed,
    purpose: Purpose,
    seed: u64,
    settings: &Settings,
    focal_drift: &[f64],
) -> Vec<Vec<Rendered>> {
    let last = poses.world_from_rig.len().saturating_sub(1).max(1) as f64;
    let reach = rig
        .rig
        .cameras
        .iter()
        .map(|c| c.rig_from_camera.translation.vector.norm())
        .fold(0.0, f64::max);
    let radius = settings.max_range() + reach;
    (0..poses.world_from_rig.len())
        .into_par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(candidates, obs), i| {
                let world_from_rig = &poses.world_from_rig[i];
                let centre = world_from_rig.translation.vector;
                candidates.clear();
                env.grid
                    .for_each_near(centre.x, centre.y, radius, |k| candidates.push(k));
                rig.rig
                    .cameras
                    .iter()
                    .zip(&rig.max_incidence_rad)
                    .enumerate()
                    .map(|(c, (cam, max_incidence))| {
                        let drift = focal_drift.get(c).copied().unwrap_or(0.0) * i as f64 / last;
                        let drifted = (drift != 0.0).then(|| with_focal_change(&cam.camera, drift));
                        let view = View {
                            camera: drifted.as_ref().unwrap_or(&cam.camera),
                            camera_from_world: (world_from_rig * cam.rig_from_camera).inverse(),
                            cos_max_incidence: max_incidence.cos(),
                        };
                        let mut rng = stream(seed, purpose, i as u64, c as u64);
                        let t = poses.timestamps[i];
                        render_image(env, candidates, &view, t, settings, &mut rng, obs);
                        Rendered {
                            features: ImageFeatures {
                                keypoints: obs.iter().map(|o| o.pixel).collect(),
                                descriptors: obs.iter().map(|o| o.descriptor).collect(),
                            },
                            landmarks: obs.iter().map(|o| o.landmark).collect(),
                        }
                    })
                    .collect()
            },
        )
        .collect()
}

impl SimulatedWorld {
    /// Simulates a scenario (see [`SimulatedWorld`] for the steps).
    ///
    /// # Errors
    /// [`SimError::Invalid`] for an invalid scenario, [`SimError::CameraFile`] or
    /// [`SimError::EmptyRig`] if its camera files cannot be read, [`SimError::Environment`] if the environment cannot be built.
    pub fn simulate(scenario: &Scenario) -> Result<Self, SimError> {
        scenario.validate()?;
        let map_rig = scenario.map_rig()?;
        let true_rig = scenario.true_rig()?;
        let seed = scenario.seed;
        let env = Environment::build(scenario.environment, scenario.scale, seed)?;
        let settings = Settings::new(&scenario.noise, &scenario.detection);
        let t = &scenario.trajectory;

        // The survey and the map.
        let survey_frames = scaled(
            (env.survey_path.length() / t.survey_spacing_m).round() as usize,
            scenario.scale,
            MIN_SURVEY_FRAMES,
        );
        let survey = trajectory::sample(
            &env.survey_path,
            survey_frames,
            t.speed_m_s,
            t.motion,
            1.0,
            SURVEY_START_S,
        );
        let survey_images = render_drive(
            &env,
            &map_rig,
            &survey,
            Purpose::SurveyImage,
            seed,
            &settings,
            &[],
        );
        let mut seen = vec![0u32; env.landmarks.len()];
        for image in survey_images.iter().flatten() {
            for l in image.landmarks.iter().flatten() {
                seen[*l as usize] += 1;
            }
        }
        let mut map_id: Vec<Option<PointId>> = vec![None; seen.len()];
        let mut true_map_points = Vec::new();
        for (l, count) in seen.iter().enumerate() {
            if *count >= MIN_MAP_OBSERVATIONS {
                map_id[l] = Some(true_map_points.len() as PointId);
                true_map_points.push(env.landmarks.positions[l]);
            }
        }
        let points = with_map_error(&true_map_points, scenario.noise.map_point_sigma_m, seed);
        let mut images = Vec::with_capacity(survey_images.len() * map_rig.rig.cameras.len());
        for (pose, frame) in survey.world_from_rig.iter().zip(survey_images) {
            for (cam, image) in map_rig.rig.cameras.iter().zip(frame) {
                images.push(MapImage {
                    camera_from_world: Some((pose * cam.rig_from_camera).inverse()),
                    point_ids: image
                        .landmarks
                        .iter()
                        .map(|l| l.and_then(|l| map_id[l as usize]))
                        .collect(),
                    features: image.features,
                });
            }
        }
        let map = Map { points, images };

        // The log.
        let drive = trajectory::sample(
            &env.calibration_path,
            scenario.frames(),
            t.speed_m_s,
            t.motion,
            0.0,
            0.0,
        );
        let focal_drift = scenario.focal_drift(&true_rig.rig);
        let log_images = render_drive(
            &env,
            &true_rig,
            &drive,
            Purpose::LogImage,
            seed,
            &settings,
            &focal_drift,
        );
        let odometry = odometry::simulate(
            &drive.world_from_rig,
            &true_rig.rig_from_odometry,
            scenario.odometry,
            OdometryNoise {
                translation: scenario.noise.odometry_translation,
                rotation_per_m: scenario.noise.odometry_rotation_rad_per_m,
            },
            seed,
        );
        let mut frames = Vec::with_capacity(log_images.len());
        let mut log_point_ids = Vec::with_capacity(log_images.len());
        for ((timestamp, frame), world_from_odometry) in
            drive.timestamps.iter().zip(log_images).zip(odometry)
        {
            let mut ids = Vec::with_capacity(frame.len());
            let mut features = Vec::with_capacity(frame.len());
            for image in frame {
                ids.push(
                    image
                        .landmarks
                        .iter()
                        .map(|l| l.and_then(|l| map_id[l as usize]))
                        .collect(),
                );
                features.push(image.features);
            }
            log_point_ids.push(ids);
            frames.push(Frame {
                timestamp: *timestamp,
                images: features,
                world_from_odometry,
            });
        }
        let log = RigLog {
            camera_names: true_rig
                .rig
                .cameras
                .iter()
                .map(|c| c.name.clone())
                .collect(),
            odometry: scenario.odometry,
            frames,
        };
        let truth = GroundTruth {
            scenario: scenario.name.clone(),
            seed,
            rig_from_camera: true_rig
                .rig
                .cameras
                .iter()
                .map(|c| c.rig_from_camera)
                .collect(),
            world_from_rig: drive.world_from_rig,
            rig_from_odometry: (scenario.odometry != OdometryKind::None)
                .then_some(true_rig.rig_from_odometry),
            pixel_noise_px: scenario.noise.pixel_sigma_px,
            camera_names: log.camera_names.clone(),
            intrinsics: true_rig
                .rig
                .cameras
                .iter()
                .map(|c| c.camera.params().to_vec())
                .collect(),
            focal_drift,
        };
        Ok(Self {
            scenario: scenario.clone(),
            map_rig: map_rig.rig,
            rig: true_rig.rig,
            map,
            log,
            truth,
            true_map_points,
            log_point_ids,
            survey_world_from_rig: survey.world_from_rig,
        })
    }

    /// Writes `map.ibcmap`, `log.ibclog`, `camchain.yaml` (the map-building configuration,
    /// via `ibc-camera-models`) and `truth.json` into `dir` (created if needed), all or
    /// nothing: every file is staged in a hidden folder first and renamed only when all four
    /// were written ([`StagedFiles`]).
    ///
    /// # Errors
    /// [`SimError::File`] if the folder cannot be created or a file cannot be encoded or
    /// written; no output file is left behind then.
    pub fn write(&self, dir: impl AsRef<Path>) -> Result<WrittenFiles, SimError> {
        let dir = dir.as_ref();
        let files = WrittenFiles {
            map: dir.join(file_names::MAP),
            log: dir.join(file_names::LOG),
            cameras: dir.join(file_names::CAMERAS),
            truth: dir.join(file_names::TRUTH),
        };
        let format = |path: &Path| {
            let path = path.to_owned();
            move |source| DataFileError::Format { path, source }
        };
        let map = map_to_bytes(&self.map).map_err(format(&files.map))?;
        let log = log_to_bytes(&self.log).map_err(format(&files.log))?;
        let truth = truth_to_json(&self.truth).map_err(|source| DataFileError::Json {
            path: files.truth.clone(),
            source,
        })?;
        self.map_rig.check_names()?;
        let cameras = self.map_rig.to_kalibr_string();
        let mut staged = StagedFiles::new(dir)?;
        staged.stage(&files.map, &map)?;
        staged.stage(&files.log, &log)?;
        staged.stage(&files.cameras, cameras.as_bytes())?;
        staged.stage(&files.truth, truth.as_bytes())?;
        staged.commit()?;
        Ok(files)
    }

    /// Summary figures: sizes, features per image, the share on map points, how far they are.
    pub fn stats(&self) -> WorldStats {
        let map_features: usize = self.map.images.iter().map(|i| i.features.len()).sum();
        let images: usize = self.log.frames.iter().map(|f| f.images.len()).sum();
        let features: usize = self
            .log
            .frames
            .iter()
            .flat_map(|f| f.images.iter().map(ImageFeatures::len))
            .sum();
        let mut ranges = Vec::new();
        for (ids, world_from_rig) in self.log_point_ids.iter().zip(&self.truth.world_from_rig) {
            for (ids, cam) in ids.iter().zip(&self.rig.cameras) {
                let centre = (world_from_rig * cam.rig_from_camera).translation.vector;
                for id in ids.iter().flatten() {
                    if let Some(p) = self.true_map_points.get(*id as usize) {
                        ranges.push((p.coords - centre).norm());
                    }
                }
            }
        }
        ranges.sort_by(f64::total_cmp);
        let quantile = |q: f64| {
            if ranges.is_empty() {
                0.0
            } else {
                ranges[((ranges.len() - 1) as f64 * q).round() as usize]
            }
        };
        let per = |n: usize, d: usize| if d == 0 { 0.0 } else { n as f64 / d as f64 };
        WorldStats {
            map_points: self.map.points.len(),
            map_images: self.map.images.len(),
            map_features_per_image: per(map_features, self.map.images.len()),
            frames: self.log.frames.len(),
            features_per_image: per(features, images),
            on_map_points: per(ranges.len(), features),
            median_range_m: quantile(0.5),
            p90_range_m: quantile(0.9),
        }
    }

    /// The drive's features on true map points as the observations of a rig bundle adjustment
    /// with free points ([`ibc_bundle_adjust::RigBundleAdjustment`]): every keypoint whose
    /// camera unprojects it to a ray within `max_ray_angle` (radians) of the optical axis,
    /// of the points seen at least twice. Points are numbered from 0 in order of first sight;
    /// the second vector gives each one's index into
    /// [`SimulatedWorld::true_map_points`].
    #[must_use]
    pub fn free_point_observations(
        &self,
        max_ray_angle: f64,
    ) -> (Vec<RigBaObservation>, Vec<PointId>) {
        let min_z = max_ray_angle.cos();
        let mut index: HashMap<PointId, usize> = HashMap::new();
        let mut ids = Vec::new();
        let mut observations = Vec::new();
        for (frame, (features, point_ids)) in
            self.log.frames.iter().zip(&self.log_point_ids).enumerate()
        {
            for (camera, ((image, point_ids), rig_camera)) in features
                .images
                .iter()
                .zip(point_ids)
                .zip(&self.rig.cameras)
                .enumerate()
            {
                for (&pixel, id) in image.keypoints.iter().zip(point_ids) {
                    let Some(id) = *id else { continue };
                    let Ok(ray) = rig_camera.camera.unproject(&pixel) else {
                        continue;
                    };
                    if ray.z < min_z {
                        continue;
                    }
                    let next = index.len();
                    let point = *index.entry(id).or_insert_with(|| {
                        ids.push(id);
                        next
                    });
                    observations.push(RigBaObservation {
                        frame,
                        camera,
                        point,
                        pixel,
                    });
                }
            }
        }
        let mut count = vec![0usize; ids.len()];
        for o in &observations {
            count[o.point] += 1;
        }
        let mut renumbered = vec![usize::MAX; ids.len()];
        let mut kept = Vec::new();
        for (j, &id) in ids.iter().enumerate() {
            if count[j] >= 2 {
                renumbered[j] = kept.len();
                kept.push(id);
            }
        }
        observations.retain(|o| renumbered[o.point] != usize::MAX);
        for o in &mut observations {
            o.point = renumbered[o.point];
        }
        (observations, kept)
    }
}

/// The map points with Gaussian error of `sigma` metres per axis (none when `sigma` is 0).
fn with_map_error(points: &[Point3<f64>], sigma: f64, seed: u64) -> Vec<Point3<f64>> {
    let Ok(normal) = Normal::new(0.0, sigma) else {
        return points.to_vec();
    };
    if sigma <= 0.0 {
        return points.to_vec();
    }
    let mut rng = stream(seed, Purpose::MapError, 0, 0);
    points
        .iter()
        .map(|p| {
            p + Vector3::new(
                normal.sample(&mut rng),
                normal.sample(&mut rng),
                normal.sample(&mut rng),
            )
        })
        .collect()
}

/// Simulates a scenario: [`SimulatedWorld::simulate`].
///
/// # Errors
/// As [`SimulatedWorld::simulate`].
pub fn simulate(scenario: &Scenario) -> Result<SimulatedWorld, SimError> {
    SimulatedWorld::simulate(scenario)
}

/// `ibc simulate` in one call: resolves `--scenario NAME|FILE`, overrides the seed when given,
/// simulates, and writes the four files into `dir`.
///
/// # Errors
/// As [`Scenario::resolve`], [`SimulatedWorld::simulate`] and [`SimulatedWorld::write`].
pub fn simulate_to_dir(
    scenario: &str,
    seed: Option<u64>,
    dir: impl AsRef<Path>,
) -> Result<(SimulatedWorld, WrittenFiles), SimError> {
    let mut s = Scenario::resolve(scenario)?;
    if let Some(seed) = seed {
        s.seed = seed;
    }
    let world = SimulatedWorld::simulate(&s)?;
    let files = world.write(dir)?;
    Ok((world, files))
}
