//! Block-by-block Schur complement of the eliminated group (Triggs et al., "Bundle
//! Adjustment — A Modern Synthesis", 2000, section 6.1; the chunked elimination of Ceres's
//! `SchurEliminator`).
//!
//! Ordering the unknowns as [eliminated e; reduced f], the damped normal equations
//! (JᵀJ + D) δ = −g split into
//!
//! ```text
//! [ A  Bᵀ ] [δe]   [−g_e]        A = J_eᵀJ_e + D_e   (block diagonal: one block per chunk)
//! [ B  C  ] [δf] = [−g_f]        B = J_fᵀJ_e,  C = J_fᵀJ_f + D_f
//! ```
//!
//! and S δf = −g_f + B A⁻¹ g_e with S = C − B A⁻¹ Bᵀ. Per chunk, with A = L Lᵀ, W_p = the
//! chunk's block of B for reduced block p, V_p = W_p L⁻ᵀ and y = L⁻¹ g_e:
//! S_pq −= V_p V_qᵀ, rhs_p += V_p y, and afterwards δe = −L⁻ᵀ (y + Σ_p V_pᵀ δf_p).
//! L, y and V are kept from the elimination for the back substitution and for the implicit
//! products of the iterative solver. For the direct solvers the updates of S are applied per
//! group of consecutive chunks, block by block ([`GROUP`]), each block receiving the same
//! operations in the same order as chunk by chunk.

use crate::kernels::{
    Shape, add_a_x, add_at_b, add_at_x, cholesky, right_solve_lower_transpose, set_at_b,
    solve_lower, solve_lower_transpose, sub_a_bt, sub_a_x, with_shape,
};
use crate::parallel::{Executor, balanced_ranges, split_at_offsets};
use crate::program::{NONE, Program};
use crate::reduced::{ReducedLayout, TargetKind};
use crate::simd::{Isa, Kernel, MulAdd, Plain, dispatch};

/// Evaluates `$kernel` with `$size` bound to `$fixed`, a constant when it is one of the
/// reduced block sizes of a rig bundle adjustment (5: a pose on a sphere, 6: a pose, 8 and 9:
/// the intrinsics of the camera models), so that the inlined kernel's loops are unrolled; the
/// same operations in the same order either way, so the same result.
macro_rules! with_fixed_size {
    ($size:expr, |$fixed:ident| $kernel:expr) => {
        match $size {
            5 => {
                let $fixed = 5;
                $kernel
            }
            6 => {
                let $fixed = 6;
                $kernel
            }
            8 => {
                let $fixed = 8;
                $kernel
            }
            9 => {
                let $fixed = 9;
                $kernel
            }
            $fixed => $kernel,
        }
    };
}

/// Per-solve buffers of the elimination.
pub(crate) struct SchurComplement {
    /// Chunk ranges, one per worker.
    partitions: Vec<core::ops::Range<usize>>,
    v: Vec<f64>,
    l: Vec<f64>,
    y: Vec<f64>,
    /// One target buffer per partition; `targets[0]` holds the sum after elimination.
    targets: Vec<Vec<f64>>,
    /// One right-hand side per partition; `rhs[0]` holds the sum.
    rhs: Vec<Vec<f64>>,
    /// Per-partition accumulators of the implicit product.
    product: Vec<Vec<f64>>,
    isa: Isa,
}

impl SchurComplement {
    pub(crate) fn new(program: &Program, layout: &ReducedLayout, threads: usize) -> Self {
        Self::with_layouts(program, &[layout], threads)
    }

    /// Buffers for eliminating into any of `layouts` (the target sized for the longest; the
    /// implicit product's accumulators if one is implicit): the sparse solver's reuse of its
    /// factorization alternates a blocks target with an implicit one.
    pub(crate) fn with_layouts(
        program: &Program,
        layouts: &[&ReducedLayout],
        threads: usize,
    ) -> Self {
        let len = layouts.iter().map(|l| l.len).max().unwrap_or(0);
        let implicit = layouts.iter().any(|l| l.kind == TargetKind::Implicit);
        let partitions = balanced_ranges(program.chunks.len(), threads, |c| {
            let ch = &program.chunks[c];
            let k = ch.f.len();
            ch.res.len() * 4 + k * (k + 1) / 2 + 1
        });
        let parts = partitions.len();
        Self {
            partitions,
            v: vec![0.0; program.v_len],
            l: vec![0.0; program.l_len],
            y: vec![0.0; program.n_e],
            targets: (0..parts).map(|_| vec![0.0; len]).collect(),
            rhs: (0..parts).map(|_| vec![0.0; program.n_f]).collect(),
            product: if implicit {
                (0..parts).map(|_| vec![0.0; program.n_f]).collect()
            } else {
                Vec::new()
            },
            isa: Isa::detect(),
        }
    }

    /// The reduced matrix (or C and the preconditioner blocks, for the implicit target).
    pub(crate) fn target(&self) -> &[f64] {
        &self.targets[0]
    }

    /// Mutable access to the reduced matrix, for in-place factorization.
    pub(crate) fn target_mut(&mut self) -> &mut [f64] {
        &mut self.targets[0]
    }

    /// The reduced right-hand side.
    pub(crate) fn rhs(&self) -> &[f64] {
        &self.rhs[0]
    }

    /// Forms the reduced system for the scaled Jacobian `jac`, scaled gradient `gradient`
    /// and damping `diag` (the added diagonal, both over the whole tangent vector). Returns
    /// false if an eliminated block's damped normal matrix is not positive definite.
    pub(crate) fn eliminate(
        &mut self,
        program: &Program,
        layout: &ReducedLayout,
        jac: &[f64],
        gradient: &[f64],
        diag: &[f64],
        exec: &Executor,
    ) -> bool {
        let v_ends: Vec<usize> = self
            .partitions
            .iter()
            .map(|r| chunk_end(program, r.end, |c| c.v_off, program.v_len))
            .collect();
        let l_ends: Vec<usize> = self
            .partitions
            .iter()
            .map(|r| chunk_end(program, r.end, |c| c.l_off, program.l_len))
            .collect();
        let y_ends: Vec<usize> = self
            .partitions
            .iter()
            .map(|r| chunk_end(program, r.end, |c| c.e_col, program.n_e))
            .collect();
        let v_parts = split_at_offsets(&mut self.v, &v_ends);
        let l_parts = split_at_offsets(&mut self.l, &l_ends);
        let y_parts = split_at_offsets(&mut self.y, &y_ends);
        let work: Vec<_> = self
            .partitions
            .iter()
            .cloned()
            .zip(v_parts)
            .zip(l_parts)
            .zip(y_parts)
            .zip(self.targets.iter_mut().zip(self.rhs.iter_mut()))
            .enumerate()
            .map(|(p, ((((range, v), l), y), (t, r)))| (p, range, v, l, y, t, r))
            .collect();
        let isa = self.isa;
        let ok = exec.map(work, |(p, range, v, l, y, target, rhs)| {
            target[..layout.len].fill(0.0);
            rhs.fill(0.0);
            let task = EliminateTask {
                program,
                layout,
                range,
                jac,
                gradient,
                diag,
                target,
                rhs,
                bufs: ChunkBuffers { v, l, y },
                free: p == 0,
            };
            dispatch(isa, task)
        });
        let ok = ok.iter().all(|&o| o);
        // Sum the partitions in order.
        let (first, rest) = self.targets.split_at_mut(1);
        for t in rest {
            for (a, b) in first[0][..layout.len].iter_mut().zip(t.iter()) {
                *a += b;
            }
        }
        let (first, rest) = self.rhs.split_at_mut(1);
        for r in rest {
            for (a, b) in first[0].iter_mut().zip(r.iter()) {
                *a += b;
            }
        }
        let target = &mut self.targets[0];
        let rhs = &mut self.rhs[0];
        let n_e = program.n_e;
        for (r, g) in rhs.iter_mut().zip(&gradient[n_e..]) {
            *r -= g;
        }
        for (k, &addr) in layout.diag_addr.iter().enumerate() {
            let size = program.f_size(k);
            let ld = layout.ld(size);
            let d = &diag[n_e + program.f_offset[k]..n_e + program.f_offset[k] + size];
            if layout.kind == TargetKind::Implicit {
                // Preconditioner block: C_aa + D_a − Σ V Vᵀ.
                let c_addr = layout.c_diag_addr[k];
                for j in 0..size {
                    for i in 0..size {
                        target[addr + i + j * size] += target[c_addr + i + j * size];
                    }
                }
            }
            for (j, dj) in d.iter().enumerate() {
                target[addr + j + j * ld] += dj;
            }
        }
        ok
    }

    /// |L⁻¹ g_e|² = g_eᵀ A⁻¹ g_e of the last elimination.
    pub(crate) fn eliminated_norm2(&self) -> f64 {
        self.y.iter().map(|v| v * v).sum()
    }

    /// δe from δf (both in the scaled tangent vector `delta`, whose reduced part is filled).
    pub(crate) fn back_substitute(&self, program: &Program, delta: &mut [f64], exec: &Executor) {
        let n_e = program.n_e;
        let (de, df) = delta.split_at_mut(n_e);
        let df: &[f64] = df;
        let y_ends: Vec<usize> = self
            .partitions
            .iter()
            .map(|r| chunk_end(program, r.end, |c| c.e_col, n_e))
            .collect();
        let parts = split_at_offsets(de, &y_ends);
        let work: Vec<_> = self.partitions.iter().cloned().zip(parts).collect();
        let isa = self.isa;
        exec.map(work, |(range, out)| {
            dispatch(
                isa,
                BackSubstituteTask {
                    program,
                    schur: self,
                    range,
                    df,
                    out,
                },
            );
        });
    }

    /// out = S x for the implicit target: (C + D_f) x − Σ_chunks V (Vᵀ x).
    pub(crate) fn implicit_product(
        &mut self,
        program: &Program,
        layout: &ReducedLayout,
        diag_f: &[f64],
        x: &[f64],
        out: &mut [f64],
        exec: &Executor,
    ) {
        let v = &self.v;
        let isa = self.isa;
        let parts: Vec<_> = self
            .partitions
            .iter()
            .cloned()
            .zip(self.product.iter_mut())
            .collect();
        exec.map(parts, |(range, acc)| {
            acc.fill(0.0);
            dispatch(
                isa,
                ProductTask {
                    program,
                    v,
                    range,
                    x,
                    acc,
                },
            );
        });
        out.copy_from_slice(&self.product[0]);
        for r in &self.product[1..] {
            for (o, a) in out.iter_mut().zip(r) {
                *o += a;
            }
        }
        let c = &self.targets[0];
        for b in &layout.blocks {
            let (ra, ca) = (b.row as usize, b.col as usize);
            let (mr, mc) = (program.f_size(ra), program.f_size(ca));
            let (or, oc) = (program.f_offset[ra], program.f_offset[ca]);
            let blk = &c[b.addr..b.addr + mr * mc];
            add_a_x::<Plain>(&mut out[or..or + mr], blk, &x[oc..oc + mc], mr, mc);
            if ra != ca {
                add_at_x::<Plain>(&mut out[oc..oc + mc], blk, &x[or..or + mr], mr, mc);
            }
        }
        for ((o, d), xv) in out.iter_mut().zip(diag_f).zip(x) {
            *o += d * xv;
        }
    }
}

/// The value of `field` at chunk `end` (or `total` past the last chunk).
fn chunk_end(
    program: &Program,
    end: usize,
    field: impl Fn(&crate::program::Chunk) -> usize,
    total: usize,
) -> usize {
    program.chunks.get(end).map_or(total, field)
}

/// Elimination of one partition of chunks (plus the free residuals for the first).
struct EliminateTask<'a> {
    program: &'a Program,
    layout: &'a ReducedLayout,
    range: core::ops::Range<usize>,
    jac: &'a [f64],
    gradient: &'a [f64],
    diag: &'a [f64],
    target: &'a mut [f64],
    rhs: &'a mut [f64],
    bufs: ChunkBuffers<'a>,
    free: bool,
}

impl Kernel for EliminateTask<'_> {
    type Output = bool;
    #[inline(always)]
    fn run<M: MulAdd>(self) -> bool {
        let t = self;
        let ok = with_shape!(t.program.shape, shape => eliminate_range::<_, M>(
            shape, t.program, t.layout, t.range, t.jac, t.gradient, t.diag, t.target, t.rhs, t.bufs
        ));
        if t.free {
            free_residuals::<M>(t.program, t.layout, t.jac, t.target);
        }
        ok
    }
}

/// Back substitution of one partition of chunks.
struct BackSubstituteTask<'a> {
    program: &'a Program,
    schur: &'a SchurComplement,
    range: core::ops::Range<usize>,
    df: &'a [f64],
    out: &'a mut [f64],
}

impl Kernel for BackSubstituteTask<'_> {
    type Output = ();
    #[inline(always)]
    fn run<M: MulAdd>(self) {
        let BackSubstituteTask {
            program,
            schur,
            range,
            df,
            out,
        } = self;
        let base = program.chunks.get(range.start).map_or(0, |c| c.e_col);
        with_shape!(program.shape, shape => {
            for ci in range.clone() {
                let c = &program.chunks[ci];
                let e = shape.e(c.e_size);
                let z = &mut out[c.e_col - base..c.e_col - base + e];
                z.copy_from_slice(&schur.y[c.e_col..c.e_col + e]);
                for (p, &fp) in program.chunk_f[c.f.clone()].iter().enumerate() {
                    let m = shape.f(program.f_size(fp as usize));
                    let vo = c.v_off + program.chunk_f_voff[c.f.start + p];
                    let off = program.f_offset[fp as usize];
                    add_at_x::<M>(z, &schur.v[vo..vo + m * e], &df[off..off + m], m, e);
                }
                solve_lower_transpose(&schur.l[c.l_off..c.l_off + e * e], z, e);
                for v in z.iter_mut() {
                    *v = -*v;
                }
            }
        });
    }
}

/// The chunk part of an implicit product, −Σ V (Vᵀ x), for one partition.
struct ProductTask<'a> {
    program: &'a Program,
    v: &'a [f64],
    range: core::ops::Range<usize>,
    x: &'a [f64],
    acc: &'a mut [f64],
}

impl Kernel for ProductTask<'_> {
    type Output = ();
    #[inline(always)]
    fn run<M: MulAdd>(self) {
        let ProductTask {
            program,
            v,
            range,
            x,
            acc,
        } = self;
        with_shape!(program.shape, shape => {
            let mut z = [0.0; 16];
            let mut zv = Vec::new();
            for ci in range.clone() {
                let c = &program.chunks[ci];
                let e = shape.e(c.e_size);
                let z: &mut [f64] = if e <= z.len() {
                    z[..e].fill(0.0);
                    &mut z[..e]
                } else {
                    zv.clear();
                    zv.resize(e, 0.0);
                    &mut zv
                };
                let fs = &program.chunk_f[c.f.clone()];
                // A point's (e = 3) products with compile-time sizes on the dynamic shape.
                for (p, &fp) in fs.iter().enumerate() {
                    let m = shape.f(program.f_size(fp as usize));
                    let vo = c.v_off + program.chunk_f_voff[c.f.start + p];
                    let off = program.f_offset[fp as usize];
                    let (vp, xp) = (&v[vo..vo + m * e], &x[off..off + m]);
                    if e == 3 {
                        with_fixed_size!(m, |fm| add_at_x::<M>(z, vp, xp, fm, 3));
                    } else {
                        add_at_x::<M>(z, vp, xp, m, e);
                    }
                }
                for (p, &fp) in fs.iter().enumerate() {
                    let m = shape.f(program.f_size(fp as usize));
                    let vo = c.v_off + program.chunk_f_voff[c.f.start + p];
                    let off = program.f_offset[fp as usize];
                    let (vp, out) = (&v[vo..vo + m * e], &mut acc[off..off + m]);
                    if e == 3 {
                        with_fixed_size!(m, |fm| sub_a_x::<M>(out, vp, z, fm, 3));
                    } else {
                        sub_a_x::<M>(out, vp, z, m, e);
                    }
                }
            }
        });
    }
}

/// A partition's slices of the V, L and y buffers.
struct ChunkBuffers<'a> {
    v: &'a mut [f64],
    l: &'a mut [f64],
    y: &'a mut [f64],
}

/// Consecutive chunks whose products V_p V_qᵀ are applied together, block by block: each
/// block of S is read and written once per group instead of once per chunk (in the full
/// garage of the rig bundle adjustment, with groups of 16, 9.3M block visits instead of 43M
/// block updates per elimination, consecutive points being seen by nearly the same frames),
/// and the operations of a visit run with the block in registers. At most 32 (a chunk mask
/// is a `u32`); 32 measured a few per cent faster than 16, 64 (with `u64` masks) no faster
/// than 32.
const GROUP: usize = 32;

/// One update of a block of S inside a group: out(m × n) ± Σ_k a_k b_kᵀ over k < `k`, a
/// packed column-major with m rows (or row-major with m columns, the same layout), b the
/// same with n: a residual's own product Jᵀ_a J_b (+, from the Jacobian) or a chunk's
/// V_p V_qᵀ (−, from the V buffer).
#[derive(Debug, Clone, Copy)]
struct BlockOp {
    a: usize,
    b: usize,
    k: u32,
    /// V_p V_qᵀ (subtracted) rather than Jᵀ_a J_b (added).
    v: bool,
}

/// Reused buffers of a group of chunks.
#[derive(Default)]
struct Group {
    /// (reduced block, chunk of the group, offset of its V block in the partition's V).
    entries: Vec<(u32, u32, usize)>,
    /// Distinct reduced blocks of the group, ascending, and the mask of the chunks having
    /// each.
    f: Vec<u32>,
    mask: Vec<u32>,
    /// V offset of (distinct block u, chunk g) at `u * GROUP + g`.
    v_off: Vec<usize>,
    ops: Vec<BlockOp>,
}

/// The chunk products V_p V_qᵀ of a block with no residual product, as operations: the
/// chunks of `common` in ascending order, their V blocks at `a[g]` and `b[g]` (points: e = 3).
#[derive(Clone, Copy)]
struct ChunkProducts<'a> {
    common: u32,
    a: &'a [usize],
    b: &'a [usize],
}

impl Iterator for ChunkProducts<'_> {
    type Item = BlockOp;
    #[inline(always)]
    fn next(&mut self) -> Option<BlockOp> {
        if self.common == 0 {
            return None;
        }
        let g = self.common.trailing_zeros() as usize;
        self.common &= self.common - 1;
        Some(BlockOp {
            a: self.a[g],
            b: self.b[g],
            k: 3,
            v: true,
        })
    }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn eliminate_range<S: Shape, M: MulAdd>(
    shape: S,
    program: &Program,
    layout: &ReducedLayout,
    range: core::ops::Range<usize>,
    jac: &[f64],
    gradient: &[f64],
    diag: &[f64],
    target: &mut [f64],
    rhs: &mut [f64],
    bufs: ChunkBuffers<'_>,
) -> bool {
    let Some(first) = program.chunks.get(range.start) else {
        return true;
    };
    let (v_base, l_base, y_base) = (first.v_off, first.l_off, first.e_col);
    let full = layout.full_pairs();
    let mut group = Group::default();
    let mut written: Vec<bool> = Vec::new();
    let mut start = range.start;
    while start < range.end {
        let end = (start + GROUP).min(range.end);
        group.entries.clear();
        for (g, ci) in (start..end).enumerate() {
            let c = &program.chunks[ci];
            let e = shape.e(c.e_size);
            let v_len = program
                .chunks
                .get(ci + 1)
                .map_or(program.v_len, |n| n.v_off)
                - c.v_off;
            let v_start = c.v_off - v_base;
            let v = &mut bufs.v[v_start..v_start + v_len];
            let l = &mut bufs.l[c.l_off - l_base..c.l_off - l_base + e * e];
            let y = &mut bufs.y[c.e_col - y_base..c.e_col - y_base + e];
            l.fill(0.0);
            let voffs = &program.chunk_f_voff[c.f.clone()];
            // Which of the chunk's W blocks a residual has written (each is, by one at least).
            written.clear();
            written.resize(voffs.len(), false);
            for ri in c.res.clone() {
                let r = &program.res[ri];
                let rows = shape.rows(r.rows as usize);
                let jr = &jac[r.jac_off..];
                let slots = program.residual_slots(r);
                let infos = program.residual_slot_info(r);
                let es = slots[r.e_slot as usize];
                let je = &jr[es.offset as usize..es.offset as usize + rows * e];
                if (rows, e) == (2, 3) {
                    add_at_b::<M>(l, 0, 3, je, je, 2, 3, 3);
                } else {
                    add_at_b::<M>(l, 0, e, je, je, rows, e, e);
                }
                for (s, info) in slots.iter().zip(infos) {
                    if info.f_local == NONE {
                        continue;
                    }
                    let f = shape.f(s.cols as usize);
                    let jf = &jr[s.offset as usize..s.offset as usize + rows * f];
                    let local = info.f_local as usize;
                    let first = !written[local];
                    written[local] = true;
                    add_w::<M>(v, voffs[local], jf, je, rows, f, e, first);
                }
                // With all pairs, a residual's own products are applied with the group's
                // (`update_group`).
                if full {
                    continue;
                }
                for cp in layout.residual_pairs(ri) {
                    let sa = slots[cp.row_slot as usize];
                    let sb = slots[cp.col_slot as usize];
                    let fa = shape.f(sa.cols as usize);
                    let fb = shape.f(sb.cols as usize);
                    let ja = &jr[sa.offset as usize..sa.offset as usize + rows * fa];
                    let jb = &jr[sb.offset as usize..sb.offset as usize + rows * fb];
                    let (addr, ld) = (cp.addr as usize, layout.ld(fa));
                    add_pair::<M>(target, addr, ld, ja, jb, rows, fa, fb);
                }
            }
            debug_assert!(
                written.iter().all(|&w| w),
                "a W block no residual of its chunk has"
            );
            for k in 0..e {
                l[k + k * e] += diag[c.e_col + k];
            }
            // A failed chunk fails the step; nothing of this elimination is used then.
            // A point's (e = 3) kernels with compile-time sizes on the dynamic shape.
            let factored = if e == 3 {
                cholesky(l, 3)
            } else {
                cholesky(l, e)
            };
            if !factored {
                return false;
            }
            y.copy_from_slice(&gradient[c.e_col..c.e_col + e]);
            if e == 3 {
                solve_lower(l, y, 3);
            } else {
                solve_lower(l, y, e);
            }
            let fs = &program.chunk_f[c.f.clone()];
            for (p, &fp) in fs.iter().enumerate() {
                let m = shape.f(program.f_size(fp as usize));
                let vp = &mut v[voffs[p]..voffs[p] + m * e];
                let off = program.f_offset[fp as usize];
                let rhs = &mut rhs[off..off + m];
                if e == 3 {
                    with_fixed_size!(m, |fm| {
                        right_solve_lower_transpose::<M>(vp, l, fm, 3);
                        add_a_x::<M>(rhs, vp, y, fm, 3);
                    });
                } else {
                    right_solve_lower_transpose::<M>(vp, l, m, e);
                    add_a_x::<M>(rhs, vp, y, m, e);
                }
                if full {
                    group.entries.push((fp, g as u32, v_start + voffs[p]));
                } else if let Some(&addr) = layout.diag_addr.get(fp as usize) {
                    sub_a_bt::<M>(target, addr, m, vp, vp, m, m, e);
                }
            }
        }
        if full {
            let chunks = start..end;
            update_group::<S, M>(
                shape, program, layout, &mut group, chunks, jac, bufs.v, target,
            );
        }
        start = end;
    }
    true
}

/// Applies a group's products to S: for every block (p, q), p ≥ q, that a chunk of the
/// group has, in chunk order, the chunk's deferred residual products Jᵀ_p J_q then its
/// −V_p V_qᵀ. Each block's operations are those of the chunk-by-chunk elimination in the
/// same order, so the result is the same to the bit. A block with chunk products only (most
/// of them: two poses of different frames) is updated straight from the chunk mask and the
/// V offsets, without listing its operations.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn update_group<S: Shape, M: MulAdd>(
    shape: S,
    program: &Program,
    layout: &ReducedLayout,
    group: &mut Group,
    chunks: core::ops::Range<usize>,
    jac: &[f64],
    v: &[f64],
    target: &mut [f64],
) {
    let Group {
        entries,
        f,
        mask,
        v_off,
        ops,
    } = group;
    entries.sort_unstable();
    f.clear();
    mask.clear();
    v_off.clear();
    for &(fb, g, off) in entries.iter() {
        if f.last() != Some(&fb) {
            f.push(fb);
            mask.push(0);
            v_off.extend_from_slice(&[0; GROUP]);
        }
        let u = f.len() - 1;
        mask[u] |= 1 << g;
        v_off[u * GROUP + g as usize] = off;
    }
    // Next residual pair of each chunk, and the end of its pairs.
    let pair_start = &layout.chunk_pair_start;
    let mut next: [usize; GROUP] = [0; GROUP];
    let mut pairs_end: [usize; GROUP] = [0; GROUP];
    // Eliminated size of each chunk; all points (e = 3) in the common case.
    let mut e_size: [u32; GROUP] = [0; GROUP];
    // Where each chunk's pair offsets count from.
    let mut jac_base: [usize; GROUP] = [0; GROUP];
    let mut points = true;
    for (g, ci) in chunks.clone().enumerate() {
        jac_base[g] = ReducedLayout::chunk_jac_base(program, ci);
        next[g] = pair_start[ci];
        pairs_end[g] = pair_start[ci + 1];
        let e = shape.e(program.chunks[ci].e_size);
        e_size[g] = e as u32;
        points &= e == 3;
    }
    let pairs = &layout.chunk_pairs;
    // Each chunk's next residual pair, by its block (column, row) packed as a key, `u64::MAX`
    // past its last; the blocks are visited in ascending key order and every pair is consumed
    // at its block's visit, so no next key is below the visited block's and a block has
    // residual products only when its key is the least next key.
    let key = |col: u32, row: u32| (u64::from(col) << 32) | u64::from(row);
    let next_key = |g: usize, next: &[usize; GROUP]| {
        pairs[next[g]..pairs_end[g]]
            .first()
            .map_or(u64::MAX, |d| key(d.col, d.row))
    };
    let n_chunks = chunks.len();
    let least_key = |next: &[usize; GROUP]| {
        (0..n_chunks)
            .map(|g| next_key(g, next))
            .fold(u64::MAX, u64::min)
    };
    let mut least = least_key(&next);
    for (qu, &fq) in f.iter().enumerate() {
        let mq = shape.f(program.f_size(fq as usize));
        let mut column = layout.column(fq);
        for (pu, &fp) in f.iter().enumerate().skip(qu) {
            let mut common = mask[pu] & mask[qu];
            if common == 0 {
                continue;
            }
            let mp = shape.f(program.f_size(fp as usize));
            let addr = column.addr(fp);
            let ld = layout.ld(mp);
            let block = key(fq, fp);
            debug_assert!(block <= least, "a residual product's block passed over");
            if points && block != least {
                // Chunk products only (two poses of different frames, in a rig bundle
                // adjustment): read from the group's V offsets, no operation list.
                let products = ChunkProducts {
                    common,
                    a: &v_off[pu * GROUP..(pu + 1) * GROUP],
                    b: &v_off[qu * GROUP..(qu + 1) * GROUP],
                };
                update_block_e3::<M, _>(target, addr, ld, products, jac, v, mp, mq);
                continue;
            }
            ops.clear();
            while common != 0 {
                let g = common.trailing_zeros() as usize;
                common &= common - 1;
                while next[g] < pairs_end[g] {
                    let d = pairs[next[g]];
                    if (d.col, d.row) != (fq, fp) {
                        break;
                    }
                    ops.push(BlockOp {
                        a: jac_base[g] + d.a as usize,
                        b: jac_base[g] + d.b as usize,
                        k: d.rows,
                        v: false,
                    });
                    next[g] += 1;
                }
                ops.push(BlockOp {
                    a: v_off[pu * GROUP + g],
                    b: v_off[qu * GROUP + g],
                    k: e_size[g],
                    v: true,
                });
            }
            if block == least {
                least = least_key(&next);
            }
            let ops = ops.iter().copied();
            if points {
                update_block_e3::<M, _>(target, addr, ld, ops, jac, v, mp, mq);
            } else {
                update_block::<M, _>(target, addr, ld, ops, jac, v, mp, mq);
            }
        }
    }
    debug_assert!(
        next == pairs_end,
        "a residual product left out of its group"
    );
}

/// out(m × n at `base`, leading dimension `ld`) updated by `ops` in order, column by column
/// with the column held in a local array: per entry the operations of [`add_at_b`] (for a
/// residual product) and [`sub_a_bt`] (for a chunk product), in the same order.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn update_block<M: MulAdd, I: Iterator<Item = BlockOp> + Clone>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    ops: I,
    jac: &[f64],
    v: &[f64],
    m: usize,
    n: usize,
) {
    const LOCAL: usize = 16;
    if m > LOCAL {
        for op in ops {
            let k = op.k as usize;
            if op.v {
                sub_a_bt::<M>(out, base, ld, &v[op.a..], &v[op.b..], m, n, k);
            } else {
                add_at_b::<M>(out, base, ld, &jac[op.a..], &jac[op.b..], k, m, n);
            }
        }
        return;
    }
    for j in 0..n {
        let col = &mut out[base + j * ld..base + j * ld + m];
        let mut acc = [0.0; LOCAL];
        acc[..m].copy_from_slice(col);
        for op in ops.clone() {
            if op.v {
                let e = op.k as usize;
                let a = &v[op.a..op.a + m * e];
                let b = &v[op.b..op.b + n * e];
                for k in 0..e {
                    let c = -b[j + n * k];
                    for i in 0..m {
                        acc[i] = M::madd(a[k * m + i], c, acc[i]);
                    }
                }
            } else if op.k == 2 {
                madd_rows::<M, 2>(&mut acc, &jac[op.a..], &jac[op.b..], j, m, n);
            } else {
                let k = op.k as usize;
                let a = &jac[op.a..op.a + k * m];
                let b = &jac[op.b..op.b + k * n];
                for r in 0..k {
                    let c = b[r * n + j];
                    for i in 0..m {
                        acc[i] = M::madd(a[r * m + i], c, acc[i]);
                    }
                }
            }
        }
        col.copy_from_slice(&acc[..m]);
    }
}

/// [`update_block`] for a point (e = 3), with compile-time block sizes for the reduced
/// blocks of a rig bundle adjustment (5: a pose on a sphere, 6: a pose, 8 and 9: intrinsics).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn update_block_e3<M: MulAdd, I: Iterator<Item = BlockOp> + Clone>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    ops: I,
    jac: &[f64],
    v: &[f64],
    m: usize,
    n: usize,
) {
    // Three columns at a time: their accumulators and the operands fit the 16 vector
    // registers, so the accumulators are never spilled and their chains run side by side.
    macro_rules! columns {
        ($p:literal, $q:literal, [$(($j0:literal, $w:literal)),*]) => {{
            $(update_columns::<M, _, $p, $q, $j0, $w>(out, base, ld, ops.clone(), jac, v);)*
        }};
    }
    match (m, n) {
        (6, 6) => columns!(6, 6, [(0, 3), (3, 3)]),
        (5, 6) => columns!(5, 6, [(0, 3), (3, 3)]),
        (8, 6) => columns!(8, 6, [(0, 3), (3, 3)]),
        (9, 6) => columns!(9, 6, [(0, 3), (3, 3)]),
        (6, 5) => columns!(6, 5, [(0, 3), (3, 2)]),
        (5, 5) => columns!(5, 5, [(0, 3), (3, 2)]),
        (8, 5) => columns!(8, 5, [(0, 3), (3, 2)]),
        (9, 5) => columns!(9, 5, [(0, 3), (3, 2)]),
        (6, 8) => columns!(6, 8, [(0, 3), (3, 3), (6, 2)]),
        (5, 8) => columns!(5, 8, [(0, 3), (3, 3), (6, 2)]),
        (8, 8) => columns!(8, 8, [(0, 3), (3, 3), (6, 2)]),
        (9, 8) => columns!(9, 8, [(0, 3), (3, 3), (6, 2)]),
        (6, 9) => columns!(6, 9, [(0, 3), (3, 3), (6, 3)]),
        (5, 9) => columns!(5, 9, [(0, 3), (3, 3), (6, 3)]),
        (8, 9) => columns!(8, 9, [(0, 3), (3, 3), (6, 3)]),
        (9, 9) => columns!(9, 9, [(0, 3), (3, 3), (6, 3)]),
        _ => update_block::<M, _>(out, base, ld, ops, jac, v, m, n),
    }
}

/// Columns `J0..J0 + W` of [`update_block`] with e = 3 and sizes known at compile time
/// (block `MP × MQ`): the columns are held in local accumulators across the operations, each
/// entry updated by the same operations in the same order.
#[inline(always)]
fn update_columns<
    M: MulAdd,
    I: Iterator<Item = BlockOp>,
    const MP: usize,
    const MQ: usize,
    const J0: usize,
    const W: usize,
>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    ops: I,
    jac: &[f64],
    v: &[f64],
) {
    let mut acc = [[0.0; MP]; W];
    for (j, col) in acc.iter_mut().enumerate() {
        let o = base + (J0 + j) * ld;
        col.copy_from_slice(&out[o..o + MP]);
    }
    for op in ops {
        if op.v {
            let a = &v[op.a..op.a + MP * 3];
            let b = &v[op.b..op.b + MQ * 3];
            for k in 0..3 {
                for (j, col) in acc.iter_mut().enumerate() {
                    let c = -b[J0 + j + MQ * k];
                    for (i, x) in col.iter_mut().enumerate() {
                        *x = M::madd(a[k * MP + i], c, *x);
                    }
                }
            }
        } else {
            let rows = op.k as usize;
            let a = &jac[op.a..op.a + rows * MP];
            let b = &jac[op.b..op.b + rows * MQ];
            for r in 0..rows {
                for (j, col) in acc.iter_mut().enumerate() {
                    let c = b[r * MQ + J0 + j];
                    for (i, x) in col.iter_mut().enumerate() {
                        *x = M::madd(a[r * MP + i], c, *x);
                    }
                }
            }
        }
    }
    for (j, col) in acc.iter().enumerate() {
        let o = base + (J0 + j) * ld;
        out[o..o + MP].copy_from_slice(col);
    }
}

/// acc(m) += Σ_r a_r b_rj over the `R` rows of a (`R × m`) and b (`R × n`), row-major.
#[inline(always)]
fn madd_rows<M: MulAdd, const R: usize>(
    acc: &mut [f64; 16],
    a: &[f64],
    b: &[f64],
    j: usize,
    m: usize,
    n: usize,
) {
    let a = &a[..R * m];
    let b = &b[..R * n];
    for r in 0..R {
        let c = b[r * n + j];
        for i in 0..m {
            acc[i] = M::madd(a[r * m + i], c, acc[i]);
        }
    }
}

/// `add_at_b` for one residual's pair of arguments (two rows: a pose and a point, two poses,
/// a pose and intrinsics), with [`with_fixed_size`]'s sizes on the dynamic shape.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn add_pair<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    a: &[f64],
    b: &[f64],
    r: usize,
    m: usize,
    n: usize,
) {
    match (r, n) {
        (2, 3) => with_fixed_size!(m, |fm| add_at_b::<M>(out, base, ld, a, b, 2, fm, 3)),
        (2, _) => with_fixed_size!(m, |fm| with_fixed_size!(n, |fn_| {
            add_at_b::<M>(out, base, ld, a, b, 2, fm, fn_)
        })),
        _ => add_at_b::<M>(out, base, ld, a, b, r, m, n),
    }
}

/// A chunk's W block (`m × e`, packed) += Jᵀ_f J_e of one residual, or = on the block's first
/// residual (`first`): the same operations as on a zeroed block, without zeroing the chunk's V
/// buffer first (a quarter of a gigabyte in the full garage with intrinsics free, written
/// once more per elimination).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn add_w<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    a: &[f64],
    b: &[f64],
    r: usize,
    m: usize,
    e: usize,
    first: bool,
) {
    if !first {
        add_pair::<M>(out, base, m, a, b, r, m, e);
        return;
    }
    match (r, e) {
        (2, 3) => with_fixed_size!(m, |fm| set_at_b::<M>(out, base, fm, a, b, 2, fm, 3)),
        _ => set_at_b::<M>(out, base, m, a, b, r, m, e),
    }
}

/// JᵀJ blocks of the residuals that have no eliminated argument.
#[inline(always)]
fn free_residuals<M: MulAdd>(
    program: &Program,
    layout: &ReducedLayout,
    jac: &[f64],
    target: &mut [f64],
) {
    for ri in program.n_chunk_residuals..program.res.len() {
        let r = &program.res[ri];
        let rows = r.rows as usize;
        let jr = &jac[r.jac_off..];
        let slots = program.residual_slots(r);
        for cp in layout.residual_pairs(ri) {
            let sa = slots[cp.row_slot as usize];
            let sb = slots[cp.col_slot as usize];
            let (fa, fb) = (sa.cols as usize, sb.cols as usize);
            let ja = &jr[sa.offset as usize..sa.offset as usize + rows * fa];
            let jb = &jr[sb.offset as usize..sb.offset as usize + rows * fb];
            let (addr, ld) = (cp.addr as usize, layout.ld(fa));
            add_at_b::<M>(target, addr, ld, ja, jb, rows, fa, fb);
        }
    }
}
