//! Weighted average of rigid transforms: Markley's quaternion mean for the rotation and the
//! weighted arithmetic mean for the translation.
//!
//! This is the rig-pose average of J. Heng, M. Bürki, G. H. Lee, P. Furgale, R. Siegwart and
//! M. Pollefeys, "Infrastructure-Based Calibration of a Multi-Camera Rig", ICRA 2014, section
//! IV-C ("quaternion averaging [Markley et al. 2007] ... and the mean translation"). Rotation
//! and translation are averaged independently: for poses `a_from_b` the translation is the
//! position of frame `b`'s origin in frame `a`, so its mean is the mean position, whatever the
//! rotations.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use crate::error::RigAveragingError;
use crate::quaternion_mean::{
    MarkleyAccumulator, QuaternionMean, check_unit, max_weight, scaled_weight,
};

/// The result of pose averaging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseMean {
    /// The mean pose: rotation from [`PoseMean::rotation`], translation the weighted mean.
    pub mean: Isometry3<f64>,
    /// The Markley mean of the rotations, with its conditioning figure.
    pub rotation: QuaternionMean,
}

/// Weighted average of poses (all expressing the same `a_from_b`).
///
/// `weights` is `None` for equal weights, or one finite positive weight per pose (only ratios
/// matter). The rotation is the Markley mean (see [`quaternion_mean`](crate::quaternion_mean)),
/// the translation `sum_i w_i t_i / sum_i w_i` (valid for translations well inside the `f64`
/// range, below about `1e300 / N`).
///
/// # Errors
/// [`RigAveragingError::EmptyInput`], [`RigAveragingError::WeightCountMismatch`],
/// [`RigAveragingError::InvalidWeight`], [`RigAveragingError::NotUnitQuaternion`],
/// [`RigAveragingError::NonFiniteTranslation`].
///
/// ```
/// use ibc_rig_averaging::pose_mean;
/// use nalgebra::{Isometry3, Vector3};
///
/// let a = Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.1));
/// let b = Isometry3::new(Vector3::new(3.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.3));
/// let mean = pose_mean(&[a, b], None)?;
/// assert!((mean.mean.translation.vector.x - 2.0).abs() < 1e-12);
/// assert!((mean.mean.rotation.angle() - 0.2).abs() < 1e-12);
/// # Ok::<(), ibc_rig_averaging::RigAveragingError>(())
/// ```
pub fn pose_mean(
    poses: &[Isometry3<f64>],
    weights: Option<&[f64]>,
) -> Result<PoseMean, RigAveragingError> {
    let w_max = max_weight(poses.len(), weights)?;
    for (i, pose) in poses.iter().enumerate() {
        check_unit(i, pose.rotation.quaternion())?;
        check_translation(i, &pose.translation.vector)?;
    }
    weighted_pose_mean(poses.iter().enumerate().map(|(i, pose)| {
        (
            pose.rotation,
            pose.translation.vector,
            scaled_weight(weights, i, w_max),
        )
    }))
}

/// Markley mean of the rotations and weighted mean of the translations of validated
/// `(rotation, translation, weight)` items (weights finite and non-negative, not all zero).
pub(crate) fn weighted_pose_mean(
    items: impl IntoIterator<Item = (UnitQuaternion<f64>, Vector3<f64>, f64)>,
) -> Result<PoseMean, RigAveragingError> {
    let mut acc = MarkleyAccumulator::new();
    let mut translation = Vector3::zeros();
    for (rotation, t, w) in items {
        acc.add_unchecked(rotation.quaternion(), w);
        translation += w * t;
    }
    let rotation = acc.finish()?;
    Ok(PoseMean {
        mean: Isometry3::from_parts(
            Translation3::from(translation / acc.weight_sum()),
            rotation.mean,
        ),
        rotation,
    })
}

/// Checks that a translation is finite.
pub(crate) fn check_translation(index: usize, t: &Vector3<f64>) -> Result<(), RigAveragingError> {
    if t.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(RigAveragingError::NonFiniteTranslation { index })
    }
}
