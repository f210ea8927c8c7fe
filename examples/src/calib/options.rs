//! Options of every pipeline stage, with the paper's values as defaults.
//!
//! J. Heng, M. Bürki, G. H. Lee, P. Furgale, R. Siegwart and M. Pollefeys,
//! "Infrastructure-Based Calibration of a Multi-Camera Rig", ICRA 2014, section IV; where the
//! paper gives no value, the value of its implementation (CamOdoCal) or this crate's choice,
//! said so on the field.

use ibc_bundle_adjust::IntrinsicsSelection;
use ibc_hand_eye::Pairing;
use ibc_pnp::{AbsolutePoseOptions, RansacOptions};
use ibc_rig_averaging::RigInitOptions;

use super::error::CalibrationError;

/// How the vocabulary tree over the map images is trained and how the map database indexes
/// features for matching.
#[derive(Clone, Debug, PartialEq)]
pub struct VocabularyOptions {
    /// Branching factor of the tree. Default 10 (DBoW2's).
    pub branching: u32,
    /// Depth of the tree. Default 5: up to 100,000 words, enough for a map of about a
    /// thousand images (DBoW2's depth 6 is meant for generic vocabularies of millions of
    /// training descriptors).
    pub depth: u32,
    /// At most this many map descriptors train the tree: a seeded random subsample of the
    /// same number of descriptors from every map image (all of them when the map has fewer).
    /// Default 50,000: on the default scenario (1.2 million map descriptors) every image is
    /// localized with it, and training takes a fraction of a second.
    pub training_descriptors: usize,
    /// Lloyd iterations per node. Default 10 (the vocabulary crate's bound).
    pub max_iterations: u32,
    /// Levels above the leaves at which the direct index groups the features of each image:
    /// a query feature is compared only with the map features under the same node (DBoW2,
    /// section IV-B). Default 2: with the default depth 5, the 1000 nodes of depth 3, where
    /// 95% of the matches of depth 2 are found at a tenth of the descriptor comparisons.
    pub direct_index_levels: u32,
    /// Seed of the subsample and of the k-means seeding. Default 0.
    pub seed: u64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for VocabularyOptions {
    fn default() -> Self {
        Self {
            branching: 10,
            depth: 5,
            training_descriptors: 50_000,
            max_iterations: 10,
            direct_index_levels: 2,
            seed: 0,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// How one image is localized against the map (the paper's section IV-A).
#[derive(Clone, Debug, PartialEq)]
pub struct LocalizationOptions {
    /// The most similar map images matched to each image. Default 10 (the paper's n).
    pub candidates: usize,
    /// Lowe's distance ratio of the matching. Default 0.7 (CamOdoCal's).
    pub ratio: f64,
    /// Keep a match only when both features are each other's nearest. Default true
    /// (CamOdoCal's cross-check).
    pub mutual_check: bool,
    /// The robust pose of each image from its 2D-3D correspondences
    /// ([`ibc_pnp::absolute_pose`]: RANSAC over P3P on bearings with a final refit). Default
    /// [`default_pose_options`]: the paper's and CamOdoCal's values.
    pub pose: AbsolutePoseOptions,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for LocalizationOptions {
    fn default() -> Self {
        Self {
            candidates: 10,
            ratio: 0.7,
            mutual_check: true,
            pose: default_pose_options(),
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// The pose options of the localization: `ibc-pnp`'s defaults but for
///
/// - the inlier threshold: 2 px, turned into an angle per camera at its principal point
///   (CamOdoCal's);
/// - 25 inliers at least, else the image stays unlocalized (the paper's);
/// - at most 2000 RANSAC iterations (enough for 10% inliers at the confidence 0.999; the
///   adaptive count stops far earlier on a good image) and at least 20 (with the inlier ratios
///   of matched images, 50% and more, the adaptive count asks for fewer);
/// - no local optimization: the final refit on all inliers gives the same pose, and the local
///   optimization doubles the cost of an image.
///
/// The RANSAC seed is mixed with each image's frame and camera indices.
pub fn default_pose_options() -> AbsolutePoseOptions {
    AbsolutePoseOptions {
        max_error_px: 2.0,
        ransac: RansacOptions {
            min_inliers: 25,
            confidence: 0.999,
            max_iterations: 2000,
            min_iterations: 20,
            local_optimization: false,
            seed: 0,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Which synchronized frames become frame sets (the paper's section IV-B).
///
/// Frames are visited in time order. A frame is kept when at least
/// [`min_cameras`](Self::min_cameras) of its images are localized and, for every camera
/// localized both in it and in the last kept set, the camera's centre is more than
/// [`min_motion_m`](Self::min_motion_m) from its centre in that set. The first frame with
/// enough localized cameras is always kept, and so is a frame that shares no localized
/// camera with the last kept set.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameSetOptions {
    /// Fewest localized cameras in a kept set. Default 2 (the paper's).
    pub min_cameras: usize,
    /// Smallest motion of every camera since the last kept set, metres. Default 0.3 (the
    /// paper's).
    pub min_motion_m: f64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for FrameSetOptions {
    fn default() -> Self {
        Self {
            min_cameras: 2,
            min_motion_m: 0.3,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// How the extrinsics and rig poses are initialized (the paper's section IV-C).
#[derive(Clone, Debug, PartialEq)]
pub struct InitializationOptions {
    /// Averaging and hypothesis options of `ibc_rig_averaging::initialize_rig`. Default:
    /// its defaults (Markley rig-pose averaging as in the paper, plus the robustly averaged
    /// extrinsics as one more hypothesis).
    pub rig: RigInitOptions,
    /// The hypotheses are the complete sets among at most this many frame sets, evenly spaced
    /// in time, and each hypothesis is scored on the same sets. Default 100: the cost grows
    /// as its square, and a hundred sets spread over the drive rank the hypotheses as well as
    /// all of them do. `usize::MAX` scores every complete set on every set (the paper).
    pub max_sets: usize,
    /// Each image contributes at most this many of its inlier correspondences (evenly
    /// spaced) to the score. Default 50.
    pub max_observations_per_image: usize,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for InitializationOptions {
    fn default() -> Self {
        Self {
            rig: RigInitOptions::default(),
            max_sets: 100,
            max_observations_per_image: 50,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// The non-linear refinement of extrinsics and rig poses (the paper's section IV-D).
#[derive(Clone, Debug, PartialEq)]
pub struct RefinementOptions {
    /// Scale `a` of the Cauchy loss `rho(s) = a^2 ln(1 + s / a^2)` on the squared pixel
    /// error, pixels. Default 1 (Ceres's customary scale; the paper uses a Cauchy loss).
    pub cauchy_scale_px: f64,
    /// Most Levenberg-Marquardt iterations. Default 50 (Ceres's).
    pub max_iterations: usize,
    /// Each localized image of a frame set contributes at most this many of its inlier
    /// correspondences (evenly spaced over its features). Default 100: the paper's images
    /// gave 74 correspondences each (37,860 over 509 localized images); a simulated image
    /// gives up to ten times more, which would cost time for little gain.
    /// `usize::MAX` keeps them all.
    pub max_observations_per_image: usize,
    /// The intrinsics refined with the extrinsics against the map, the same set for every
    /// camera. Default [`IntrinsicsSelection::None`] (the paper's refinement; see
    /// `ibc calibrate --refine-intrinsics` for the measurements behind the default).
    pub intrinsics: IntrinsicsSelection,
    /// A selected intrinsic parameter whose observability (the share of its information left
    /// once every other parameter is free, see [`ibc_bundle_adjust::rig_bundle_adjustment`])
    /// is below this is held at the camera file's value and listed as held. Default 1e-4: its
    /// standard deviation is then over a hundred times what it would be were every other
    /// parameter known. Not higher: the garage fisheyes' horizontal principal points, nearly
    /// a rotation of the camera, measure 0.002-0.007 and are still determined to 0.05-0.09 px
    /// from 100 frames.
    pub min_observability: f64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for RefinementOptions {
    fn default() -> Self {
        Self {
            cauchy_scale_px: 1.0,
            max_iterations: 50,
            max_observations_per_image: 100,
            intrinsics: IntrinsicsSelection::None,
            min_observability: 1e-4,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// Which hand-eye method relates the rig to the odometry.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum HandEyeMethod {
    /// From the rig log's odometry kind: planar odometry uses Guo et al., 6-DoF odometry
    /// Daniilidis, no odometry no hand-eye. The default.
    #[default]
    Auto,
    /// Guo, Mirzaei and Roumeliotis's planar method (ground vehicles).
    Planar,
    /// Daniilidis's dual-quaternion method (6-DoF motion).
    Daniilidis,
    /// No hand-eye calibration.
    Skip,
}

/// The hand-eye calibration between the rig and the odometry (the paper's section IV-E).
#[derive(Clone, Debug, PartialEq)]
pub struct HandEyeOptions {
    /// The method. Default [`HandEyeMethod::Auto`].
    pub method: HandEyeMethod,
    /// Which pairs of frame sets give the motions. Default `Pairing::Window { size: 8 }`:
    /// between each set and each of the next 8 (this crate's choice). Dead-reckoned odometry
    /// drifts, so motions over long stretches carry its accumulated error, while motions over
    /// a few sets rotate enough to be informative. On the default scenario the in-plane
    /// translation error is 3.3 mm with 8 sets, 52 mm with all pairs.
    pub pairing: Pairing,
    /// Refine the linear solution on the absolute trajectories of every frame set
    /// (`ibc_hand_eye::refine_trajectories`). Default false: that refinement models
    /// independent noise on each pose, which drifting odometry is not (on the default
    /// scenario it moves the in-plane translation 0.1 m away from the truth).
    pub refine: bool,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for HandEyeOptions {
    fn default() -> Self {
        Self {
            method: HandEyeMethod::Auto,
            pairing: Pairing::Window { size: 8 },
            refine: false,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// Every option of [`calibrate`](super::calibrate). The defaults are the paper's (see each
/// stage's options).
#[derive(Clone, Debug, PartialEq)]
pub struct CalibrationOptions {
    /// Vocabulary training and the map database.
    pub vocabulary: VocabularyOptions,
    /// Localization of each image.
    pub localization: LocalizationOptions,
    /// Frame-set selection.
    pub frame_sets: FrameSetOptions,
    /// Initialization.
    pub initialization: InitializationOptions,
    /// Refinement.
    pub refinement: RefinementOptions,
    /// Hand-eye calibration.
    pub hand_eye: HandEyeOptions,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        Self {
            vocabulary: VocabularyOptions::default(),
            localization: LocalizationOptions::default(),
            frame_sets: FrameSetOptions::default(),
            initialization: InitializationOptions::default(),
            refinement: RefinementOptions::default(),
            hand_eye: HandEyeOptions::default(),
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

fn invalid(name: &'static str, reason: impl Into<String>) -> CalibrationError {
    CalibrationError::InvalidOption {
        name,
        reason: reason.into(),
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), CalibrationError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            name,
            format!("{value} is not a finite positive number"),
        ))
    }
}

fn at_least(name: &'static str, value: usize, min: usize) -> Result<(), CalibrationError> {
    if value >= min {
        Ok(())
    } else {
        Err(invalid(name, format!("{value} is below the minimum {min}")))
    }
}

impl CalibrationOptions {
    /// Checks every value's range (the stages' own checks, such as the vocabulary's, run
    /// when they start).
    ///
    /// # Errors
    /// [`CalibrationError::InvalidOption`] naming the first option out of range.
    pub fn validate(&self) -> Result<(), CalibrationError> {
        let v = &self.vocabulary;
        at_least("vocabulary.branching", v.branching as usize, 2)?;
        at_least("vocabulary.depth", v.depth as usize, 1)?;
        at_least("vocabulary.training_descriptors", v.training_descriptors, 1)?;
        at_least("vocabulary.max_iterations", v.max_iterations as usize, 1)?;
        let l = &self.localization;
        at_least("localization.candidates", l.candidates, 1)?;
        if !(l.ratio > 0.0 && l.ratio <= 1.0) {
            return Err(invalid(
                "localization.ratio",
                format!("{} is outside (0, 1]", l.ratio),
            ));
        }
        l.pose
            .validate()
            .map_err(CalibrationError::InvalidPoseOptions)?;
        at_least("frame_sets.min_cameras", self.frame_sets.min_cameras, 2)?;
        let m = self.frame_sets.min_motion_m;
        if !(m.is_finite() && m >= 0.0) {
            return Err(invalid(
                "frame_sets.min_motion_m",
                format!("{m} is not a distance >= 0"),
            ));
        }
        at_least("initialization.max_sets", self.initialization.max_sets, 1)?;
        at_least(
            "initialization.max_observations_per_image",
            self.initialization.max_observations_per_image,
            1,
        )?;
        positive(
            "refinement.cauchy_scale_px",
            self.refinement.cauchy_scale_px,
        )?;
        at_least(
            "refinement.max_observations_per_image",
            self.refinement.max_observations_per_image,
            1,
        )?;
        let m = self.refinement.min_observability;
        if !(0.0..=1.0).contains(&m) {
            return Err(invalid(
                "refinement.min_observability",
                format!("{m} is not in [0, 1]"),
            ));
        }
        if let Pairing::Window { size: 0 } = self.hand_eye.pairing {
            return Err(invalid(
                "hand_eye.pairing",
                "a window of 0 sets pairs nothing",
            ));
        }
        Ok(())
    }
}

/// `count` indices evenly spaced over `0..n` (all of them when `count >= n`), increasing.
pub(crate) fn evenly_spaced(n: usize, count: usize) -> Vec<usize> {
    if count >= n {
        return (0..n).collect();
    }
    if count == 1 {
        return vec![0];
    }
    (0..count).map(|i| i * (n - 1) / (count - 1)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_bad_values_are_named() {
        assert!(CalibrationOptions::default().validate().is_ok());
        let o = CalibrationOptions {
            localization: LocalizationOptions {
                ratio: 1.5,
                ..Default::default()
            },
            ..Default::default()
        };
        let e = o.validate().unwrap_err().to_string();
        assert!(e.contains("localization.ratio"), "{e}");
        let o = CalibrationOptions {
            refinement: RefinementOptions {
                cauchy_scale_px: f64::NAN,
                ..Default::default()
            },
            ..Default::default()
        };
        assert!(
            o.validate()
                .unwrap_err()
                .to_string()
                .contains("cauchy_scale_px")
        );
    }

    #[test]
    fn evenly_spaced_covers_both_ends() {
        assert_eq!(evenly_spaced(10, 3), vec![0, 4, 9]);
        assert_eq!(evenly_spaced(3, 5), vec![0, 1, 2]);
        assert_eq!(evenly_spaced(7, 1), vec![0]);
        assert_eq!(evenly_spaced(0, 4), Vec::<usize>::new());
    }
}
