//! Products with the block-sparse Jacobian as it is stored: one row-major block per
//! (residual block, free argument), in program order.

use crate::program::Program;

/// Calls `f(residual index, block start, rows, cols, first tangent column)` for every stored
/// Jacobian block, residual by residual.
#[inline]
fn for_each_block(program: &Program, mut f: impl FnMut(usize, usize, usize, usize, usize)) {
    for (i, r) in program.res.iter().enumerate() {
        for (slot, info) in program
            .residual_slots(r)
            .iter()
            .zip(program.residual_slot_info(r))
        {
            if slot.wanted {
                let start = r.jac_off + slot.offset as usize;
                f(
                    i,
                    start,
                    r.rows as usize,
                    slot.cols as usize,
                    info.col as usize,
                );
            }
        }
    }
}

/// J ← J diag(scale).
pub(crate) fn scale_columns(program: &Program, jac: &mut [f64], scale: &[f64]) {
    for_each_block(program, |_, start, rows, cols, col| {
        let sc = &scale[col..col + cols];
        for row in jac[start..start + rows * cols].chunks_exact_mut(cols) {
            for (v, s) in row.iter_mut().zip(sc) {
                *v *= s;
            }
        }
    });
}

/// The decrease of the Gauss-Newton model ½|r + J δ|² from ½|r|²:
/// −(Jδ)ᵀ(r + Jδ/2).
pub(crate) fn model_cost_change(
    program: &Program,
    jac: &[f64],
    residuals: &[f64],
    delta: &[f64],
) -> f64 {
    let mut jd = vec![0.0; program.n_res_values];
    for_each_block(program, |i, start, rows, cols, col| {
        let d = &delta[col..col + cols];
        let off = program.res[i].res_off;
        for (k, row) in jac[start..start + rows * cols]
            .chunks_exact(cols)
            .enumerate()
        {
            jd[off + k] += row.iter().zip(d).map(|(a, b)| a * b).sum::<f64>();
        }
    });
    jd.iter()
        .zip(residuals)
        .map(|(v, r)| -v * (r + 0.5 * v))
        .sum()
}
