//! Evaluation of residuals, robust costs and block Jacobians, in parallel over fixed tasks.
//!
//! After a cost function writes its residual r and Jacobian blocks, the loss is folded in with
//! Ceres's corrector (so the solver sees an ordinary least-squares problem with the robust
//! gradient), every Jacobian column is multiplied by its Jacobi scale, and the gradient Jᵀr
//! and the column norms diag(JᵀJ) are accumulated in the same pass. Tasks are fixed ranges of
//! residuals that end on chunk boundaries; their sums are combined in task order, so results
//! do not depend on the thread count.

use crate::LossCurvature;
use crate::corrector::Corrector;
use crate::cost::Jacobians;
use crate::kernels::{Shape, with_shape};
use crate::parallel::{Executor, split_at_offsets};
use crate::problem::Problem;
use crate::program::Program;
use crate::simd::{Isa, Kernel, MulAdd, dispatch};

/// Residual blocks per evaluation task (fixed, so sums do not depend on the thread count).
const RESIDUALS_PER_TASK: usize = 2048;

/// At most this many tasks, which bounds the per-task partial sums over reduced blocks.
const MAX_TASKS: usize = 64;

/// Why an evaluation failed (indices are problem residual-block indices).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EvalError {
    /// The cost function returned false.
    Failed(usize),
    /// A residual or Jacobian entry is not finite.
    NonFinite(usize),
    /// A Jacobian block was written with the wrong shape (residual, argument).
    Shape(usize, usize),
}

/// What a Jacobian evaluation accumulates besides residuals and Jacobian blocks.
pub(crate) struct Accumulated<'a> {
    /// Jᵀr over the tangent vector.
    pub gradient: &'a mut [f64],
    /// diag(JᵀJ) over the tangent vector.
    pub column_norms: &'a mut [f64],
}

/// Calls `f` with the parameter slices of `blocks` inside the value vector `x`.
#[inline(always)]
fn with_params<R>(
    problem: &Problem,
    blocks: &[usize],
    x: &[f64],
    f: impl FnOnce(&[&[f64]]) -> R,
) -> R {
    const INLINE: usize = 8;
    if blocks.len() <= INLINE {
        let mut params: [&[f64]; INLINE] = [&[]; INLINE];
        for (p, &b) in params.iter_mut().zip(blocks) {
            *p = problem.slice(x, b);
        }
        f(&params[..blocks.len()])
    } else {
        let params: Vec<&[f64]> = blocks.iter().map(|&b| problem.slice(x, b)).collect();
        f(&params)
    }
}

/// ½ ρ(|r|²) of problem residual block `ri` at `x`; `scratch` must hold its residuals.
pub(crate) fn residual_cost(
    problem: &Problem,
    ri: usize,
    x: &[f64],
    scratch: &mut [f64],
) -> Result<f64, EvalError> {
    let rb = &problem.residuals[ri];
    let r = &mut scratch[..rb.rows];
    if !with_params(problem, &rb.blocks, x, |p| rb.cost.evaluate(p, r, None)) {
        return Err(EvalError::Failed(ri));
    }
    let s: f64 = r.iter().map(|v| v * v).sum();
    if !s.is_finite() {
        return Err(EvalError::NonFinite(ri));
    }
    Ok(if rb.loss.is_trivial() {
        0.5 * s
    } else {
        0.5 * rb.loss.evaluate(s)[0]
    })
}

/// Evaluates a compiled program.
pub(crate) struct Evaluator<'a> {
    pub problem: &'a Problem,
    pub program: &'a Program,
    tasks: Vec<core::ops::Range<usize>>,
    max_rows: usize,
    isa: Isa,
    /// How a robust loss's curvature enters the corrected Jacobians.
    curvature: LossCurvature,
}

/// Index of the chunk holding chunk residual `i` (program order).
fn chunk_of(program: &Program, i: usize) -> usize {
    program.chunks.partition_point(|c| c.res.end <= i)
}

impl<'a> Evaluator<'a> {
    pub(crate) fn new(problem: &'a Problem, program: &'a Program) -> Self {
        // Tasks end on chunk boundaries, so each owns its eliminated blocks' gradient.
        let n = program.res.len();
        let per_task = RESIDUALS_PER_TASK.max(n.div_ceil(MAX_TASKS));
        let mut tasks = Vec::new();
        let mut start = 0;
        for c in &program.chunks {
            if c.res.end - start >= per_task {
                tasks.push(start..c.res.end);
                start = c.res.end;
            }
        }
        while start < n {
            let end = (start + per_task).min(n);
            tasks.push(start..end);
            start = end;
        }
        let max_rows = problem.residuals.iter().map(|r| r.rows).max().unwrap_or(0);
        Self {
            problem,
            program,
            tasks,
            max_rows,
            isa: Isa::detect(),
            curvature: LossCurvature::Reweighted,
        }
    }

    /// The same evaluator with `curvature` for the corrected Jacobians (Ceres's rule unless
    /// set).
    pub(crate) fn with_curvature(self, curvature: LossCurvature) -> Self {
        Self { curvature, ..self }
    }

    /// Cost of the residuals whose arguments are all constant.
    pub(crate) fn fixed_cost(&self, x: &[f64]) -> Result<f64, EvalError> {
        let mut scratch = vec![0.0; self.max_rows];
        let mut cost = 0.0;
        for &ri in &self.program.fixed_residuals {
            cost += residual_cost(self.problem, ri, x, &mut scratch)?;
        }
        Ok(cost)
    }

    /// Cost of the program's residuals at `x` (values laid out like the problem's).
    pub(crate) fn cost(&self, x: &[f64], exec: &Executor) -> Result<f64, EvalError> {
        let partial = exec.map(self.tasks.clone(), |range| {
            let mut scratch = vec![0.0; self.max_rows];
            let mut cost = 0.0;
            for i in range {
                let ri = self.program.res[i].user as usize;
                cost += residual_cost(self.problem, ri, x, &mut scratch)?;
            }
            Ok(cost)
        });
        let mut total = 0.0;
        for c in partial {
            total += c?;
        }
        Ok(total)
    }

    /// Corrected residuals and scaled Jacobian blocks at `x`, with their gradient and
    /// column norms; returns the cost. Without a `scale`, the columns of coordinates held by
    /// [`Problem::set_constant_subset`] are still zeroed (the program's column mask); a given
    /// `scale` must hold zeros there itself.
    pub(crate) fn jacobian(
        &self,
        x: &[f64],
        residuals: &mut [f64],
        jacobian: &mut [f64],
        scale: Option<&[f64]>,
        acc: Accumulated<'_>,
        exec: &Executor,
    ) -> Result<f64, EvalError> {
        let prog = self.program;
        let scale = scale.or((!prog.col_mask.is_empty()).then_some(prog.col_mask.as_slice()));
        let n_e = prog.n_e;
        let next = |t: &core::ops::Range<usize>| prog.res.get(t.end);
        let res_ends: Vec<usize> = self
            .tasks
            .iter()
            .map(|t| next(t).map_or(prog.n_res_values, |r| r.res_off))
            .collect();
        let jac_ends: Vec<usize> = self
            .tasks
            .iter()
            .map(|t| next(t).map_or(prog.n_jac_values, |r| r.jac_off))
            .collect();
        // Eliminated columns of a task: from its first chunk's to the next task's.
        let e_col = |i: usize| {
            if i >= prog.n_chunk_residuals {
                n_e
            } else {
                prog.chunks[chunk_of(prog, i)].e_col
            }
        };
        let e_ends: Vec<usize> = self.tasks.iter().map(|t| e_col(t.end)).collect();
        let (g_e, g_f) = acc.gradient.split_at_mut(n_e);
        let (c_e, c_f) = acc.column_norms.split_at_mut(n_e);
        let work: Vec<_> = self
            .tasks
            .iter()
            .cloned()
            .zip(split_at_offsets(residuals, &res_ends))
            .zip(split_at_offsets(jacobian, &jac_ends))
            .zip(
                split_at_offsets(g_e, &e_ends)
                    .into_iter()
                    .zip(split_at_offsets(c_e, &e_ends)),
            )
            .map(|(((range, res), jac), (ge, ce))| {
                let e_base = e_col(range.start);
                JacobianTask {
                    evaluator: self,
                    x,
                    scale,
                    range,
                    res,
                    jac,
                    ge,
                    ce,
                    e_base,
                    gf: vec![0.0; prog.n_f],
                    cf: vec![0.0; prog.n_f],
                }
            })
            .collect();
        let isa = self.isa;
        let partial = exec.map(work, |task| dispatch(isa, task));
        let mut total = 0.0;
        g_f.fill(0.0);
        c_f.fill(0.0);
        for p in partial {
            let (c, gf, cf) = p?;
            total += c;
            for (a, b) in g_f.iter_mut().zip(&gf) {
                *a += b;
            }
            for (a, b) in c_f.iter_mut().zip(&cf) {
                *a += b;
            }
        }
        Ok(total)
    }
}

/// One task of a Jacobian evaluation.
struct JacobianTask<'a, 'p> {
    evaluator: &'a Evaluator<'p>,
    x: &'a [f64],
    scale: Option<&'a [f64]>,
    range: core::ops::Range<usize>,
    res: &'a mut [f64],
    jac: &'a mut [f64],
    /// Gradient and column norms of the task's eliminated blocks (owned by the task).
    ge: &'a mut [f64],
    ce: &'a mut [f64],
    /// Tangent offset of `ge[0]`.
    e_base: usize,
    /// Partial gradient and column norms of the reduced blocks.
    gf: Vec<f64>,
    cf: Vec<f64>,
}

type TaskOutput = Result<(f64, Vec<f64>, Vec<f64>), EvalError>;

impl Kernel for JacobianTask<'_, '_> {
    type Output = TaskOutput;
    #[inline(always)]
    fn run<M: MulAdd>(self) -> TaskOutput {
        with_shape!(self.evaluator.program.shape, shape => self.run_shape::<_, M>(shape))
    }
}

impl JacobianTask<'_, '_> {
    #[inline(always)]
    fn run_shape<S: Shape, M: MulAdd>(mut self, shape: S) -> TaskOutput {
        let prog = self.evaluator.program;
        let problem = self.evaluator.problem;
        let n_e = prog.n_e;
        let res_base = prog.res[self.range.start].res_off;
        let jac_base = prog.res[self.range.start].jac_off;
        self.ge.fill(0.0);
        self.ce.fill(0.0);
        let mut cost = 0.0;
        for i in self.range.clone() {
            let layout = &prog.res[i];
            // Chunk residuals have the shape's row count; free ones are read as they are.
            let rows = if i < prog.n_chunk_residuals {
                shape.rows(layout.rows as usize)
            } else {
                layout.rows as usize
            };
            let r0 = layout.res_off - res_base;
            let j0 = layout.jac_off - jac_base;
            let j_end = prog.res.get(i + 1).map_or(prog.n_jac_values, |n| n.jac_off) - jac_base;
            let r = &mut self.res[r0..r0 + rows];
            let jac = &mut self.jac[j0..j_end];
            let ri = layout.user as usize;
            let rb = &problem.residuals[ri];
            let slots = prog.residual_slots(layout);
            let (ok, shape_error) = with_params(problem, &rb.blocks, self.x, |p| {
                let mut jw = Jacobians::new(jac, slots, rows);
                let ok = rb.cost.evaluate(p, r, Some(&mut jw));
                (ok, jw.shape_error())
            });
            if !ok {
                return Err(EvalError::Failed(ri));
            }
            if let Some(position) = shape_error {
                return Err(EvalError::Shape(ri, position));
            }
            let s: f64 = r.iter().map(|v| v * v).sum();
            if !s.is_finite() {
                return Err(EvalError::NonFinite(ri));
            }
            let corrector = if rb.loss.is_trivial() {
                cost += 0.5 * s;
                None
            } else {
                let rho = rb.loss.evaluate(s);
                cost += 0.5 * rho[0];
                Some(Corrector::with_curvature(s, rho, self.evaluator.curvature))
            };
            // A plain √ρ′ reweighting of the Jacobian is folded into the column scaling; a
            // Triggs correction of a residual of up to `TRIGGS_ROWS` rows is applied block by
            // block with the scaling below (from the uncorrected residual kept here), that of
            // a longer residual in a separate pass first.
            let mut factor = 1.0;
            let mut uncorrected = [0.0; TRIGGS_ROWS];
            let mut triggs = None;
            if let Some(c) = &corrector {
                if let Some(f) = c.jacobian_factor() {
                    factor = f;
                } else if rows <= TRIGGS_ROWS {
                    uncorrected[..rows].copy_from_slice(r);
                    triggs = Some(c);
                } else {
                    for slot in slots.iter().filter(|s| s.wanted) {
                        let cols = slot.cols as usize;
                        let off = slot.offset as usize;
                        c.correct_jacobian(r, &mut jac[off..off + rows * cols], cols);
                    }
                }
                c.correct_residual(r);
            }
            let triggs = triggs.map(|c| (c, &uncorrected[..rows]));
            let mut finite = 0.0;
            for (slot, info) in slots.iter().zip(prog.residual_slot_info(layout)) {
                if !slot.wanted {
                    continue;
                }
                let col = info.col as usize;
                let is_e = col < n_e;
                let cols = if i >= prog.n_chunk_residuals {
                    slot.cols as usize
                } else if is_e {
                    shape.e(slot.cols as usize)
                } else {
                    shape.f(slot.cols as usize)
                };
                let off = slot.offset as usize;
                let block = &mut jac[off..off + rows * cols];
                let (g, c) = if is_e {
                    let k = col - self.e_base;
                    (&mut self.ge[k..k + cols], &mut self.ce[k..k + cols])
                } else {
                    let k = col - n_e;
                    (&mut self.gf[k..k + cols], &mut self.cf[k..k + cols])
                };
                let scale = self.scale.map(|s| &s[col..col + cols]);
                // Two rows (a reprojection) and the block sizes of a rig bundle adjustment
                // at compile time on the dynamic shape; the same operations either way.
                let (t, f) = (triggs, factor);
                finite += match (rows, cols) {
                    (2, 3) => finish_block::<M>(block, r, 2, 3, t, f, scale, g, c),
                    (2, 5) => finish_block::<M>(block, r, 2, 5, t, f, scale, g, c),
                    (2, 6) => finish_block::<M>(block, r, 2, 6, t, f, scale, g, c),
                    (2, 8) => finish_block::<M>(block, r, 2, 8, t, f, scale, g, c),
                    (2, 9) => finish_block::<M>(block, r, 2, 9, t, f, scale, g, c),
                    _ => finish_block::<M>(block, r, rows, cols, t, f, scale, g, c),
                };
            }
            // Any non-finite entry makes the sum of entry × 0 a NaN.
            if !finite.is_finite() {
                return Err(EvalError::NonFinite(ri));
            }
        }
        Ok((cost, self.gf, self.cf))
    }
}

/// Columns up to this count are accumulated in local arrays that LLVM keeps in registers.
const LOCAL: usize = 16;

/// Residual rows up to this count have their Triggs correction applied block by block, in
/// [`finish_block`], with the block's sizes known at compile time in the common cases.
const TRIGGS_ROWS: usize = 4;

/// Applies a Triggs correction (the corrector and the uncorrected residual) if there is one,
/// then multiplies a row-major Jacobian block's columns by `factor` times their scale,
/// accumulates its gradient Jᵀr and squared column norms, and returns Σ entry × 0 (NaN if an
/// entry is not finite).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn finish_block<M: MulAdd>(
    block: &mut [f64],
    r: &[f64],
    rows: usize,
    cols: usize,
    triggs: Option<(&Corrector, &[f64])>,
    factor: f64,
    scale: Option<&[f64]>,
    g: &mut [f64],
    c: &mut [f64],
) -> f64 {
    let g = &mut g[..cols];
    let c = &mut c[..cols];
    let block = &mut block[..rows * cols];
    if cols <= LOCAL {
        // Independent accumulators per column: no aliasing with the outputs and no long
        // dependency chain through one running sum.
        let mut sc = [factor; LOCAL];
        if let Some(scale) = scale {
            for (s, v) in sc.iter_mut().zip(&scale[..cols]) {
                *s = factor * v;
            }
        }
        // The correction's rᵀJ per column, then each entry corrected in registers as it is
        // scaled (the operations of `Corrector::correct_jacobian`, without storing the
        // corrected block and loading it again).
        let mut r_dot_j = [0.0; LOCAL];
        if let Some((_, uncorrected)) = triggs {
            for (k, &u) in uncorrected[..rows].iter().enumerate() {
                let row = &block[k * cols..k * cols + cols];
                for j in 0..cols {
                    r_dot_j[j] += row[j] * u;
                }
            }
        }
        let (mut gl, mut cl, mut pl) = ([0.0; LOCAL], [0.0; LOCAL], [0.0; LOCAL]);
        for k in 0..rows {
            let row = &mut block[k * cols..k * cols + cols];
            let rk = r[k];
            for j in 0..cols {
                let x = match triggs {
                    Some((corrector, uncorrected)) => {
                        corrector.corrected_entry(row[j], uncorrected[k], r_dot_j[j])
                    }
                    None => row[j],
                };
                let v = x * sc[j];
                row[j] = v;
                pl[j] = M::madd(v, 0.0, pl[j]);
                gl[j] = M::madd(v, rk, gl[j]);
                cl[j] = M::madd(v, v, cl[j]);
            }
        }
        for j in 0..cols {
            g[j] += gl[j];
            c[j] += cl[j];
        }
        return pl[..cols].iter().sum();
    }
    if let Some((corrector, uncorrected)) = triggs {
        corrector.correct_jacobian(&uncorrected[..rows], block, cols);
    }
    let mut probe = 0.0;
    for k in 0..rows {
        let row = &mut block[k * cols..k * cols + cols];
        let rk = r[k];
        for (j, v) in row.iter_mut().enumerate() {
            *v *= factor * scale.map_or(1.0, |s| s[j]);
            probe = M::madd(*v, 0.0, probe);
            g[j] = M::madd(*v, rk, g[j]);
            c[j] = M::madd(*v, *v, c[j]);
        }
    }
    probe
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RobustLoss;
    use crate::simd::{Fused, Plain};

    /// A Triggs correction applied inside [`finish_block`] (in registers for a block of up
    /// to `LOCAL` columns) gives the block, gradient and column norms of the separate pass
    /// (`Corrector::correct_jacobian`, then the scaling) bit for bit, with and without column
    /// scales, for a reprojection's blocks and a wider one, with either multiply-add.
    #[test]
    fn triggs_correction_in_finish_block_is_the_separate_pass() {
        check_triggs::<Plain>();
        check_triggs::<Fused>();
    }

    fn check_triggs<M: MulAdd>() {
        for (rows, cols) in [(2, 3), (2, 6), (2, 8), (3, 5), (2, LOCAL + 4)] {
            let uncorrected: Vec<f64> = (0..rows).map(|k| 0.7 - 0.45 * k as f64).collect();
            let s: f64 = uncorrected.iter().map(|v| v * v).sum();
            let rho = RobustLoss::Cauchy { scale: 1.0 }.evaluate(s);
            let corrector = Corrector::with_curvature(s, rho, LossCurvature::InlierCurvature);
            assert!(
                corrector.jacobian_factor().is_none(),
                "an inlier is corrected"
            );
            let mut r = uncorrected.clone();
            corrector.correct_residual(&mut r);
            let jac: Vec<f64> = (0..rows * cols)
                .map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.173)
                .collect();
            let scales: Vec<f64> = (0..cols).map(|j| 1.0 / (1.0 + j as f64)).collect();
            for scale in [None, Some(scales.as_slice())] {
                let (mut fused, mut separate) = (jac.clone(), jac.clone());
                let (mut g1, mut c1) = (vec![0.25; cols], vec![0.5; cols]);
                let (mut g2, mut c2) = (g1.clone(), c1.clone());
                let triggs = Some((&corrector, uncorrected.as_slice()));
                let p1 = finish_block::<M>(
                    &mut fused, &r, rows, cols, triggs, 1.0, scale, &mut g1, &mut c1,
                );
                corrector.correct_jacobian(&uncorrected, &mut separate, cols);
                let p2 = finish_block::<M>(
                    &mut separate,
                    &r,
                    rows,
                    cols,
                    None,
                    1.0,
                    scale,
                    &mut g2,
                    &mut c2,
                );
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fused), bits(&separate), "{rows} x {cols}");
                assert_eq!(bits(&g1), bits(&g2), "{rows} x {cols}");
                assert_eq!(bits(&c1), bits(&c2), "{rows} x {cols}");
                assert_eq!(p1.to_bits(), p2.to_bits());
                assert_ne!(fused, jac, "the block was corrected");
            }
        }
    }
}
