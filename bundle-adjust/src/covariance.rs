//! Covariance of the non-eliminated blocks at the current parameters: the matching blocks of
//! (JᵀJ)⁻¹, obtained as the inverse of the undamped Schur complement S (the marginal
//! information of the reduced blocks; Triggs et al. 2000, section 6.1), in each block's
//! tangent coordinates.
//!
//! J is the Jacobian of the robustified residuals (Ceres's corrector applied), without the
//! solver's column scaling. The result assumes whitened residuals (unit variance per
//! residual): multiply by σ² for a known pixel noise σ, or by the a-posteriori variance
//! factor 2·cost / (residuals − parameters).
//!
//! Before inverting, the conditioning of S is checked on its unit-diagonal equilibration, as
//! Ceres's `Covariance` checks the reciprocal condition number of JᵀJ against
//! `min_reciprocal_condition_number`: an information matrix singular up to rounding (an open
//! gauge) is a [`BundleAdjustError::CovarianceRankDeficient`], never rounding noise returned as
//! a covariance (see [`Problem::covariance`]).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{
    LltError, LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::cholesky::llt::solve::{solve_in_place, solve_in_place_scratch};
use faer::{MatMut, Par};
use nalgebra::DMatrix;

use crate::dense_solver::spd_inverse;
use crate::error::{BundleAdjustError, Result};
use crate::evaluator::{Accumulated, EvalError, Evaluator};
use crate::options::SolverOptions;
use crate::parallel::Executor;
use crate::problem::{ParameterBlockId, Problem};
use crate::program::{NONE, Program};
use crate::reduced::{ReducedLayout, TargetKind};
use crate::schur::SchurComplement;

/// Covariance of a set of parameter blocks.
#[derive(Debug, Clone, PartialEq)]
pub struct Covariance {
    blocks: Vec<ParameterBlockId>,
    offsets: Vec<usize>,
    matrix: DMatrix<f64>,
}

impl Covariance {
    /// The blocks, in the order of [`Covariance::matrix`].
    #[must_use]
    pub fn blocks(&self) -> &[ParameterBlockId] {
        &self.blocks
    }

    /// The joint covariance of all the blocks, stacked in the order of
    /// [`Covariance::blocks`], in tangent coordinates.
    #[must_use]
    pub fn matrix(&self) -> &DMatrix<f64> {
        &self.matrix
    }

    /// The cross-covariance of blocks `a` and `b` (`tangent(a) × tangent(b)`), or `None` if
    /// either was not requested.
    #[must_use]
    pub fn block(&self, a: ParameterBlockId, b: ParameterBlockId) -> Option<DMatrix<f64>> {
        let i = self.blocks.iter().position(|&x| x == a)?;
        let j = self.blocks.iter().position(|&x| x == b)?;
        let (r0, r1) = (self.offsets[i], self.offsets[i + 1]);
        let (c0, c1) = (self.offsets[j], self.offsets[j + 1]);
        Some(self.matrix.view((r0, c0), (r1 - r0, c1 - c0)).into_owned())
    }
}

impl Problem {
    /// The covariance of `blocks` (free blocks outside the eliminated group) at the current
    /// parameters. The eliminated group is chosen as [`Problem::solve`] chooses it with
    /// `options`; `options.num_threads` workers evaluate the Jacobian.
    ///
    /// **Conditioning.** Before inverting, the reduced information S (the Schur complement of
    /// the eliminated blocks, over all free non-eliminated blocks) is equilibrated to a unit
    /// diagonal, Ŝ = D^-1/2 S D^-1/2 with D = diag S, so that its condition does not depend on
    /// the units of the parameters (pixels, metres, radians), and its reciprocal condition
    /// number λmin(Ŝ)/λmax(Ŝ) is estimated (power and inverse iteration). Below
    /// [`SolverOptions::min_reciprocal_condition_number`] the information is singular up to
    /// rounding (a gauge freedom left open, such as the scale of a bundle adjustment with one
    /// fixed image, or an unobservable parameter): the inverse would be rounding noise, and a
    /// [`BundleAdjustError::CovarianceRankDeficient`] names the reciprocal condition number
    /// and the block with the largest share of the undetermined direction instead. Fix the
    /// gauge ([`crate::BundleAdjustmentOptions::gauge`], [`Problem::set_constant`],
    /// [`Problem::set_constant_subset`]) for a covariance in that gauge.
    ///
    /// Coordinates held by [`Problem::set_constant_subset`] have zero rows and columns.
    ///
    /// # Errors
    /// [`BundleAdjustError::CovarianceUnavailable`] for a constant or eliminated block,
    /// [`BundleAdjustError::CovarianceRankDeficient`] when the information is singular up to
    /// rounding (see above), [`BundleAdjustError::SingularInformation`] when an eliminated
    /// block's information is singular (a point seen once, say), and the errors of
    /// [`Problem::solve`]'s preparation.
    pub fn covariance(
        &self,
        blocks: &[ParameterBlockId],
        options: &SolverOptions,
    ) -> Result<Covariance> {
        options.validate()?;
        self.check_values()?;
        let program = Program::new(self, options.automatic_elimination)?;
        let mut offsets = vec![0];
        let mut cols = Vec::with_capacity(blocks.len());
        for &id in blocks {
            let block = self.block(id)?;
            let col = program.block_col[id.0];
            if col == NONE || (col as usize) < program.n_e {
                return Err(BundleAdjustError::CovarianceUnavailable { block: id.0 });
            }
            cols.push(col as usize - program.n_e);
            offsets.push(offsets[offsets.len() - 1] + block.tangent);
        }
        let exec = Executor::new(options.num_threads)?;
        let evaluator = Evaluator::new(self, &program);
        let n = program.n_tangent();
        let mut res = vec![0.0; program.n_res_values];
        let mut jac = vec![0.0; program.n_jac_values];
        let mut g = vec![0.0; n];
        let mut norms = vec![0.0; n];
        let acc = Accumulated {
            gradient: &mut g,
            column_norms: &mut norms,
        };
        evaluator
            .jacobian(&self.values, &mut res, &mut jac, None, acc, &exec)
            .map_err(|e| match e {
                EvalError::Failed(residual) => {
                    BundleAdjustError::InitialEvaluationFailed { residual }
                }
                EvalError::NonFinite(residual) => BundleAdjustError::NonFiniteResidual { residual },
                EvalError::Shape(residual, position) => {
                    BundleAdjustError::JacobianShapeMismatch { residual, position }
                }
            })?;
        let layout = ReducedLayout::new(&program, TargetKind::Dense)?;
        let mut schur = SchurComplement::new(&program, &layout, exec.threads());
        let zeros = vec![0.0; n];
        // A coordinate held by `set_constant_subset` has a zero Jacobian column: a unit
        // diagonal decouples it without touching the others (its variance is zeroed below).
        let held_diag: Vec<f64> = program.col_mask.iter().map(|m| 1.0 - m).collect();
        let diag = if held_diag.is_empty() {
            &zeros
        } else {
            &held_diag
        };
        if !schur.eliminate(&program, &layout, &jac, &zeros, diag, &exec) {
            return Err(BundleAdjustError::SingularInformation);
        }
        let nf = program.n_f;
        let inverse = conditioned_inverse(schur.target_mut(), nf, options).map_err(
            |(reciprocal_condition_number, coordinate)| {
                // The reduced block holding the coordinate.
                let k = program.f_offset.partition_point(|&o| o <= coordinate) - 1;
                BundleAdjustError::CovarianceRankDeficient {
                    reciprocal_condition_number,
                    min_reciprocal_condition_number: options.min_reciprocal_condition_number,
                    block: program.f_blocks[k.min(program.f_blocks.len() - 1)],
                }
            },
        )?;
        let held = |c: usize| program.col_mask.get(program.n_e + c) == Some(&0.0);
        let total = offsets[offsets.len() - 1];
        let mut matrix = DMatrix::zeros(total, total);
        for (i, &ci) in cols.iter().enumerate() {
            for (j, &cj) in cols.iter().enumerate() {
                for r in 0..offsets[i + 1] - offsets[i] {
                    for c in 0..offsets[j + 1] - offsets[j] {
                        if !held(ci + r) && !held(cj + c) {
                            matrix[(offsets[i] + r, offsets[j] + c)] =
                                inverse[ci + r + (cj + c) * nf];
                        }
                    }
                }
            }
        }
        Ok(Covariance {
            blocks: blocks.to_vec(),
            offsets,
            matrix,
        })
    }
}

/// Iterations of the power and inverse iterations that estimate the extreme eigenvalues of
/// the equilibrated information (inverse iteration converges at once on a near-null
/// direction, the case that matters).
const EIGEN_ITERATIONS: usize = 60;

/// Factors the lower triangle of column-major `a` (`n × n`) in place.
fn cholesky(a: &mut [f64], n: usize) -> core::result::Result<(), LltError> {
    let mut scratch = MemBuffer::new(cholesky_in_place_scratch::<f64>(
        n,
        Par::Seq,
        Default::default(),
    ));
    cholesky_in_place(
        MatMut::from_column_major_slice_mut(a, n, n),
        LltRegularization::default(),
        Par::Seq,
        MemStack::new(&mut scratch),
        Default::default(),
    )
    .map(|_| ())
}

/// Solves in place with a Cholesky factor from [`cholesky`]; `b` is `n × k` column-major.
fn cholesky_solve(factor: &mut [f64], n: usize, b: &mut [f64], k: usize) {
    let mut scratch = MemBuffer::new(solve_in_place_scratch::<f64>(n, k, Par::Seq));
    let factor = MatMut::from_column_major_slice_mut(factor, n, n);
    solve_in_place(
        factor.as_ref(),
        MatMut::from_column_major_slice_mut(b, n, k),
        Par::Seq,
        MemStack::new(&mut scratch),
    );
}

/// y = A x for a symmetric `a` given by its lower triangle (column-major `n × n`).
fn symmetric_product(a: &[f64], n: usize, x: &[f64], y: &mut [f64]) {
    y.fill(0.0);
    for j in 0..n {
        let col = &a[j * n..(j + 1) * n];
        y[j] += col[j] * x[j];
        for i in j + 1..n {
            y[i] += col[i] * x[j];
            y[j] += col[i] * x[i];
        }
    }
}

fn normalize(v: &mut [f64]) -> f64 {
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if norm > 0.0 {
        v.iter_mut().for_each(|x| *x /= norm);
    }
    norm
}

/// A deterministic start vector with no special direction.
fn start_vector(n: usize) -> Vec<f64> {
    let mut v: Vec<f64> = (0..n)
        .map(|i| 1.0 + 0.5 * ((i as f64) * 0.618_033_988_749_895).fract())
        .collect();
    normalize(&mut v);
    v
}

/// The inverse of the reduced information `s` (lower triangle, column-major `n × n`,
/// overwritten), after checking its conditioning.
///
/// The check works on the equilibrated matrix Ŝ = D^-1/2 S D^-1/2 (D = diag S, unit diagonal),
/// whose condition does not depend on the units of the parameters: its largest eigenvalue by
/// power iteration, its smallest by inverse iteration (on Ŝ + σI, σ = 1e-10 λmax, when Ŝ is not
/// numerically positive definite). Returns `Err((reciprocal condition, coordinate))` when
/// λmin/λmax is below `options.min_reciprocal_condition_number` (at rounding level, possibly
/// slightly negative, when Ŝ is singular), with the coordinate of the largest entry of the smallest eigenvector: the
/// direction the data do not determine.
fn conditioned_inverse(
    s: &mut [f64],
    n: usize,
    options: &SolverOptions,
) -> core::result::Result<Vec<f64>, (f64, usize)> {
    if n == 0 {
        return Ok(Vec::new());
    }
    // Equilibrate; a coordinate without information is the undetermined direction itself.
    let mut d = vec![0.0; n];
    for i in 0..n {
        let v = s[i + i * n];
        if !(v.is_finite() && v > 0.0) {
            return Err((0.0, i));
        }
        d[i] = 1.0 / v.sqrt();
    }
    for j in 0..n {
        for i in j..n {
            s[i + j * n] *= d[i] * d[j];
        }
    }
    let equilibrated = s.to_vec();
    // λmax by power iteration (Ŝ has a unit diagonal, so 1 ≤ λmax ≤ n).
    let mut v = start_vector(n);
    let mut w = vec![0.0; n];
    let mut lambda_max = 1.0f64;
    for _ in 0..EIGEN_ITERATIONS {
        symmetric_product(&equilibrated, n, &v, &mut w);
        lambda_max = normalize(&mut w).max(1.0);
        core::mem::swap(&mut v, &mut w);
    }
    // λmin by inverse iteration on the factor of Ŝ, or of Ŝ + σI when Ŝ is not positive
    // definite.
    let mut shift = 0.0;
    if cholesky(s, n).is_err() {
        shift = 1e-10 * lambda_max;
        s.copy_from_slice(&equilibrated);
        for i in 0..n {
            s[i + i * n] += shift;
        }
        if cholesky(s, n).is_err() {
            return Err((0.0, 0));
        }
    }
    let mut v = start_vector(n);
    for _ in 0..EIGEN_ITERATIONS {
        cholesky_solve(s, n, &mut v, 1);
        if normalize(&mut v) == 0.0 || v.iter().any(|x| !x.is_finite()) {
            return Err((0.0, 0));
        }
    }
    symmetric_product(&equilibrated, n, &v, &mut w);
    let lambda_min: f64 = v.iter().zip(&w).map(|(a, b)| a * b).sum();
    let rcond = lambda_min / lambda_max;
    if shift > 0.0 || rcond < options.min_reciprocal_condition_number {
        let coordinate = v
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map_or(0, |(i, _)| i);
        return Err((rcond, coordinate));
    }
    s.copy_from_slice(&equilibrated);
    let Some(mut inverse) = spd_inverse(s, n) else {
        return Err((rcond, 0));
    };
    for j in 0..n {
        for i in 0..n {
            inverse[i + j * n] *= d[i] * d[j];
        }
    }
    if inverse.iter().all(|v| v.is_finite()) {
        Ok(inverse)
    } else {
        Err((0.0, 0))
    }
}
