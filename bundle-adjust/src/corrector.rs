//! How a robust loss enters the least-squares solver: Ceres's corrector (Ceres Solver,
//! `corrector.h`), after B. Triggs, P. McLauchlan, R. Hartley and A. Fitzgibbon, "Bundle
//! Adjustment -- A Modern Synthesis", Vision Algorithms: Theory and Practice, LNCS 1883, 2000,
//! section 6.8 (equations 10-11).
//!
//! The losses themselves are [`crate::RobustLoss`] (`ibc-pnp`'s, with Ceres's definitions):
//! the cost of a residual block is ½ ρ(|r|²), and [`crate::RobustLoss::evaluate`] gives
//! `[ρ(s), ρ'(s), ρ''(s)]`.

use crate::error::{BundleAdjustError, Result};
use crate::{LossCurvature, RobustLoss};

/// Smallest D = 1 + 2 s ρ″ / ρ′ for which [`LossCurvature::InlierCurvature`] keeps the
/// loss's curvature along the residual; below it the residual is reweighted as in Ceres.
const MIN_INLIER_CURVATURE: f64 = 0.25;

/// The corrector that turns a robustified residual block into an ordinary least-squares one
/// with the same gradient and a Gauss-Newton Hessian that keeps the loss's curvature
/// (Triggs et al. 2000, equations 10-11; the rule Ceres's `Corrector` follows).
///
/// With α the smaller root of ½α² − α − (ρ''/ρ') s = 0, the corrected residual is
/// √ρ' / (1 − α) r and the corrected Jacobian √ρ' (I − α r rᵀ / s) J. When ρ'' ≤ 0 (every loss
/// in the outlier region, and all four [`crate::RobustLoss`] variants) α = 0: plain √ρ'
/// reweighting, unless [`LossCurvature::InlierCurvature`] asks for the correction where
/// (1 − α)² = 1 + 2 s ρ''/ρ' is at least [`MIN_INLIER_CURVATURE`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Corrector {
    sqrt_rho1: f64,
    residual_scaling: f64,
    alpha_sq_norm: f64,
}

impl Corrector {
    /// Builds the corrector for squared norm `s` and loss values `rho` with the given rule
    /// for the loss's curvature.
    #[inline]
    pub(crate) fn with_curvature(s: f64, rho: [f64; 3], curvature: LossCurvature) -> Self {
        let sqrt_rho1 = rho[1].sqrt();
        if curvature == LossCurvature::InlierCurvature && s > 0.0 && rho[2] < 0.0 {
            // (1 − α)² = D, the factor of the curvature along the residual.
            let d = 1.0 + 2.0 * s * rho[2] / rho[1];
            if d >= MIN_INLIER_CURVATURE {
                let root = d.sqrt();
                return Self {
                    sqrt_rho1,
                    residual_scaling: sqrt_rho1 / root,
                    alpha_sq_norm: (1.0 - root) / s,
                };
            }
        }
        if s == 0.0 || rho[2] <= 0.0 {
            return Self {
                sqrt_rho1,
                residual_scaling: sqrt_rho1,
                alpha_sq_norm: 0.0,
            };
        }
        let d = 1.0 + 2.0 * s * rho[2] / rho[1];
        let alpha = 1.0 - d.sqrt();
        Self {
            sqrt_rho1,
            residual_scaling: sqrt_rho1 / (1.0 - alpha),
            alpha_sq_norm: alpha / s,
        }
    }

    /// The factor √ρ′ when the Jacobian correction is a plain reweighting (ρ″ ≤ 0), `None`
    /// when it needs [`Self::correct_jacobian`].
    #[inline]
    pub(crate) fn jacobian_factor(&self) -> Option<f64> {
        (self.alpha_sq_norm == 0.0).then_some(self.sqrt_rho1)
    }

    /// Corrects one row-major Jacobian block (`rows` × `cols`) in place, using the
    /// uncorrected residual.
    #[inline]
    pub(crate) fn correct_jacobian(&self, residual: &[f64], jacobian: &mut [f64], cols: usize) {
        if self.alpha_sq_norm == 0.0 {
            for v in jacobian.iter_mut() {
                *v *= self.sqrt_rho1;
            }
            return;
        }
        for c in 0..cols {
            let mut r_dot_j = 0.0;
            for (k, r) in residual.iter().enumerate() {
                r_dot_j += jacobian[k * cols + c] * r;
            }
            for (k, &r) in residual.iter().enumerate() {
                let v = &mut jacobian[k * cols + c];
                *v = self.corrected_entry(*v, r, r_dot_j);
            }
        }
    }

    /// One corrected Jacobian entry √ρ′ (J_kc − α r_k (rᵀJ)_c / s), from the entry J_kc, the
    /// uncorrected residual's r_k and the column's rᵀJ, for a corrector that is not a plain
    /// reweighting.
    #[inline(always)]
    pub(crate) fn corrected_entry(&self, entry: f64, r_k: f64, r_dot_j: f64) -> f64 {
        self.sqrt_rho1 * (entry - self.alpha_sq_norm * r_k * r_dot_j)
    }

    /// Corrects the residual in place (call after [`Self::correct_jacobian`]).
    #[inline]
    pub(crate) fn correct_residual(&self, residual: &mut [f64]) {
        for v in residual.iter_mut() {
            *v *= self.residual_scaling;
        }
    }
}

/// Checks a loss's scale, as [`crate::BundleAdjustError::InvalidLossScale`].
pub(crate) fn validate_loss(loss: &RobustLoss) -> Result<()> {
    loss.validate()
        .map_err(|_| BundleAdjustError::InvalidLossScale {
            scale: match *loss {
                RobustLoss::Huber { scale }
                | RobustLoss::Cauchy { scale }
                | RobustLoss::SoftL1 { scale } => scale,
                _ => f64::NAN,
            },
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// The corrected residual and Jacobian reproduce the robust cost's gradient
    /// (ρ' Jᵀ r) whatever the sign of ρ''.
    #[test]
    fn corrector_preserves_the_gradient() {
        let r = [0.8, -1.3];
        let j = [0.5, -1.0, 2.0, 0.25, 0.75, -0.5];
        let s: f64 = r.iter().map(|v| v * v).sum();
        // A made-up loss with rho'' > 0 exercises the Triggs branch.
        for rho in [RobustLoss::Cauchy { scale: 1.0 }.evaluate(s), [s, 0.7, 0.2]] {
            let c = Corrector::with_curvature(s, rho, LossCurvature::Reweighted);
            let mut jc = j;
            let mut rc = r;
            c.correct_jacobian(&r, &mut jc, 3);
            c.correct_residual(&mut rc);
            for col in 0..3 {
                let expected = rho[1] * (j[col] * r[0] + j[3 + col] * r[1]);
                let got = jc[col] * rc[0] + jc[3 + col] * rc[1];
                assert_relative_eq!(got, expected, max_relative = 1e-12);
            }
        }
    }

    /// With the inlier curvature, the corrected Gauss-Newton Hessian of an inlier is the
    /// robust cost's, Jᵀ (ρ′ I + 2 ρ″ r rᵀ) J, and the gradient is still ρ′ Jᵀ r; an outlier
    /// (D < 1/4) is reweighted as in Ceres.
    #[test]
    fn inlier_curvature_gives_the_robust_hessian() {
        let j = [0.5, -1.0, 2.0, 0.25, 0.75, -0.5];
        let loss = RobustLoss::Cauchy { scale: 1.0 };
        let hessian = |jc: &[f64; 6], a: usize, b: usize| jc[a] * jc[b] + jc[3 + a] * jc[3 + b];
        // |r|² = 0.25: D = 0.6; |r|² = 2.5: D < 0.
        for (r, inlier) in [([0.3, -0.4], true), ([1.2, -1.0], false)] {
            let s: f64 = r.iter().map(|v| v * v).sum();
            let rho = loss.evaluate(s);
            let c = Corrector::with_curvature(s, rho, LossCurvature::InlierCurvature);
            let mut jc = j;
            let mut rc = r;
            c.correct_jacobian(&r, &mut jc, 3);
            c.correct_residual(&mut rc);
            let rj = |col: usize| j[col] * r[0] + j[3 + col] * r[1];
            for a in 0..3 {
                let gradient = jc[a] * rc[0] + jc[3 + a] * rc[1];
                assert_relative_eq!(gradient, rho[1] * rj(a), max_relative = 1e-12);
                for b in 0..3 {
                    let plain = rho[1] * hessian(&j, a, b);
                    let expected = if inlier {
                        plain + 2.0 * rho[2] * rj(a) * rj(b)
                    } else {
                        plain
                    };
                    assert_relative_eq!(hessian(&jc, a, b), expected, max_relative = 1e-12);
                }
            }
        }
    }

    #[test]
    fn invalid_scales_name_the_scale() {
        for a in [0.0, -1.0, f64::INFINITY] {
            for loss in [
                RobustLoss::Huber { scale: a },
                RobustLoss::Cauchy { scale: a },
                RobustLoss::SoftL1 { scale: a },
            ] {
                assert_eq!(
                    validate_loss(&loss),
                    Err(BundleAdjustError::InvalidLossScale { scale: a })
                );
            }
        }
        assert!(matches!(
            validate_loss(&RobustLoss::Cauchy { scale: f64::NAN }),
            Err(BundleAdjustError::InvalidLossScale { scale }) if scale.is_nan()
        ));
        assert!(validate_loss(&RobustLoss::Trivial).is_ok());
        assert!(validate_loss(&RobustLoss::Cauchy { scale: 1.0 }).is_ok());
    }
}
