//! A non-linear least-squares problem: parameter blocks, residual blocks and their losses.
//!
//! The problem owns the parameter values; [`Problem::solve`] updates them in place and
//! [`Problem::parameter_block`] reads them back.

use std::sync::Arc;

use crate::RobustLoss;
use crate::corrector::validate_loss;
use crate::cost::CostFunction;
use crate::error::{BundleAdjustError, Result};
use crate::manifold::Manifold;
use crate::options::SolverOptions;
use crate::summary::Summary;

/// Identifies a parameter block of one [`Problem`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParameterBlockId(pub(crate) usize);

impl ParameterBlockId {
    /// The block's index, in order of creation.
    #[must_use]
    pub fn index(self) -> usize {
        self.0
    }
}

/// Identifies a residual block of one [`Problem`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ResidualBlockId(pub(crate) usize);

impl ResidualBlockId {
    /// The block's index, in order of creation.
    #[must_use]
    pub fn index(self) -> usize {
        self.0
    }
}

#[derive(Debug, Clone)]
pub(crate) struct ParameterBlock {
    pub offset: usize,
    pub size: usize,
    pub tangent: usize,
    pub manifold: Option<Arc<dyn Manifold>>,
    pub constant: bool,
    pub eliminate: bool,
}

pub(crate) struct ResidualBlock {
    pub cost: Box<dyn CostFunction>,
    pub loss: RobustLoss,
    pub blocks: Vec<usize>,
    pub rows: usize,
}

/// A robust non-linear least-squares problem, min ½ Σᵢ ρᵢ(|rᵢ(x)|²).
#[derive(Default)]
pub struct Problem {
    pub(crate) values: Vec<f64>,
    pub(crate) blocks: Vec<ParameterBlock>,
    pub(crate) residuals: Vec<ResidualBlock>,
}

impl core::fmt::Debug for Problem {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Problem")
            .field("parameter_blocks", &self.blocks.len())
            .field("residual_blocks", &self.residuals.len())
            .finish()
    }
}

impl Problem {
    /// An empty problem.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a vector parameter block holding `values`.
    ///
    /// # Errors
    /// [`BundleAdjustError::EmptyParameterBlock`] for an empty slice,
    /// [`BundleAdjustError::NonFiniteParameter`] for a NaN or infinite value.
    pub fn add_parameter_block(&mut self, values: &[f64]) -> Result<ParameterBlockId> {
        self.push_block(values, None)
    }

    /// Adds a parameter block living on `manifold` (see [`crate::manifold`]).
    ///
    /// # Errors
    /// As [`Problem::add_parameter_block`], and
    /// [`BundleAdjustError::ManifoldSizeMismatch`] when `values` does not have the manifold's
    /// ambient size.
    pub fn add_manifold_block(
        &mut self,
        values: &[f64],
        manifold: impl Manifold + 'static,
    ) -> Result<ParameterBlockId> {
        if manifold.ambient_size() != values.len() {
            return Err(BundleAdjustError::ManifoldSizeMismatch {
                expected: manifold.ambient_size(),
                got: values.len(),
            });
        }
        if manifold.tangent_size() == 0 {
            return Err(BundleAdjustError::EmptyParameterBlock);
        }
        self.push_block(values, Some(Arc::new(manifold)))
    }

    fn push_block(
        &mut self,
        values: &[f64],
        manifold: Option<Arc<dyn Manifold>>,
    ) -> Result<ParameterBlockId> {
        if values.is_empty() {
            return Err(BundleAdjustError::EmptyParameterBlock);
        }
        let id = self.blocks.len();
        check_finite(id, values)?;
        let tangent = manifold.as_ref().map_or(values.len(), |m| m.tangent_size());
        self.blocks.push(ParameterBlock {
            offset: self.values.len(),
            size: values.len(),
            tangent,
            manifold,
            constant: false,
            eliminate: false,
        });
        self.values.extend_from_slice(values);
        Ok(ParameterBlockId(id))
    }

    /// Holds a block constant (`true`) or frees it again (`false`).
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn set_constant(&mut self, block: ParameterBlockId, constant: bool) -> Result<()> {
        self.block_mut(block)?.constant = constant;
        Ok(())
    }

    /// Puts a block in (or takes it out of) the group eliminated by the Schur complement.
    /// No two eliminated blocks may share a residual block. When no block is marked, the
    /// solver chooses the group itself (see
    /// [`crate::SolverOptions::automatic_elimination`]).
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn set_eliminated(&mut self, block: ParameterBlockId, eliminate: bool) -> Result<()> {
        self.block_mut(block)?.eliminate = eliminate;
        Ok(())
    }

    /// Whether a block is held constant.
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn is_constant(&self, block: ParameterBlockId) -> Result<bool> {
        Ok(self.block(block)?.constant)
    }

    /// Adds a residual block r = `cost`(blocks...) with robust loss `loss` (its cost is
    /// ½ ρ(|r|²); [`RobustLoss::Trivial`] for plain least squares).
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`],
    /// [`BundleAdjustError::ParameterCountMismatch`],
    /// [`BundleAdjustError::ParameterSizeMismatch`],
    /// [`BundleAdjustError::DuplicateParameterBlock`],
    /// [`BundleAdjustError::DegenerateCostFunction`] or
    /// [`BundleAdjustError::InvalidLossScale`].
    pub fn add_residual_block(
        &mut self,
        cost: impl CostFunction + 'static,
        loss: RobustLoss,
        blocks: &[ParameterBlockId],
    ) -> Result<ResidualBlockId> {
        self.add_boxed_residual_block(Box::new(cost), loss, blocks)
    }

    /// [`Problem::add_residual_block`] for an already boxed cost function.
    ///
    /// # Errors
    /// As [`Problem::add_residual_block`].
    pub fn add_boxed_residual_block(
        &mut self,
        cost: Box<dyn CostFunction>,
        loss: RobustLoss,
        blocks: &[ParameterBlockId],
    ) -> Result<ResidualBlockId> {
        validate_loss(&loss)?;
        let sizes = cost.parameter_block_sizes();
        let rows = cost.num_residuals();
        if rows == 0 || sizes.is_empty() {
            return Err(BundleAdjustError::DegenerateCostFunction);
        }
        if sizes.len() != blocks.len() {
            return Err(BundleAdjustError::ParameterCountMismatch {
                expected: sizes.len(),
                got: blocks.len(),
            });
        }
        for (position, (&id, &expected)) in blocks.iter().zip(sizes).enumerate() {
            let block = self.block(id)?;
            if block.size != expected {
                return Err(BundleAdjustError::ParameterSizeMismatch {
                    block: id.0,
                    position,
                    expected,
                    got: block.size,
                });
            }
            if blocks[..position].contains(&id) {
                return Err(BundleAdjustError::DuplicateParameterBlock { block: id.0 });
            }
        }
        let id = self.residuals.len();
        self.residuals.push(ResidualBlock {
            cost,
            loss,
            blocks: blocks.iter().map(|b| b.0).collect(),
            rows,
        });
        Ok(ResidualBlockId(id))
    }

    /// The current values of a block.
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn parameter_block(&self, block: ParameterBlockId) -> Result<&[f64]> {
        let b = self.block(block)?;
        Ok(&self.values[b.offset..b.offset + b.size])
    }

    /// Overwrites the values of a block.
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`],
    /// [`BundleAdjustError::ParameterSizeMismatch`] or
    /// [`BundleAdjustError::NonFiniteParameter`].
    pub fn set_parameter_block(&mut self, block: ParameterBlockId, values: &[f64]) -> Result<()> {
        let b = self.block(block)?;
        if values.len() != b.size {
            return Err(BundleAdjustError::ParameterSizeMismatch {
                block: block.0,
                position: 0,
                expected: b.size,
                got: values.len(),
            });
        }
        check_finite(block.0, values)?;
        let offset = b.offset;
        self.values[offset..offset + values.len()].copy_from_slice(values);
        Ok(())
    }

    /// Minimizes the cost with Levenberg-Marquardt and a Schur-complement linear solver,
    /// updating the free blocks in place (see [`crate::levenberg_marquardt`]).
    ///
    /// # Errors
    /// [`BundleAdjustError::EmptyProblem`], [`BundleAdjustError::InvalidOption`],
    /// [`BundleAdjustError::NonFiniteParameter`],
    /// [`BundleAdjustError::EliminatedBlocksCoupled`], or an evaluation error at the initial
    /// parameters. Trouble during the iterations ends the solve with a
    /// [`crate::Termination`] instead.
    pub fn solve(&mut self, options: &SolverOptions) -> Result<Summary> {
        crate::levenberg_marquardt::solve(self, options)
    }

    /// Number of parameter blocks.
    #[must_use]
    pub fn num_parameter_blocks(&self) -> usize {
        self.blocks.len()
    }

    /// Number of residual blocks.
    #[must_use]
    pub fn num_residual_blocks(&self) -> usize {
        self.residuals.len()
    }

    /// Tangent size of a block (its stored size for a vector block).
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn tangent_size(&self, block: ParameterBlockId) -> Result<usize> {
        Ok(self.block(block)?.tangent)
    }

    pub(crate) fn block(&self, id: ParameterBlockId) -> Result<&ParameterBlock> {
        let count = self.blocks.len();
        self.blocks
            .get(id.0)
            .ok_or(BundleAdjustError::UnknownParameterBlock { block: id.0, count })
    }

    fn block_mut(&mut self, id: ParameterBlockId) -> Result<&mut ParameterBlock> {
        let count = self.blocks.len();
        self.blocks
            .get_mut(id.0)
            .ok_or(BundleAdjustError::UnknownParameterBlock { block: id.0, count })
    }

    /// The values of block `b` inside a full parameter vector laid out like `self.values`.
    #[inline]
    pub(crate) fn slice<'a>(&self, values: &'a [f64], b: usize) -> &'a [f64] {
        let block = &self.blocks[b];
        &values[block.offset..block.offset + block.size]
    }

    /// Checks every stored value is finite.
    pub(crate) fn check_values(&self) -> Result<()> {
        for (id, b) in self.blocks.iter().enumerate() {
            check_finite(id, &self.values[b.offset..b.offset + b.size])?;
        }
        Ok(())
    }
}

fn check_finite(block: usize, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(BundleAdjustError::NonFiniteParameter {
            block,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}
