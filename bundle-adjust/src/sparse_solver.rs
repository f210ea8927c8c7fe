//! Sparse Cholesky solve of the reduced system with faer: the lower triangle of S is
//! expanded from its stored blocks into compressed columns, the fill-reducing (AMD) ordering
//! and symbolic factorization are computed once per solve, and each iteration only runs the
//! numeric factorization and the triangular solves. The last factor is kept: it
//! preconditions the conjugate gradients of the steps that reuse it
//! ([`crate::SolverOptions::reuse_factorization`]).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::error::{BundleAdjustError, Result};
use crate::pcg::Preconditioner;
use crate::program::Program;
use crate::reduced::ReducedLayout;

/// Structure and workspace of the sparse factorization, built once per solve.
pub(crate) struct SparseSolver {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For every stored value of the compressed lower triangle, its address in the block
    /// storage.
    map: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    /// `l_values` holds the factor of a positive definite matrix.
    factored: bool,
    scratch: MemBuffer,
}

impl SparseSolver {
    pub(crate) fn new(program: &Program, layout: &ReducedLayout) -> Result<Self> {
        let n = program.n_f;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        let mut map = Vec::new();
        col_ptr.push(0);
        // `layout.blocks` is sorted by (column block, row block); the diagonal block comes
        // first in its column.
        let mut start = 0;
        while start < layout.blocks.len() {
            let col = layout.blocks[start].col as usize;
            let mut end = start;
            while end < layout.blocks.len() && layout.blocks[end].col as usize == col {
                end += 1;
            }
            let cols = program.f_size(col);
            for j in 0..cols {
                for b in &layout.blocks[start..end] {
                    let row = b.row as usize;
                    let rows = program.f_size(row);
                    let first = if row == col { j } else { 0 };
                    for i in first..rows {
                        row_idx.push(program.f_offset[row] + i);
                        map.push(b.addr + i + j * rows);
                    }
                }
                col_ptr.push(row_idx.len());
            }
            start = end;
        }
        if col_ptr.len() != n + 1 {
            return Err(BundleAdjustError::Internal {
                reason: "the reduced system's block structure is incomplete",
            });
        }
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(
            structure,
            Side::Lower,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams::default(),
        )
        .map_err(|source| BundleAdjustError::SparseFactorization {
            unknowns: n,
            source,
        })?;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let l_values = vec![0.0; symbolic.len_val()];
        let values = vec![0.0; map.len()];
        Ok(Self {
            n,
            col_ptr,
            row_idx,
            map,
            values,
            symbolic,
            l_values,
            factored: false,
            scratch: MemBuffer::new(req),
        })
    }

    /// Factors the reduced matrix held in block storage `blocks` and solves S x = `rhs`.
    /// Returns false if S is not numerically positive definite.
    pub(crate) fn solve(&mut self, blocks: &[f64], rhs: &[f64], x: &mut [f64]) -> bool {
        x.copy_from_slice(rhs);
        if self.n == 0 {
            return true;
        }
        for (v, &m) in self.values.iter_mut().zip(&self.map) {
            *v = blocks[m];
        }
        let structure = SymbolicSparseColMatRef::new_checked(
            self.n,
            self.n,
            &self.col_ptr,
            None,
            &self.row_idx,
        );
        let a = SparseColMatRef::new(structure, &self.values);
        let stack = MemStack::new(&mut self.scratch);
        self.factored = false;
        let Ok(llt) = self.symbolic.factorize_numeric_llt(
            &mut self.l_values,
            a,
            Side::Lower,
            LltRegularization::default(),
            Par::Seq,
            stack,
            Default::default(),
        ) else {
            return false;
        };
        let b = MatMut::from_column_major_slice_mut(x, self.n, 1);
        llt.solve_in_place_with_conj(Conj::No, b, Par::Seq, stack);
        self.factored = true;
        x.iter().all(|v| v.is_finite())
    }

    /// Whether a factor is kept (the last [`Self::solve`] factored its matrix).
    pub(crate) fn factored(&self) -> bool {
        self.factored
    }

    /// x = M⁻¹ `rhs` with M the matrix of the last factorization (requires [`Self::factored`]).
    fn solve_with_factor(&mut self, rhs: &[f64], x: &mut [f64]) {
        x.copy_from_slice(rhs);
        if self.n == 0 {
            return;
        }
        let llt = LltRef::new(&self.symbolic, &self.l_values);
        let stack = MemStack::new(&mut self.scratch);
        let b = MatMut::from_column_major_slice_mut(x, self.n, 1);
        llt.solve_in_place_with_conj(Conj::No, b, Par::Seq, stack);
    }
}

impl Preconditioner for SparseSolver {
    fn apply(&mut self, _program: &Program, r: &[f64], z: &mut [f64]) {
        self.solve_with_factor(r, z);
    }
}
