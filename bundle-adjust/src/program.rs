//! The compiled form of a [`Problem`] that the solver iterates on: which blocks are free,
//! which are eliminated, the order of the residuals (grouped by eliminated block, one
//! "chunk" per block, as in Ceres's Schur eliminator) and where every residual and Jacobian
//! block lives in the flat evaluation buffers.

use crate::cost::JacobianSlot;
use crate::error::{BundleAdjustError, Result};
use crate::problem::Problem;

/// Marker for "no index".
pub(crate) const NONE: u32 = u32::MAX;

/// One residual block in program order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ResidualLayout {
    /// Index of the residual block in the problem.
    pub user: u32,
    /// Number of residuals.
    pub rows: u32,
    /// Offset of the residual values in the residual buffer.
    pub res_off: usize,
    /// Offset of the residual's Jacobian blocks in the Jacobian buffer.
    pub jac_off: usize,
    /// First slot (argument) of this residual in `Program::slots`.
    pub slot_start: u32,
    /// Number of arguments.
    pub n_slots: u32,
    /// The argument that is eliminated, or `NONE`.
    pub e_slot: u32,
}

/// What the solver knows about one argument of a residual block.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SlotInfo {
    /// Offset of the block in the tangent vector, or `NONE` if constant.
    pub col: u32,
    /// Index of the block in the reduced system, or `NONE` if not a reduced block.
    pub f_index: u32,
    /// Index in the chunk's list of distinct reduced blocks (chunk residuals only), or `NONE`.
    pub f_local: u32,
}

/// The residuals sharing one eliminated block.
#[derive(Debug, Clone)]
pub(crate) struct Chunk {
    /// Offset of the eliminated block in the tangent vector.
    pub e_col: usize,
    /// Tangent size of the eliminated block.
    pub e_size: usize,
    /// Program residual range.
    pub res: core::ops::Range<usize>,
    /// Range of the chunk's distinct reduced blocks in `Program::chunk_f`.
    pub f: core::ops::Range<usize>,
    /// Offset of the chunk's V blocks (reduced × eliminated) in the V buffer.
    pub v_off: usize,
    /// Offset of the chunk's Cholesky factor (e × e) in the L buffer.
    pub l_off: usize,
}

/// Block sizes shared by every chunk residual, which lets the Schur kernels run with
/// compile-time sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum ShapeKind {
    /// 2 residuals, a 3-vector eliminated (a point), one 9-block (a BAL camera).
    R2E3F9,
    /// 2 residuals, a 3-vector eliminated, one 6-block (a pose).
    R2E3F6,
    /// 2 residuals, a 6-block eliminated (a rig pose), one 6-block (an extrinsic).
    R2E6F6,
    /// Anything else.
    Dynamic,
}

/// The compiled problem.
#[derive(Debug, Clone)]
pub(crate) struct Program {
    pub res: Vec<ResidualLayout>,
    pub slots: Vec<JacobianSlot>,
    pub slot_info: Vec<SlotInfo>,
    pub n_res_values: usize,
    pub n_jac_values: usize,
    pub chunks: Vec<Chunk>,
    /// Residuals `0..n_chunk_residuals` belong to chunks; the rest have no eliminated block.
    pub n_chunk_residuals: usize,
    /// Distinct reduced blocks of each chunk, ascending.
    pub chunk_f: Vec<u32>,
    /// Offset of each entry of `chunk_f`'s V block from its chunk's `v_off`.
    pub chunk_f_voff: Vec<usize>,
    pub v_len: usize,
    pub l_len: usize,
    /// Reduced blocks (problem ids), in reduced-system order.
    pub f_blocks: Vec<usize>,
    /// Offset of each reduced block inside the reduced vector (length `f_blocks.len() + 1`).
    pub f_offset: Vec<usize>,
    /// Tangent size of the eliminated part.
    pub n_e: usize,
    /// Tangent size of the reduced part.
    pub n_f: usize,
    /// Free blocks (problem ids) in tangent-vector order.
    pub active_blocks: Vec<usize>,
    /// Tangent offset per problem block, `NONE` for constant or unused blocks.
    pub block_col: Vec<u32>,
    /// Residual blocks whose arguments are all constant.
    pub fixed_residuals: Vec<usize>,
    pub shape: ShapeKind,
    /// Per tangent column, 1 for a free coordinate and 0 for one held by
    /// [`Problem::set_constant_subset`]; empty when no coordinate is held. The evaluator
    /// multiplies the Jacobian columns by it, so held coordinates never move.
    pub col_mask: Vec<f64>,
}

impl Program {
    /// Compiles `problem`. `automatic` chooses the eliminated group when none is marked.
    pub(crate) fn new(problem: &Problem, automatic: bool) -> Result<Self> {
        if problem.live_residuals == 0 {
            return Err(BundleAdjustError::EmptyProblem);
        }
        let nb = problem.blocks.len();
        let mut used = vec![false; nb];
        for r in &problem.residuals {
            for &b in &r.blocks {
                used[b] = true;
            }
        }
        let active: Vec<bool> = (0..nb)
            .map(|b| used[b] && !problem.blocks[b].is_fixed())
            .collect();
        let eliminate = elimination_group(problem, &active, automatic)?;

        // Tangent layout: eliminated blocks, then reduced blocks, each by ascending id.
        let e_list: Vec<usize> = (0..nb).filter(|&b| eliminate[b]).collect();
        let f_blocks: Vec<usize> = (0..nb).filter(|&b| active[b] && !eliminate[b]).collect();
        let mut block_col = vec![NONE; nb];
        let mut e_index = vec![NONE; nb];
        let mut col = 0usize;
        for (i, &b) in e_list.iter().enumerate() {
            block_col[b] = to_u32(col)?;
            e_index[b] = to_u32(i)?;
            col += problem.blocks[b].tangent;
        }
        let n_e = col;
        let mut f_index = vec![NONE; nb];
        let mut f_offset = Vec::with_capacity(f_blocks.len() + 1);
        for (i, &b) in f_blocks.iter().enumerate() {
            block_col[b] = to_u32(col)?;
            f_index[b] = to_u32(i)?;
            f_offset.push(col - n_e);
            col += problem.blocks[b].tangent;
        }
        let n_f = col - n_e;
        f_offset.push(n_f);
        let mut active_blocks = e_list.clone();
        active_blocks.extend_from_slice(&f_blocks);

        // Residual order: chunk residuals grouped by eliminated block, then free residuals.
        // The chunks' members by a counting sort (stable: ascending within a chunk).
        let mut fixed_residuals = Vec::new();
        let mut free = Vec::new();
        let mut chunk_of_residual = vec![NONE; problem.residuals.len()];
        let mut member_start = vec![0usize; e_list.len() + 1];
        for (ri, r) in problem.residuals.iter().enumerate() {
            if r.removed {
                continue;
            }
            if r.blocks.iter().all(|&b| !active[b]) {
                fixed_residuals.push(ri);
            } else if let Some(&b) = r.blocks.iter().find(|&&b| eliminate[b]) {
                chunk_of_residual[ri] = e_index[b];
                member_start[e_index[b] as usize + 1] += 1;
            } else {
                free.push(ri);
            }
        }
        for e in 0..e_list.len() {
            member_start[e + 1] += member_start[e];
        }
        let mut members_sorted = vec![0usize; member_start[e_list.len()]];
        let mut fill = member_start.clone();
        for (ri, &e) in chunk_of_residual.iter().enumerate() {
            if e != NONE {
                members_sorted[fill[e as usize]] = ri;
                fill[e as usize] += 1;
            }
        }
        let chunk_members = member_start.windows(2).map(|w| &members_sorted[w[0]..w[1]]);

        // Sized once: a bundle adjustment has millions of residual blocks.
        let n_slots: usize = problem
            .residuals
            .iter()
            .filter(|r| !r.removed)
            .map(|r| r.blocks.len())
            .sum();
        let mut program = Program {
            res: Vec::with_capacity(problem.live_residuals),
            slots: Vec::with_capacity(n_slots),
            slot_info: Vec::with_capacity(n_slots),
            n_res_values: 0,
            n_jac_values: 0,
            chunks: Vec::with_capacity(e_list.len()),
            n_chunk_residuals: 0,
            chunk_f: Vec::new(),
            chunk_f_voff: Vec::new(),
            v_len: 0,
            l_len: 0,
            f_blocks,
            f_offset,
            n_e,
            n_f,
            active_blocks,
            block_col,
            fixed_residuals,
            shape: ShapeKind::Dynamic,
            col_mask: Vec::new(),
        };
        if program
            .active_blocks
            .iter()
            .any(|&b| !problem.blocks[b].held.is_empty())
        {
            let mut mask = vec![1.0; n_e + n_f];
            for &b in &program.active_blocks {
                let col = program.block_col[b] as usize;
                for &h in &problem.blocks[b].held {
                    mask[col + h] = 0.0;
                }
            }
            program.col_mask = mask;
        }
        let mut local: Vec<(u32, u32)> = Vec::new();
        for (ei, members) in chunk_members.enumerate() {
            let b = e_list[ei];
            let e_size = problem.blocks[b].tangent;
            let res_start = program.res.len();
            // Distinct reduced blocks of the chunk, ascending.
            local.clear();
            for &ri in members {
                for &pb in &problem.residuals[ri].blocks {
                    if f_index[pb] != NONE {
                        local.push((f_index[pb], 0));
                    }
                }
            }
            local.sort_unstable();
            local.dedup();
            let f_start = program.chunk_f.len();
            let mut voff = 0usize;
            for entry in &mut local {
                program.chunk_f.push(entry.0);
                program.chunk_f_voff.push(voff);
                entry.1 = to_u32(program.chunk_f.len() - 1 - f_start)?;
                let fb = program.f_blocks[entry.0 as usize];
                voff += problem.blocks[fb].tangent * e_size;
            }
            for &ri in members {
                program.push_residual(problem, ri, &f_index, |fi| {
                    local
                        .binary_search_by_key(&fi, |e| e.0)
                        .map_or(NONE, |k| local[k].1)
                })?;
            }
            program.chunks.push(Chunk {
                e_col: program.block_col[b] as usize,
                e_size,
                res: res_start..program.res.len(),
                f: f_start..program.chunk_f.len(),
                v_off: program.v_len,
                l_off: program.l_len,
            });
            program.v_len += voff;
            program.l_len += e_size * e_size;
        }
        program.n_chunk_residuals = program.res.len();
        for &ri in &free {
            program.push_residual(problem, ri, &f_index, |_| NONE)?;
        }
        program.shape = program.detect_shape();
        Ok(program)
    }

    fn push_residual(
        &mut self,
        problem: &Problem,
        ri: usize,
        f_index: &[u32],
        f_local: impl Fn(u32) -> u32,
    ) -> Result<()> {
        let r = &problem.residuals[ri];
        let slot_start = to_u32(self.slots.len())?;
        let mut e_slot = NONE;
        let mut offset = 0usize;
        for (k, &b) in r.blocks.iter().enumerate() {
            let col = self.block_col[b];
            let tangent = problem.blocks[b].tangent;
            let wanted = col != NONE;
            if wanted && f_index[b] == NONE {
                e_slot = to_u32(k)?;
            }
            self.slots.push(JacobianSlot {
                offset: to_u32(offset)?,
                cols: to_u32(tangent)?,
                wanted,
            });
            self.slot_info.push(SlotInfo {
                col,
                f_index: f_index[b],
                f_local: if f_index[b] == NONE {
                    NONE
                } else {
                    f_local(f_index[b])
                },
            });
            if wanted {
                offset += r.rows * tangent;
            }
        }
        self.res.push(ResidualLayout {
            user: to_u32(ri)?,
            rows: to_u32(r.rows)?,
            res_off: self.n_res_values,
            jac_off: self.n_jac_values,
            slot_start,
            n_slots: to_u32(r.blocks.len())?,
            e_slot,
        });
        self.n_res_values += r.rows;
        self.n_jac_values += offset;
        Ok(())
    }

    /// The fixed shape of all chunk residuals, if they share one.
    fn detect_shape(&self) -> ShapeKind {
        if self.n_chunk_residuals == 0 {
            return ShapeKind::Dynamic;
        }
        let mut shape: Option<(u32, u32, u32)> = None;
        for r in &self.res[..self.n_chunk_residuals] {
            let slots = self.residual_slots(r);
            let mut e = None;
            let mut f = None;
            let mut n_f = 0;
            for (s, info) in slots.iter().zip(self.residual_slot_info(r)) {
                if !s.wanted {
                    continue;
                }
                if info.f_index == NONE {
                    e = Some(s.cols);
                } else {
                    f = Some(s.cols);
                    n_f += 1;
                }
            }
            // At most one reduced argument; one whose reduced argument is constant (a gauge
            // block, say) fits any reduced size.
            let Some(e) = e else {
                return ShapeKind::Dynamic;
            };
            if n_f > 1 {
                return ShapeKind::Dynamic;
            }
            match (shape, f) {
                (None, _) => shape = Some((r.rows, e, f.unwrap_or(0))),
                (Some((rows, se, sf)), f) if rows == r.rows && se == e => {
                    if let Some(f) = f {
                        if sf == 0 {
                            shape = Some((rows, se, f));
                        } else if sf != f {
                            return ShapeKind::Dynamic;
                        }
                    }
                }
                _ => return ShapeKind::Dynamic,
            }
        }
        match shape {
            Some((2, 3, 9)) => ShapeKind::R2E3F9,
            Some((2, 3, 6)) => ShapeKind::R2E3F6,
            Some((2, 6, 6)) => ShapeKind::R2E6F6,
            _ => ShapeKind::Dynamic,
        }
    }

    #[inline]
    pub(crate) fn residual_slots(&self, r: &ResidualLayout) -> &[JacobianSlot] {
        &self.slots[r.slot_start as usize..(r.slot_start + r.n_slots) as usize]
    }

    #[inline]
    pub(crate) fn residual_slot_info(&self, r: &ResidualLayout) -> &[SlotInfo] {
        &self.slot_info[r.slot_start as usize..(r.slot_start + r.n_slots) as usize]
    }

    /// Total tangent dimension.
    pub(crate) fn n_tangent(&self) -> usize {
        self.n_e + self.n_f
    }

    /// Size of reduced block `k`.
    #[inline]
    pub(crate) fn f_size(&self, k: usize) -> usize {
        self.f_offset[k + 1] - self.f_offset[k]
    }
}

/// `v` as a 32-bit index, or [`BundleAdjustError::TooLarge`].
pub(crate) fn to_u32(v: usize) -> Result<u32> {
    u32::try_from(v).map_err(|_| BundleAdjustError::TooLarge { index: v })
}

/// The blocks to eliminate: the marked ones (checked to be independent), or a greedy maximal
/// independent set of the free blocks, lowest degree first (Ceres's `IndependentSetOrdering`).
fn elimination_group(problem: &Problem, active: &[bool], automatic: bool) -> Result<Vec<bool>> {
    let nb = problem.blocks.len();
    let marked: Vec<bool> = (0..nb)
        .map(|b| active[b] && problem.blocks[b].eliminate)
        .collect();
    if marked.iter().any(|&m| m) {
        for r in &problem.residuals {
            let mut first = None;
            for &b in &r.blocks {
                if marked[b] {
                    if let Some(first) = first {
                        return Err(BundleAdjustError::EliminatedBlocksCoupled {
                            first,
                            second: b,
                        });
                    }
                    first = Some(b);
                }
            }
        }
        return Ok(marked);
    }
    let mut chosen = vec![false; nb];
    if !automatic {
        return Ok(chosen);
    }
    // Block -> residuals adjacency (compressed).
    let mut degree = vec![0usize; nb];
    for r in &problem.residuals {
        for &b in &r.blocks {
            if active[b] {
                degree[b] += 1;
            }
        }
    }
    let mut start = vec![0usize; nb + 1];
    for b in 0..nb {
        start[b + 1] = start[b] + degree[b];
    }
    let mut fill = start.clone();
    let mut adjacency = vec![0usize; start[nb]];
    for (ri, r) in problem.residuals.iter().enumerate() {
        for &b in &r.blocks {
            if active[b] {
                adjacency[fill[b]] = ri;
                fill[b] += 1;
            }
        }
    }
    let mut order: Vec<usize> = (0..nb).filter(|&b| active[b]).collect();
    order.sort_by_key(|&b| (degree[b], b));
    let mut blocked = vec![false; nb];
    for b in order {
        if blocked[b] {
            continue;
        }
        chosen[b] = true;
        for &ri in &adjacency[start[b]..start[b + 1]] {
            for &other in &problem.residuals[ri].blocks {
                if other != b {
                    blocked[other] = true;
                }
            }
        }
    }
    Ok(chosen)
}
