//! Covariance of the non-eliminated blocks at the current parameters: the matching blocks of
//! (JᵀJ)⁻¹, obtained as the inverse of the undamped Schur complement S (the marginal
//! information of the reduced blocks; Triggs et al. 2000, section 6.1), in each block's
//! tangent coordinates.
//!
//! J is the Jacobian of the robustified residuals (Ceres's corrector applied), without the
//! solver's column scaling. The result assumes whitened residuals (unit variance per
//! residual): multiply by σ² for a known pixel noise σ, or by the a-posteriori variance
//! factor 2·cost / (residuals − parameters).

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
    /// # Errors
    /// [`BundleAdjustError::CovarianceUnavailable`] for a constant or eliminated block,
    /// [`BundleAdjustError::SingularInformation`] when JᵀJ is singular (for instance an
    /// unfixed gauge), and the errors of [`Problem::solve`]'s preparation.
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
        let layout = ReducedLayout::new(&program, TargetKind::Dense);
        let mut schur = SchurComplement::new(&program, &layout, exec.threads());
        let zeros = vec![0.0; n];
        if !schur.eliminate(&program, &layout, &jac, &zeros, &zeros, &exec) {
            return Err(BundleAdjustError::SingularInformation);
        }
        let nf = program.n_f;
        let inverse =
            spd_inverse(schur.target_mut(), nf).ok_or(BundleAdjustError::SingularInformation)?;
        let total = offsets[offsets.len() - 1];
        let mut matrix = DMatrix::zeros(total, total);
        for (i, &ci) in cols.iter().enumerate() {
            for (j, &cj) in cols.iter().enumerate() {
                for r in 0..offsets[i + 1] - offsets[i] {
                    for c in 0..offsets[j + 1] - offsets[j] {
                        matrix[(offsets[i] + r, offsets[j] + c)] = inverse[ci + r + (cj + c) * nf];
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
