//! 6-DoF hand-eye calibration with dual quaternions.
//!
//! K. Daniilidis, "Hand-eye calibration using dual quaternions", The International Journal of
//! Robotics Research 18(3):286-298, 1999.
//!
//! A rigid motion `(R, t)` is the unit dual quaternion `q̌ = q + ε q'`, `q' = ½ t q` (`t` as
//! a pure quaternion). `A_i X = X B_i` becomes `ǎ_i q̌ = q̌ b̌_i`; with the signs of `a_i` and
//! `b_i` aligned (equal scalar parts, screw congruence), its vector parts give six linear
//! equations in the eight unknowns `(q, q')` (Daniilidis eq. 31):
//!
//! ```text
//! ⎡ a - b     [a + b]×     0₃          0₃       ⎤ ⎡ q  ⎤
//! ⎣ a' - b'   [a' + b']×   a - b     [a + b]×   ⎦ ⎣ q' ⎦ = 0
//! ```
//!
//! (`a`, `b`, `a'`, `b'` the vector parts of `a_i`, `b_i`, `a'_i`, `b'_i`; `(q₀, q_v)` the
//! order of the unknown quaternions). Stacked for `m` motions, the `6m × 8` matrix `T` has a
//! two-dimensional null space when two rotation axes are not parallel; the solution is the
//! combination `λ₁ v₇ + λ₂ v₈` of its last right singular vectors with `|q| = 1` and
//! `qᵀq' = 0` (eq. 34-36). When every rotation axis is parallel (planar motion) the translation
//! along that axis drops out: the sixth singular value falls to the noise level of the last
//! two, and the solver reports [`HandEyeError::ParallelRotationAxes`] instead of returning an
//! arbitrary translation.
//!
//! Translations are divided by their RMS before `T` is formed, so the two kinds of rows have
//! the same scale and the singular values do not depend on the unit of length. The singular
//! values and right singular vectors are those of the `8 × 8` triangular factor `R` of the
//! Householder QR decomposition `T = QR`: the same as an SVD of `T` gives, to rounding, at a
//! fraction of its cost. On exact data the solution is exact to about `ε σ₁ / σ₆` (relative):
//! 1e-12 unless the rotation axes are within a fraction of a degree of parallel.

use nalgebra::{DMatrix, Isometry3, Matrix3, Quaternion, SMatrix, SymmetricEigen, Translation3};
use nalgebra::{UnitQuaternion, Vector3, Vector4, linalg::SVD};

use crate::NonExhaustive;
use crate::error::{Decomposition, HandEyeError, NullSpaceStep, OptionField, Result, Unobservable};
use crate::motion::{MotionPair, check_pairs};
use crate::quadratic::unit_circle_roots;
use crate::refine::{Free, Problem, RefineOptions, Uncertainty, Unknowns};
use crate::screening::{AlignedMotion, MotionScreening, screen};

/// Default smallest ratio `σ₆ / σ₇` of the singular values of Daniilidis' matrix `T` for the
/// motion to count as non-degenerate: 10.
///
/// With exact data `σ₇ = σ₈ = 0` and any `σ₆ > 0` passes. With noise, `σ₇` and `σ₈` measure it,
/// and planar motion leaves `σ₆` at the same level (ratios below 2.5 in the crate's tests),
/// as do motions rotating 0.5 to 3 degrees (1.3 to 7.6), while OpenCV's simulated robot motions
/// give 30 and more. Below 10 the weakest direction of `X` is barely above the noise.
pub const DEFAULT_MIN_SIGNAL_TO_NOISE: f64 = 10.0;

/// Axis spread (radians, RMS) below which a degenerate motion set is reported as having
/// parallel rotation axes: 0.1 rad (about 6 degrees).
pub const PARALLEL_AXIS_SPREAD: f64 = 0.1;

/// Iteration limit of the singular value decomposition (it converges in a few dozen).
const SVD_MAX_ITERATIONS: usize = 10_000;

/// Options of [`daniilidis`].
///
/// Write them as `DaniilidisOptions { field: value, ..Default::default() }`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DaniilidisOptions {
    /// Which motions form the linear system. Default [`MotionScreening::default()`]: rotations
    /// between 2 and 175 degrees.
    pub screening: MotionScreening,
    /// Smallest `σ₆ / σ₇` accepted; default [`DEFAULT_MIN_SIGNAL_TO_NOISE`].
    pub min_signal_to_noise: f64,
    /// Nonlinear refinement of the linear solution on the residual of `A_i X = X B_i` over all
    /// motions (see [`crate::refine`]), or `None` (default, the paper's linear solution). When
    /// the absolute trajectories are at hand, [`crate::refine_trajectories`] is the better
    /// refinement.
    pub refine: Option<RefineOptions>,
    /// Keeps the struct open to new fields; use `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for DaniilidisOptions {
    fn default() -> Self {
        Self {
            screening: MotionScreening::default(),
            min_signal_to_noise: DEFAULT_MIN_SIGNAL_TO_NOISE,
            refine: None,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// A 6-DoF hand-eye solution and what the motions say about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandEyeSolution {
    /// `X = a_from_b` (`rig_from_odometry` in the pipeline): `A_i X = X B_i`.
    pub a_from_b: Isometry3<f64>,
    /// Motions in the linear system.
    pub motions_used: usize,
    /// Motions left out of the linear system for rotating less than the minimum.
    pub rejected_small_rotation: usize,
    /// Motions left out of the linear system for rotating too close to a half turn.
    pub rejected_near_half_turn: usize,
    /// Singular values of `T` (translations in units of their RMS), largest first.
    pub singular_values: [f64; 8],
    /// The degeneracy figure `σ₆ / σ₇` (`σ₇` floored at `ε σ₁`, so about 1e12 and more with exact
    /// data).
    pub signal_to_noise: f64,
    /// Residuals of `A_i X = X B_i` over all motions and predicted standard deviations of `X`
    /// (rotation about the axes of frame `a`, translation in frame `a`). The conditioning figure:
    /// small rotations or near-planar motion show here as large standard deviations.
    pub uncertainty: Uncertainty,
    /// Levenberg-Marquardt iterations of the refinement, `None` if it was not run.
    pub refinement_iterations: Option<usize>,
}

/// Solves `A_i X = X B_i` for `X = a_from_b` with Daniilidis' dual-quaternion method (see the
/// module docs), then refines it unless `options.refine` is `None`.
///
/// # Errors
/// - [`HandEyeError::NonFinite`], [`HandEyeError::NotUnitQuaternion`],
///   [`HandEyeError::InvalidOptions`] for invalid input;
/// - [`HandEyeError::NoRotation`] if no motion rotates by the minimum angle,
///   [`HandEyeError::TooFewMotions`] if fewer than two motions pass the screening;
/// - [`HandEyeError::ParallelRotationAxes`] for planar motion (or rotation about one axis);
///   [`HandEyeError::Degenerate`] if `σ₆ / σ₇` is too small for another reason (rotations
///   too small for the noise);
/// - [`HandEyeError::NegativeDiscriminant`] if the null space holds no unit dual quaternion.
pub fn daniilidis(pairs: &[MotionPair], options: &DaniilidisOptions) -> Result<HandEyeSolution> {
    check_pairs(pairs)?;
    if options.min_signal_to_noise.is_nan() || options.min_signal_to_noise < 0.0 {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::DaniilidisMinSignalToNoise,
            value: options.min_signal_to_noise,
        });
    }
    let screened = screen(
        pairs.iter().map(|p| (p.a.rotation, p.b.rotation)),
        &options.screening,
    )?;
    screened.require(2, &options.screening)?;
    let used = &screened.motions;

    let length = rms_translation(pairs, used);
    // Right singular vectors of T from the SVD of the triangular factor of its QR
    // decomposition (same singular values and right vectors, and an 8 × 8 SVD).
    let r = triangular_factor(system_matrix(pairs, used, length));
    let svd = SVD::try_new(r, false, true, f64::EPSILON, SVD_MAX_ITERATIONS).ok_or(
        HandEyeError::NoConvergence {
            what: Decomposition::DaniilidisSvd,
        },
    )?;
    let v_t = svd.v_t.ok_or(HandEyeError::NoConvergence {
        what: Decomposition::DaniilidisSvd,
    })?;
    let singular_values: [f64; 8] = svd.singular_values.into();
    let noise = singular_values[6].max(f64::EPSILON * singular_values[0]);
    let signal_to_noise = singular_values[5] / noise;
    if signal_to_noise.is_nan() || signal_to_noise < options.min_signal_to_noise {
        return Err(degeneracy(used, &v_t, signal_to_noise));
    }

    let v7 = v_t.row(6).transpose();
    let v8 = v_t.row(7).transpose();
    let (u1, w1) = (v7.fixed_rows::<4>(0), v7.fixed_rows::<4>(4));
    let (u2, w2) = (v8.fixed_rows::<4>(0), v8.fixed_rows::<4>(4));
    // qᵀq' = 0 (eq. 35) as a quadratic in (λ₁, λ₂).
    let roots = unit_circle_roots(u1.dot(&w1), u1.dot(&w2) + u2.dot(&w1), u2.dot(&w2)).map_err(
        |discriminant| HandEyeError::NegativeDiscriminant {
            step: NullSpaceStep::DualQuaternion,
            discriminant,
        },
    )?;
    // Of the two roots, the solution has the larger |q| (the other is (0, q), |q| = 0 with exact
    // data); it is then scaled to |q| = 1 (eq. 36).
    let real_norm = |(l1, l2): (f64, f64)| (u1 * l1 + u2 * l2).norm();
    let (l1, l2) = if real_norm(roots[0]) >= real_norm(roots[1]) {
        roots[0]
    } else {
        roots[1]
    };
    let real = u1 * l1 + u2 * l2;
    let dual = (w1 * l1 + w2 * l2) / real.norm();
    let real = real / real.norm();
    let q = Quaternion::new(real[0], real[1], real[2], real[3]);
    let q_dual = Quaternion::new(dual[0], dual[1], dual[2], dual[3]);
    // t = 2 q' q̄ (vector part), back in the caller's unit of length.
    let t = (q_dual * q.conjugate()).imag() * (2.0 * length);
    let a_from_b = Isometry3::from_parts(Translation3::from(t), UnitQuaternion::new_normalize(q));

    let problem = Problem::new(pairs.iter().map(|p| (p.a, p.b)).collect(), Free::ALL);
    let start = Unknowns {
        z: a_from_b,
        scale: 1.0,
    };
    let (fit, refinement_iterations) = match &options.refine {
        Some(refine) => {
            let (fit, iterations) = problem.refine(start, refine)?;
            (fit, Some(iterations))
        }
        None => (problem.assess(start), None),
    };
    Ok(HandEyeSolution {
        a_from_b: fit.unknowns.z,
        motions_used: used.len(),
        rejected_small_rotation: screened.rejected_small,
        rejected_near_half_turn: screened.rejected_half_turn,
        singular_values,
        signal_to_noise,
        uncertainty: fit.uncertainty,
        refinement_iterations,
    })
}

/// RMS norm of the translations of the used motions (1 if they are all zero).
fn rms_translation(pairs: &[MotionPair], used: &[AlignedMotion]) -> f64 {
    let sum: f64 = used
        .iter()
        .map(|m| {
            let p = &pairs[m.index];
            p.a.translation.vector.norm_squared() + p.b.translation.vector.norm_squared()
        })
        .sum();
    let rms = (sum / (2 * used.len()) as f64).sqrt();
    if rms > 0.0 { rms } else { 1.0 }
}

/// The `6m × 8` matrix `T` of Daniilidis eq. 31, translations divided by `length`.
fn system_matrix(pairs: &[MotionPair], used: &[AlignedMotion], length: f64) -> DMatrix<f64> {
    let mut t = DMatrix::zeros(6 * used.len(), 8);
    for (k, motion) in used.iter().enumerate() {
        let pair = &pairs[motion.index];
        let (a, b) = (motion.qa, motion.qb);
        let half_pure = |v: Vector3<f64>| Quaternion::from_imag(v * (0.5 / length));
        let a_dual = half_pure(pair.a.translation.vector) * a;
        let b_dual = half_pure(pair.b.translation.vector) * b;
        let real = block(&a, &b);
        let dual = block(&a_dual, &b_dual);
        let row = 6 * k;
        t.fixed_view_mut::<3, 4>(row, 0).copy_from(&real);
        t.fixed_view_mut::<3, 4>(row + 3, 0).copy_from(&dual);
        t.fixed_view_mut::<3, 4>(row + 3, 4).copy_from(&real);
    }
    t
}

/// The upper-triangular factor `R` of the QR decomposition of a tall `n × 8` matrix (n ≥ 8),
/// by Householder reflections applied to its contiguous columns. `T = QR` has the singular
/// values and right singular vectors of `R`.
fn triangular_factor(t: DMatrix<f64>) -> SMatrix<f64, 8, 8> {
    let n = t.nrows();
    let mut a = t.data.into();
    let a: &mut Vec<f64> = &mut a;
    let mut r = SMatrix::<f64, 8, 8>::zeros();
    for k in 0..8 {
        let (head, tail) = a.split_at_mut((k + 1) * n);
        let v = &mut head[k * n + k..(k + 1) * n];
        let norm = dot(v, v).sqrt();
        if norm == 0.0 {
            // Zero column below the diagonal: nothing to eliminate.
            for j in k + 1..8 {
                r[(k, j)] = tail[(j - k - 1) * n + k];
            }
            continue;
        }
        // Reflect v onto -sign(v₀) |v| e₁ (no cancellation), H = I - 2 u uᵀ / uᵀu.
        let alpha = -norm.copysign(v[0]);
        v[0] -= alpha;
        let scale = 2.0 / dot(v, v);
        r[(k, k)] = alpha;
        for j in k + 1..8 {
            let column = &mut tail[(j - k - 1) * n + k..(j - k) * n];
            let factor = dot(v, column) * scale;
            for (c, x) in column.iter_mut().zip(v.iter()) {
                *c -= factor * x;
            }
            r[(k, j)] = column[0];
        }
    }
    r
}

/// `xᵀy` summed in four independent lanes (which the compiler can keep in vector registers).
fn dot(x: &[f64], y: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (x4, y4) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = x4
        .remainder()
        .iter()
        .zip(y4.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in x4.zip(y4) {
        for lane in 0..4 {
            lanes[lane] += a[lane] * b[lane];
        }
    }
    lanes[0] + lanes[1] + lanes[2] + lanes[3] + tail
}

/// The `3 × 4` block `[a - b, [a + b]×]` acting on `(q₀, q_v)`.
fn block(a: &Quaternion<f64>, b: &Quaternion<f64>) -> nalgebra::Matrix3x4<f64> {
    let mut m = nalgebra::Matrix3x4::zeros();
    m.set_column(0, &(a.imag() - b.imag()));
    m.fixed_view_mut::<3, 3>(0, 1)
        .copy_from(&(a.imag() + b.imag()).cross_matrix());
    m
}

/// Names what a degenerate motion set leaves unobservable.
fn degeneracy(
    used: &[AlignedMotion],
    v_t: &SMatrix<f64, 8, 8>,
    signal_to_noise: f64,
) -> HandEyeError {
    // Scatter of the rotation axes of the A_i, weighted by sin²(θ/2).
    let scatter: Matrix3<f64> = used
        .iter()
        .map(|m| m.qa.imag() * m.qa.imag().transpose())
        .sum();
    let eigen = SymmetricEigen::new(scatter);
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| eigen.eigenvalues[j].total_cmp(&eigen.eigenvalues[i]));
    let largest = eigen.eigenvalues[order[0]];
    let rest = eigen.eigenvalues[order[1]] + eigen.eigenvalues[order[2]];
    let axis_spread = if largest > 0.0 {
        (rest.max(0.0) / largest).sqrt()
    } else {
        0.0
    };
    if largest > 0.0 && axis_spread < PARALLEL_AXIS_SPREAD {
        return HandEyeError::ParallelRotationAxes {
            axis_a: eigen.eigenvectors.column(order[0]).into_owned(),
            axis_spread,
            signal_to_noise,
        };
    }
    // Otherwise the weakest direction of T (the sixth right singular vector) says whether the
    // rotation part q or the translation part q' is poorly determined.
    let weakest: Vector4<f64> = v_t.row(5).transpose().fixed_rows::<4>(0).into_owned();
    let unobservable = if weakest.norm_squared() > 0.5 {
        Unobservable::Rotation
    } else {
        Unobservable::Translation
    };
    HandEyeError::Degenerate {
        unobservable,
        signal_to_noise,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn triangular_factor_matches_the_qr_decomposition() {
        let t = DMatrix::from_fn(20, 8, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 - 5.0 + (i as f64).sin()
        });
        let r = triangular_factor(t.clone());
        // Upper triangular, and RᵀR = TᵀT (R is unique up to the signs of its rows).
        for i in 0..8 {
            for j in 0..i {
                assert_eq!(r[(i, j)], 0.0);
            }
        }
        let expected = t.transpose() * &t;
        let gram = r.transpose() * r;
        assert_relative_eq!(
            gram,
            SMatrix::<f64, 8, 8>::from_fn(|i, j| expected[(i, j)]),
            max_relative = 1e-12
        );
        let svd_t = SVD::new(t, false, false);
        let svd_r = SVD::new(r, false, false);
        for k in 0..8 {
            assert_relative_eq!(
                svd_t.singular_values[k],
                svd_r.singular_values[k],
                max_relative = 1e-12
            );
        }
    }
}
