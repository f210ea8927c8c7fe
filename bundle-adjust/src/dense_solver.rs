//! Dense Cholesky solve of the reduced system (faer's blocked LLᵀ, in place on the lower
//! triangle accumulated by the elimination).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{
    LltRegularization, cholesky_in_place, cholesky_in_place_scratch,
};
use faer::linalg::cholesky::llt::solve::{solve_in_place, solve_in_place_scratch};
use faer::{MatMut, Par};

/// Workspace for dense solves of one size.
pub(crate) struct DenseSolver {
    n: usize,
    scratch: MemBuffer,
}

impl DenseSolver {
    pub(crate) fn new(n: usize) -> Self {
        let req = cholesky_in_place_scratch::<f64>(n, Par::Seq, Default::default())
            .or(solve_in_place_scratch::<f64>(n, 1, Par::Seq));
        Self {
            n,
            scratch: MemBuffer::new(req),
        }
    }

    /// Factors `s` (column-major `n × n`, lower triangle filled) in place and solves
    /// S x = `rhs` into `x`. Returns false if S is not numerically positive definite.
    pub(crate) fn solve(&mut self, s: &mut [f64], rhs: &[f64], x: &mut [f64]) -> bool {
        let n = self.n;
        x.copy_from_slice(rhs);
        if n == 0 {
            return true;
        }
        let mut a = MatMut::from_column_major_slice_mut(s, n, n);
        let stack = MemStack::new(&mut self.scratch);
        if cholesky_in_place(
            a.as_mut(),
            LltRegularization::default(),
            Par::Seq,
            stack,
            Default::default(),
        )
        .is_err()
        {
            return false;
        }
        let b = MatMut::from_column_major_slice_mut(x, n, 1);
        solve_in_place(a.as_ref(), b, Par::Seq, stack);
        x.iter().all(|v| v.is_finite())
    }
}

/// The inverse of a symmetric positive-definite matrix given by its lower triangle
/// (column-major `n × n`), or `None` if it is not numerically positive definite.
pub(crate) fn spd_inverse(s: &mut [f64], n: usize) -> Option<Vec<f64>> {
    let mut solver = DenseSolver::new(n);
    let req = solve_in_place_scratch::<f64>(n, n, Par::Seq);
    let mut scratch = MemBuffer::new(req);
    let mut a = MatMut::from_column_major_slice_mut(s, n, n);
    if n > 0
        && cholesky_in_place(
            a.as_mut(),
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut solver.scratch),
            Default::default(),
        )
        .is_err()
    {
        return None;
    }
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i + i * n] = 1.0;
    }
    if n > 0 {
        let b = MatMut::from_column_major_slice_mut(&mut inv, n, n);
        solve_in_place(a.as_ref(), b, Par::Seq, MemStack::new(&mut scratch));
    }
    inv.iter().all(|v| v.is_finite()).then_some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn solves_from_the_lower_triangle_only() {
        let n = 40;
        let m = DMatrix::from_fn(n, n, |i, j| ((i * 13 + j * 7) as f64 * 0.1).sin());
        let a = &m * m.transpose() + DMatrix::identity(n, n) * 3.0;
        let mut lower = a.lower_triangle();
        // Garbage above the diagonal must be ignored.
        for j in 1..n {
            lower[(0, j)] = 1e9;
        }
        let b = DVector::from_fn(n, |i, _| (i as f64).cos());
        let mut x = vec![0.0; n];
        let mut solver = DenseSolver::new(n);
        assert!(solver.solve(lower.as_mut_slice(), b.as_slice(), &mut x));
        assert_relative_eq!(&a * DVector::from_vec(x), b, epsilon = 1e-10);

        let mut lower = a.lower_triangle();
        let inv = spd_inverse(lower.as_mut_slice(), n).unwrap();
        let prod = &a * DMatrix::from_vec(n, n, inv);
        assert_relative_eq!(prod, DMatrix::identity(n, n), epsilon = 1e-9);
    }

    #[test]
    fn indefinite_matrices_fail() {
        let mut s = vec![1.0, 2.0, 2.0, 1.0];
        let mut x = vec![0.0; 2];
        assert!(!DenseSolver::new(2).solve(&mut s, &[1.0, 1.0], &mut x));
        let mut s = vec![1.0, 2.0, 2.0, 1.0];
        assert!(spd_inverse(&mut s, 2).is_none());
    }
}
