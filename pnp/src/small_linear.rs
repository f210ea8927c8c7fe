//! Small dense linear systems in fixed-size arrays: Gaussian elimination with partial
//! pivoting, and the `L D L^T` solve of a symmetric positive definite 4 x 4 system.
//!
//! G. H. Golub and C. F. Van Loan, "Matrix Computations", 4th edition, Johns Hopkins, 2013:
//! algorithms 3.4.1 (partial pivoting) and 4.1.2 (`L D L^T`). EPnP solves a 3 x 3, a 6 x 6 and
//! a few 4 x 4 systems per candidate; on stack arrays they cost a few hundred instructions.

#![allow(clippy::needless_range_loop)]

/// The solution of `a x = b` by Gaussian elimination with partial pivoting; `None` if a pivot
/// is zero (a singular matrix) or the solution is not finite.
pub(crate) fn solve_linear<const N: usize>(
    mut a: [[f64; N]; N],
    mut b: [f64; N],
) -> Option<[f64; N]> {
    for k in 0..N {
        let mut pivot = k;
        for i in k + 1..N {
            if a[i][k].abs() > a[pivot][k].abs() {
                pivot = i;
            }
        }
        if a[pivot][k] == 0.0 {
            return None;
        }
        a.swap(k, pivot);
        b.swap(k, pivot);
        let inverse = 1.0 / a[k][k];
        let pivot_row = a[k];
        for i in k + 1..N {
            let factor = a[i][k] * inverse;
            // Full-width rows: the columns up to k are never read again, and fixed-length
            // rows vectorize.
            for (x, p) in a[i].iter_mut().zip(&pivot_row) {
                *x -= factor * p;
            }
            b[i] -= factor * b[k];
        }
    }
    let mut x = [0.0; N];
    for k in (0..N).rev() {
        let mut sum = b[k];
        for j in k + 1..N {
            sum -= a[k][j] * x[j];
        }
        x[k] = sum / a[k][k];
    }
    let total: f64 = x.iter().sum();
    (total * 0.0 == 0.0).then_some(x)
}

/// The solution of `a x = b` for a symmetric positive definite 4 x 4 `a`, given by its upper
/// triangle packed by rows (`a00 a01 a02 a03 a11 a12 a13 a22 a23 a33`), by the factorization
/// `a = L D L^T` (unit lower triangular `L`, diagonal `D`: the Cholesky factorization without
/// its square roots, which keeps them off the critical path); `None` if `a` is not positive
/// definite (a pivot of `D` not positive).
pub(crate) fn cholesky_solve_4(a: &[f64; 10], b: &[f64; 4]) -> Option<[f64; 4]> {
    let [a00, a01, a02, a03, a11, a12, a13, a22, a23, a33] = *a;
    // Column by column: d_j = a_jj - sum_k l_jk^2 d_k, l_ij = (a_ij - sum_k l_ik d_k l_jk) / d_j.
    let d0 = a00;
    if d0.is_nan() || d0 <= 0.0 {
        return None;
    }
    let i0 = 1.0 / d0;
    let (l10, l20, l30) = (a01 * i0, a02 * i0, a03 * i0);
    let d1 = a11 - l10 * a01;
    if d1.is_nan() || d1 <= 0.0 {
        return None;
    }
    let i1 = 1.0 / d1;
    let u21 = a12 - l20 * a01;
    let u31 = a13 - l30 * a01;
    let (l21, l31) = (u21 * i1, u31 * i1);
    let d2 = a22 - l20 * a02 - l21 * u21;
    if d2.is_nan() || d2 <= 0.0 {
        return None;
    }
    let i2 = 1.0 / d2;
    let u32 = a23 - l30 * a02 - l31 * u21;
    let l32 = u32 * i2;
    let d3 = a33 - l30 * a03 - l31 * u31 - l32 * u32;
    if d3.is_nan() || d3 <= 0.0 {
        return None;
    }
    let i3 = 1.0 / d3;
    // L y = b, D z = y, L^T x = z.
    let y0 = b[0];
    let y1 = b[1] - l10 * y0;
    let y2 = b[2] - l20 * y0 - l21 * y1;
    let y3 = b[3] - l30 * y0 - l31 * y1 - l32 * y2;
    let x3 = y3 * i3;
    let x2 = y2 * i2 - l32 * x3;
    let x1 = y1 * i1 - l21 * x2 - l31 * x3;
    let x0 = y0 * i0 - l10 * x1 - l20 * x2 - l30 * x3;
    Some([x0, x1, x2, x3])
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{SMatrix, SVector};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn systems_are_solved_to_round_off() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let a: [[f64; 6]; 6] =
                core::array::from_fn(|_| core::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let b: [f64; 6] = core::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let x = solve_linear(a, b).unwrap();
            let m = SMatrix::<f64, 6, 6>::from_fn(|i, j| a[i][j]);
            let residual = m * SVector::<f64, 6>::from(x) - SVector::<f64, 6>::from(b);
            assert!(residual.norm() < 1e-10 * (1.0 + SVector::<f64, 6>::from(x).norm()));
            // B^T B + I is positive definite.
            let b4 = SMatrix::<f64, 4, 4>::from_fn(|i, j| a[i][j]);
            let spd = b4.transpose() * b4 + SMatrix::<f64, 4, 4>::identity();
            let packed = [
                spd[(0, 0)],
                spd[(0, 1)],
                spd[(0, 2)],
                spd[(0, 3)],
                spd[(1, 1)],
                spd[(1, 2)],
                spd[(1, 3)],
                spd[(2, 2)],
                spd[(2, 3)],
                spd[(3, 3)],
            ];
            let rhs = [b[0], b[1], b[2], b[3]];
            let y = SVector::<f64, 4>::from(cholesky_solve_4(&packed, &rhs).unwrap());
            let residual = spd * y - SVector::<f64, 4>::from(rhs);
            assert!(residual.norm() < 1e-12 * spd.norm() * y.norm());
        }
        assert!(solve_linear([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0]).is_none());
        let indefinite = [1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0];
        assert!(cholesky_solve_4(&indefinite, &[1.0; 4]).is_none());
        let not_finite = [f64::NAN, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 1.0];
        assert!(cholesky_solve_4(&not_finite, &[1.0; 4]).is_none());
    }
}
