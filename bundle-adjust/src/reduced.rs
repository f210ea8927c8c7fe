//! Where every block product of the Schur elimination lands in the reduced system, computed
//! once per solve so the per-iteration loops only add at known addresses.
//!
//! Three targets:
//! - dense: the lower triangle of the reduced matrix S, column-major `n × n`;
//! - blocks: every non-zero block S_ab (a ≥ b) of S stored packed column-major, for the
//!   sparse factorization;
//! - implicit: the blocks of C = F_ᵀF (the reduced blocks' own normal equations) followed by
//!   the diagonal blocks of S (the Schur-Jacobi preconditioner), for conjugate gradients.
//!
//! The addresses of a residual's own products are listed per residual; those of a chunk's
//! products V_p V_qᵀ (as many as the pairs of the chunk's reduced blocks, ~2,100 per point in
//! a rig bundle adjustment) are not: the elimination walks a group of chunks column by
//! column and finds each block in its column of the stored structure ([`ColumnCursor`]), so
//! the layout's size and build time follow the number of stored blocks, not the number of
//! updates.

use crate::error::Result;
use crate::program::{NONE, Program, ResidualLayout, to_u32};

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
    /// Address of block (row, col) in the target (32 bits, which halves the pair: the
    /// implicit target lists six a residual with intrinsics free, 10.7M in the full garage of
    /// the rig bundle adjustment).
    pub addr: u32,
}

/// A stored block of the target (blocks and implicit targets).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct BlockEntry {
    pub row: u32,
    pub col: u32,
    pub addr: usize,
}

/// A chunk residual's product Jᵀ_row J_col (direct targets), applied to S with its chunk's
/// products V_p V_qᵀ; 20 bytes (32 with 64-bit offsets), one per pair of a chunk residual's
/// reduced blocks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ChunkPair {
    /// Reduced block of the column.
    pub col: u32,
    /// Reduced block of the row.
    pub row: u32,
    /// Offsets of the row's and the column's Jacobian blocks in the Jacobian buffer, from
    /// the chunk's first residual's ([`ReducedLayout::chunk_jac_base`]).
    pub a: u32,
    pub b: u32,
    /// Residual rows.
    pub rows: u32,
}

/// The precomputed addresses.
#[derive(Debug, Clone)]
pub(crate) struct ReducedLayout {
    pub kind: TargetKind,
    /// Reduced dimension.
    pub n: usize,
    /// Length of the target buffer.
    pub len: usize,
    /// Per program residual from `c_first` on, the start of its pairs in `c_pairs` (length
    /// residuals − `c_first` + 1): every residual's for the implicit target, the free
    /// residuals' for the direct ones (a chunk residual's products are applied with its
    /// chunk's, from `chunk_pairs`).
    c_start: Vec<usize>,
    c_first: usize,
    c_pairs: Vec<CPair>,
    /// Address of each reduced block's diagonal block of S (or of the preconditioner; empty
    /// for an implicit target without it).
    pub diag_addr: Vec<usize>,
    /// Implicit target: address of each reduced block's diagonal block of C.
    pub c_diag_addr: Vec<usize>,
    /// Stored blocks, sorted by (col, row): all of S's for the blocks target, C's for the
    /// implicit target.
    pub blocks: Vec<BlockEntry>,
    /// Start of each column's blocks in `blocks` (length reduced blocks + 1; blocks and
    /// implicit targets).
    pub col_start: Vec<usize>,
    /// Offset of each reduced block in the reduced vector (dense target).
    offsets: Vec<usize>,
    /// Direct targets: the products of each chunk's residuals, sorted by (column, row) within
    /// a chunk (residual order within a block), and the start of each chunk's (length chunks
    /// + 1).
    pub chunk_pairs: Vec<ChunkPair>,
    pub chunk_pair_start: Vec<usize>,
}

/// The addresses of the blocks (p, q) of one column q of the target, for rows p ≥ q asked in
/// ascending order (a chunk's reduced blocks are sorted): each is found from the previous
/// one, most often at the next stored block.
pub(crate) enum ColumnCursor<'a> {
    /// Dense target: `offsets[p] + col`, `col` the column's offset times the leading
    /// dimension.
    Dense { offsets: &'a [usize], col: usize },
    /// Blocks target: the column's stored blocks (rows ascending) and the next one.
    Blocks {
        blocks: &'a [BlockEntry],
        next: usize,
    },
}

impl ColumnCursor<'_> {
    /// The address of block (`row`, column). `row` must be a stored block of the column,
    /// above the previous one asked.
    #[inline(always)]
    pub(crate) fn addr(&mut self, row: u32) -> usize {
        match self {
            ColumnCursor::Dense { offsets, col } => offsets[row as usize] + *col,
            ColumnCursor::Blocks { blocks, next } => {
                let mut k = *next;
                if blocks.get(k).is_none_or(|b| b.row != row) {
                    k += blocks[k..].partition_point(|b| b.row < row);
                }
                let b = blocks[k];
                debug_assert_eq!(b.row, row, "a chunk pair without a stored block");
                *next = k + 1;
                b.addr
            }
        }
    }
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

    /// The products Jᵀ_a J_b of residual `ri`'s reduced arguments with their addresses: of
    /// every residual for the implicit target, of the free residuals for the direct ones.
    #[inline(always)]
    pub(crate) fn residual_pairs(&self, ri: usize) -> &[CPair] {
        debug_assert!(
            ri >= self.c_first,
            "the pairs of a chunk residual were not kept"
        );
        let k = ri - self.c_first;
        &self.c_pairs[self.c_start[k]..self.c_start[k + 1]]
    }

    /// Whether every chunk pair is updated (direct solvers) or only the diagonal.
    #[inline(always)]
    pub(crate) fn full_pairs(&self) -> bool {
        self.kind != TargetKind::Implicit
    }

    /// The blocks of column `col` of a direct target ([`Self::full_pairs`]).
    #[inline(always)]
    pub(crate) fn column(&self, col: u32) -> ColumnCursor<'_> {
        let col = col as usize;
        if self.kind == TargetKind::Dense {
            ColumnCursor::Dense {
                offsets: &self.offsets,
                col: self.offsets[col] * self.n,
            }
        } else {
            ColumnCursor::Blocks {
                blocks: &self.blocks[self.col_start[col]..self.col_start[col + 1]],
                next: 0,
            }
        }
    }

    /// The address of stored block (`row`, `col`), `row ≥ col` (blocks and implicit targets).
    fn find(&self, row: u32, col: u32) -> usize {
        let column = &self.blocks[self.col_start[col as usize]..self.col_start[col as usize + 1]];
        let k = column.partition_point(|b| b.row < row);
        debug_assert_eq!(column[k].row, row, "a pair without a stored block");
        column[k].addr
    }

    /// The layout of `kind`.
    ///
    /// # Errors
    /// [`BundleAdjustError::TooLarge`] when an address of the target or an offset in a
    /// chunk's Jacobian does not fit 32 bits.
    pub(crate) fn new(program: &Program, kind: TargetKind) -> Result<Self> {
        let n = program.n_f;
        let nf = program.f_blocks.len();
        let (chunk_pairs, chunk_pair_start) = if kind == TargetKind::Implicit {
            (Vec::new(), Vec::new())
        } else {
            chunk_pairs(program)?
        };
        // The direct targets keep only the free residuals' pairs.
        let c_first = if kind == TargetKind::Implicit {
            0
        } else {
            program.n_chunk_residuals
        };
        let kept = &program.res[c_first..];
        let mut c_start = Vec::with_capacity(kept.len() + 1);
        c_start.push(0);
        for r in kept {
            c_start.push(c_start[c_start.len() - 1] + pair_count(program, r));
        }
        // The kept residuals' pairs with their addresses.
        let c_pairs = |addr: &dyn Fn(u32, u32) -> usize| {
            let mut pairs = ResidualPairs::default();
            let mut out = Vec::with_capacity(c_start[kept.len()]);
            for r in kept {
                out.extend(pairs.of(program, r).iter().map(|&(sa, sb, fa, fb)| CPair {
                    row_slot: sa,
                    col_slot: sb,
                    addr: addr(fa, fb) as u32,
                }));
            }
            out
        };
        let off = &program.f_offset;
        if kind == TargetKind::Dense {
            let addr = |a: u32, b: u32| off[a as usize] + off[b as usize] * n;
            // Every address is below n².
            to_u32(n * n)?;
            let c_pairs = c_pairs(&addr);
            return Ok(Self {
                kind,
                n,
                len: n * n,
                c_start,
                c_first,
                c_pairs,
                diag_addr: (0..nf as u32).map(|a| addr(a, a)).collect(),
                c_diag_addr: Vec::new(),
                blocks: Vec::new(),
                col_start: Vec::new(),
                offsets: off.clone(),
                chunk_pairs,
                chunk_pair_start,
            });
        }
        // Stored blocks: S's (residual and chunk pairs) or C's (residual pairs), column by
        // column, rows ascending.
        let size = |a: u32| off[a as usize + 1] - off[a as usize];
        let mut blocks = Vec::new();
        let mut col_start = Vec::with_capacity(nf + 1);
        let mut len = 0usize;
        for_each_column(program, kind == TargetKind::Blocks, |col, rows| {
            col_start.push(blocks.len());
            for &row in rows {
                blocks.push(BlockEntry {
                    row,
                    col,
                    addr: len,
                });
                len += size(row) * size(col);
            }
        });
        col_start.push(blocks.len());
        let mut layout = Self {
            kind,
            n,
            len,
            c_start: Vec::new(),
            c_first,
            c_pairs: Vec::new(),
            diag_addr: Vec::new(),
            c_diag_addr: Vec::new(),
            blocks,
            col_start,
            offsets: Vec::new(),
            chunk_pairs,
            chunk_pair_start,
        };
        // Every address of C's blocks is below the target's length.
        to_u32(layout.len)?;
        layout.c_pairs = c_pairs(&|a, b| layout.find(a, b));
        layout.c_start = c_start;
        let c_diag: Vec<usize> = (0..nf as u32).map(|a| layout.find(a, a)).collect();
        if kind == TargetKind::Blocks {
            layout.diag_addr = c_diag;
        } else {
            // Preconditioner blocks follow C's blocks.
            let mut diag_addr = Vec::with_capacity(nf);
            for a in 0..nf as u32 {
                diag_addr.push(layout.len);
                layout.len += size(a) * size(a);
            }
            layout.diag_addr = diag_addr;
            layout.c_diag_addr = c_diag;
        }
        Ok(layout)
    }

    /// The offset in the Jacobian buffer from which chunk `ci`'s [`ChunkPair`] offsets count.
    #[inline(always)]
    pub(crate) fn chunk_jac_base(program: &Program, ci: usize) -> usize {
        program.res[program.chunks[ci].res.start].jac_off
    }

    /// The implicit target without the preconditioner's blocks (C's only), for conjugate
    /// gradients preconditioned otherwise ([`crate::SolverOptions::reuse_factorization`]):
    /// the elimination then skips the diagonal blocks of S.
    pub(crate) fn without_preconditioner(mut self) -> Self {
        if self.kind == TargetKind::Implicit
            && let Some(&first) = self.diag_addr.first()
        {
            self.len = first;
            self.diag_addr.clear();
        }
        self
    }
}

/// The pairs of reduced blocks of a residual (row block index ≥ column block index), as
/// (row slot, column slot, row block, column block), ordered by row block then column block;
/// the buffers are reused from residual to residual.
#[derive(Default)]
struct ResidualPairs {
    fslots: Vec<(u32, u16)>,
    pairs: Vec<(u16, u16, u32, u32)>,
}

impl ResidualPairs {
    fn of(&mut self, program: &Program, r: &ResidualLayout) -> &[(u16, u16, u32, u32)] {
        self.fslots.clear();
        for (k, info) in program.residual_slot_info(r).iter().enumerate() {
            if info.f_index != NONE {
                self.fslots.push((info.f_index, k as u16));
            }
        }
        self.fslots.sort_unstable();
        self.pairs.clear();
        for (i, &(fa, sa)) in self.fslots.iter().enumerate() {
            for &(fb, sb) in &self.fslots[..=i] {
                self.pairs.push((sa, sb, fa, fb));
            }
        }
        &self.pairs
    }
}

/// The number of pairs of residual `r`'s reduced blocks.
fn pair_count(program: &Program, r: &ResidualLayout) -> usize {
    let nf = program
        .residual_slot_info(r)
        .iter()
        .filter(|info| info.f_index != NONE)
        .count();
    nf * (nf + 1) / 2
}

/// The residual pairs of every chunk, as [`ChunkPair`]s sorted by (column, row) within a
/// chunk (stable, so in residual order within a block), with the start of each chunk's. The
/// sort is a two-pass counting sort on the blocks' indices among the chunk's own (ascending
/// like the blocks).
fn chunk_pairs(program: &Program) -> Result<(Vec<ChunkPair>, Vec<usize>)> {
    let chunk_residuals = &program.res[..program.n_chunk_residuals];
    let total = chunk_residuals.iter().map(|r| pair_count(program, r)).sum();
    let mut pairs = Vec::with_capacity(total);
    let mut residual_pairs = ResidualPairs::default();
    let mut start = Vec::with_capacity(program.chunks.len() + 1);
    // The chunk's pairs in residual order, their (column, row) local indices, and the
    // orders of the two passes.
    let mut unsorted: Vec<ChunkPair> = Vec::new();
    let mut keys: Vec<(u32, u32)> = Vec::new();
    let (mut identity, mut by_row, mut by_col) = (Vec::new(), Vec::new(), Vec::new());
    let mut count: Vec<usize> = Vec::new();
    for (ci, c) in program.chunks.iter().enumerate() {
        start.push(pairs.len());
        let base = ReducedLayout::chunk_jac_base(program, ci);
        unsorted.clear();
        keys.clear();
        for ri in c.res.clone() {
            let r = &program.res[ri];
            let slots = program.residual_slots(r);
            let infos = program.residual_slot_info(r);
            let jac = r.jac_off - base;
            for &(sa, sb, fa, fb) in residual_pairs.of(program, r) {
                let (sa, sb) = (sa as usize, sb as usize);
                unsorted.push(ChunkPair {
                    col: fb,
                    row: fa,
                    a: to_u32(jac + slots[sa].offset as usize)?,
                    b: to_u32(jac + slots[sb].offset as usize)?,
                    rows: r.rows,
                });
                keys.push((infos[sb].f_local, infos[sa].f_local));
            }
        }
        // Pass 1: by row, from residual order; pass 2: by column, stable.
        let locals = c.f.len();
        identity.clear();
        identity.extend(0..to_u32(keys.len())?);
        counting_sort(&identity, |k| keys[k].1, locals, &mut count, &mut by_row);
        counting_sort(&by_row, |k| keys[k].0, locals, &mut count, &mut by_col);
        pairs.extend(by_col.iter().map(|&k| unsorted[k as usize]));
    }
    start.push(pairs.len());
    Ok((pairs, start))
}

/// `order` (indices into a list) stably sorted by `key` (below `buckets`) into `out`.
fn counting_sort(
    order: &[u32],
    key: impl Fn(usize) -> u32,
    buckets: usize,
    count: &mut Vec<usize>,
    out: &mut Vec<u32>,
) {
    count.clear();
    count.resize(buckets + 1, 0);
    for &k in order {
        count[key(k as usize) as usize + 1] += 1;
    }
    for b in 0..buckets {
        count[b + 1] += count[b];
    }
    out.clear();
    out.resize(order.len(), 0);
    for &k in order {
        let next = &mut count[key(k as usize) as usize];
        out[*next] = k;
        *next += 1;
    }
}

/// Calls `f(col, rows)` for every column of the stored blocks in ascending order, with the
/// column's rows ascending: the diagonal, the row blocks of every residual that has the
/// column's block and, with `chunks`, of every chunk that has it (a chunk residual's pairs are
/// among its chunk's, so then only the free residuals are visited). A column's rows are
/// collected once each with a marker per row block, without listing the pairs.
fn for_each_column(program: &Program, chunks: bool, mut f: impl FnMut(u32, &[u32])) {
    let nf = program.f_blocks.len();
    // Groups of reduced blocks, each sorted ascending: chunks, then residuals.
    let mut items: Vec<u32> = Vec::new();
    let mut ends: Vec<usize> = Vec::new();
    if chunks {
        for c in &program.chunks {
            items.extend_from_slice(&program.chunk_f[c.f.clone()]);
            ends.push(items.len());
        }
    }
    let first_residual = if chunks { program.n_chunk_residuals } else { 0 };
    for r in &program.res[first_residual..] {
        let start = items.len();
        items.extend(
            program
                .residual_slot_info(r)
                .iter()
                .filter(|info| info.f_index != NONE)
                .map(|info| info.f_index),
        );
        items[start..].sort_unstable();
        ends.push(items.len());
    }
    // Per reduced block, where it occurs: (position in `items`, end of its group).
    let mut count = vec![0usize; nf + 1];
    for &a in &items {
        count[a as usize + 1] += 1;
    }
    for a in 0..nf {
        count[a + 1] += count[a];
    }
    let mut fill = count.clone();
    let mut occurrences = vec![(0usize, 0usize); items.len()];
    let mut start = 0;
    for &end in &ends {
        for (pos, &a) in items.iter().enumerate().take(end).skip(start) {
            occurrences[fill[a as usize]] = (pos, end);
            fill[a as usize] += 1;
        }
        start = end;
    }
    let mut mark = vec![NONE; nf];
    let mut rows: Vec<u32> = Vec::new();
    for col in 0..nf {
        let c = col as u32;
        rows.clear();
        rows.push(c);
        mark[col] = c;
        for &(pos, end) in &occurrences[count[col]..count[col + 1]] {
            for &row in &items[pos + 1..end] {
                if mark[row as usize] != c {
                    mark[row as usize] = c;
                    rows.push(row);
                }
            }
        }
        rows.sort_unstable();
        f(c, &rows);
    }
}
