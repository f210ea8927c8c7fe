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
