//! Residual blocks: the [`CostFunction`] trait and the [`Jacobians`] it writes into.
//!
//! A cost function maps the values of its parameter blocks to a residual vector r of fixed
//! length and, on request, writes the Jacobian of r with respect to each block's tangent step
//! (∂r(x ⊞ δ)/∂δ at δ = 0; for a plain vector block that is ∂r/∂x). Jacobian blocks are
//! stored row-major, `num_residuals × tangent_size`, straight into the solver's block-sparse
//! Jacobian: no scalar sparse matrix is ever assembled.

use nalgebra::SMatrix;

/// A residual block's function: residuals and analytic Jacobians.
///
/// ```
/// use ibc_bundle_adjust::{CostFunction, Jacobians};
/// use nalgebra::Matrix2;
///
/// /// r = x − target for a 2-vector x.
/// struct Prior([f64; 2]);
///
/// impl CostFunction for Prior {
///     fn num_residuals(&self) -> usize { 2 }
///     fn parameter_block_sizes(&self) -> &[usize] { &[2] }
///     fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
///         r[0] = p[0][0] - self.0[0];
///         r[1] = p[0][1] - self.0[1];
///         if let Some(j) = j {
///             j.set(0, &Matrix2::identity());
///         }
///         true
///     }
/// }
/// ```
pub trait CostFunction: Send + Sync {
    /// Length of the residual vector (fixed for the life of the function).
    fn num_residuals(&self) -> usize;

    /// Number of stored (ambient) values of each parameter block, in argument order.
    fn parameter_block_sizes(&self) -> &[usize];

    /// Computes the residuals for `parameters` (one slice per block, ambient values) and, when
    /// `jacobians` is given, the Jacobian blocks it asks for
    /// (see [`Jacobians::wants`]). Returns false when the residual is undefined at these
    /// parameters (a point behind a camera, say): the solver then rejects the step.
    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool;
}

/// Where one argument's Jacobian block lives inside a residual block's Jacobian storage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct JacobianSlot {
    /// Offset from the start of the residual block's Jacobian storage.
    pub offset: u32,
    /// Number of columns (the block's tangent size).
    pub cols: u32,
    /// False for constant blocks, whose Jacobian is never needed.
    pub wanted: bool,
}

/// The Jacobian blocks a cost function writes, one per argument, each row-major
/// `num_residuals × tangent_size`.
#[derive(Debug)]
pub struct Jacobians<'a> {
    data: &'a mut [f64],
    slots: &'a [JacobianSlot],
    rows: usize,
    shape_error: Option<usize>,
}

impl<'a> Jacobians<'a> {
    pub(crate) fn new(data: &'a mut [f64], slots: &'a [JacobianSlot], rows: usize) -> Self {
        Self {
            data,
            slots,
            rows,
            shape_error: None,
        }
    }

    /// Whether the solver needs the Jacobian of argument `i` (false for constant blocks).
    #[inline]
    #[must_use]
    pub fn wants(&self, i: usize) -> bool {
        self.slots.get(i).is_some_and(|s| s.wanted)
    }

    /// The row-major storage (`num_residuals × tangent_size`) of argument `i`'s Jacobian, or
    /// `None` when it is not wanted.
    #[inline]
    pub fn row_major_mut(&mut self, i: usize) -> Option<&mut [f64]> {
        let slot = *self.slots.get(i)?;
        if !slot.wanted {
            return None;
        }
        let start = slot.offset as usize;
        self.data
            .get_mut(start..start + self.rows * slot.cols as usize)
    }

    /// Writes argument `i`'s Jacobian from a fixed-size matrix (rows = residuals, columns =
    /// tangent size). Does nothing when the block is not wanted; a matrix of the wrong shape
    /// is recorded and reported by the solver as
    /// [`crate::BundleAdjustError::JacobianShapeMismatch`].
    #[inline]
    pub fn set<const R: usize, const C: usize>(&mut self, i: usize, jacobian: &SMatrix<f64, R, C>) {
        let Some(slot) = self.slots.get(i).copied() else {
            self.shape_error = Some(i);
            return;
        };
        if !slot.wanted {
            return;
        }
        if R != self.rows || C != slot.cols as usize {
            self.shape_error = Some(i);
            return;
        }
        let start = slot.offset as usize;
        if let Some(block) = self.data.get_mut(start..start + R * C) {
            // Column-major source, row-major destination.
            let src = jacobian.as_slice();
            for c in 0..C {
                for r in 0..R {
                    block[r * C + c] = src[c * R + r];
                }
            }
        }
    }

    /// The argument whose Jacobian was written with the wrong shape, if any.
    pub(crate) fn shape_error(&self) -> Option<usize> {
        self.shape_error
    }
}

/// Checks whether residual blocks can be evaluated as the solver's first evaluation needs:
/// the cost function returns true, writes every Jacobian block with the right shape, and
/// everything it writes is finite. Reuses its buffers from one check to the next.
#[derive(Debug, Default)]
pub(crate) struct EvaluationProbe {
    slots: Vec<JacobianSlot>,
    residuals: Vec<f64>,
    jacobian: Vec<f64>,
}

impl EvaluationProbe {
    /// Whether `cost` can be evaluated at `parameters`, with every Jacobian block wanted
    /// (`tangents` gives each argument's tangent size).
    pub(crate) fn evaluates(
        &mut self,
        cost: &dyn CostFunction,
        parameters: &[&[f64]],
        tangents: &[usize],
    ) -> bool {
        let rows = cost.num_residuals();
        self.slots.clear();
        let mut offset = 0usize;
        for &t in tangents {
            let (Ok(off), Ok(cols)) = (u32::try_from(offset), u32::try_from(t)) else {
                return false;
            };
            self.slots.push(JacobianSlot {
                offset: off,
                cols,
                wanted: true,
            });
            offset += rows * t;
        }
        self.residuals.clear();
        self.residuals.resize(rows, 0.0);
        self.jacobian.clear();
        self.jacobian.resize(offset, 0.0);
        let mut jacobians = Jacobians::new(&mut self.jacobian, &self.slots, rows);
        let ok = cost.evaluate(parameters, &mut self.residuals, Some(&mut jacobians));
        ok && jacobians.shape_error().is_none()
            && self.residuals.iter().all(|v| v.is_finite())
            && self.jacobian.iter().all(|v| v.is_finite())
    }

    /// |r|² of `cost` at `parameters`, evaluated without Jacobians (about a fifth of the
    /// work of [`Self::evaluates`] for a reprojection), or `None` when it cannot be evaluated
    /// or is not finite. For costs whose Jacobians exist wherever their residuals do, as the
    /// camera models' projections: one that does not still fails the solve with a typed
    /// error naming its block.
    pub(crate) fn residual_norm2(
        &mut self,
        cost: &dyn CostFunction,
        parameters: &[&[f64]],
    ) -> Option<f64> {
        self.residuals.clear();
        self.residuals.resize(cost.num_residuals(), 0.0);
        let ok = cost.evaluate(parameters, &mut self.residuals, None);
        let s: f64 = self.residuals.iter().map(|v| v * v).sum();
        (ok && s.is_finite()).then_some(s)
    }
}
