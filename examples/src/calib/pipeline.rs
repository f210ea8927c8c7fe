//! The whole calibration: [`calibrate`] runs the stages in order and gathers what the reports
//! need into a [`Calibration`].

use std::sync::Arc;
use std::time::Instant;

use ibc_bundle_adjust::IntrinsicsSelection;
use ibc_camera_models::{Camera, CameraModel, Rig};
use ibc_vocab_tree::{Descriptor, Vocabulary};
use nalgebra::{Isometry3, Vector2};

use super::accuracy::{
    CameraAccuracy, HandEyeAccuracy, IntrinsicsAccuracy, camera_accuracy, hand_eye_accuracy,
    true_rig_from_odometry,
};
use super::camera_matching::{CameraMatching, match_cameras};
use super::error::CalibrationError;
use super::frame_sets::{FrameSet, select_frame_sets};
use super::hand_eye::{HandEye, HandEyeFailure, HandEyeSolver, calibrate_hand_eye, choose_solver};
use super::initialization::{Initialization, initialize};
use super::localization::{
    Correspondence, ImageLocalization, LocalizationFailure, Localizations, localize_log,
};
use super::map_index::MapIndex;
use super::options::{CalibrationOptions, evenly_spaced};
use super::progress::{NoProgress, Progress, Stage};
use super::quality::{Quality, RefinementFacts, assess};
use super::refinement::{
    IntrinsicsStart, Refinement, RigObservation, refine_from, reprojection_error,
    reprojection_residuals,
};
use crate::data::{GroundTruth, Map, OdometryKind, RigLog};

/// Wall-clock seconds per stage (not deterministic: leave them out of comparisons).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timing {
    /// Training (or taking) the vocabulary and indexing the map.
    pub vocabulary: f64,
    /// Localizing every image.
    pub localization: f64,
    /// Frame-set selection and initialization.
    pub initialization: f64,
    /// Refinement.
    pub refinement: f64,
    /// Hand-eye calibration.
    pub hand_eye: f64,
    /// Everything.
    pub total: f64,
}

/// The result of [`calibrate`]: the estimate and everything the reports show about how it
/// was reached.
#[derive(Clone, Debug)]
pub struct Calibration {
    /// Camera names, from the rig log.
    pub camera_names: Vec<String>,
    /// The cameras' intrinsics: the camera file's, or the refined ones where the refinement
    /// refined them ([`RefinementOptions::intrinsics`](super::RefinementOptions)); the camera
    /// file's stay in [`prior_rig`](Self::prior_rig).
    pub cameras: Vec<Camera>,
    /// The camera file's cameras in the log's order (see [`super::camera_matching`]); their
    /// extrinsics are the configuration before the calibration, in the file's rig frame.
    pub prior_rig: Rig,
    /// How the camera file's cameras were matched to the log's.
    pub camera_matching: CameraMatching,
    /// The estimated extrinsics `rig_from_camera`; the rig frame is camera 0's.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// The kind of odometry in the log.
    pub odometry: OdometryKind,
    /// Every image's localization, `[frame][camera]`.
    pub localizations: Localizations,
    /// The kept frame sets.
    pub frame_sets: Vec<FrameSet>,
    /// The initialization.
    pub initialization: Initialization,
    /// The refinement (its rig poses are those of [`frame_sets`](Self::frame_sets)).
    pub refinement: Refinement,
    /// The refinement's observations.
    pub observations: Vec<RigObservation>,
    /// Reprojection error of each observation at the initial estimate, pixels (NaN where it
    /// cannot be projected).
    pub initial_errors_px: Vec<f64>,
    /// The same at the refined estimate.
    pub final_errors_px: Vec<f64>,
    /// Per-camera residual figures and the warnings of the quality gates
    /// ([`super::quality`]).
    pub quality: Quality,
    /// The hand-eye method used, `None` when no hand-eye calibration was asked for (no
    /// odometry, or skipped).
    pub hand_eye_solver: Option<HandEyeSolver>,
    /// The hand-eye calibration: `None` when not asked for.
    pub hand_eye: Option<Result<HandEye, HandEyeFailure>>,
    /// Seconds per stage.
    pub timing: Timing,
}

/// The errors of a calibration against ground truth (see [`super::accuracy`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Accuracy {
    /// Per camera, relative to camera 0 (`None` for camera 0).
    pub cameras: Vec<Option<CameraAccuracy>>,
    /// The hand-eye errors, when both a result and a true `rig_from_odometry` exist.
    pub hand_eye: Option<HandEyeAccuracy>,
    /// Per camera, the errors of its intrinsics (`None` when the truth does not hold them).
    pub intrinsics: Vec<Option<IntrinsicsAccuracy>>,
    /// Mean reprojection error of the refinement's observations at the true poses, pixels:
    /// what the pixel noise alone (and any map error) gives.
    pub reprojection_error_at_truth_px: f64,
}

/// Mean of the finite values (NaN when there is none).
pub fn finite_mean(values: &[f64]) -> f64 {
    let (sum, n) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

impl Calibration {
    /// The extrinsics the camera file held, in the log's camera order and the file's rig frame.
    pub fn prior_rig_from_camera(&self) -> Vec<Isometry3<f64>> {
        self.prior_rig
            .cameras
            .iter()
            .map(|c| c.rig_from_camera)
            .collect()
    }

    /// Number of frame sets used.
    pub fn frame_sets_used(&self) -> usize {
        self.frame_sets.len()
    }

    /// Mean number of localized cameras per frame set (the paper's "poses per set").
    pub fn mean_poses_per_set(&self) -> f64 {
        let n = self.frame_sets.len().max(1) as f64;
        self.frame_sets
            .iter()
            .map(FrameSet::localized)
            .sum::<usize>() as f64
            / n
    }

    /// Number of 2D-3D correspondences in the refinement.
    pub fn correspondences(&self) -> usize {
        self.observations.len()
    }

    /// Mean reprojection error before refinement, pixels.
    pub fn initial_error_px(&self) -> f64 {
        finite_mean(&self.initial_errors_px)
    }

    /// Mean reprojection error after refinement, pixels.
    pub fn final_error_px(&self) -> f64 {
        finite_mean(&self.final_errors_px)
    }

    /// The refined rig poses with the log frame each belongs to.
    pub fn rig_trajectory(&self) -> impl Iterator<Item = (usize, &Isometry3<f64>)> {
        self.frame_sets
            .iter()
            .map(|s| s.frame)
            .zip(&self.refinement.world_from_rig)
    }

    /// The errors against ground truth.
    ///
    /// # Errors
    /// [`CalibrationError::Truth`] when the truth is not the truth of the calibrated log
    /// (another number of frames, or other cameras).
    pub fn accuracy(&self, truth: &GroundTruth) -> Result<Accuracy, CalibrationError> {
        truth.check_log(&self.camera_names, self.localizations.images.len())?;
        let cameras = camera_accuracy(&self.rig_from_camera, &truth.rig_from_camera)?;
        let hand_eye = match (&self.hand_eye, true_rig_from_odometry(truth)) {
            (Some(Ok(h)), Some(t)) => Some(hand_eye_accuracy(h, &t)),
            _ => None,
        };
        let mut errors = Vec::with_capacity(self.observations.len());
        for o in &self.observations {
            let frame = self.frame_sets[o.set as usize].frame;
            let c = o.camera as usize;
            errors.push(
                reprojection_error(
                    &self.cameras[c],
                    &truth.rig_from_camera[c],
                    &truth.world_from_rig[frame],
                    o,
                )
                .unwrap_or(f64::NAN),
            );
        }
        let intrinsics = self
            .cameras
            .iter()
            .enumerate()
            .map(|(c, camera)| {
                truth
                    .intrinsics
                    .get(c)
                    .and_then(|t| IntrinsicsAccuracy::of(camera, t))
            })
            .collect();
        Ok(Accuracy {
            cameras,
            hand_eye,
            intrinsics,
            reprojection_error_at_truth_px: finite_mean(&errors),
        })
    }
}

/// Runs the whole calibration with the default progress (none) and a vocabulary trained on
/// the map: [`calibrate_with`] with `None` and [`NoProgress`].
///
/// # Errors
/// As [`calibrate_with`].
pub fn calibrate<D: Descriptor>(
    map: &Map<D>,
    log: &RigLog<D>,
    rig: &Rig,
    options: &CalibrationOptions,
) -> Result<Calibration, CalibrationError> {
    calibrate_with(map, log, rig, options, None, &NoProgress)
}

/// Checks the inputs' sizes before any work.
fn check_inputs<D>(map: &Map<D>, log: &RigLog<D>, rig: &Rig) -> Result<(), CalibrationError> {
    let k = rig.cameras.len();
    if k < 2 {
        return Err(CalibrationError::TooFewCameras { cameras: k });
    }
    if log.frames.is_empty() {
        return Err(CalibrationError::EmptyLog);
    }
    if map.points.is_empty() {
        return Err(CalibrationError::EmptyMap {
            what: "no map point",
        });
    }
    for (i, image) in map.images.iter().enumerate() {
        let f = &image.features;
        if f.keypoints.len() != f.descriptors.len() || image.point_ids.len() != f.len() {
            return Err(CalibrationError::InvalidInput(format!(
                "map image {i} has {} keypoints, {} descriptors and {} point ids",
                f.keypoints.len(),
                f.descriptors.len(),
                image.point_ids.len()
            )));
        }
    }
    for (i, frame) in log.frames.iter().enumerate() {
        if frame.images.len() != k {
            return Err(CalibrationError::InvalidInput(format!(
                "frame {i} of the log has {} images for {k} cameras",
                frame.images.len()
            )));
        }
        if let Some(c) = frame
            .images
            .iter()
            .position(|f| f.keypoints.len() != f.descriptors.len())
        {
            return Err(CalibrationError::InvalidInput(format!(
                "frame {i}, camera {c}: keypoints and descriptors differ in number"
            )));
        }
    }
    Ok(())
}

/// The refinement's observations: for every frame set and localized camera, at most
/// `per_image` of its inliers, evenly spaced. With `reselect` (the cameras, extrinsics, rig
/// poses of an estimate, and an error bound in pixels), the inliers are chosen again among
/// every correspondence of the image: those whose reprojection error under that estimate is
/// within the bound.
fn observations<D>(
    sets: &[FrameSet],
    localizations: &Localizations,
    map: &Map<D>,
    log: &RigLog<D>,
    per_image: usize,
    reselect: Option<(&Refinement, f64)>,
) -> Vec<RigObservation> {
    let mut out = Vec::new();
    for (s, set) in sets.iter().enumerate() {
        for c in 0..set.camera_from_world.len() {
            let Some(image) = localizations.get(set.frame, c) else {
                continue;
            };
            let keypoints = &log.frames[set.frame].images[c].keypoints;
            let observation = |corr: &Correspondence| {
                let point = map.points.get(corr.point as usize)?;
                let pixel = keypoints.get(corr.feature as usize)?;
                Some(RigObservation {
                    set: s as u32,
                    camera: c as u32,
                    point: *point,
                    pixel: *pixel,
                })
            };
            let inliers: Vec<RigObservation> = match reselect {
                None => image.inliers.iter().filter_map(observation).collect(),
                Some((estimate, bound_px)) => {
                    let (Some(camera), Some(e), Some(w)) = (
                        estimate.cameras.get(c),
                        estimate.rig_from_camera.get(c),
                        estimate.world_from_rig.get(s),
                    ) else {
                        continue;
                    };
                    image
                        .correspondences
                        .iter()
                        .filter_map(observation)
                        .filter(|o| {
                            reprojection_error(camera, e, w, o).is_some_and(|r| r <= bound_px)
                        })
                        .collect()
                }
            };
            out.extend(
                evenly_spaced(inliers.len(), per_image)
                    .into_iter()
                    .map(|i| inliers[i]),
            );
        }
    }
    out
}

/// The lengths of residuals (NaN stays NaN).
fn lengths(residuals: &[Vector2<f64>]) -> Vec<f64> {
    residuals.iter().map(Vector2::norm).collect()
}

/// An error naming the first camera localized in none of its images, with the most frequent
/// reason.
fn check_every_camera_localized(
    localizations: &Localizations,
    names: &[String],
) -> Result<(), CalibrationError> {
    for (c, name) in names.iter().enumerate() {
        let results: Vec<&ImageLocalization> = localizations
            .images
            .iter()
            .filter_map(|f| f.get(c))
            .collect();
        if results.iter().any(|r| r.is_ok()) {
            continue;
        }
        // The most frequent kind of failure, shown by an instance.
        let failures: Vec<&LocalizationFailure> =
            results.iter().filter_map(|r| r.as_ref().err()).collect();
        let kind_count = |f: &LocalizationFailure| {
            let kind = std::mem::discriminant(f);
            failures
                .iter()
                .filter(|g| std::mem::discriminant(**g) == kind)
                .count()
        };
        let reason = failures
            .iter()
            .max_by_key(|f| kind_count(f))
            .map_or_else(String::new, |f| {
                format!("{f}, in {} of {} images", kind_count(f), results.len())
            });
        return Err(CalibrationError::CameraNotLocalized {
            camera: name.clone(),
            images: results.len(),
            reason,
        });
    }
    Ok(())
}

/// Images, localized images and localization inliers of every camera.
fn localization_counts(
    localizations: &Localizations,
    cameras: usize,
) -> Vec<(usize, usize, usize)> {
    (0..cameras)
        .map(|c| {
            let mut counts = (0, 0, 0);
            for frame in &localizations.images {
                if let Some(image) = frame.get(c) {
                    counts.0 += 1;
                    if let Ok(l) = image {
                        counts.1 += 1;
                        counts.2 += l.inliers.len();
                    }
                }
            }
            counts
        })
        .collect()
}

/// Runs the whole calibration: the map index (the given vocabulary, or one trained on the
/// map), localization, frame sets, initialization, refinement and, when the log has odometry
/// and the options ask for it, hand-eye calibration. The cameras of `rig` are matched to the
/// log's by name (by order when the file carries no names: see [`super::camera_matching`]);
/// their intrinsics are used as they are, their extrinsics only reported as the prior
/// configuration.
///
/// # Errors
/// [`CalibrationError::InvalidOption`], [`CalibrationError::CameraCountMismatch`],
/// [`CalibrationError::CameraNamesMismatch`],
/// [`CalibrationError::TooFewCameras`], [`CalibrationError::EmptyLog`],
/// [`CalibrationError::EmptyMap`], [`CalibrationError::InvalidInput`] for bad input;
/// [`CalibrationError::Vocabulary`]; [`CalibrationError::NothingLocalized`] and
/// [`CalibrationError::NoCompleteFrameSet`] when the log does not fit the map;
/// [`CalibrationError::Initialization`] and [`CalibrationError::Refinement`] when a solver
/// fails. A failed hand-eye calibration is not an error: it is reported in
/// [`Calibration::hand_eye`].
pub fn calibrate_with<D: Descriptor>(
    map: &Map<D>,
    log: &RigLog<D>,
    rig: &Rig,
    options: &CalibrationOptions,
    vocabulary: Option<Arc<Vocabulary<D>>>,
    progress: &dyn Progress,
) -> Result<Calibration, CalibrationError> {
    let start = Instant::now();
    options.validate()?;
    let (rig, camera_matching) = match_cameras(rig, &log.camera_names)?;
    check_inputs(map, log, &rig)?;
    let cameras: Vec<Camera> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let mut timing = Timing::default();

    progress.start(Stage::Vocabulary, 0);
    let t = Instant::now();
    let index = match vocabulary {
        Some(v) => MapIndex::build(map, v, options.vocabulary.direct_index_levels)?,
        None => MapIndex::train(map, &options.vocabulary)?,
    };
    timing.vocabulary = t.elapsed().as_secs_f64();
    progress.finish(Stage::Vocabulary);

    progress.start(
        Stage::Localization,
        (log.frames.len() * cameras.len()) as u64,
    );
    let t = Instant::now();
    let localizations = localize_log(&index, map, &cameras, log, &options.localization, progress)?;
    drop(index);
    timing.localization = t.elapsed().as_secs_f64();
    progress.finish(Stage::Localization);
    let (localized, images) = (localizations.localized_count(), localizations.image_count());
    if localized == 0 {
        return Err(CalibrationError::NothingLocalized { images });
    }
    check_every_camera_localized(&localizations, &log.camera_names)?;

    progress.start(Stage::Initialization, 0);
    let t = Instant::now();
    let frame_sets = select_frame_sets(&localizations, &options.frame_sets);
    if frame_sets.is_empty() {
        return Err(CalibrationError::NoCompleteFrameSet {
            reason: format!(
                "no frame has {} or more localized cameras",
                options.frame_sets.min_cameras
            ),
            localized,
            images,
        });
    }
    let initialization = initialize(
        &frame_sets,
        &localizations,
        map,
        log,
        &cameras,
        &options.initialization,
    )?;
    timing.initialization = t.elapsed().as_secs_f64();
    progress.finish(Stage::Initialization);

    progress.start(Stage::Refinement, 0);
    let t = Instant::now();
    let per_image = options.refinement.max_observations_per_image;
    let refine_intrinsics = options.refinement.intrinsics != IntrinsicsSelection::None;
    // With intrinsics, the first pass only chooses the second's correspondences: a quarter
    // of them do (the bound it chooses them by is 2 px; its estimate is within hundredths).
    let first_per_image = if refine_intrinsics {
        (per_image / 4).max(10)
    } else {
        per_image
    };
    let mut observations =
        observations(&frame_sets, &localizations, map, log, first_per_image, None);
    let mut refinement = refine_from(
        &IntrinsicsStart {
            prior: &cameras,
            start: &cameras,
            held: &[],
            // With intrinsics, this pass only chooses the next one's correspondences.
            final_pass: !refine_intrinsics,
        },
        &initialization.rig_from_camera,
        &initialization.world_from_rig,
        &observations,
        &options.refinement,
    )?;
    if refine_intrinsics {
        // The inliers were chosen under the camera file's intrinsics: where those are off,
        // the choice keeps the noise that agrees with them and biases the refined intrinsics
        // towards them (by 15 standard deviations on the garage with every focal length 1 %
        // long). Chosen again under the refined estimate, with the localization's bound, and
        // refined again from there, the parameters the first pass found undetermined held at
        // the camera file's values.
        let bound_px = options.localization.pose.max_error_px;
        observations = self::observations(
            &frame_sets,
            &localizations,
            map,
            log,
            per_image,
            Some((&refinement, bound_px)),
        );
        let held: Vec<(usize, usize, f64)> = refinement
            .intrinsics
            .iter()
            .enumerate()
            .flat_map(|(c, i)| i.held.iter().map(move |h| (c, h.index, h.observability)))
            .collect();
        refinement = refine_from(
            &IntrinsicsStart {
                prior: &cameras,
                start: &refinement.cameras,
                held: &held,
                final_pass: true,
            },
            &refinement.rig_from_camera,
            &refinement.world_from_rig,
            &observations,
            &options.refinement,
        )?;
    }
    let initial_residuals = reprojection_residuals(
        &cameras,
        &initialization.rig_from_camera,
        &initialization.world_from_rig,
        &observations,
    );
    let final_residuals = reprojection_residuals(
        &refinement.cameras,
        &refinement.rig_from_camera,
        &refinement.world_from_rig,
        &observations,
    );
    let prior_rig_from_camera: Vec<Isometry3<f64>> =
        rig.cameras.iter().map(|c| c.rig_from_camera).collect();
    let quality = assess(&RefinementFacts {
        names: &log.camera_names,
        image_sizes: cameras.iter().map(|c| (c.width(), c.height())).collect(),
        localization: localization_counts(&localizations, cameras.len()),
        observations: observations
            .iter()
            .map(|o| (o.camera as usize, o.pixel))
            .collect(),
        initial: &initial_residuals,
        refined: &final_residuals,
        cauchy_scale_px: options.refinement.cauchy_scale_px,
        converged: (
            refinement.converged,
            &refinement.termination,
            refinement.iterations,
        ),
        covariance: refinement.rig_from_camera_std.is_some(),
        prior_rig_from_camera: &prior_rig_from_camera,
        rig_from_camera: &refinement.rig_from_camera,
        intrinsics: (&refinement.cameras, &refinement.intrinsics),
    });
    timing.refinement = t.elapsed().as_secs_f64();
    progress.finish(Stage::Refinement);

    let t = Instant::now();
    let hand_eye_solver = choose_solver(options.hand_eye.method, log.odometry);
    let hand_eye = hand_eye_solver.map(|solver| {
        progress.start(Stage::HandEye, 0);
        let poses: Vec<(Isometry3<f64>, Isometry3<f64>)> = frame_sets
            .iter()
            .zip(&refinement.world_from_rig)
            .filter_map(|(set, rig)| Some((*rig, log.frames[set.frame].world_from_odometry?)))
            .collect();
        let result = calibrate_hand_eye(solver, &poses, &options.hand_eye);
        progress.finish(Stage::HandEye);
        result
    });
    timing.hand_eye = t.elapsed().as_secs_f64();
    timing.total = start.elapsed().as_secs_f64();

    Ok(Calibration {
        camera_names: log.camera_names.clone(),
        cameras: refinement.cameras.clone(),
        prior_rig: rig,
        camera_matching,
        rig_from_camera: refinement.rig_from_camera.clone(),
        odometry: log.odometry,
        localizations,
        frame_sets,
        initialization,
        refinement,
        observations,
        initial_errors_px: lengths(&initial_residuals),
        final_errors_px: lengths(&final_residuals),
        quality,
        hand_eye_solver,
        hand_eye,
        timing,
    })
}
