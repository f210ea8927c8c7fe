//! Initial camera extrinsics and rig poses from sets of camera poses.
//!
//! J. Heng, M. Bürki, G. H. Lee, P. Furgale, R. Siegwart and M. Pollefeys,
//! "Infrastructure-Based Calibration of a Multi-Camera Rig", ICRA 2014, section IV-C.
//!
//! Notation (crate conventions): frame set `s` holds, per camera `c`, an optional
//! `camera_from_world` `C_sc` (the localization result; `None` when the image was not
//! localized). The unknowns are the extrinsics `E_c = rig_from_camera` and the rig poses
//! `P_s = world_from_rig`, tied by `C_sc^-1 = P_s E_c`. The rig frame is the frame of camera
//! 0 (`E_0 = I`), as in the paper.
//!
//! 1. Each complete set `h` (every camera localized) gives a hypothesis
//!    `E_c = C_h0 C_hc^-1` (camera 0's frame from camera `c`'s frame at that instant).
//! 2. Under a hypothesis, each localized camera of each set gives a rig pose estimate
//!    `C_sc^-1 E_c^-1`; their average (Markley rotation mean plus mean translation, or the
//!    robust mean) is `P_s`. Sets missing camera 0 get a rig pose too.
//! 3. The hypothesis is scored by the mean reprojection error over all images, each image
//!    (`s`, `c`) evaluated at `camera_from_world = E_c^-1 P_s^-1` by the caller's
//!    [`ImageScorer`]; the lowest mean wins.
//!
//! Besides the paper's single-set hypotheses, this module scores the extrinsics averaged over
//! all complete sets (per camera, by [`RigInitOptions::extrinsic_averaging`]) and reports both
//! scores. Hypotheses x sets are evaluated in parallel with rayon (the default `rayon`
//! feature; sequentially without it); each hypothesis's errors are summed in set and camera
//! order, so the result depends neither on the thread count nor on the feature.
//! Cost: `O(H * (S * K + observations))` for `H` complete sets, `S` sets, `K` cameras.

use nalgebra::Isometry3;

use crate::NonExhaustive;
use crate::error::RigAveragingError;
use crate::parallel::{first_error, map_indexed};
use crate::pose_mean::{PoseMean, pose_mean, weighted_pose_mean};
use crate::quaternion_mean::check_unit;
use crate::robust::{RobustOptions, robust_pose_mean};
use crate::scoring::{ImageScore, ImageScorer};

/// How a set of poses is averaged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Averaging {
    /// Markley rotation mean and mean translation, as in the paper.
    Plain,
    /// The Cauchy-robust mean of [`robust_pose_mean`] (meaningful with three or more poses;
    /// with two it equals the plain mean).
    Robust(RobustOptions),
}

impl Averaging {
    fn validate(&self) -> Result<(), RigAveragingError> {
        match self {
            Averaging::Plain => Ok(()),
            Averaging::Robust(robust) => robust.validate(),
        }
    }
}

/// Options of [`initialize_rig`].
///
/// The paper scores only single-set hypotheses and averages rig poses plainly. The default
/// keeps the plain rig-pose averaging of the paper, and additionally scores the extrinsics
/// averaged robustly over all complete sets (this crate's addition; the winner is still the
/// lowest score). Write them as one expression:
///
/// ```
/// use ibc_rig_averaging::{Averaging, RigInitOptions};
///
/// let options = RigInitOptions { extrinsic_averaging: Averaging::Plain, ..Default::default() };
/// assert!(options.averaged_extrinsics);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigInitOptions {
    /// Also score the extrinsics averaged over all complete sets (default `true`).
    pub averaged_extrinsics: bool,
    /// How each camera's extrinsic is averaged over the complete sets (default
    /// `Averaging::Robust(RobustOptions::default())`, so one corrupted set is down-weighted).
    pub extrinsic_averaging: Averaging,
    /// How a set's per-camera rig pose estimates are averaged (default `Averaging::Plain`,
    /// the paper's).
    pub rig_pose_averaging: Averaging,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for RigInitOptions {
    fn default() -> Self {
        Self {
            averaged_extrinsics: true,
            extrinsic_averaging: Averaging::Robust(RobustOptions::default()),
            rig_pose_averaging: Averaging::Plain,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl RigInitOptions {
    /// Sets whether the averaged extrinsics are scored too.
    #[must_use]
    pub fn with_averaged_extrinsics(mut self, enabled: bool) -> Self {
        self.averaged_extrinsics = enabled;
        self
    }

    /// Sets how extrinsics are averaged over complete sets.
    #[must_use]
    pub fn with_extrinsic_averaging(mut self, averaging: Averaging) -> Self {
        self.extrinsic_averaging = averaging;
        self
    }

    /// Sets how rig pose estimates are averaged within a set.
    #[must_use]
    pub fn with_rig_pose_averaging(mut self, averaging: Averaging) -> Self {
        self.rig_pose_averaging = averaging;
        self
    }

    fn validate(&self) -> Result<(), RigAveragingError> {
        self.extrinsic_averaging.validate()?;
        self.rig_pose_averaging.validate()
    }
}

/// Where a hypothesis of the extrinsics came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HypothesisSource {
    /// The complete frame set with this index.
    CompleteSet(usize),
    /// Each camera's extrinsic averaged over all complete sets.
    AveragedExtrinsics,
}

/// The score of one hypothesis: the mean reprojection error over all images.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HypothesisScore {
    /// `error_sum / observations`, pixels; NaN when there are no observations.
    pub mean_error: f64,
    /// Sum of the reprojection errors over all images, pixels.
    pub error_sum: f64,
    /// Number of observations over all images.
    pub observations: usize,
}

impl HypothesisScore {
    fn from_sum(error_sum: f64, observations: usize) -> Self {
        let mean_error = if observations == 0 {
            f64::NAN
        } else {
            error_sum / observations as f64
        };
        Self {
            mean_error,
            error_sum,
            observations,
        }
    }

    /// The mean error as a ranking key: non-finite means rank last.
    fn key(&self) -> f64 {
        if self.mean_error.is_finite() {
            self.mean_error
        } else {
            f64::INFINITY
        }
    }
}

/// The result of [`initialize_rig`].
#[derive(Clone, Debug, PartialEq)]
pub struct RigInitialization {
    /// The chosen extrinsics `rig_from_camera`, one per camera; `rig_from_camera[0]` is the
    /// identity (the rig frame is camera 0's).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// The rig pose `world_from_rig` of every frame set under the chosen extrinsics.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// Which hypothesis was chosen.
    pub source: HypothesisSource,
    /// Its score (the lowest finite mean reprojection error).
    pub score: HypothesisScore,
    /// The best single-set hypothesis (lowest score; earliest set on ties) and its score, to
    /// compare with the averaged extrinsics.
    pub best_set: (usize, HypothesisScore),
    /// The averaged extrinsics and their score, when [`RigInitOptions::averaged_extrinsics`].
    pub averaged: Option<(Vec<Isometry3<f64>>, HypothesisScore)>,
    /// Every single-set hypothesis as (set index, score), in set order.
    pub set_scores: Vec<(usize, HypothesisScore)>,
    /// The smallest conditioning figure of the rig-pose rotation averages under the chosen
    /// hypothesis (see [`QuaternionMean::conditioning`](crate::QuaternionMean::conditioning));
    /// near 0 some set's cameras disagree on the rig orientation by about 180 degrees.
    pub min_rig_pose_conditioning: f64,
}

impl RigInitialization {
    /// Whether the averaged extrinsics scored strictly better than the best single set.
    pub fn averaged_is_better(&self) -> bool {
        self.averaged
            .as_ref()
            .is_some_and(|(_, score)| score.key() < self.best_set.1.key())
    }
}

/// Frame sets checked and turned into `world_from_camera` poses.
struct Prepared {
    cameras: usize,
    world_from_camera: Vec<Vec<Option<Isometry3<f64>>>>,
}

/// One hypothesis of the extrinsics, with their inverses.
struct Hypothesis {
    source: HypothesisSource,
    rig_from_camera: Vec<Isometry3<f64>>,
    camera_from_rig: Vec<Isometry3<f64>>,
}

impl Hypothesis {
    fn new(source: HypothesisSource, rig_from_camera: Vec<Isometry3<f64>>) -> Self {
        let camera_from_rig = rig_from_camera.iter().map(Isometry3::inverse).collect();
        Self {
            source,
            rig_from_camera,
            camera_from_rig,
        }
    }
}

/// The contribution of one frame set to one hypothesis's score.
#[derive(Clone, Copy)]
struct SetScore {
    error_sum: f64,
    observations: usize,
    conditioning: f64,
}

/// Initial extrinsics and rig poses, as in Heng et al. 2014, section IV-C (see the module
/// documentation for the formulas).
///
/// `sets[s][c]` is camera `c`'s `camera_from_world` in frame set `s`, `None` if that image was
/// not localized. Every set must list the same number of cameras (at least two) and localize
/// at least two of them; at least one set must be complete. `scorer` gives the reprojection
/// error of an image at a candidate pose.
///
/// # Errors
/// [`RigAveragingError::NoFrameSets`], [`RigAveragingError::TooFewRigCameras`],
/// [`RigAveragingError::CameraCountMismatch`], [`RigAveragingError::SetTooFewCameras`],
/// [`RigAveragingError::InvalidCameraPose`], [`RigAveragingError::NoCompleteSet`],
/// [`RigAveragingError::NoFiniteScore`] (the scorer reported no observations or only
/// non-finite errors), and [`RigAveragingError::InvalidRobustOptions`] for bad robust options.
pub fn initialize_rig<S, Sc>(
    sets: &[S],
    scorer: &Sc,
    options: &RigInitOptions,
) -> Result<RigInitialization, RigAveragingError>
where
    S: AsRef<[Option<Isometry3<f64>>]>,
    Sc: ImageScorer + ?Sized,
{
    options.validate()?;
    let prepared = prepare(sets)?;
    let complete: Vec<usize> = (0..prepared.world_from_camera.len())
        .filter(|&s| prepared.world_from_camera[s].iter().all(Option::is_some))
        .collect();
    if complete.is_empty() {
        return Err(RigAveragingError::NoCompleteSet { sets: sets.len() });
    }
    let mut hypotheses: Vec<Hypothesis> = complete
        .iter()
        .map(|&h| single_set_hypothesis(&prepared.world_from_camera[h], h))
        .collect();
    if options.averaged_extrinsics {
        let rig_from_camera = average_extrinsics(&hypotheses, prepared.cameras, options)?;
        hypotheses.push(Hypothesis::new(
            HypothesisSource::AveragedExtrinsics,
            rig_from_camera,
        ));
    }

    let rig_pose_averaging = options.rig_pose_averaging;
    let results: Vec<(HypothesisScore, f64)> = first_error(map_indexed(&hypotheses, 1, |_, h| {
        score_hypothesis(&prepared, h, scorer, &rig_pose_averaging)
    }))?;

    let set_scores: Vec<(usize, HypothesisScore)> = complete
        .iter()
        .zip(&results)
        .map(|(&s, (score, _))| (s, *score))
        .collect();
    let best_set = lowest(set_scores.iter().copied(), |(_, score)| score.key())
        .ok_or(RigAveragingError::NoCompleteSet { sets: sets.len() })?;
    let chosen = lowest(
        (0..results.len()).filter(|&i| results[i].0.mean_error.is_finite()),
        |&i| results[i].0.key(),
    )
    .ok_or(RigAveragingError::NoFiniteScore)?;

    let hypothesis = &hypotheses[chosen];
    let world_from_rig = first_error(map_indexed(&prepared.world_from_camera, 1, |_, set| {
        rig_pose_estimate(set, &hypothesis.camera_from_rig, &rig_pose_averaging).map(|m| m.mean)
    }))?;
    let averaged = options.averaged_extrinsics.then(|| {
        let last = hypotheses.len() - 1;
        (hypotheses[last].rig_from_camera.clone(), results[last].0)
    });
    Ok(RigInitialization {
        rig_from_camera: hypothesis.rig_from_camera.clone(),
        world_from_rig,
        source: hypothesis.source,
        score: results[chosen].0,
        best_set,
        averaged,
        set_scores,
        min_rig_pose_conditioning: results[chosen].1,
    })
}

/// The hypothesis of complete set `h`: `E_c = C_h0 C_hc^-1`, with `E_0` exactly the identity
/// (camera 0 defines the rig frame).
fn single_set_hypothesis(world_from_camera: &[Option<Isometry3<f64>>], h: usize) -> Hypothesis {
    let world_from_camera0 = world_from_camera
        .first()
        .copied()
        .flatten()
        .unwrap_or_else(Isometry3::identity);
    let camera0_from_world = world_from_camera0.inverse();
    let rig_from_camera = world_from_camera
        .iter()
        .enumerate()
        .map(|(c, w)| match w {
            Some(w) if c > 0 => camera0_from_world * w,
            _ => Isometry3::identity(),
        })
        .collect();
    Hypothesis::new(HypothesisSource::CompleteSet(h), rig_from_camera)
}

/// The first item with the smallest key (ties keep the earliest).
fn lowest<T>(items: impl Iterator<Item = T>, key: impl Fn(&T) -> f64) -> Option<T> {
    items.reduce(|best, next| if key(&next) < key(&best) { next } else { best })
}

/// The rig pose `world_from_rig` of every frame set for known extrinsics `rig_from_camera`,
/// averaged over each set's localized cameras (step 2 of [`initialize_rig`]).
///
/// `rig_from_camera` needs one entry per camera slot; it need not have camera 0 at the
/// identity. Each [`PoseMean`] carries the conditioning of its rotation average.
///
/// # Errors
/// As [`initialize_rig`] for the sets (except that no set needs to be complete), plus
/// [`RigAveragingError::ExtrinsicCountMismatch`] when `rig_from_camera` does not have one
/// entry per camera, and [`RigAveragingError::InvalidExtrinsic`] for an extrinsic that is not
/// a finite rigid transform.
pub fn rig_poses<S>(
    sets: &[S],
    rig_from_camera: &[Isometry3<f64>],
    averaging: &Averaging,
) -> Result<Vec<PoseMean>, RigAveragingError>
where
    S: AsRef<[Option<Isometry3<f64>>]>,
{
    let prepared = prepare(sets)?;
    if rig_from_camera.len() != prepared.cameras {
        return Err(RigAveragingError::ExtrinsicCountMismatch {
            expected: prepared.cameras,
            found: rig_from_camera.len(),
        });
    }
    for (camera, pose) in rig_from_camera.iter().enumerate() {
        if !is_rigid(pose) {
            return Err(RigAveragingError::InvalidExtrinsic { camera });
        }
    }
    averaging.validate()?;
    let camera_from_rig: Vec<Isometry3<f64>> =
        rig_from_camera.iter().map(Isometry3::inverse).collect();
    first_error(map_indexed(&prepared.world_from_camera, 1, |_, set| {
        rig_pose_estimate(set, &camera_from_rig, averaging)
    }))
}

/// Validates the frame sets and inverts the camera poses.
fn prepare<S>(sets: &[S]) -> Result<Prepared, RigAveragingError>
where
    S: AsRef<[Option<Isometry3<f64>>]>,
{
    let first = sets.first().ok_or(RigAveragingError::NoFrameSets)?;
    let cameras = first.as_ref().len();
    if cameras < 2 {
        return Err(RigAveragingError::TooFewRigCameras { cameras });
    }
    let mut world_from_camera = Vec::with_capacity(sets.len());
    for (s, set) in sets.iter().enumerate() {
        let set = set.as_ref();
        if set.len() != cameras {
            return Err(RigAveragingError::CameraCountMismatch {
                set: s,
                expected: cameras,
                found: set.len(),
            });
        }
        let mut localized = 0;
        let mut inverted = Vec::with_capacity(cameras);
        for (camera, pose) in set.iter().enumerate() {
            inverted.push(match pose {
                Some(pose) if is_rigid(pose) => {
                    localized += 1;
                    Some(pose.inverse())
                }
                Some(_) => return Err(RigAveragingError::InvalidCameraPose { set: s, camera }),
                None => None,
            });
        }
        if localized < 2 {
            return Err(RigAveragingError::SetTooFewCameras { set: s, localized });
        }
        world_from_camera.push(inverted);
    }
    Ok(Prepared {
        cameras,
        world_from_camera,
    })
}

/// Whether a pose has a finite translation and a unit rotation quaternion.
fn is_rigid(pose: &Isometry3<f64>) -> bool {
    pose.translation.vector.iter().all(|x| x.is_finite())
        && check_unit(0, pose.rotation.quaternion()).is_ok()
}

/// Each camera's extrinsic averaged over the single-set hypotheses (camera 0 stays identity).
fn average_extrinsics(
    hypotheses: &[Hypothesis],
    cameras: usize,
    options: &RigInitOptions,
) -> Result<Vec<Isometry3<f64>>, RigAveragingError> {
    let mut averaged = vec![Isometry3::identity(); cameras];
    for (c, extrinsic) in averaged.iter_mut().enumerate().skip(1) {
        let poses: Vec<Isometry3<f64>> = hypotheses.iter().map(|h| h.rig_from_camera[c]).collect();
        *extrinsic = match &options.extrinsic_averaging {
            Averaging::Plain => pose_mean(&poses, None)?.mean,
            Averaging::Robust(robust) => robust_pose_mean(&poses, None, robust)?.mean.mean,
        };
    }
    Ok(averaged)
}

/// The rig pose of one set: the average of `world_from_camera_c * camera_from_rig_c` over the
/// localized cameras (at least two, checked by `prepare`).
fn rig_pose_estimate(
    world_from_camera: &[Option<Isometry3<f64>>],
    camera_from_rig: &[Isometry3<f64>],
    averaging: &Averaging,
) -> Result<PoseMean, RigAveragingError> {
    let estimates = world_from_camera
        .iter()
        .zip(camera_from_rig)
        .filter_map(|(w, c)| w.as_ref().map(|w| w * c));
    match averaging {
        Averaging::Plain => {
            weighted_pose_mean(estimates.map(|e| (e.rotation, e.translation.vector, 1.0)))
        }
        Averaging::Robust(robust) => {
            let poses: Vec<Isometry3<f64>> = estimates.collect();
            Ok(robust_pose_mean(&poses, None, robust)?.mean)
        }
    }
}

/// Scores one hypothesis over all sets: sets in parallel, summed in set order.
fn score_hypothesis<Sc>(
    prepared: &Prepared,
    hypothesis: &Hypothesis,
    scorer: &Sc,
    averaging: &Averaging,
) -> Result<(HypothesisScore, f64), RigAveragingError>
where
    Sc: ImageScorer + ?Sized,
{
    // A set is a few microseconds of work; chunks of 16 keep rayon's splitting overhead small
    // while leaving enough chunks to balance.
    let per_set: Vec<SetScore> = first_error(map_indexed(
        &prepared.world_from_camera,
        16,
        |s, set| -> Result<SetScore, RigAveragingError> {
            let rig_pose = rig_pose_estimate(set, &hypothesis.camera_from_rig, averaging)?;
            let rig_from_world = rig_pose.mean.inverse();
            let mut total = ImageScore::default();
            for (c, camera_from_rig) in hypothesis.camera_from_rig.iter().enumerate() {
                let score = scorer.score_image(s, c, &(camera_from_rig * rig_from_world));
                total.error_sum += score.error_sum;
                total.observations += score.observations;
            }
            Ok(SetScore {
                error_sum: total.error_sum,
                observations: total.observations,
                conditioning: rig_pose.rotation.conditioning,
            })
        },
    ))?;
    let (error_sum, observations, conditioning) =
        per_set
            .iter()
            .fold((0.0, 0usize, f64::INFINITY), |(e, n, k), set| {
                (
                    e + set.error_sum,
                    n + set.observations,
                    k.min(set.conditioning),
                )
            });
    Ok((
        HypothesisScore::from_sum(error_sum, observations),
        conditioning,
    ))
}
