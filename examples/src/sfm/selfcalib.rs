//! Self-calibration of a rig's extrinsics from its own log, without a map (TrimBot2020 D3.1
//! §3.3.3: global structure from motion with the rig's relative poses the same at every time,
//! then bundle adjustment alternating with triangulation).
//!
//! 1. Feature tracks ([`super::build_tracks`]): candidate pairs, matching, verification by
//!    relative pose on bearings, union-find.
//! 2. The viewing graph over the images: rig-form robust rotation averaging (Chatterjee and
//!    Govindu, "Robust Relative Rotation Averaging", T-PAMI 2018) gives one `world_from_rig`
//!    rotation per frame and one `rig_from_camera` rotation per camera; rig-form translation
//!    averaging (Zhuang, Cheong and Lee, "Baseline Desensitizing in Translation Averaging",
//!    CVPR 2018) gives the rig positions and the lever arms, up to scale.
//! 3. Triangulation of every track from the averaged poses (the observations reprojecting
//!    farther than `outlier_threshold_px` left out), then the rig bundle adjustment with free
//!    points (Cauchy loss; gauge: the reference camera, the first frame, and the baseline from
//!    camera 0 to the camera farthest from it); the tracks are triangulated again from the
//!    refined poses and the adjustment repeated until the extrinsics stop changing
//!    (TrimBot's loop). After the first round whose reprojection error is within the search
//!    radius, the tracks are completed and merged by guided matching of the adjusted points
//!    ([`TrackCompletion`]): the verified pairs split a landmark into several tracks, and the
//!    merged ones link the cameras.
//! 4. Scale: the rig's trajectory against the odometry's, when the log has it: Guo, Mirzaei and
//!    Roumeliotis's planar hand-eye method with an unknown scale (ICRA 2012) on the motions over
//!    windows of 8 frames for wheel odometry; for 6-DoF odometry, Daniilidis's rotation (IJRR
//!    1999) and the scale by linear least squares (Andreff, Horaud and Espiau, IJRR 2001); else
//!    a known baseline between two cameras; else unknown, and said so.

use ibc_bundle_adjust::{
    RigBaObservation, RigBundleAdjustment, RigBundleAdjustmentOptions, RobustLoss, ScaleGauge,
    SolverOptions,
};
use ibc_camera_models::{Camera, CameraModel};
use ibc_hand_eye::{
    DaniilidisOptions, MotionPair, Pairing, PlanarOptions, daniilidis, guo_planar, relative_motions,
};
use ibc_pnp::{TriangulationOptions, triangulate};
use ibc_rig_averaging::{
    DirectionEdge, RigLayout, RigView, RotationAveragingOptions, RotationEdge, TimeDistance,
    TranslationAveragingOptions, ViewingGraphError, rig_rotation_averaging,
    rig_translation_averaging_with_distances,
};
use ibc_vocab_tree::Descriptor;
use nalgebra::{
    Isometry3, Matrix3, Matrix3x4, Matrix4, Matrix6, Point3, Translation3, Vector2, Vector3,
    Vector4,
};
use rayon::prelude::*;

use super::completion::{Completed, TrackCompletion, complete_tracks};
use super::error::SelfCalibrationError;
use super::tracks::{TrackOptions, Tracks, build_tracks_with_rig};
use crate::NonExhaustive;
use crate::calib::accuracy::relative_to_first;
use crate::data::{OdometryKind, RigLog};

/// Where the metric scale of a self-calibration comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum ScaleSource {
    /// The log's odometry if it has any, else unknown (default).
    #[default]
    Auto,
    /// The distance between the centres of cameras `a` and `b` is known.
    Baseline {
        /// The first camera.
        a: usize,
        /// The second camera.
        b: usize,
        /// Their distance, metres.
        distance_m: f64,
    },
    /// Leave the scale unknown (the extrinsics' translations are up to one common factor).
    Unknown,
}

/// Options of [`self_calibrate`].
#[derive(Clone, Debug, PartialEq)]
pub struct SelfCalibrationOptions {
    /// Feature tracks. Default [`TrackOptions::default`].
    pub tracks: TrackOptions,
    /// Rig-form rotation averaging. Default [`RotationAveragingOptions::default`].
    pub rotation_averaging: RotationAveragingOptions,
    /// Rig-form translation averaging. Default [`TranslationAveragingOptions::default`].
    pub translation_averaging: TranslationAveragingOptions,
    /// Triangulation of the tracks. Default [`TriangulationOptions::default`] (1.5 degrees of
    /// parallax at least).
    pub triangulation: TriangulationOptions,
    /// Robust loss of the bundle adjustment. Default Cauchy with a scale of 1 pixel.
    pub loss: RobustLoss,
    /// Solver of the bundle adjustment. Default the rig bundle adjustment's
    /// ([`RigBundleAdjustmentOptions::default`]: Ceres's, with the loss's curvature kept for
    /// the inliers) on two threads, as `ibc calibrate`'s refinement (a fixed split: the same
    /// result on every machine).
    pub solver: SolverOptions,
    /// An observation reprojecting farther than this from its keypoint after triangulation is
    /// left out of the next adjustment, pixels. Default 3 (six standard deviations of 0.5 px
    /// noise).
    pub outlier_threshold_px: f64,
    /// Most rounds of triangulation and adjustment. Default 5.
    pub max_rounds: usize,
    /// The loop stops when no extrinsic moved in a round by more than this fraction of its own
    /// standard deviation (rotation and translation, each on its largest axis): further rounds
    /// would change nothing the data can tell. Default 0.5: the few outliers that come and
    /// go between rounds move a well-determined extrinsic by a fraction of its standard
    /// deviation round after round (measured on the fisheye pair: 0.30 of it in rotation), so
    /// a tighter bound may never be reached; half a deviation adds at most 12 % to the error
    /// in quadrature.
    pub change_tolerance: f64,
    /// ... or, where a covariance is not available, when no extrinsic rotation moved more than
    /// this, radians (default 1e-6, 0.2 arc seconds), and no translation more than this
    /// fraction of the largest lever arm (default 1e-5).
    pub rotation_tolerance: f64,
    /// See [`SelfCalibrationOptions::rotation_tolerance`].
    pub translation_tolerance: f64,
    /// The metric scale. Default [`ScaleSource::Auto`].
    pub scale: ScaleSource,
    /// With known extrinsics held (a map being built), the relative cost change at which the
    /// adjustment of a round that is not the last stops (default 1e-4; the last round uses
    /// the solver's own `function_tolerance`). The next round re-triangulates every track and
    /// adjusts again from where this one stopped, so polishing an intermediate solution to
    /// the solver's 1e-6 only costs iterations. When the extrinsics are estimated, whose rounds
    /// are compared with their standard deviations, only the rounds before the track
    /// completion (which place the points for it) stop there.
    pub intermediate_function_tolerance: f64,
    /// Whether the translation averaging also uses the distances the odometry travelled
    /// between consecutive frames of (nearly) the same heading, and how much it trusts them
    /// (default `None`: directions only; [`super::MapOptions::default`] uses them). Directions
    /// leave the spacing of frames along a straight drive undetermined; these distances fix it
    /// and the scale. Unused when the log has no odometry.
    pub odometry_distances: Option<OdometryDistances>,
    /// Whether the tracks are completed and merged by guided matching after the first rounds
    /// ([`TrackCompletion`]; default on, with its defaults). The verified pairs split a
    /// landmark into several tracks and leave many of its observations out; the rounds after a
    /// completion adjust the longer tracks.
    pub track_completion: Option<TrackCompletion>,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for SelfCalibrationOptions {
    fn default() -> Self {
        Self {
            tracks: TrackOptions::default(),
            rotation_averaging: RotationAveragingOptions::default(),
            translation_averaging: TranslationAveragingOptions::default(),
            triangulation: TriangulationOptions::default(),
            loss: RobustLoss::Cauchy { scale: 1.0 },
            solver: SolverOptions {
                // As `ibc calibrate`'s refinement: a fixed split, the same result everywhere.
                num_threads: crate::calib::refinement::REFINEMENT_THREADS,
                ..RigBundleAdjustmentOptions::default().solver
            },
            outlier_threshold_px: 3.0,
            max_rounds: 5,
            change_tolerance: 0.5,
            rotation_tolerance: 1e-6,
            translation_tolerance: 1e-5,
            scale: ScaleSource::Auto,
            intermediate_function_tolerance: 1e-4,
            odometry_distances: None,
            track_completion: Some(TrackCompletion::default()),
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// How [`SelfCalibrationOptions::odometry_distances`] turns the odometry into distances
/// between rig positions.
///
/// Between consecutive frames whose odometry turned by `theta <= max_turn_rad`, the rig's
/// origin moved the odometry's distance `L` up to the lever arm from the odometry's origin
/// (at most `theta * lever_bound_m`), so the distance is given the standard deviation
/// `relative_sigma * L + theta * lever_bound_m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryDistances {
    /// The odometry's distance error as a fraction of the distance (default 0.01).
    pub relative_sigma: f64,
    /// The largest turn between two frames whose distance is used, radians (default 0.5
    /// degree).
    pub max_turn_rad: f64,
    /// A bound on the distance from the odometry's origin to the rig's (the reference
    /// camera), metres (default 5).
    pub lever_bound_m: f64,
}

impl Default for OdometryDistances {
    fn default() -> Self {
        Self {
            relative_sigma: 0.01,
            max_turn_rad: 0.5_f64.to_radians(),
            lever_bound_m: 5.0,
        }
    }
}

/// The distances of `options` between consecutive frames of `log` (see
/// [`OdometryDistances`]); empty without odometry.
fn odometry_distances<D: Descriptor>(
    log: &RigLog<D>,
    options: &OdometryDistances,
) -> Vec<TimeDistance> {
    let mut out = Vec::new();
    for (t, pair) in log.frames.windows(2).enumerate() {
        let (Some(a), Some(b)) = (pair[0].world_from_odometry, pair[1].world_from_odometry) else {
            continue;
        };
        let step = a.inverse() * b;
        let turn = step.rotation.angle();
        let length = step.translation.vector.norm();
        if turn <= options.max_turn_rad && length > 0.0 {
            let sigma = options.relative_sigma * length + turn * options.lever_bound_m;
            out.push(TimeDistance::new(t, t + 1, length, sigma));
        }
    }
    out
}

/// How the scale of a [`SelfCalibration`] was fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScaleEstimate {
    /// From the odometry: the factor applied to the reconstruction.
    Odometry {
        /// Metres per unit of the reconstruction before scaling.
        factor: f64,
    },
    /// From the known baseline.
    Baseline,
    /// From the rig's known extrinsics (a map built by a calibrated rig).
    KnownExtrinsics,
    /// Not known: the translations are in the unit where the averaged baselines have mean
    /// length 1 (only ratios of lengths mean anything).
    Unknown,
}

impl ScaleEstimate {
    /// The name in reports: `"odometry"`, `"baseline"`, `"known-extrinsics"` or `"unknown"`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Odometry { .. } => "odometry",
            Self::Baseline => "baseline",
            Self::KnownExtrinsics => "known-extrinsics",
            Self::Unknown => "unknown",
        }
    }
}

/// One round of triangulation and bundle adjustment.
#[derive(Clone, Debug, PartialEq)]
pub struct Round {
    /// Points triangulated.
    pub points: usize,
    /// Observations in the adjustment.
    pub observations: usize,
    /// Observations left out as outliers after triangulation.
    pub outliers: usize,
    /// Observations in the adjustment whose ray is at or beyond 90 degrees from its camera's
    /// optical axis (a fisheye's rim; unusable by a solver that divides by z).
    pub wide_observations: usize,
    /// RMS reprojection error after the adjustment, pixels.
    pub rms_px: f64,
    /// Levenberg-Marquardt iterations of the adjustment.
    pub iterations: usize,
    /// Largest change of an extrinsic rotation in the round, radians.
    pub rotation_change: f64,
    /// Largest change of an extrinsic translation in the round, in the reconstruction's unit.
    pub translation_change: f64,
    /// Observations added to tracks by the completion after the round
    /// ([`SelfCalibrationOptions::track_completion`]).
    pub completed_observations: usize,
    /// Tracks merged into another by the completion after the round.
    pub merged_tracks: usize,
}

/// Counts of the feature tracking.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct TrackStats {
    /// Images with features.
    pub images: usize,
    /// Candidate pairs matched.
    pub candidate_pairs: usize,
    /// Pairs that passed the verification.
    pub verified_pairs: usize,
    /// Verified pairs between two different cameras.
    pub cross_camera_pairs: usize,
    /// Tracks of two or more images.
    pub tracks: usize,
    /// Tracks dropped for holding two keypoints of one image.
    pub inconsistent_tracks: usize,
}

/// A rig's extrinsics from its own log ([`self_calibrate`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SelfCalibration {
    /// `rig_from_camera` of every camera; the rig frame is camera 0's, so its extrinsic is the
    /// identity. Metres when [`SelfCalibration::scale`] is known.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// The same from the averaging alone (before triangulation and adjustment), in the same
    /// unit.
    pub initial_rig_from_camera: Vec<Isometry3<f64>>,
    /// `world_from_rig` at every frame of the log; `None` for a frame the graph left out.
    pub world_from_rig: Vec<Option<Isometry3<f64>>>,
    /// The triangulated points, world frame.
    pub points: Vec<Point3<f64>>,
    /// Covariance of each extrinsic (`[rho, phi]`, right perturbation; rotation radians,
    /// translation in the result's unit), scaled by the last adjustment's a-posteriori
    /// variance factor 2 cost / (residuals - unknowns), so it is for the log's own pixel noise;
    /// `None` for camera 0 (the gauge) or when it could not be computed.
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// Why the last adjustment gave no covariance of the estimated extrinsics (for example
    /// "the covariance is undefined: the information matrix is singular", when some point or
    /// rig pose it marginalizes out is not determined); `None` when it did, or when the
    /// extrinsics were held. Without it the rounds' convergence falls back to the fixed
    /// tolerances and the result has no standard deviations.
    pub covariance_error: Option<String>,
    /// How many odometry distances the translation averaging used
    /// ([`SelfCalibrationOptions::odometry_distances`]; 0 without).
    pub odometry_distances: usize,
    /// How the scale was fixed.
    pub scale: ScaleEstimate,
    /// The rounds of triangulation and adjustment.
    pub rounds: Vec<Round>,
    /// Whether the extrinsics stopped changing within `max_rounds`.
    pub converged: bool,
    /// The feature tracking's counts.
    pub tracks: TrackStats,
}

impl SelfCalibration {
    /// Standard deviations of camera `camera`'s extrinsic: (largest rotation axis, radians;
    /// largest translation axis, the result's unit), or `None` without a covariance.
    pub fn extrinsic_std(&self, camera: usize) -> Option<(f64, f64)> {
        let c = self.extrinsic_covariance.get(camera)?.as_ref()?;
        let t = (0..3).map(|k| c[(k, k)]).fold(0.0_f64, f64::max).sqrt();
        let r = (3..6).map(|k| c[(k, k)]).fold(0.0_f64, f64::max).sqrt();
        Some((r, t))
    }
}

/// The error of each extrinsic against the truth, both relative to camera 0: (rotation
/// radians, translation metres). With `align_scale`, the estimate's translations are first
/// scaled by the least-squares factor onto the truth's (for a result of unknown scale).
pub fn extrinsic_errors(
    estimate: &[Isometry3<f64>],
    truth: &[Isometry3<f64>],
    align_scale: bool,
) -> Vec<(f64, f64)> {
    let (e, t) = (relative_to_first(estimate), relative_to_first(truth));
    let scale = if align_scale {
        let num: f64 = e
            .iter()
            .zip(&t)
            .map(|(a, b)| a.translation.vector.dot(&b.translation.vector))
            .sum();
        let den: f64 = e.iter().map(|a| a.translation.vector.norm_squared()).sum();
        if den > 0.0 { num / den } else { 1.0 }
    } else {
        1.0
    };
    e.iter()
        .zip(&t)
        .map(|(a, b)| {
            (
                a.rotation.angle_to(&b.rotation),
                (a.translation.vector * scale - b.translation.vector).norm(),
            )
        })
        .collect()
}

/// Self-calibrates the extrinsics of the rig that recorded `log` (see the module
/// documentation). `cameras` are its intrinsics, in the log's camera order; `names` name them in
/// messages.
///
/// # Errors
/// [`SelfCalibrationError`]: input and option errors; no verified pair; a camera the graph does
/// not connect to the reference camera ([`SelfCalibrationError::UndeterminedCamera`], naming
/// it); averaging, triangulation or adjustment failures; a scale the odometry cannot give.
pub fn self_calibrate<D: Descriptor>(
    log: &RigLog<D>,
    cameras: &[Camera],
    options: &SelfCalibrationOptions,
) -> Result<SelfCalibration, SelfCalibrationError> {
    reconstruct(log, cameras, None, false, options).map(|(result, _)| result)
}

/// One observation of the final reconstruction: keypoint `keypoint` of camera `camera`'s
/// image at frame `frame` observes point `point`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PointObservation {
    pub frame: usize,
    pub camera: usize,
    pub keypoint: u32,
    pub point: usize,
}

/// The reconstruction behind [`self_calibrate`] and [`super::build_map`]: with `known`
/// extrinsics (`rig_from_camera` of every camera, metres), they are held, the averaged
/// trajectory is scaled to them, and the reconstruction is metric.
pub(crate) fn reconstruct<D: Descriptor>(
    log: &RigLog<D>,
    cameras: &[Camera],
    known: Option<&[Isometry3<f64>]>,
    refine_known: bool,
    options: &SelfCalibrationOptions,
) -> Result<(SelfCalibration, Vec<PointObservation>), SelfCalibrationError> {
    // Known extrinsics held (their lever arms fix the scale), or only the start of a
    // refinement whose scale is held by the reference camera's longest known baseline.
    let held = known.is_some() && !refine_known;
    check_options(options, cameras.len())?;
    if let Some(k) = known
        && k.len() != cameras.len()
    {
        return Err(SelfCalibrationError::CameraCount {
            cameras: k.len(),
            log: cameras.len(),
        });
    }
    // Held extrinsics verify the pairs of one frame by themselves.
    let mut tracks = build_tracks_with_rig(log, cameras, known.filter(|_| held), &options.tracks)?;
    if tracks.pairs.is_empty() {
        return Err(SelfCalibrationError::NoVerifiedPairs {
            candidates: tracks.candidate_pairs,
        });
    }
    let name = |c: usize| {
        log.camera_names
            .get(c)
            .cloned()
            .unwrap_or_else(|| format!("camera {c}"))
    };
    let undetermined = |e: ViewingGraphError| match e {
        ViewingGraphError::UndeterminedCamera { camera, reason } => {
            SelfCalibrationError::UndeterminedCamera {
                camera: name(camera),
                reason: reason.to_string(),
            }
        }
        e => SelfCalibrationError::Averaging(e),
    };
    let stats = TrackStats {
        images: tracks.images.len(),
        candidate_pairs: tracks.candidate_pairs,
        verified_pairs: tracks.pairs.len(),
        cross_camera_pairs: tracks
            .pairs
            .iter()
            .filter(|p| tracks.images[p.a].camera != tracks.images[p.b].camera)
            .count(),
        tracks: tracks.tracks.len(),
        inconsistent_tracks: tracks.inconsistent_tracks,
    };
    for camera in 0..cameras.len() {
        if !tracks.images.iter().any(|i| i.camera == camera) {
            return Err(SelfCalibrationError::UndeterminedCamera {
                camera: name(camera),
                reason: "it has no features".into(),
            });
        }
    }

    // The viewing graph: views are the images of the verified pairs.
    let mut view_of = vec![None; tracks.images.len()];
    let mut views = Vec::new();
    for p in &tracks.pairs {
        for image in [p.a, p.b] {
            if view_of[image].is_none() {
                view_of[image] = Some(views.len());
                views.push(image);
            }
        }
    }
    // Views in image order (deterministic, independent of the pair order).
    views.sort_unstable();
    for (v, &image) in views.iter().enumerate() {
        view_of[image] = Some(v);
    }
    let layout = RigLayout::new(
        log.frames.len(),
        cameras.len(),
        views
            .iter()
            .map(|&i| RigView {
                time: tracks.images[i].frame,
                camera: tracks.images[i].camera,
            })
            .collect(),
    )
    .map_err(SelfCalibrationError::Averaging)?;
    let view = |image: usize| view_of[image].unwrap_or(usize::MAX);
    let rotation_edges: Vec<RotationEdge> = tracks
        .pairs
        .iter()
        .map(|p| RotationEdge::new(view(p.a), view(p.b), p.b_from_a.rotation))
        .collect();
    let rotations = rig_rotation_averaging(&layout, &rotation_edges, &options.rotation_averaging)
        .map_err(undetermined)?;
    let direction_edges: Vec<DirectionEdge> = tracks
        .pairs
        .iter()
        .filter(|p| p.has_direction)
        .filter_map(|p| {
            let (i, j) = (view(p.a), view(p.b));
            let camera_from_world_j = rotations.camera_from_world.get(j).copied().flatten()?;
            rotations.camera_from_world.get(i).copied().flatten()?;
            let t = p.b_from_a.translation.vector;
            let norm = t.norm();
            (norm > 0.0)
                .then(|| DirectionEdge::new(i, j, -(camera_from_world_j.inverse() * t) / norm))
        })
        .collect();
    let distances = match &options.odometry_distances {
        Some(o) if log.odometry != OdometryKind::None => odometry_distances(log, o),
        _ => Vec::new(),
    };
    let translations = rig_translation_averaging_with_distances(
        &layout,
        &rotations.world_from_rig,
        &direction_edges,
        &distances,
        &options.translation_averaging,
    )
    .map_err(undetermined)?;
    let mut rig_from_camera: Vec<Isometry3<f64>> = rotations
        .rig_from_camera
        .iter()
        .zip(&translations.lever_arms)
        .map(|(q, t)| Isometry3::from_parts(Translation3::from(*t), *q))
        .collect();
    let mut world_from_rig: Vec<Option<Isometry3<f64>>> = rotations
        .world_from_rig
        .iter()
        .zip(&translations.rig_positions)
        .map(|(q, t)| match (q, t) {
            (Some(q), Some(t)) => Some(Isometry3::from_parts(Translation3::from(*t), *q)),
            _ => None,
        })
        .collect();
    if let Some(known) = known {
        // The rig frame is camera 0's; the averaged trajectory is scaled onto the known lever
        // arms (least squares on their lengths).
        let first = known[0].inverse();
        let known: Vec<Isometry3<f64>> = known.iter().map(|k| first * k).collect();
        let (num, den) = rig_from_camera
            .iter()
            .zip(&known)
            .fold((0.0, 0.0), |(n, d), (a, k)| {
                let a = a.translation.vector.norm();
                (n + a * k.translation.vector.norm(), d + a * a)
            });
        if !(den > 0.0 && num > 0.0) {
            return Err(SelfCalibrationError::InvalidOption {
                option: "known extrinsics",
                reason: "the rig's cameras are all at one place: the scale is not known".into(),
            });
        }
        // Odometry distances made the averaging metric already.
        let s = if translations.distances_used > 0 {
            1.0
        } else {
            num / den
        };
        for pose in world_from_rig.iter_mut().flatten() {
            pose.translation.vector *= s;
        }
        rig_from_camera = known;
    }
    let initial = rig_from_camera.clone();

    // Triangulation and adjustment until the extrinsics stop changing.
    let lever = rig_from_camera
        .iter()
        .map(|p| p.translation.vector.norm())
        .fold(0.0_f64, f64::max)
        .max(f64::MIN_POSITIVE);
    let mut rounds = Vec::new();
    let mut converged = false;
    let mut points = Vec::new();
    let mut covariance = vec![None; cameras.len()];
    let mut covariance_error = None;
    // Each track's point from the last adjustment: the next round starts from it.
    let mut track_points: Vec<Option<Point3<f64>>> = vec![None; tracks.tracks.len()];
    let mut final_observations = Vec::new();
    let mut completions = 0;
    for round in 0..options.max_rounds {
        let last = round + 1 == options.max_rounds;
        let triangulated = triangulate_tracks(
            &tracks,
            log,
            cameras,
            (&world_from_rig, &rig_from_camera),
            &track_points,
            options,
        );
        if triangulated.points.len() < 10 {
            return Err(SelfCalibrationError::TooFewPoints {
                points: triangulated.points.len(),
            });
        }
        // Frames of the adjustment: those with a pose and an observation.
        let mut frame_of = vec![None; log.frames.len()];
        let mut frames = Vec::new();
        for o in &triangulated.observations {
            if frame_of[o.frame].is_none() {
                frame_of[o.frame] = Some(frames.len());
                frames.push(o.frame);
            }
        }
        frames.sort_unstable();
        for (k, &f) in frames.iter().enumerate() {
            frame_of[f] = Some(k);
        }
        let observations: Vec<RigBaObservation> = triangulated
            .observations
            .iter()
            .map(|o| RigBaObservation {
                frame: frame_of[o.frame].unwrap_or(0),
                camera: o.camera,
                point: o.point,
                pixel: o.pixel,
            })
            .collect();
        for camera in 0..cameras.len() {
            if !observations.iter().any(|o| o.camera == camera) {
                return Err(SelfCalibrationError::UndeterminedCamera {
                    camera: name(camera),
                    reason: "no track of it could be triangulated".into(),
                });
            }
        }
        let problem = RigBundleAdjustment {
            cameras: cameras.to_vec(),
            rig_from_camera: rig_from_camera.clone(),
            world_from_rig: frames
                .iter()
                .map(|&f| world_from_rig[f].unwrap_or_else(Isometry3::identity))
                .collect(),
            points: triangulated.points.iter().map(|p| p.coords).collect(),
            observations,
        };
        // With known extrinsics held, the round that settles the observations (below) or the
        // last one converges to the solver's tolerance; the others stop earlier.
        let settles = rounds.last().is_some_and(|previous: &Round| {
            triangulated.observations.len() <= previous.observations + previous.observations / 1000
        });
        // While a completion is due, a round only places the points for it.
        let completes = !last
            && options
                .track_completion
                .is_some_and(|completion| completions < completion.rounds);
        let mut solver = options.solver.clone();
        if (held && !last && !settles) || completes {
            solver.function_tolerance = solver
                .function_tolerance
                .max(options.intermediate_function_tolerance);
        }
        let solved = problem
            .solve(&RigBundleAdjustmentOptions {
                loss: options.loss,
                // Known extrinsics are held, and their lever arms fix the scale.
                scale: if held {
                    ScaleGauge::Free
                } else {
                    ScaleGauge::InitialBaseline
                },
                held_extrinsics: if held {
                    (0..cameras.len()).collect()
                } else {
                    Vec::new()
                },
                covariance: !held,
                solver,
                ..Default::default()
            })
            .map_err(SelfCalibrationError::BundleAdjustment)?;
        final_observations = triangulated
            .observations
            .iter()
            .map(|o| PointObservation {
                frame: o.frame,
                camera: o.camera,
                keypoint: o.keypoint,
                point: o.point,
            })
            .collect();
        // The a-posteriori variance factor 2 cost / (residuals - unknowns): the solver's
        // covariance is for unit pixel noise (as `ibc calibrate`'s refinement does).
        let residuals = 2 * triangulated.observations.len();
        let unknowns = 3 * triangulated.points.len()
            + 6 * frames.len()
            + if held { 0 } else { 6 * (cameras.len() - 1) };
        let variance = if residuals > unknowns {
            2.0 * solved.summary.final_cost / (residuals - unknowns) as f64
        } else {
            f64::NAN
        };
        covariance_error = if held {
            None
        } else if let Some(e) = &solved.covariance_error {
            Some(e.to_string())
        } else if !variance.is_finite() {
            Some(format!(
                "{residuals} residuals for {unknowns} unknowns: no noise level to scale it by"
            ))
        } else {
            None
        };
        let scaled: Vec<Option<Matrix6<f64>>> = solved
            .extrinsic_covariance
            .iter()
            .map(|c| c.filter(|_| variance.is_finite()).map(|c| c * variance))
            .collect();
        let mut rotation_change = 0.0_f64;
        let mut translation_change = 0.0_f64;
        let mut within_uncertainty = true;
        for (camera, (old, new)) in rig_from_camera
            .iter()
            .zip(&solved.rig_from_camera)
            .enumerate()
        {
            let (dr, dt) = (
                old.rotation.angle_to(&new.rotation),
                (old.translation.vector - new.translation.vector).norm(),
            );
            rotation_change = rotation_change.max(dr);
            translation_change = translation_change.max(dt);
            if camera == 0 {
                continue;
            }
            match scaled.get(camera).and_then(Option::as_ref) {
                Some(c) => {
                    let t = (0..3).map(|k| c[(k, k)]).fold(0.0_f64, f64::max).sqrt();
                    let r = (3..6).map(|k| c[(k, k)]).fold(0.0_f64, f64::max).sqrt();
                    within_uncertainty &=
                        dr <= options.change_tolerance * r && dt <= options.change_tolerance * t;
                }
                None => within_uncertainty = false,
            }
        }
        rig_from_camera.clone_from(&solved.rig_from_camera);
        for pose in world_from_rig.iter_mut() {
            *pose = None;
        }
        for (&f, pose) in frames.iter().zip(&solved.world_from_rig) {
            world_from_rig[f] = Some(*pose);
        }
        points = solved.points.iter().map(|p| Point3::from(*p)).collect();
        track_points.fill(None);
        for (&track, point) in triangulated.tracks.iter().zip(&points) {
            track_points[track] = Some(*point);
        }
        covariance = scaled;
        // The projections are only as good as the adjustment: the completion waits for a
        // round whose RMS reprojection error is within its search radius.
        let completed = match &options.track_completion {
            Some(completion) if completes && solved.final_rms <= completion.radius_px => {
                completions += 1;
                complete_tracks(
                    &mut tracks,
                    &mut track_points,
                    log,
                    cameras,
                    (&world_from_rig, &rig_from_camera),
                    completion,
                    options.outlier_threshold_px,
                )
            }
            _ => Completed::default(),
        };
        rounds.push(Round {
            points: points.len(),
            observations: triangulated.observations.len(),
            outliers: triangulated.outliers,
            wide_observations: triangulated.observations.iter().filter(|o| o.wide).count(),
            rms_px: solved.final_rms,
            iterations: solved.summary.iterations,
            rotation_change,
            translation_change,
            completed_observations: completed.extended,
            merged_tracks: completed.merged,
        });
        // With known extrinsics nothing moves them: the rounds stop when the observations
        // admitted settle (fewer than 0.1 % more). Completed tracks are adjusted first.
        if completed != Completed::default() {
            continue;
        }
        if (held && settles)
            || (!held && within_uncertainty)
            || (!held
                && rotation_change <= options.rotation_tolerance
                && translation_change <= options.translation_tolerance * lever)
        {
            converged = true;
            break;
        }
        if last {
            break;
        }
    }

    // Scale.
    let (factor, scale) = match options.scale {
        _ if known.is_some() => (1.0, ScaleEstimate::KnownExtrinsics),
        ScaleSource::Baseline { a, b, distance_m } => {
            let d = (rig_from_camera[a].translation.vector - rig_from_camera[b].translation.vector)
                .norm();
            if d <= 0.0 {
                return Err(SelfCalibrationError::InvalidOption {
                    option: "scale",
                    reason: format!(
                        "cameras `{}` and `{}` came out at the same place",
                        name(a),
                        name(b)
                    ),
                });
            }
            (distance_m / d, ScaleEstimate::Baseline)
        }
        ScaleSource::Auto if log.odometry != OdometryKind::None => {
            let factor = odometry_scale(log, &world_from_rig)?;
            (factor, ScaleEstimate::Odometry { factor })
        }
        ScaleSource::Auto | ScaleSource::Unknown => (1.0, ScaleEstimate::Unknown),
    };
    let scaled = |p: &Isometry3<f64>| {
        Isometry3::from_parts(
            Translation3::from(p.translation.vector * factor),
            p.rotation,
        )
    };
    let extrinsic_covariance = covariance
        .into_iter()
        .map(|c| {
            c.map(|mut c: Matrix6<f64>| {
                for i in 0..6 {
                    for j in 0..6 {
                        c[(i, j)] *=
                            if i < 3 { factor } else { 1.0 } * if j < 3 { factor } else { 1.0 };
                    }
                }
                c
            })
        })
        .collect();
    Ok((
        SelfCalibration {
            rig_from_camera: rig_from_camera.iter().map(scaled).collect(),
            // The first round held the averaging's baseline (the gauge), so its unit is the
            // adjusted one.
            initial_rig_from_camera: initial.iter().map(scaled).collect(),
            world_from_rig: world_from_rig
                .iter()
                .map(|p| p.as_ref().map(scaled))
                .collect(),
            points: points
                .iter()
                .map(|p| Point3::from(p.coords * factor))
                .collect(),
            extrinsic_covariance,
            covariance_error,
            odometry_distances: translations.distances_used,
            scale,
            rounds,
            converged,
            tracks: stats,
        },
        final_observations,
    ))
}

fn check_options(
    options: &SelfCalibrationOptions,
    cameras: usize,
) -> Result<(), SelfCalibrationError> {
    let invalid =
        |option, reason: String| Err(SelfCalibrationError::InvalidOption { option, reason });
    if !(options.outlier_threshold_px > 0.0 && options.outlier_threshold_px.is_finite()) {
        return invalid(
            "outlier_threshold_px",
            format!(
                "must be finite and positive, got {}",
                options.outlier_threshold_px
            ),
        );
    }
    if !(options.change_tolerance >= 0.0 && options.change_tolerance.is_finite()) {
        return invalid(
            "change_tolerance",
            format!(
                "must be finite and non-negative, got {}",
                options.change_tolerance
            ),
        );
    }
    if !(options.intermediate_function_tolerance >= 0.0
        && options.intermediate_function_tolerance < 1.0)
    {
        return invalid(
            "intermediate_function_tolerance",
            format!(
                "must be in [0, 1), got {}",
                options.intermediate_function_tolerance
            ),
        );
    }
    if options.max_rounds == 0 {
        return invalid("max_rounds", "must be at least 1".into());
    }
    if let Some(o) = &options.odometry_distances {
        if !(o.relative_sigma.is_finite() && o.relative_sigma > 0.0) {
            return invalid(
                "odometry_distances.relative_sigma",
                format!("must be finite and positive, got {}", o.relative_sigma),
            );
        }
        let checks = [
            ("odometry_distances.max_turn_rad", o.max_turn_rad),
            ("odometry_distances.lever_bound_m", o.lever_bound_m),
        ];
        for (option, value) in checks {
            if !(value.is_finite() && value >= 0.0) {
                return invalid(
                    option,
                    format!("must be finite and not negative, got {value}"),
                );
            }
        }
    }
    if let Some(c) = &options.track_completion {
        if !(c.radius_px.is_finite() && c.radius_px > 0.0) {
            return invalid(
                "track_completion.radius_px",
                format!("must be finite and positive, got {}", c.radius_px),
            );
        }
        if !(c.ratio > 0.0 && c.ratio <= 1.0) {
            return invalid(
                "track_completion.ratio",
                format!("must be in (0, 1], got {}", c.ratio),
            );
        }
        if !(c.max_descriptor_fraction > 0.0 && c.max_descriptor_fraction <= 1.0) {
            return invalid(
                "track_completion.max_descriptor_fraction",
                format!("must be in (0, 1], got {}", c.max_descriptor_fraction),
            );
        }
    }
    if let ScaleSource::Baseline { a, b, distance_m } = options.scale
        && (a >= cameras || b >= cameras || a == b || !(distance_m > 0.0 && distance_m.is_finite()))
    {
        return invalid(
            "scale",
            format!(
                "a baseline needs two different cameras of {cameras} and a finite positive \
                 distance, got {a}, {b}, {distance_m} m"
            ),
        );
    }
    options
        .triangulation
        .validate()
        .map_err(|e| SelfCalibrationError::InvalidOption {
            option: "triangulation",
            reason: e.to_string(),
        })
}

/// One observation of a triangulated point.
struct TrackObservation {
    frame: usize,
    keypoint: u32,
    camera: usize,
    point: usize,
    pixel: Vector2<f64>,
    /// The ray is at or beyond 90 degrees from the optical axis (bearing z <= 0).
    wide: bool,
}

/// One observation of a track with its camera's pose.
struct Ray {
    keypoint: u32,
    camera: usize,
    frame: usize,
    camera_from_world: Isometry3<f64>,
    bearing: Vector3<f64>,
    pixel: Vector2<f64>,
}

/// A triangulated track: its point, the observations kept, and how many were left out.
struct TrackPoint {
    point: Point3<f64>,
    rays: Vec<Ray>,
    outliers: usize,
}

struct Triangulated {
    points: Vec<Point3<f64>>,
    /// The track of each point.
    tracks: Vec<usize>,
    observations: Vec<TrackObservation>,
    outliers: usize,
}

/// Triangulates every track from the current poses (a track adjusted in the last round keeps
/// its adjusted point); observations reprojecting farther than the threshold are left out, and
/// the point triangulated again without them.
fn triangulate_tracks<D: Descriptor>(
    tracks: &Tracks,
    log: &RigLog<D>,
    cameras: &[Camera],
    (world_from_rig, rig_from_camera): (&[Option<Isometry3<f64>>], &[Isometry3<f64>]),
    previous: &[Option<Point3<f64>>],
    options: &SelfCalibrationOptions,
) -> Triangulated {
    let solved: Vec<Option<TrackPoint>> = tracks
        .tracks
        .par_iter()
        .zip(previous)
        .map(|(track, previous)| {
            let mut obs: Vec<Ray> = Vec::with_capacity(track.observations.len());
            for &(image, k) in &track.observations {
                let id = tracks.images[image];
                let Some(pose) = world_from_rig.get(id.frame).copied().flatten() else {
                    continue;
                };
                let Some(Some(bearing)) = tracks.bearings[image].get(k as usize) else {
                    continue;
                };
                let Some(pixel) = log.frames[id.frame].images[id.camera]
                    .keypoints
                    .get(k as usize)
                else {
                    continue;
                };
                let camera_from_world = (pose * rig_from_camera[id.camera]).inverse();
                obs.push(Ray {
                    keypoint: k,
                    camera: id.camera,
                    frame: id.frame,
                    camera_from_world,
                    bearing: *bearing,
                    pixel: *pixel,
                });
            }
            let mut outliers = 0;
            for attempt in 0..2 {
                if obs.len() < 2 {
                    return None;
                }
                let point = match previous {
                    Some(p) if attempt == 0 => *p,
                    _ => {
                        let poses: Vec<Isometry3<f64>> =
                            obs.iter().map(|o| o.camera_from_world).collect();
                        let bearings: Vec<Vector3<f64>> = obs.iter().map(|o| o.bearing).collect();
                        triangulate(&poses, &bearings, &options.triangulation)
                            .ok()?
                            .point
                    }
                };
                let before = obs.len();
                obs.retain(|o| {
                    cameras[o.camera]
                        .project(&(o.camera_from_world * point).coords)
                        .is_ok_and(|p| (p - o.pixel).norm() <= options.outlier_threshold_px)
                });
                outliers += before - obs.len();
                if obs.len() == before {
                    return Some(TrackPoint {
                        point,
                        rays: obs,
                        outliers,
                    });
                }
            }
            None
        })
        .collect();
    let mut points = Vec::new();
    let mut point_tracks = Vec::new();
    let mut observations = Vec::new();
    let mut outliers = 0;
    for (track, solved) in solved
        .into_iter()
        .enumerate()
        .filter_map(|(t, s)| Some((t, s?)))
    {
        if solved.rays.len() < 2 {
            continue;
        }
        outliers += solved.outliers;
        let index = points.len();
        points.push(solved.point);
        point_tracks.push(track);
        for ray in solved.rays {
            observations.push(TrackObservation {
                frame: ray.frame,
                keypoint: ray.keypoint,
                camera: ray.camera,
                point: index,
                pixel: ray.pixel,
                wide: ray.bearing.z <= 0.0,
            });
        }
    }
    Triangulated {
        points,
        tracks: point_tracks,
        observations,
        outliers,
    }
}

/// Metres per unit of the reconstruction, from the rig's trajectory against the odometry (see
/// the module documentation).
fn odometry_scale<D: Descriptor>(
    log: &RigLog<D>,
    world_from_rig: &[Option<Isometry3<f64>>],
) -> Result<f64, SelfCalibrationError> {
    let (mut rig, mut odometry) = (Vec::new(), Vec::new());
    for (frame, pose) in log.frames.iter().zip(world_from_rig) {
        if let (Some(p), Some(o)) = (pose, frame.world_from_odometry) {
            rig.push(*p);
            odometry.push(o);
        }
    }
    let pairs = relative_motions(&rig, &odometry, Pairing::Window { size: 8 })
        .map_err(SelfCalibrationError::Scale)?;
    if log.odometry == OdometryKind::Planar {
        // Guo et al.'s windowed estimate: relative motions keep the odometry's per-step
        // accuracy, where a fit on the absolute trajectories inherits its drift (measured on the
        // garage: 0.04 % against 0.11 %).
        let s = guo_planar(
            &pairs,
            &PlanarOptions {
                estimate_scale: true,
                ..Default::default()
            },
        )
        .map_err(SelfCalibrationError::Scale)?;
        return Ok(s.scale);
    }
    // 6-DoF: the rotation of X from Daniilidis on the motions scaled by the ratio of path
    // lengths (the rotation does not depend on the scale), then the scale and the translation of
    // X by linear least squares on `(R_A - I) t_X + s t_A = R_X t_B` (Andreff, Horaud and
    // Espiau, "Robot Hand-Eye Calibration Using Structure-from-Motion", IJRR 2001).
    let (a, b): (f64, f64) = pairs.iter().fold((0.0, 0.0), |(a, b), p| {
        (
            a + p.a.translation.vector.norm(),
            b + p.b.translation.vector.norm(),
        )
    });
    let s0 = if a > 0.0 { b / a } else { 1.0 };
    let scaled: Vec<MotionPair> = pairs
        .iter()
        .map(|p| {
            MotionPair::new(
                Isometry3::from_parts(
                    Translation3::from(p.a.translation.vector * s0),
                    p.a.rotation,
                ),
                p.b,
            )
        })
        .collect();
    let x =
        daniilidis(&scaled, &DaniilidisOptions::default()).map_err(SelfCalibrationError::Scale)?;
    let rotation = x.a_from_b.rotation.to_rotation_matrix();
    let mut normal = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    for p in &pairs {
        let r_a = p.a.rotation.to_rotation_matrix().into_inner();
        let mut row = Matrix3x4::<f64>::zeros();
        row.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(r_a - Matrix3::identity()));
        row.fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&p.a.translation.vector);
        normal += row.transpose() * row;
        rhs += row.transpose() * (rotation * p.b.translation.vector);
    }
    let solution = normal
        .cholesky()
        .map(|c| c.solve(&rhs))
        .ok_or(SelfCalibrationError::ScaleUndetermined)?;
    if !(solution[3] > 0.0 && solution[3].is_finite()) {
        return Err(SelfCalibrationError::ScaleUndetermined);
    }
    Ok(solution[3])
}
