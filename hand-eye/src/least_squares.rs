//! Weighted Levenberg-Marquardt shared by the refinements, and the covariance of its result.
//!
//! A model has residual blocks of a rotation part (radians) and a translation part (length),
//! weighted by `1/σ_r` and `1/σ_t`. Unless the caller fixes them, `σ_r` and `σ_t` are the RMS
//! residual per component, estimated at the start and again after a first convergence
//! (variance-component estimation), so neither kind of residual dominates by a choice of unit.
//! The covariance of the unknowns is `s² (JᵀJ)⁻¹` (weighted Jacobian, `s²` the residual
//! variance factor).

use nalgebra::{SMatrix, SVector, Vector3};

use crate::error::{HandEyeError, OptionField, Result};
use crate::refine::RefineOptions;

/// Smallest noise figure used as a weight, relative to one radian or to the model's length
/// scale (exact data have zero residuals).
const SIGMA_FLOOR: f64 = 1e-14;

/// A least-squares model with `N` unknowns (some of which may be held fixed).
pub(crate) trait Model<const N: usize> {
    /// The unknowns.
    type State: Copy;
    /// Number of residual blocks.
    fn blocks(&self) -> usize;
    /// Unweighted residual of block `i`: rotation part, translation part.
    fn residual(&self, state: &Self::State, i: usize) -> (Vector3<f64>, Vector3<f64>);
    /// Unweighted Jacobian of block `i` (rows: rotation, translation).
    fn jacobian(&self, state: &Self::State, i: usize) -> SMatrix<f64, 6, N>;
    /// The state moved by `step`.
    fn apply(&self, state: &Self::State, step: &SVector<f64, N>) -> Self::State;
    /// Which unknowns may change.
    fn free(&self) -> [bool; N];
    /// Typical length of the translations, for the floor of `σ_t`.
    fn length(&self) -> f64;
}

/// Fit of a state: residual RMS (per block norm) and covariance of the free unknowns (`None`
/// if the normal matrix is singular: the data do not determine them).
pub(crate) struct Assessment<const N: usize> {
    pub(crate) rotation_rms: f64,
    pub(crate) translation_rms: f64,
    pub(crate) covariance: Option<SMatrix<f64, N, N>>,
}

/// One pass over the blocks: unweighted sums of squared residuals and the rotation and
/// translation parts of the normal equations. Weights are per kind of residual, so the weighted
/// system is `H_r / σ_r² + H_t / σ_t²` and need not be recomputed when they change.
struct Sums<const N: usize> {
    rotation: f64,
    translation: f64,
    h_rotation: SMatrix<f64, N, N>,
    h_translation: SMatrix<f64, N, N>,
    g_rotation: SVector<f64, N>,
    g_translation: SVector<f64, N>,
}

impl<const N: usize> Sums<N> {
    fn cost(&self, sigma: (f64, f64)) -> f64 {
        self.rotation / (sigma.0 * sigma.0) + self.translation / (sigma.1 * sigma.1)
    }

    /// Weighted normal equations `(JᵀJ, Jᵀe)`; fixed unknowns get zero rows and columns and a
    /// unit diagonal.
    fn normal_equations(
        &self,
        sigma: (f64, f64),
        free: &[bool; N],
    ) -> (SMatrix<f64, N, N>, SVector<f64, N>) {
        let (wr, wt) = (1.0 / (sigma.0 * sigma.0), 1.0 / (sigma.1 * sigma.1));
        let mut h = self.h_rotation * wr + self.h_translation * wt;
        let mut g = self.g_rotation * wr + self.g_translation * wt;
        for (k, free) in free.iter().enumerate() {
            if !free {
                h.row_mut(k).fill(0.0);
                h.column_mut(k).fill(0.0);
                h[(k, k)] = 1.0;
                g[k] = 0.0;
            }
        }
        (h, g)
    }
}

/// Sums of squared residuals only (rotation, translation).
fn squared_sums<const N: usize, M: Model<N>>(model: &M, state: &M::State) -> (f64, f64) {
    (0..model.blocks()).fold((0.0, 0.0), |(sr, st), i| {
        let (er, et) = model.residual(state, i);
        (sr + er.norm_squared(), st + et.norm_squared())
    })
}

fn sums<const N: usize, M: Model<N>>(model: &M, state: &M::State) -> Sums<N> {
    let mut sums = Sums {
        rotation: 0.0,
        translation: 0.0,
        h_rotation: SMatrix::zeros(),
        h_translation: SMatrix::zeros(),
        g_rotation: SVector::zeros(),
        g_translation: SVector::zeros(),
    };
    for i in 0..model.blocks() {
        let (er, et) = model.residual(state, i);
        let j = model.jacobian(state, i);
        sums.rotation += er.norm_squared();
        sums.translation += et.norm_squared();
        accumulate(&mut sums.h_rotation, &mut sums.g_rotation, &j, 0, &er);
        accumulate(&mut sums.h_translation, &mut sums.g_translation, &j, 3, &et);
    }
    // Only the upper triangles were accumulated.
    for a in 0..N {
        for b in 0..a {
            sums.h_rotation[(a, b)] = sums.h_rotation[(b, a)];
            sums.h_translation[(a, b)] = sums.h_translation[(b, a)];
        }
    }
    sums
}

/// `h += JᵀJ` (upper triangle) and `g += Jᵀe` for the three rows of `j` from `first`.
fn accumulate<const N: usize>(
    h: &mut SMatrix<f64, N, N>,
    g: &mut SVector<f64, N>,
    j: &SMatrix<f64, 6, N>,
    first: usize,
    e: &Vector3<f64>,
) {
    for a in 0..N {
        let column = [j[(first, a)], j[(first + 1, a)], j[(first + 2, a)]];
        if column == [0.0; 3] {
            continue;
        }
        g[a] += column[0] * e.x + column[1] * e.y + column[2] * e.z;
        for b in a..N {
            h[(a, b)] += column[0] * j[(first, b)]
                + column[1] * j[(first + 1, b)]
                + column[2] * j[(first + 2, b)];
        }
    }
}

/// Noise per component estimated from the sums of squared residuals, floored.
fn estimated_sigmas<const N: usize, M: Model<N>>(model: &M, squared: (f64, f64)) -> (f64, f64) {
    let count = (3 * model.blocks().max(1)) as f64;
    (
        (squared.0 / count).sqrt().max(SIGMA_FLOOR),
        (squared.1 / count).sqrt().max(SIGMA_FLOOR * model.length()),
    )
}

/// Levenberg-Marquardt with fixed weights; returns the state and the iterations taken.
fn levenberg_marquardt<const N: usize, M: Model<N>>(
    model: &M,
    start: M::State,
    sigma: (f64, f64),
    max_iterations: usize,
) -> (M::State, usize) {
    let free = model.free();
    let mut current = start;
    let mut current_sums = sums(model, &current);
    let mut damping = 1e-6;
    let mut iterations = 0;
    while iterations < max_iterations {
        iterations += 1;
        let current_cost = current_sums.cost(sigma);
        let (h, g) = current_sums.normal_equations(sigma, &free);
        let mut improved = false;
        while damping < 1e12 {
            let mut damped = h;
            for k in 0..N {
                damped[(k, k)] += damping * h[(k, k)].max(f64::MIN_POSITIVE);
            }
            let Some(cholesky) = damped.cholesky() else {
                damping *= 10.0;
                continue;
            };
            let candidate = model.apply(&current, &-cholesky.solve(&g));
            let (sr, st) = squared_sums(model, &candidate);
            let candidate_cost = sr / (sigma.0 * sigma.0) + st / (sigma.1 * sigma.1);
            if candidate_cost.is_finite() && candidate_cost <= current_cost {
                improved = current_cost - candidate_cost > 1e-12 * current_cost;
                current = candidate;
                damping = (damping * 0.1).max(1e-12);
                break;
            }
            damping *= 10.0;
        }
        if !improved {
            break;
        }
        current_sums = sums(model, &current);
    }
    (current, iterations)
}

/// Two Levenberg-Marquardt runs, the weights re-estimated in between (unless given).
pub(crate) fn minimize<const N: usize, M: Model<N>>(
    model: &M,
    start: M::State,
    options: &RefineOptions,
) -> Result<(M::State, usize)> {
    for (sigma, field) in [
        (options.rotation_sigma, OptionField::RotationSigma),
        (options.translation_sigma, OptionField::TranslationSigma),
    ] {
        if let Some(value) = sigma.filter(|s| !(*s > 0.0 && s.is_finite())) {
            return Err(HandEyeError::InvalidOptions { field, value });
        }
    }
    let sigmas = |state: &M::State| {
        let estimated = estimated_sigmas(model, squared_sums(model, state));
        (
            options.rotation_sigma.unwrap_or(estimated.0),
            options.translation_sigma.unwrap_or(estimated.1),
        )
    };
    let (first, n1) = levenberg_marquardt(model, start, sigmas(&start), options.max_iterations);
    let (second, n2) = levenberg_marquardt(model, first, sigmas(&first), options.max_iterations);
    Ok((second, n1 + n2))
}

/// Residual RMS and covariance of the free unknowns at `state` (one pass over the blocks).
pub(crate) fn assess<const N: usize, M: Model<N>>(model: &M, state: &M::State) -> Assessment<N> {
    let sums = sums(model, state);
    let sigma = estimated_sigmas(model, (sums.rotation, sums.translation));
    let free = model.free();
    let (h, _) = sums.normal_equations(sigma, &free);
    let blocks = model.blocks().max(1) as f64;
    let unknowns = free.iter().filter(|f| **f).count();
    let dof = (6 * model.blocks()).saturating_sub(unknowns).max(1) as f64;
    let factor = sums.cost(sigma) / dof;
    let covariance = h.cholesky().map(|c| {
        let mut covariance = c.inverse() * factor;
        for (k, free) in free.iter().enumerate() {
            if !free {
                covariance.row_mut(k).fill(0.0);
                covariance.column_mut(k).fill(0.0);
            }
        }
        covariance
    });
    Assessment {
        rotation_rms: (sums.rotation / blocks).sqrt(),
        translation_rms: (sums.translation / blocks).sqrt(),
        covariance,
    }
}

/// Square roots of three diagonal entries of a covariance from `first` on, infinite if there
/// is no covariance.
pub(crate) fn standard_deviations<const N: usize>(
    covariance: &Option<SMatrix<f64, N, N>>,
    first: usize,
) -> Vector3<f64> {
    match covariance {
        Some(c) => Vector3::from_fn(|k, _| c[(first + k, first + k)].max(0.0).sqrt()),
        None => Vector3::repeat(f64::INFINITY),
    }
}
