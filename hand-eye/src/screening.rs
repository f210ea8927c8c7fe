//! Screening of motions before the quaternion-based steps, and quaternion sign alignment.
//!
//! Both Daniilidis' dual-quaternion system and the null-space step of Guo et al. use the
//! quaternions of `A_i` and `B_i` and rely on the *screw congruence theorem* (Chen 1991, used by
//! Daniilidis 1999, §3): since `A_i = X B_i X⁻¹`, both rotate by the same angle, so their
//! quaternions have the same scalar part `cos(θ/2)` — but only for the right choice of sign, as
//! `q` and `-q` are the same rotation. [`screen`] picks that sign by making both scalar parts
//! non-negative. Near a half turn the scalar parts are close to zero and noise can flip one of
//! them, so such motions are rejected; motions that barely rotate say almost nothing about `X`
//! and are rejected too.

use nalgebra::{Quaternion, UnitQuaternion};

use crate::NonExhaustive;
use crate::error::{HandEyeError, OptionField, Result};

/// Default smallest rotation angle of a motion used by the quaternion steps: 2 degrees.
///
/// With rotation noise of a few milliradians, the axis of a smaller rotation is uncertain by
/// several degrees and the translation constraint `(R_A - I) t_X = ...` is scaled by
/// `2 sin(θ/2)`, which amplifies the translation noise by 30 or more.
pub const DEFAULT_MIN_ROTATION: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// Default largest rotation angle of a motion used by the quaternion steps: 175 degrees.
///
/// Within 5 degrees of a half turn the scalar part `cos(θ/2)` is below `sin(2.5°) = 0.044`;
/// beyond that margin it stays above twenty times its noise for rotation noise up to 2 mrad
/// per axis, so the sign alignment cannot be fooled.
pub const DEFAULT_MAX_ROTATION: f64 = 175.0 * std::f64::consts::PI / 180.0;

/// Which motions the quaternion-based steps use.
///
/// A motion is used when both its rotation angles (of `A_i` and of `B_i`) lie in
/// `[min_rotation, max_rotation]`.
///
/// Write them as `MotionScreening { field: value, ..Default::default() }` or with
/// [`MotionScreening::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionScreening {
    /// Smallest rotation angle, radians, in `[0, max_rotation)`. Default
    /// [`DEFAULT_MIN_ROTATION`] (2 degrees).
    pub min_rotation: f64,
    /// Largest rotation angle, radians, in `(min_rotation, π]`. Default
    /// [`DEFAULT_MAX_ROTATION`] (175 degrees).
    pub max_rotation: f64,
    /// Keeps the struct open to new fields; use `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for MotionScreening {
    fn default() -> Self {
        Self {
            min_rotation: DEFAULT_MIN_ROTATION,
            max_rotation: DEFAULT_MAX_ROTATION,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl MotionScreening {
    /// Screening with the given smallest and largest rotation angles, radians.
    #[must_use]
    pub fn new(min_rotation: f64, max_rotation: f64) -> Self {
        Self {
            min_rotation,
            max_rotation,
            non_exhaustive: NonExhaustive(()),
        }
    }

    fn validate(&self) -> Result<()> {
        if !(self.min_rotation >= 0.0 && self.min_rotation < std::f64::consts::PI) {
            return Err(HandEyeError::InvalidOptions {
                field: OptionField::MinRotation,
                value: self.min_rotation,
            });
        }
        if !(self.max_rotation > self.min_rotation && self.max_rotation <= std::f64::consts::PI) {
            return Err(HandEyeError::InvalidOptions {
                field: OptionField::MaxRotation,
                value: self.max_rotation,
            });
        }
        Ok(())
    }
}

/// A motion that passed the screening, with sign-aligned quaternions.
#[derive(Debug, Clone, Copy)]
pub(crate) struct AlignedMotion {
    /// Index of the motion pair in the caller's slice.
    pub(crate) index: usize,
    /// Quaternion of `A_i`, scalar part non-negative.
    pub(crate) qa: Quaternion<f64>,
    /// Quaternion of `B_i`, scalar part non-negative.
    pub(crate) qb: Quaternion<f64>,
}

/// The motions kept by [`screen`] and the counts of those rejected.
#[derive(Debug, Clone, Default)]
pub(crate) struct Screened {
    pub(crate) motions: Vec<AlignedMotion>,
    pub(crate) rejected_small: usize,
    pub(crate) rejected_half_turn: usize,
    pub(crate) largest_rotation: f64,
}

impl Screened {
    /// Errors unless at least `needed` motions were kept.
    pub(crate) fn require(&self, needed: usize, options: &MotionScreening) -> Result<()> {
        if self.motions.is_empty() && self.rejected_half_turn == 0 {
            return Err(HandEyeError::NoRotation {
                largest_rotation: self.largest_rotation,
                min_rotation: options.min_rotation,
            });
        }
        if self.motions.len() < needed {
            return Err(HandEyeError::TooFewMotions {
                usable: self.motions.len(),
                needed,
                rejected_small: self.rejected_small,
                rejected_half_turn: self.rejected_half_turn,
            });
        }
        Ok(())
    }
}

/// Keeps the rotations `(R_A, R_B)` whose angles both lie in the screening range and aligns the
/// signs of their quaternions (both scalar parts made non-negative).
pub(crate) fn screen(
    rotations: impl Iterator<Item = (UnitQuaternion<f64>, UnitQuaternion<f64>)>,
    options: &MotionScreening,
) -> Result<Screened> {
    options.validate()?;
    // θ = 2 atan2(|v|, |w|) compared with a threshold θ₀ without an arctangent: θ < θ₀ if and
    // only if |v| cos(θ₀/2) < |w| sin(θ₀/2).
    let (min_sin, min_cos) = (0.5 * options.min_rotation).sin_cos();
    let (max_sin, max_cos) = (0.5 * options.max_rotation).sin_cos();
    let below =
        |q: &UnitQuaternion<f64>, sin: f64, cos: f64| q.imag().norm() * cos < q.w.abs() * sin;
    let mut screened = Screened::default();
    // The rotation with the largest |v| / |w|, whose angle the errors report.
    let mut largest = UnitQuaternion::<f64>::identity();
    for (index, (ra, rb)) in rotations.enumerate() {
        for q in [&ra, &rb] {
            if q.imag().norm() * largest.w.abs() > largest.imag().norm() * q.w.abs() {
                largest = *q;
            }
        }
        if below(&ra, min_sin, min_cos) || below(&rb, min_sin, min_cos) {
            screened.rejected_small += 1;
        } else if !below(&ra, max_sin, max_cos) || !below(&rb, max_sin, max_cos) {
            screened.rejected_half_turn += 1;
        } else {
            screened.motions.push(AlignedMotion {
                index,
                qa: positive_scalar(ra.into_inner()),
                qb: positive_scalar(rb.into_inner()),
            });
        }
    }
    screened.largest_rotation = largest.angle();
    Ok(screened)
}

/// `q` or `-q`, whichever has a non-negative scalar part.
fn positive_scalar(q: Quaternion<f64>) -> Quaternion<f64> {
    if q.w < 0.0 { -q } else { q }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn rot(angle: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), angle)
    }

    #[test]
    fn rejects_small_and_half_turn_rotations_and_aligns_signs() {
        let deg = std::f64::consts::PI / 180.0;
        let flipped = UnitQuaternion::new_unchecked(-rot(30.0 * deg).into_inner());
        let rotations = [
            (rot(1.0 * deg), rot(1.0 * deg)),
            (rot(30.0 * deg), flipped),
            (rot(178.0 * deg), rot(178.0 * deg)),
        ];
        let screened = screen(rotations.into_iter(), &MotionScreening::default()).unwrap();
        assert_eq!(screened.rejected_small, 1);
        assert_eq!(screened.rejected_half_turn, 1);
        assert_eq!(screened.motions.len(), 1);
        let kept = screened.motions[0];
        assert_eq!(kept.index, 1);
        assert!(kept.qa.w > 0.0 && kept.qb.w > 0.0);
        assert!((kept.qa - kept.qb).norm() < 1e-15);
        assert!((screened.largest_rotation - 178.0 * deg).abs() < 1e-12);
    }

    #[test]
    fn requires_enough_motions() {
        let options = MotionScreening::default();
        let none = screen([(rot(0.01), rot(0.01))].into_iter(), &options).unwrap();
        assert!(matches!(
            none.require(2, &options),
            Err(HandEyeError::NoRotation { .. })
        ));
        let one = screen([(rot(0.5), rot(0.5))].into_iter(), &options).unwrap();
        assert!(matches!(
            one.require(2, &options),
            Err(HandEyeError::TooFewMotions {
                usable: 1,
                needed: 2,
                ..
            })
        ));
        let bad = MotionScreening::new(0.5, 0.1);
        assert!(matches!(
            screen(std::iter::empty(), &bad),
            Err(HandEyeError::InvalidOptions { .. })
        ));
    }
}
