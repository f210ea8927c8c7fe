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
use crate::summary::{IterationControl, IterationSummary, Summary};

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
    /// Tangent coordinates held at their values ([`Problem::set_constant_subset`]), ascending
    /// and distinct.
    pub held: Vec<usize>,
}

impl ParameterBlock {
    /// Whether nothing of the block may move: constant, or every tangent coordinate held.
    pub(crate) fn is_fixed(&self) -> bool {
        self.constant || self.held.len() == self.tangent
    }
}

pub(crate) struct ResidualBlock {
    pub cost: Box<dyn CostFunction>,
    pub loss: RobustLoss,
    /// The arguments; empty once removed.
    pub blocks: Arguments,
    pub rows: usize,
    /// Removed by [`Problem::remove_residual_block`]: left out of every solve.
    pub removed: bool,
}

/// A residual block's parameter blocks: up to [`Arguments::INLINE`] held in place, so that a
/// problem of millions of residual blocks (a bundle adjustment's observations) does not
/// allocate a list per block, and the passes over them read it next to the block.
#[derive(Debug, Clone)]
pub(crate) enum Arguments {
    Inline {
        ids: [usize; Arguments::INLINE],
        len: u8,
    },
    Heap(Vec<usize>),
}

impl Arguments {
    /// The most arguments held in place: a reprojection with free intrinsics has four.
    const INLINE: usize = 4;

    fn new(ids: &[ParameterBlockId]) -> Self {
        match u8::try_from(ids.len()) {
            Ok(len) if ids.len() <= Self::INLINE => {
                let mut inline = [0; Self::INLINE];
                for (to, id) in inline.iter_mut().zip(ids) {
                    *to = id.0;
                }
                Self::Inline { ids: inline, len }
            }
            _ => Self::Heap(ids.iter().map(|id| id.0).collect()),
        }
    }
}

impl core::ops::Deref for Arguments {
    type Target = [usize];
    #[inline]
    fn deref(&self) -> &[usize] {
        match self {
            Self::Inline { ids, len } => &ids[..usize::from(*len)],
            Self::Heap(ids) => ids,
        }
    }
}

impl<'a> IntoIterator for &'a Arguments {
    type Item = &'a usize;
    type IntoIter = core::slice::Iter<'a, usize>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

/// What a removed residual block holds instead of its cost function (no allocation).
struct RemovedCost;

impl CostFunction for RemovedCost {
    fn num_residuals(&self) -> usize {
        0
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[]
    }
    fn evaluate(&self, _: &[&[f64]], _: &mut [f64], _: Option<&mut crate::Jacobians<'_>>) -> bool {
        false
    }
}

/// A robust non-linear least-squares problem, min ½ Σᵢ ρᵢ(|rᵢ(x)|²).
#[derive(Default)]
pub struct Problem {
    pub(crate) values: Vec<f64>,
    pub(crate) blocks: Vec<ParameterBlock>,
    pub(crate) residuals: Vec<ResidualBlock>,
    /// Number of residual blocks not removed.
    pub(crate) live_residuals: usize,
}

impl core::fmt::Debug for Problem {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Problem")
            .field("parameter_blocks", &self.blocks.len())
            .field("residual_blocks", &self.live_residuals)
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
            held: Vec::new(),
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

    /// Holds the entries `indices` of a block at their current values while the others stay
    /// free (Ceres's `SubsetManifold`); an empty slice frees them all again. Replaces any
    /// subset set before; repeated indices count once. Holding every entry is the same as
    /// [`Problem::set_constant`]. Useful to keep some intrinsics of a camera (a principal
    /// point, the distortion) while refining the others.
    ///
    /// For a vector block the indices are entries of the block, which stay bit-identical
    /// through a solve. For a block on a [`Manifold`] they are coordinates of the tangent
    /// step δ: the solver never steps along them (for [`crate::Se3Manifold`], δ = `[ρ, φ]` of
    /// the right perturbation T · Exp(δ), so holding indices 3..6 keeps the rotation and
    /// holding 0..3 forbids translation steps in the block's own frame). A held coordinate
    /// has zero variance in [`Problem::covariance`].
    ///
    /// ```
    /// use ibc_bundle_adjust::Problem;
    ///
    /// let mut problem = Problem::new();
    /// let intrinsics = problem.add_parameter_block(&[460.0, 458.0, 370.0, 245.0])?;
    /// // Hold the principal point, refine the focal lengths.
    /// problem.set_constant_subset(intrinsics, &[2, 3])?;
    /// assert_eq!(problem.constant_subset(intrinsics)?, &[2, 3]);
    /// # Ok::<(), ibc_bundle_adjust::BundleAdjustError>(())
    /// ```
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem,
    /// [`BundleAdjustError::SubsetIndexOutOfRange`] for an index at or past the block's
    /// tangent size (its size for a vector block).
    pub fn set_constant_subset(
        &mut self,
        block: ParameterBlockId,
        indices: &[usize],
    ) -> Result<()> {
        let b = self.block_mut(block)?;
        if let Some(&index) = indices.iter().find(|&&i| i >= b.tangent) {
            return Err(BundleAdjustError::SubsetIndexOutOfRange {
                block: block.0,
                index,
                tangent: b.tangent,
            });
        }
        let mut held = indices.to_vec();
        held.sort_unstable();
        held.dedup();
        b.held = held;
        Ok(())
    }

    /// The entries (tangent coordinates for a manifold block) of a block held by
    /// [`Problem::set_constant_subset`], ascending; empty when none is held.
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] for an id of another problem.
    pub fn constant_subset(&self, block: ParameterBlockId) -> Result<&[usize]> {
        Ok(&self.block(block)?.held)
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

    /// Room for `additional` more residual blocks, allocated once (a bundle adjustment
    /// knows its observation count).
    pub(crate) fn reserve_residual_blocks(&mut self, additional: usize) {
        self.residuals.reserve(additional);
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
            blocks: Arguments::new(blocks),
            rows,
            removed: false,
        });
        self.live_residuals += 1;
        Ok(ResidualBlockId(id))
    }

    /// Removes a residual block: later solves (and [`Problem::covariance`]) leave it out, as
    /// if it had never been added; its cost function is dropped. The ids of the other
    /// residual blocks stay valid and new ones are never reused, so an online user can drop
    /// old observations between solves. A parameter block left without residual blocks is
    /// simply not optimized (it keeps its values).
    ///
    /// ```
    /// use ibc_bundle_adjust::{CostFunction, Jacobians, Problem, RobustLoss};
    /// use ibc_bundle_adjust::nalgebra::Matrix1;
    ///
    /// /// r = x − target.
    /// struct Prior(f64);
    /// impl CostFunction for Prior {
    ///     fn num_residuals(&self) -> usize { 1 }
    ///     fn parameter_block_sizes(&self) -> &[usize] { &[1] }
    ///     fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
    ///         r[0] = p[0][0] - self.0;
    ///         if let Some(j) = j { j.set(0, &Matrix1::new(1.0)); }
    ///         true
    ///     }
    /// }
    ///
    /// let mut problem = Problem::new();
    /// let x = problem.add_parameter_block(&[0.0])?;
    /// let old = problem.add_residual_block(Prior(1.0), RobustLoss::Trivial, &[x])?;
    /// problem.add_residual_block(Prior(3.0), RobustLoss::Trivial, &[x])?;
    /// problem.remove_residual_block(old)?;
    /// assert_eq!(problem.num_residual_blocks(), 1);
    /// problem.solve(&Default::default())?;
    /// // Only the second prior is left: x goes to 3 (to the default tolerances).
    /// assert!((problem.parameter_block(x)?[0] - 3.0).abs() < 1e-3);
    /// # Ok::<(), ibc_bundle_adjust::BundleAdjustError>(())
    /// ```
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownResidualBlock`] for an id of another problem or one
    /// already removed.
    pub fn remove_residual_block(&mut self, residual: ResidualBlockId) -> Result<()> {
        let count = self.live_residuals;
        match self.residuals.get_mut(residual.0) {
            Some(r) if !r.removed => {
                r.removed = true;
                r.blocks = Arguments::new(&[]);
                r.cost = Box::new(RemovedCost);
                self.live_residuals -= 1;
                Ok(())
            }
            _ => Err(BundleAdjustError::UnknownResidualBlock {
                residual: residual.0,
                count,
            }),
        }
    }

    /// Whether a residual block id names a block of this problem that was not removed.
    #[must_use]
    pub fn has_residual_block(&self, residual: ResidualBlockId) -> bool {
        self.residuals.get(residual.0).is_some_and(|r| !r.removed)
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
        crate::levenberg_marquardt::solve(self, options, &mut |_| IterationControl::Continue)
    }

    /// [`Problem::solve`], calling `callback` with every iteration's summary as it is logged
    /// (iteration 0, the evaluation of the start, first; rejected steps too). Returning
    /// [`IterationControl::Stop`] ends the solve with [`crate::Termination::UserStop`] at the
    /// last accepted point: a progress display, a cancel button or a custom stopping rule.
    /// With [`SolverOptions::max_iterations`] and
    /// [`SolverOptions::max_solver_time_in_seconds`] this bounds the work of an online solve.
    ///
    /// ```
    /// use ibc_bundle_adjust::{CostFunction, IterationControl, Jacobians, Problem, RobustLoss,
    ///     SolverOptions, Termination};
    /// use ibc_bundle_adjust::nalgebra::Matrix1;
    ///
    /// /// r = exp(x) − 2, slow enough to take several iterations from x = 3.
    /// struct Exp;
    /// impl CostFunction for Exp {
    ///     fn num_residuals(&self) -> usize { 1 }
    ///     fn parameter_block_sizes(&self) -> &[usize] { &[1] }
    ///     fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
    ///         r[0] = p[0][0].exp() - 2.0;
    ///         if let Some(j) = j { j.set(0, &Matrix1::new(p[0][0].exp())); }
    ///         true
    ///     }
    /// }
    /// let mut problem = Problem::new();
    /// let x = problem.add_parameter_block(&[3.0])?;
    /// problem.add_residual_block(Exp, RobustLoss::Trivial, &[x])?;
    /// let mut seen = Vec::new();
    /// let summary = problem.solve_with_callback(&SolverOptions::default(), |it| {
    ///     seen.push(it.iteration);
    ///     if it.iteration == 2 { IterationControl::Stop } else { IterationControl::Continue }
    /// })?;
    /// assert_eq!(summary.termination, Termination::UserStop);
    /// assert_eq!(seen, [0, 1, 2]);
    /// # Ok::<(), ibc_bundle_adjust::BundleAdjustError>(())
    /// ```
    ///
    /// # Errors
    /// As [`Problem::solve`].
    pub fn solve_with_callback(
        &mut self,
        options: &SolverOptions,
        mut callback: impl FnMut(&IterationSummary) -> IterationControl,
    ) -> Result<Summary> {
        crate::levenberg_marquardt::solve(self, options, &mut callback)
    }

    /// Number of parameter blocks.
    #[must_use]
    pub fn num_parameter_blocks(&self) -> usize {
        self.blocks.len()
    }

    /// Number of residual blocks (not counting removed ones).
    #[must_use]
    pub fn num_residual_blocks(&self) -> usize {
        self.live_residuals
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
