//! The data a calibration consumes and produces: the map, the rig log and the ground truth.
//!
//! Conventions (as in every ibc crate):
//! - Poses are [`Isometry3<f64>`] named `a_from_b`: `camera_from_world` maps a world point into
//!   the camera frame, `world_from_rig` is a rig pose, `world_from_odometry` an odometry pose.
//!   The world frame is the map's frame.
//! - Keypoints are pixels with pixel centres at integer coordinates (OpenCV, Kalibr, CamOdoCal).
//! - Descriptors are any [`ibc_vocab_tree::Descriptor`]; the simulator writes 256-bit binary
//!   descriptors ([`BinaryDescriptor`]).
//!
//! The file formats that store these types are documented in [`io`].

pub mod io;

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Point3, Vector2};

/// A 256-bit binary descriptor (ORB, BRIEF), compared by Hamming distance.
pub type BinaryDescriptor = [u64; 4];

/// A 64-float descriptor (SURF-64, as CamOdoCal uses), compared by Euclidean distance.
pub type FloatDescriptor = [f32; 64];

/// Index of a map point in [`Map::points`].
pub type PointId = u32;

/// The features detected in one image: keypoints and their descriptors, index for index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ImageFeatures<D> {
    /// Keypoint positions in pixels (pixel centres at integer coordinates).
    pub keypoints: Vec<Vector2<f64>>,
    /// One descriptor per keypoint.
    pub descriptors: Vec<D>,
}

impl<D> ImageFeatures<D> {
    /// Number of features.
    pub fn len(&self) -> usize {
        self.keypoints.len()
    }

    /// True when the image has no features.
    pub fn is_empty(&self) -> bool {
        self.keypoints.is_empty()
    }
}

/// One image of the map: its features, each linked to the map point it observes (if any).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapImage<D> {
    /// The pose of the camera that took the image, when the map knows it (plots use it; the
    /// calibration does not need it).
    pub camera_from_world: Option<Isometry3<f64>>,
    /// The image's features.
    pub features: ImageFeatures<D>,
    /// For each feature, the map point it observes, or `None` for a feature that is not in the
    /// map (same length as `features`).
    pub point_ids: Vec<Option<PointId>>,
}

/// The prior map of the calibration area: 3D points in the world frame and the map images
/// whose features observe them. Built once (by a survey with SLAM or SfM), then used "as a
/// giant chessboard".
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Map<D> {
    /// Map points in the world frame, metres.
    pub points: Vec<Point3<f64>>,
    /// Map images, in survey order.
    pub images: Vec<MapImage<D>>,
}

/// The kind of motion the odometry of a rig log measures, which decides the hand-eye method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OdometryKind {
    /// No odometry was logged: no hand-eye calibration.
    #[default]
    None,
    /// Planar motion of a ground vehicle (wheel odometry): Guo et al.'s planar method.
    Planar,
    /// General 6-DoF motion (pose tracker, GPS/INS): Daniilidis' dual-quaternion method.
    SixDof,
}

/// One synchronized frame of the rig: the features of every camera's image, taken at the same
/// time, and the odometry pose at that time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame<D> {
    /// Time stamp in seconds.
    pub timestamp: f64,
    /// One entry per camera, in the order of [`RigLog::camera_names`].
    pub images: Vec<ImageFeatures<D>>,
    /// The odometry pose at this frame (`world_from_odometry` in the odometry's own world
    /// frame, which need not be the map's), when odometry is logged.
    pub world_from_odometry: Option<Isometry3<f64>>,
}

/// What the rig recorded while driving through the mapped area.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RigLog<D> {
    /// Camera names, in the order of each frame's images and of the camera file.
    pub camera_names: Vec<String>,
    /// The kind of odometry in the frames.
    pub odometry: OdometryKind,
    /// The synchronized frames, in time order.
    pub frames: Vec<Frame<D>>,
}

/// The truth behind a simulated world, to score a calibration against.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundTruth {
    /// Name of the scenario that produced the world.
    pub scenario: String,
    /// The seed it was simulated with.
    pub seed: u64,
    /// True extrinsics of the calibrated rig, one per camera, in the simulator's vehicle frame.
    /// A calibration's rig frame is its first camera, so compare poses relative to camera 0.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// True rig pose at every frame of the log.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// True transform from the odometry frame into the vehicle frame, when odometry is logged.
    pub rig_from_odometry: Option<Isometry3<f64>>,
    /// Standard deviation of the keypoint noise, pixels per axis.
    pub pixel_noise_px: f64,
    /// The log's camera names, in its order (empty when the file does not say: older files).
    pub camera_names: Vec<String>,
    /// The true intrinsics of each camera during the log (CamOdoCal order, the camera file's
    /// model) at the first frame of the log; empty when the file does not say (older files).
    pub intrinsics: Vec<Vec<f64>>,
    /// Per camera, the relative change of its focal lengths over the log, linear in the frame
    /// index from 0 at the first frame (a lens warming up); empty when none drifts.
    pub focal_drift: Vec<f64>,
}

/// Why a ground truth is not the truth of a rig log.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum TruthMismatch {
    /// The truth has a rig pose per frame of another log.
    #[error(
        "the ground truth has {truth} frames but the rig log {log}: is it the truth of this \
         log?"
    )]
    Frames {
        /// Rig poses in the truth.
        truth: usize,
        /// Frames in the log.
        log: usize,
    },
    /// The truth has another number of cameras.
    #[error("the ground truth has {truth} cameras but the rig log {log}")]
    CameraCount {
        /// Cameras in the truth.
        truth: usize,
        /// Cameras in the log.
        log: usize,
    },
    /// The truth names other cameras, or the same in another order.
    #[error(
        "the ground truth names the cameras {} but the rig log {}",
        truth.join(", "),
        log.join(", ")
    )]
    CameraNames {
        /// The truth's names.
        truth: Vec<String>,
        /// The log's names.
        log: Vec<String>,
    },
}

impl GroundTruth {
    /// Checks that this is the truth of a log with these camera names and this many frames.
    ///
    /// # Errors
    /// [`TruthMismatch`] saying what differs.
    pub fn check_log(&self, camera_names: &[String], frames: usize) -> Result<(), TruthMismatch> {
        if self.rig_from_camera.len() != camera_names.len() {
            return Err(TruthMismatch::CameraCount {
                truth: self.rig_from_camera.len(),
                log: camera_names.len(),
            });
        }
        if !self.camera_names.is_empty() && self.camera_names != camera_names {
            return Err(TruthMismatch::CameraNames {
                truth: self.camera_names.clone(),
                log: camera_names.to_vec(),
            });
        }
        if self.world_from_rig.len() != frames {
            return Err(TruthMismatch::Frames {
                truth: self.world_from_rig.len(),
                log: frames,
            });
        }
        Ok(())
    }

    /// The true camera `camera` at log frame `frame`: `like`'s model with the truth's
    /// intrinsics, its focal lengths drifted as [`focal_drift`](Self::focal_drift) says;
    /// `None` when the truth holds no intrinsics for it, or they do not fit `like`'s model.
    pub fn camera_at(&self, camera: usize, frame: usize, like: &Camera) -> Option<Camera> {
        let mut params = self.intrinsics.get(camera)?.clone();
        let last = self.world_from_rig.len().saturating_sub(1).max(1) as f64;
        let drift = self.focal_drift.get(camera).copied().unwrap_or(0.0) * frame as f64 / last;
        for i in like.focal_length_indices() {
            *params.get_mut(i)? *= 1.0 + drift;
        }
        let mut out = like.clone();
        out.set_params(&params).ok()?;
        Some(out)
    }
}
