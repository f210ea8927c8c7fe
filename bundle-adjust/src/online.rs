//! Online calibration: intrinsics and extrinsics re-estimated while the rig runs, over a
//! sliding window of frame sets (TrimBot2020 deliverable D3.1, §3.3.2: intrinsic and
//! extrinsic parameters refined inside bundle adjustment by Levenberg-Marquardt with
//! preconditioned conjugate gradients, "if we detect a reliable geometric configuration with
//! enough constraints").
//!
//! Frame sets arrive one by one ([`OnlineCalibrator::push`]): a start rig pose (from
//! localization against the map) and the frame set's 2D-3D observations. The last
//! [`OnlineOptions::window`] of them are kept. Every [`OnlineOptions::update_every`] frame
//! sets, once the window is full, the window is checked and, when it qualifies, refined:
//!
//! 1. **Geometry** (TrimBot's condition that the rig both rotated and translated): the largest
//!    angle between the rig's orientation at any frame set of the window and at its first
//!    must reach [`OnlineOptions::min_rotation_deg`], and the largest distance between their
//!    positions [`OnlineOptions::min_translation_m`]; otherwise the update is skipped with
//!    [`SkipReason::TooLittleRotation`] or [`SkipReason::TooLittleTranslation`].
//! 2. **Refinement**: [`RigRefinement`] (the map fixed) over the extrinsics, the window's rig
//!    poses and the selected intrinsics ([`OnlineOptions::intrinsics`]), warm-started from the
//!    current estimate and from the rig poses of the previous update, with the iterative
//!    (PCG) reduced solver on one thread unless [`OnlineOptions::refinement`] says otherwise.
//! 3. **Observability**: a free intrinsic whose observability (see
//!    [`crate::rig_bundle_adjustment`]) is below [`OnlineOptions::min_observability`] rejects
//!    the update ([`SkipReason::Undetermined`], naming the camera and the parameter); the
//!    estimate stays as it was.
//!
//! An accepted update replaces the estimate and comes with its covariance, scaled by the
//! a-posteriori variance factor `2 cost / (residuals - unknowns)`.

use std::collections::VecDeque;

use ibc_camera_models::{Camera, Rig};
use nalgebra::{DMatrix, Isometry3, Matrix6, Vector2, Vector3};

use crate::NonExhaustive;
use crate::error::{BundleAdjustError, Result};
use crate::options::{LinearSolverType, SolverOptions};
use crate::rig::{
    IntrinsicsSelection, RigObservation, RigRefinement, RigRefinementOptions, check_pose,
};
use crate::summary::Summary;

/// One observation of a frame set: camera `camera` saw the map point `world_point` at `pixel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineObservation {
    /// Camera index (into the rig's cameras).
    pub camera: usize,
    /// The map point, world frame.
    pub world_point: Vector3<f64>,
    /// The observed pixel.
    pub pixel: Vector2<f64>,
}

/// One frame set: the rig's start pose and what its cameras saw.
#[derive(Debug, Clone, PartialEq)]
pub struct OnlineFrameSet {
    /// The start `world_from_rig` (from localization against the map).
    pub world_from_rig: Isometry3<f64>,
    /// Its observations.
    pub observations: Vec<OnlineObservation>,
}

/// Options of [`OnlineCalibrator`].
///
/// ```
/// use ibc_bundle_adjust::{IntrinsicsSelection, OnlineOptions};
///
/// let options = OnlineOptions {
///     window: 30,
///     intrinsics: IntrinsicsSelection::FocalAndCenter,
///     ..Default::default()
/// };
/// assert_eq!(options.update_every, 10);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct OnlineOptions {
    /// Frame sets in the sliding window (default 50).
    pub window: usize,
    /// An update is tried every this many frame sets once the window is full (default 10).
    pub update_every: usize,
    /// Least rotation of the rig within the window, degrees (default 10).
    pub min_rotation_deg: f64,
    /// Least translation of the rig within the window, metres (default 1).
    pub min_translation_m: f64,
    /// The intrinsics re-estimated with the extrinsics (default the focal lengths: the
    /// principal points trade against the cameras' rotations, see `ibc calibrate
    /// --refine-intrinsics`).
    pub intrinsics: IntrinsicsSelection,
    /// A free intrinsic whose observability is below this rejects the update (default 1e-4).
    pub min_observability: f64,
    /// The refinement's options (default: Cauchy loss of 1 px, the reference camera 0, the
    /// iterative (PCG) reduced solver on one thread, at most 20 iterations; its `intrinsics`,
    /// `held_intrinsics` and `covariance` are set by the calibrator).
    pub refinement: RigRefinementOptions,
    /// Keeps the struct open to new fields: write it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for OnlineOptions {
    fn default() -> Self {
        Self {
            window: 50,
            update_every: 10,
            min_rotation_deg: 10.0,
            min_translation_m: 1.0,
            intrinsics: IntrinsicsSelection::Focal,
            min_observability: 1e-4,
            refinement: RigRefinementOptions {
                solver: SolverOptions {
                    linear_solver: LinearSolverType::IterativeSchur,
                    num_threads: 1,
                    max_iterations: 20,
                    ..Default::default()
                },
                ..Default::default()
            },
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// Why an update was not made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SkipReason {
    /// The rig turned too little within the window.
    #[error(
        "the rig turned {spread_deg:.1} deg within the window, less than the {needed_deg:.1} deg \
         an update needs"
    )]
    TooLittleRotation {
        /// Its largest turn from the window's first frame set, degrees.
        spread_deg: f64,
        /// [`OnlineOptions::min_rotation_deg`].
        needed_deg: f64,
    },
    /// The rig moved too little within the window.
    #[error(
        "the rig moved {spread_m:.2} m within the window, less than the {needed_m:.2} m an \
         update needs"
    )]
    TooLittleTranslation {
        /// Its largest distance from the window's first frame set, metres.
        spread_m: f64,
        /// [`OnlineOptions::min_translation_m`].
        needed_m: f64,
    },
    /// The window does not determine a free intrinsic.
    #[error(
        "the window does not determine `{parameter}` of camera {camera} (observability \
         {observability:.2e})"
    )]
    Undetermined {
        /// The camera.
        camera: usize,
        /// The parameter's name.
        parameter: &'static str,
        /// Its observability.
        observability: f64,
    },
    /// The refinement failed.
    #[error("the refinement failed: {0}")]
    Refinement(BundleAdjustError),
}

/// An accepted update.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct OnlineUpdate {
    /// Frame sets pushed so far (the update covers the last [`OnlineOptions::window`]).
    pub frame_sets: usize,
    /// The cameras with their re-estimated intrinsics.
    pub cameras: Vec<Camera>,
    /// The re-estimated extrinsics.
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// Covariance of each extrinsic in its right tangent `[ρ, φ]`, scaled by the variance
    /// factor; `None` for the reference camera or when undefined.
    pub extrinsic_covariance: Vec<Option<Matrix6<f64>>>,
    /// Covariance of each camera's intrinsics (CamOdoCal order, zero for held parameters),
    /// scaled by the variance factor; `None` when none is free or undefined.
    pub intrinsic_covariance: Vec<Option<DMatrix<f64>>>,
    /// The a-posteriori variance factor `2 cost / (residuals - unknowns)` (pixels²).
    pub variance_factor: f64,
    /// The solver's summary.
    pub summary: Summary,
}

/// What [`OnlineCalibrator::push`] did with a frame set.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum OnlineEvent {
    /// Kept; no update was due (the window is not full, or not every
    /// [`OnlineOptions::update_every`] frame sets yet).
    Kept,
    /// An update was due and made.
    Updated(Box<OnlineUpdate>),
    /// An update was due and not made, for this reason.
    Skipped(SkipReason),
}

/// The online calibrator (see the module documentation).
#[derive(Debug, Clone)]
pub struct OnlineCalibrator {
    cameras: Vec<Camera>,
    rig_from_camera: Vec<Isometry3<f64>>,
    options: OnlineOptions,
    window: VecDeque<OnlineFrameSet>,
    pushed: usize,
}

impl OnlineCalibrator {
    /// A calibrator starting from `rig`'s intrinsics and extrinsics.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidOption`] for a window below 2 frame sets, an update
    /// interval of 0, a negative or non-finite geometry bound, an observability bound outside
    /// [0, 1] or a reference camera the rig does not have.
    pub fn new(rig: &Rig, options: OnlineOptions) -> Result<Self> {
        let invalid = |name, reason: String| BundleAdjustError::InvalidOption { name, reason };
        if options.window < 2 {
            return Err(invalid("window", format!("{} is below 2", options.window)));
        }
        if options.update_every == 0 {
            return Err(invalid("update_every", "0 never updates".to_owned()));
        }
        for (name, v) in [
            ("min_rotation_deg", options.min_rotation_deg),
            ("min_translation_m", options.min_translation_m),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(name, format!("{v} is not a finite value >= 0")));
            }
        }
        if !(0.0..=1.0).contains(&options.min_observability) {
            return Err(invalid(
                "min_observability",
                format!("{} is not in [0, 1]", options.min_observability),
            ));
        }
        if options.refinement.reference_camera >= rig.cameras.len() {
            return Err(invalid(
                "refinement.reference_camera",
                format!(
                    "camera {} does not exist ({} cameras)",
                    options.refinement.reference_camera,
                    rig.cameras.len()
                ),
            ));
        }
        Ok(Self {
            cameras: rig.cameras.iter().map(|c| c.camera.clone()).collect(),
            rig_from_camera: rig.cameras.iter().map(|c| c.rig_from_camera).collect(),
            window: VecDeque::with_capacity(options.window),
            options,
            pushed: 0,
        })
    }

    /// The current cameras (intrinsics).
    #[must_use]
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    /// The current extrinsics.
    #[must_use]
    pub fn rig_from_camera(&self) -> &[Isometry3<f64>] {
        &self.rig_from_camera
    }

    /// Adds a frame set to the window and, when an update is due, tries it.
    ///
    /// # Errors
    /// [`BundleAdjustError::IndexOutOfRange`] for an observation naming a camera the rig does
    /// not have, [`BundleAdjustError::NonFiniteObservation`] or
    /// [`BundleAdjustError::NonFiniteInput`] for non-finite input: the frame set is not kept.
    /// A refinement that fails is not an error but [`SkipReason::Refinement`].
    pub fn push(&mut self, frame_set: OnlineFrameSet) -> Result<OnlineEvent> {
        let nc = self.cameras.len();
        check_pose(self.pushed, &frame_set.world_from_rig, "world_from_rig")?;
        for (i, o) in frame_set.observations.iter().enumerate() {
            if o.camera >= nc {
                return Err(BundleAdjustError::IndexOutOfRange {
                    what: "observation",
                    position: i,
                    target: "camera",
                    index: o.camera,
                    count: nc,
                });
            }
            if !(o.world_point.iter().all(|v| v.is_finite())
                && o.pixel.iter().all(|v| v.is_finite()))
            {
                return Err(BundleAdjustError::NonFiniteObservation { index: i });
            }
        }
        if self.window.len() == self.options.window {
            self.window.pop_front();
        }
        self.window.push_back(frame_set);
        self.pushed += 1;
        let due = self.window.len() == self.options.window
            && (self.pushed - self.options.window).is_multiple_of(self.options.update_every);
        if !due {
            return Ok(OnlineEvent::Kept);
        }
        Ok(match self.update() {
            Ok(update) => OnlineEvent::Updated(Box::new(update)),
            Err(reason) => OnlineEvent::Skipped(reason),
        })
    }

    /// The rig's largest turn (degrees) and distance (metres) from the window's first frame
    /// set.
    fn spread(&self) -> (f64, f64) {
        let Some(first) = self.window.front() else {
            return (0.0, 0.0);
        };
        self.window.iter().fold((0.0f64, 0.0f64), |(r, t), f| {
            (
                r.max(
                    first
                        .world_from_rig
                        .rotation
                        .angle_to(&f.world_from_rig.rotation)
                        .to_degrees(),
                ),
                t.max(
                    (f.world_from_rig.translation.vector - first.world_from_rig.translation.vector)
                        .norm(),
                ),
            )
        })
    }

    /// Checks and refines the window (see the module documentation).
    fn update(&mut self) -> std::result::Result<OnlineUpdate, SkipReason> {
        let (rotation, translation) = self.spread();
        if rotation < self.options.min_rotation_deg {
            return Err(SkipReason::TooLittleRotation {
                spread_deg: rotation,
                needed_deg: self.options.min_rotation_deg,
            });
        }
        if translation < self.options.min_translation_m {
            return Err(SkipReason::TooLittleTranslation {
                spread_m: translation,
                needed_m: self.options.min_translation_m,
            });
        }
        let mut observations = Vec::new();
        for (frame, set) in self.window.iter().enumerate() {
            observations.extend(set.observations.iter().map(|o| RigObservation {
                frame,
                camera: o.camera,
                world_point: o.world_point,
                pixel: o.pixel,
            }));
        }
        let problem = RigRefinement {
            cameras: self.cameras.clone(),
            rig_from_camera: self.rig_from_camera.clone(),
            world_from_rig: self.window.iter().map(|f| f.world_from_rig).collect(),
            observations,
        };
        let options = RigRefinementOptions {
            intrinsics: self.options.intrinsics,
            held_intrinsics: Vec::new(),
            covariance: true,
            ..self.options.refinement.clone()
        };
        let result = problem.refine(&options).map_err(SkipReason::Refinement)?;
        if let Some(o) = result
            .observability
            .iter()
            .filter(|o| o.intrinsic)
            .find(|o| o.observability < self.options.min_observability || !o.std_dev.is_finite())
        {
            return Err(SkipReason::Undetermined {
                camera: o.camera,
                parameter: o.name,
                observability: o.observability,
            });
        }
        let used = problem.observations.len() - result.excluded_observations.len();
        let free_intrinsics: usize = self
            .cameras
            .iter()
            .map(|c| self.options.intrinsics.indices(c).len())
            .sum();
        let unknowns = 6 * (self.cameras.len() - 1) + 6 * self.window.len() + free_intrinsics;
        let residuals = 2 * used;
        let variance_factor = if residuals > unknowns {
            2.0 * result.summary.final_cost / (residuals - unknowns) as f64
        } else {
            f64::NAN
        };
        // The refined rig poses start the next update.
        for (set, pose) in self.window.iter_mut().zip(&result.world_from_rig) {
            set.world_from_rig = *pose;
        }
        self.cameras.clone_from(&result.cameras);
        self.rig_from_camera.clone_from(&result.rig_from_camera);
        Ok(OnlineUpdate {
            frame_sets: self.pushed,
            cameras: result.cameras,
            rig_from_camera: result.rig_from_camera,
            extrinsic_covariance: result
                .extrinsic_covariance
                .iter()
                .map(|c| c.map(|c| c * variance_factor))
                .collect(),
            intrinsic_covariance: result
                .intrinsic_covariance
                .iter()
                .map(|c| c.as_ref().map(|c| c * variance_factor))
                .collect(),
            variance_factor,
            summary: result.summary,
        })
    }
}
