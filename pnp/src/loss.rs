//! Robust losses `rho(s)` of the squared residual norm `s = |r|^2`: the workspace's one loss
//! type, also used by `ibc-bundle-adjust`.
//!
//! Definitions, derivatives and the floor on `rho'` are those of Ceres Solver's loss
//! functions (Ceres Solver documentation, "Modeling Non-linear Least Squares", section
//! `LossFunction`; `ceres/loss_function.h`): the cost of a residual is `rho(|r|^2)`, and the
//! scale `a > 0` is the residual norm at which the loss starts to down-weight (for Huber, the
//! norm at which the quadratic becomes linear).
//!
//! A least-squares solver uses a loss through the robustified normal equations of B. Triggs,
//! P. McLauchlan, R. Hartley and A. Fitzgibbon, "Bundle Adjustment -- A Modern Synthesis",
//! Vision Algorithms: Theory and Practice, LNCS 1883, 2000, section 6.8 (equations 10-11): the
//! residual and Jacobian are corrected with `rho'` and `rho''`. Where `rho'' <= 0`, as for
//! every loss here, the correction is the plain reweighting by `rho'` of iteratively
//! reweighted least squares, which is what [`crate::refine_pose`] does.

use crate::error::{PnpError, Result};

/// A robust loss `rho(s)` of the squared norm `s = |r|^2` of a residual `r`.
///
/// The unit of `scale` is that of the residual: radians for the bearing error of
/// [`crate::refine_pose`] (turn pixels into an angle with [`crate::angle_from_pixels`] or
/// [`crate::angle_from_pixels_at`]); for [`crate::refine_pose_weighted`], whose residual is
/// whitened by the information matrix, pixels when the information is that of one-pixel
/// noise (`sigma_px = 1` in [`crate::bearing_information`]); pixels for a reprojection
/// error.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub enum RobustLoss {
    /// Plain least squares, `rho(s) = s`: the maximum-likelihood estimate under Gaussian
    /// noise. The default.
    #[default]
    Trivial,
    /// Huber: `rho(s) = s` for `s <= a^2`, `2 a sqrt(s) - a^2` above.
    Huber {
        /// The scale `a`, in the residual's unit (see the type's docs).
        scale: f64,
    },
    /// Cauchy: `rho(s) = a^2 ln(1 + s / a^2)`.
    Cauchy {
        /// The scale `a`, in the residual's unit (see the type's docs).
        scale: f64,
    },
    /// Soft L1 (pseudo-Huber): `rho(s) = 2 a^2 (sqrt(1 + s / a^2) - 1)`.
    SoftL1 {
        /// The scale `a`, in the residual's unit (see the type's docs).
        scale: f64,
    },
}

/// Smallest `rho'` returned, as in Ceres: a positive floor keeps `sqrt(rho')` and `1 / rho'`
/// finite for huge residuals.
const MIN_RHO_PRIME: f64 = f64::MIN_POSITIVE;

impl RobustLoss {
    /// Checks that the scale is finite and positive ([`RobustLoss::Trivial`] has none).
    ///
    /// # Errors
    /// [`PnpError::InvalidLossScale`] with the scale otherwise.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Self::Trivial => Ok(()),
            Self::Huber { scale } | Self::Cauchy { scale } | Self::SoftL1 { scale } => {
                if scale.is_finite() && scale > 0.0 {
                    Ok(())
                } else {
                    Err(PnpError::InvalidLossScale { scale })
                }
            }
        }
    }

    /// `[rho(s), rho'(s), rho''(s)]` for a squared norm `s >= 0`, with Ceres's formulas and
    /// its floor on `rho'` (the smallest positive normal `f64`). Assumes a valid scale
    /// ([`RobustLoss::validate`]).
    #[inline]
    #[must_use]
    pub fn evaluate(&self, s: f64) -> [f64; 3] {
        match *self {
            Self::Trivial => [s, 1.0, 0.0],
            Self::Huber { scale: a } => {
                let b = a * a;
                if s > b {
                    let r = s.sqrt();
                    let rho1 = (a / r).max(MIN_RHO_PRIME);
                    [2.0 * a * r - b, rho1, -rho1 / (2.0 * s)]
                } else {
                    [s, 1.0, 0.0]
                }
            }
            Self::Cauchy { scale: a } => {
                let b = a * a;
                let c = 1.0 / b;
                let sum = 1.0 + s * c;
                let inv = 1.0 / sum;
                // ln_1p keeps rho ~ s accurate for tiny s, where ln(sum) would round; above
                // 1e-3 the plain logarithm is as accurate (to 1e-13) and cheaper.
                let x = s * c;
                let log = if x < 1e-3 { x.ln_1p() } else { sum.ln() };
                [b * log, inv.max(MIN_RHO_PRIME), -c * inv * inv]
            }
            Self::SoftL1 { scale: a } => {
                let b = a * a;
                let c = 1.0 / b;
                let sum = 1.0 + s * c;
                let tmp = sum.sqrt();
                let rho1 = (1.0 / tmp).max(MIN_RHO_PRIME);
                // 2b (sqrt(sum) - 1) written as 2s / (sqrt(sum) + 1) to avoid cancellation.
                [2.0 * s / (tmp + 1.0), rho1, -(c * rho1) / (2.0 * sum)]
            }
        }
    }

    /// `rho(s)`, the cost of a residual of squared norm `s`: `evaluate(s)[0]`.
    #[inline]
    #[must_use]
    pub fn rho(&self, s: f64) -> f64 {
        self.evaluate(s)[0]
    }

    /// `rho'(s)`, the weight of a residual of squared norm `s` in iteratively reweighted
    /// least squares: `evaluate(s)[1]`.
    #[inline]
    #[must_use]
    pub fn weight(&self, s: f64) -> f64 {
        self.evaluate(s)[1]
    }

    /// True for [`RobustLoss::Trivial`], whose reweighting is the identity.
    #[inline]
    #[must_use]
    pub fn is_trivial(&self) -> bool {
        matches!(self, Self::Trivial)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn losses() -> [RobustLoss; 7] {
        [
            RobustLoss::Trivial,
            RobustLoss::Huber { scale: 1.0 },
            RobustLoss::Huber { scale: 0.3 },
            RobustLoss::Cauchy { scale: 1.0 },
            RobustLoss::Cauchy { scale: 2.5 },
            RobustLoss::SoftL1 { scale: 1.0 },
            RobustLoss::SoftL1 { scale: 0.7 },
        ]
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for loss in losses() {
            for s in [1e-3f64, 0.05, 0.5, 0.9, 1.7, 4.0, 30.0, 1e3] {
                let h = 1e-6 * s.max(1e-3);
                let [_, d1, d2] = loss.evaluate(s);
                let fd1 = (loss.rho(s + h) - loss.rho(s - h)) / (2.0 * h);
                let fd2 = (loss.weight(s + h) - loss.weight(s - h)) / (2.0 * h);
                assert!(
                    (d1 - fd1).abs() <= 1e-6 * d1.abs().max(1e-3),
                    "{loss:?} {s}"
                );
                assert!(
                    (d2 - fd2).abs() <= 1e-4 * d2.abs().max(1e-3),
                    "{loss:?} {s}"
                );
            }
        }
    }

    #[test]
    fn every_loss_is_quadratic_near_zero() {
        for loss in losses() {
            let [rho, d1, _] = loss.evaluate(1e-12);
            assert!((rho / 1e-12 - 1.0).abs() <= 1e-6, "{loss:?}");
            assert!((d1 - 1.0).abs() <= 1e-6, "{loss:?}");
        }
    }

    #[test]
    fn the_floor_keeps_the_weight_positive() {
        for loss in losses() {
            assert!(loss.weight(1e300) > 0.0, "{loss:?}");
        }
    }
}
