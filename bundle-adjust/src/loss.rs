//! Robust loss functions ρ(s) of the squared residual norm s = |r|², with Ceres's
//! definitions (Ceres Solver, `loss_function.h`; Triggs et al., "Bundle Adjustment — A Modern
//! Synthesis", 2000, section 6.8).
//!
//! The cost of a residual block is ½ ρ(|r|²). Each loss returns `[ρ(s), ρ'(s), ρ''(s)]`; the
//! scale `a > 0` is where the loss starts to down-weight (for Huber it is the residual norm at
//! which the quadratic becomes linear).

use crate::error::{BundleAdjustError, Result};

/// A robust loss ρ(s) applied to the squared norm s of a residual block.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[non_exhaustive]
pub enum Loss {
    /// ρ(s) = s: ordinary least squares.
    #[default]
    Trivial,
    /// Huber with scale a: ρ(s) = s for s ≤ a², 2a√s − a² above.
    Huber(f64),
    /// Cauchy with scale a: ρ(s) = a² log(1 + s/a²).
    Cauchy(f64),
    /// Soft L1 with scale a: ρ(s) = 2a² (√(1 + s/a²) − 1).
    SoftL1(f64),
}

/// Smallest ρ' allowed, as in Ceres: a positive floor keeps √ρ' and 1/ρ' finite.
const MIN_RHO_PRIME: f64 = f64::MIN_POSITIVE;

impl Loss {
    /// Checks that the scale is finite and positive.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidLossScale`] otherwise.
    pub fn validate(&self) -> Result<()> {
        match *self {
            Loss::Trivial => Ok(()),
            Loss::Huber(a) | Loss::Cauchy(a) | Loss::SoftL1(a) => {
                if a.is_finite() && a > 0.0 {
                    Ok(())
                } else {
                    Err(BundleAdjustError::InvalidLossScale(a))
                }
            }
        }
    }

    /// Returns `[ρ(s), ρ'(s), ρ''(s)]` for a squared norm `s ≥ 0`.
    #[inline]
    #[must_use]
    pub fn evaluate(&self, s: f64) -> [f64; 3] {
        match *self {
            Loss::Trivial => [s, 1.0, 0.0],
            Loss::Huber(a) => {
                let b = a * a;
                if s > b {
                    let r = s.sqrt();
                    let rho1 = (a / r).max(MIN_RHO_PRIME);
                    [2.0 * a * r - b, rho1, -rho1 / (2.0 * s)]
                } else {
                    [s, 1.0, 0.0]
                }
            }
            Loss::Cauchy(a) => {
                let b = a * a;
                let c = 1.0 / b;
                let sum = 1.0 + s * c;
                let inv = 1.0 / sum;
                // ln_1p keeps ρ ≈ s accurate for tiny s, where ln(sum) would round; above
                // 1e-3 the plain logarithm is as accurate (to 1e-13) and cheaper.
                let x = s * c;
                let log = if x < 1e-3 { x.ln_1p() } else { sum.ln() };
                [b * log, inv.max(MIN_RHO_PRIME), -c * inv * inv]
            }
            Loss::SoftL1(a) => {
                let b = a * a;
                let c = 1.0 / b;
                let sum = 1.0 + s * c;
                let tmp = sum.sqrt();
                let rho1 = (1.0 / tmp).max(MIN_RHO_PRIME);
                // 2b(√sum − 1) written as 2s/(√sum + 1) to avoid cancellation.
                [2.0 * s / (tmp + 1.0), rho1, -(c * rho1) / (2.0 * sum)]
            }
        }
    }

    /// True for [`Loss::Trivial`], whose correction is the identity.
    #[inline]
    #[must_use]
    pub fn is_trivial(&self) -> bool {
        matches!(self, Loss::Trivial)
    }
}

/// The corrector that turns a robustified residual block into an ordinary least-squares one
/// with the same gradient and a Gauss-Newton Hessian that keeps the loss's curvature
/// (Triggs et al. 2000, equations 10-11; the rule Ceres's `Corrector` follows).
///
/// With α the smaller root of ½α² − α − (ρ''/ρ') s = 0, the corrected residual is
/// √ρ' / (1 − α) r and the corrected Jacobian √ρ' (I − α r rᵀ / s) J. When ρ'' ≤ 0 (every loss
/// in the outlier region, and all four losses here) α = 0: plain √ρ' reweighting.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Corrector {
    sqrt_rho1: f64,
    residual_scaling: f64,
    alpha_sq_norm: f64,
}

impl Corrector {
    /// Builds the corrector for squared norm `s` and loss values `rho`.
    #[inline]
    pub(crate) fn new(s: f64, rho: [f64; 3]) -> Self {
        let sqrt_rho1 = rho[1].sqrt();
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
            for (k, r) in residual.iter().enumerate() {
                let v = &mut jacobian[k * cols + c];
                *v = self.sqrt_rho1 * (*v - self.alpha_sq_norm * r * r_dot_j);
            }
        }
    }

    /// Corrects the residual in place (call after [`Self::correct_jacobian`]).
    #[inline]
    pub(crate) fn correct_residual(&self, residual: &mut [f64]) {
        for v in residual.iter_mut() {
            *v *= self.residual_scaling;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn losses() -> Vec<Loss> {
        vec![
            Loss::Trivial,
            Loss::Huber(1.0),
            Loss::Huber(0.3),
            Loss::Cauchy(1.0),
            Loss::Cauchy(2.5),
            Loss::SoftL1(1.0),
            Loss::SoftL1(0.7),
        ]
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for loss in losses() {
            for &s in &[1e-3f64, 0.05, 0.5, 0.9, 1.7, 4.0, 30.0, 1e3] {
                let h = 1e-6 * s.max(1e-3);
                let [_, d1, d2] = loss.evaluate(s);
                let fd1 = (loss.evaluate(s + h)[0] - loss.evaluate(s - h)[0]) / (2.0 * h);
                let fd2 = (loss.evaluate(s + h)[1] - loss.evaluate(s - h)[1]) / (2.0 * h);
                assert_relative_eq!(d1, fd1, max_relative = 1e-6, epsilon = 1e-9);
                assert_relative_eq!(d2, fd2, max_relative = 1e-4, epsilon = 1e-7);
            }
        }
    }

    #[test]
    fn all_losses_are_quadratic_near_zero() {
        for loss in losses() {
            let [rho, d1, _] = loss.evaluate(1e-12);
            assert_relative_eq!(rho, 1e-12, max_relative = 1e-6);
            assert_relative_eq!(d1, 1.0, max_relative = 1e-6);
        }
    }

    #[test]
    fn cauchy_matches_its_definition() {
        let [rho, d1, d2] = Loss::Cauchy(2.0).evaluate(3.0);
        assert_relative_eq!(rho, 4.0 * (1.0f64 + 0.75).ln(), max_relative = 1e-15);
        assert_relative_eq!(d1, 1.0 / 1.75, max_relative = 1e-15);
        assert_relative_eq!(d2, -0.25 / (1.75 * 1.75), max_relative = 1e-15);
    }

    #[test]
    fn invalid_scales_are_rejected() {
        for a in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(Loss::Cauchy(a).validate().is_err());
            assert!(Loss::Huber(a).validate().is_err());
            assert!(Loss::SoftL1(a).validate().is_err());
        }
        assert!(Loss::Trivial.validate().is_ok());
    }

    /// The corrected residual and Jacobian reproduce the robust cost's gradient
    /// (ρ' Jᵀ r) whatever the sign of ρ''.
    #[test]
    fn corrector_preserves_the_gradient() {
        let r = [0.8, -1.3];
        let j = [0.5, -1.0, 2.0, 0.25, 0.75, -0.5];
        let s: f64 = r.iter().map(|v| v * v).sum();
        // A made-up loss with rho'' > 0 exercises the Triggs branch.
        for rho in [Loss::Cauchy(1.0).evaluate(s), [s, 0.7, 0.2]] {
            let c = Corrector::new(s, rho);
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
}
