//! Where every block product of the Schur elimination lands in the reduced system, computed
//! once per solve so the per-iteration loops only add at precomputed addresses.
//!
//! Three targets:
//! - dense: the lower triangle of the reduced matrix S, column-major `n × n`;
//! - blocks: every non-zero block S_ab (a ≥ b) of S stored packed column-major, for the
//!   sparse factorization;
//! - implicit: the blocks of C = F_ᵀF (the reduced blocks' own normal equations) followed by
//!   the diagonal blocks of S (the Schur-Jacobi preconditioner), for conjugate gradients.

use std::collections::HashMap;

use crate::program::{NONE, Program};

/// Which target the addresses point into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TargetKind {
    Dense,
    Blocks,
    Implicit,
}

/// A product Jᵀ_row J_col of one residual's two reduced arguments.
#[derive(Debug, Clone, Copy)]
pub(crate) struct CPair {
    /// Argument (slot) index of the row block inside the residual.
    pub row_slot: u16,
    /// Argument index of the column block.
    pub col_slot: u16,
    /// Address of block (row, col) in the target.
    pub addr: usize,
}

/// A stored block of the target (blocks and implicit targets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct BlockEntry {
    pub row: u32,
    pub col: u32,
    pub addr: usize,
}

/// The precomputed addresses.
#[derive(Debug, Clone)]
pub(crate) struct ReducedLayout {
    pub kind: TargetKind,
    /// Reduced dimension.
    pub n: usize,
    /// Length of the target buffer.
    pub len: usize,
    /// Per program residual, the start of its pairs in `c_pairs` (length residuals + 1).
    pub c_start: Vec<usize>,
    pub c_pairs: Vec<CPair>,
    /// Per chunk, the start of its addresses in `vv_addr` (length chunks + 1).
    pub vv_start: Vec<usize>,
    /// Addresses of the V_p V_qᵀ updates: every pair p ≥ q (index p(p+1)/2 + q) for direct
    /// targets, only p = q for the implicit target.
    pub vv_addr: Vec<usize>,
    /// Address of each reduced block's diagonal block of S (or of the preconditioner).
    pub diag_addr: Vec<usize>,
    /// Implicit target: address of each reduced block's diagonal block of C.
    pub c_diag_addr: Vec<usize>,
    /// Stored blocks, sorted by (col, row): all of S's for the blocks target, C's for the
    /// implicit target.
    pub blocks: Vec<BlockEntry>,
}

impl ReducedLayout {
    /// Leading dimension of a block whose row block has `rows` rows.
    #[inline(always)]
    pub(crate) fn ld(&self, rows: usize) -> usize {
        if self.kind == TargetKind::Dense {
            self.n
        } else {
            rows
        }
    }

    /// Whether every chunk pair is updated (direct solvers) or only the diagonal.
    #[inline(always)]
    pub(crate) fn full_pairs(&self) -> bool {
        self.kind != TargetKind::Implicit
    }

    pub(crate) fn new(program: &Program, kind: TargetKind) -> Self {
        let n = program.n_f;
        let nf = program.f_blocks.len();
        // Residual pairs (row block index >= column block index).
        let mut c_start = Vec::with_capacity(program.res.len() + 1);
        let mut raw_c: Vec<(u16, u16, u32, u32)> = Vec::new();
        let mut fslots: Vec<(u32, u16)> = Vec::new();
        for r in &program.res {
            c_start.push(raw_c.len());
            fslots.clear();
            for (k, info) in program.residual_slot_info(r).iter().enumerate() {
                if info.f_index != NONE {
                    fslots.push((info.f_index, k as u16));
                }
            }
            fslots.sort_unstable();
            for (i, &(fa, sa)) in fslots.iter().enumerate() {
                for &(fb, sb) in &fslots[..=i] {
                    raw_c.push((sa, sb, fa, fb));
                }
            }
        }
        c_start.push(raw_c.len());
        // Chunk pairs.
        let full = kind != TargetKind::Implicit;
        let mut vv_start = Vec::with_capacity(program.chunks.len() + 1);
        let mut raw_vv: Vec<(u32, u32)> = Vec::new();
        for c in &program.chunks {
            vv_start.push(raw_vv.len());
            let fs = &program.chunk_f[c.f.clone()];
            for (p, &fp) in fs.iter().enumerate() {
                if full {
                    for &fq in &fs[..=p] {
                        raw_vv.push((fp, fq));
                    }
                } else {
                    raw_vv.push((fp, fp));
                }
            }
        }
        vv_start.push(raw_vv.len());

        let off = &program.f_offset;
        let size = |a: u32| off[a as usize + 1] - off[a as usize];
        match kind {
            TargetKind::Dense => {
                let addr = |a: u32, b: u32| off[a as usize] + off[b as usize] * n;
                Self {
                    kind,
                    n,
                    len: n * n,
                    c_start,
                    c_pairs: raw_c
                        .iter()
                        .map(|&(sa, sb, fa, fb)| CPair {
                            row_slot: sa,
                            col_slot: sb,
                            addr: addr(fa, fb),
                        })
                        .collect(),
                    vv_start,
                    vv_addr: raw_vv.iter().map(|&(a, b)| addr(a, b)).collect(),
                    diag_addr: (0..nf as u32).map(|a| addr(a, a)).collect(),
                    c_diag_addr: Vec::new(),
                    blocks: Vec::new(),
                }
            }
            TargetKind::Blocks | TargetKind::Implicit => {
                // Stored blocks: S's (residual and chunk pairs) or C's (residual pairs).
                let mut keys: Vec<(u32, u32)> = raw_c.iter().map(|&(_, _, a, b)| (b, a)).collect();
                keys.extend((0..nf as u32).map(|a| (a, a)));
                if kind == TargetKind::Blocks {
                    keys.extend(raw_vv.iter().map(|&(a, b)| (b, a)));
                }
                keys.sort_unstable();
                keys.dedup();
                let mut index = HashMap::with_capacity(keys.len());
                let mut blocks = Vec::with_capacity(keys.len());
                let mut len = 0usize;
                for &(col, row) in &keys {
                    index.insert((row, col), len);
                    blocks.push(BlockEntry {
                        row,
                        col,
                        addr: len,
                    });
                    len += size(row) * size(col);
                }
                let c_pairs = raw_c
                    .iter()
                    .map(|&(sa, sb, fa, fb)| CPair {
                        row_slot: sa,
                        col_slot: sb,
                        addr: index[&(fa, fb)],
                    })
                    .collect();
                let c_diag: Vec<usize> = (0..nf as u32).map(|a| index[&(a, a)]).collect();
                if kind == TargetKind::Blocks {
                    Self {
                        kind,
                        n,
                        len,
                        c_start,
                        c_pairs,
                        vv_start,
                        vv_addr: raw_vv.iter().map(|k| index[k]).collect(),
                        diag_addr: c_diag,
                        c_diag_addr: Vec::new(),
                        blocks,
                    }
                } else {
                    // Preconditioner blocks follow C's blocks.
                    let mut diag_addr = Vec::with_capacity(nf);
                    for a in 0..nf as u32 {
                        diag_addr.push(len);
                        len += size(a) * size(a);
                    }
                    Self {
                        kind,
                        n,
                        len,
                        c_start,
                        c_pairs,
                        vv_start,
                        vv_addr: raw_vv.iter().map(|&(a, _)| diag_addr[a as usize]).collect(),
                        diag_addr,
                        c_diag_addr: c_diag,
                        blocks,
                    }
                }
            }
        }
    }
}
