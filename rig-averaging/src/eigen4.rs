//! Eigen-decomposition of a real symmetric 4x4 matrix by the cyclic Jacobi method.
//!
//! C. G. J. Jacobi, "Über ein leichtes Verfahren die in der Theorie der Säcularstörungen
//! vorkommenden Gleichungen numerisch aufzulösen", Crelle's Journal 30 (1846); the rotation
//! formulas are those of G. H. Golub and C. F. Van Loan, *Matrix Computations*, 4th ed.,
//! section 8.5.2 (the symmetric Schur decomposition of a 2x2 block, taking the smaller rotation
//! angle).
//!
//! Each rotation `J(p, q)` zeroes the entry `a_pq` of `A <- J^T A J` and accumulates
//! `V <- V J`, so `A_0 = V diag(A) V^T` at every step. Convergence is quadratic once the
//! off-diagonal part is small; a 4x4 matrix typically needs three or four sweeps.
//!
//! The sweep uses the parallel (round-robin) ordering of Brent and Luk ("The solution of
//! singular-value and symmetric eigenvalue problems on multiprocessor arrays", SIAM J. Sci.
//! Stat. Comput. 6(1), 1985): three rounds of two disjoint rotations, `{(0,1), (2,3)}`,
//! `{(0,2), (1,3)}`, `{(0,3), (1,2)}`. The two rotations of a round commute (neither touches
//! the other's 2x2 block), so both are computed from the same matrix and the processor
//! overlaps their division and square-root chains, which dominate the cost of a 4x4 Jacobi.
//! The eigenvectors are accurate to `eps * ||A|| / gap`, which is what Markley's averaging
//! needs: the eigenvector of the largest eigenvalue with an error set by the gap.

/// A symmetric 4x4 matrix stored as full rows (both triangles kept equal).
pub(crate) type Sym4 = [[f64; 4]; 4];

/// Upper bound on Jacobi sweeps. Quadratic convergence brings a 4x4 matrix to the stopping
/// test in at most about six sweeps even from adversarial starts; the cap only guards against
/// a NaN entry (which never satisfies the test).
const MAX_SWEEPS: usize = 32;

/// An off-diagonal entry below `NEGLIGIBLE * ||A||_F` is treated as zero: a tenth of the
/// machine epsilon, so dropping all six (both triangles) perturbs `A` by less than
/// `eps * ||A||_F`.
const NEGLIGIBLE: f64 = 0.1 * f64::EPSILON;

/// Eigenvalues and eigenvectors of a symmetric 4x4 matrix.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Eigen4 {
    /// Eigenvalues, in no particular order.
    pub values: [f64; 4],
    /// `vectors[r][k]` is component `r` of the eigenvector of `values[k]` (columns are
    /// eigenvectors, orthonormal to rounding).
    pub vectors: [[f64; 4]; 4],
}

impl Eigen4 {
    /// The indices of the eigenvalues sorted from largest to smallest (ties keep index order).
    pub fn descending_order(&self) -> [usize; 4] {
        let mut order = [0, 1, 2, 3];
        // Insertion sort on four entries: stable, so equal eigenvalues keep index order.
        for i in 1..4 {
            let mut j = i;
            while j > 0 && self.values[order[j - 1]] < self.values[order[j]] {
                order.swap(j - 1, j);
                j -= 1;
            }
        }
        order
    }
}

/// Diagonalizes the symmetric matrix `a` (only symmetric input is meaningful: both triangles
/// are read and updated together).
///
/// Stops after the first sweep in which every off-diagonal entry was negligible:
/// `|a_pq| <= NEGLIGIBLE * ||A||_F`. The dropped entries then perturb `A` by less than
/// `eps * ||A||_F`, the size of the rounding in forming `A` itself, so by Weyl's and the
/// Davis-Kahan theorems the eigenvalues are exact to `eps * ||A||_F` and an eigenvector to
/// `eps * ||A||_F / gap`. (A relative test such as `|a_pq| <= eps * sqrt(|a_pp a_qq|)` would
/// chase the tiny eigenvalues of a nearly rank-one matrix into subnormal numbers, which costs
/// a hundred times more per operation and buys nothing for the largest eigenvector.)
pub(crate) fn symmetric_eigen4(mut a: Sym4) -> Eigen4 {
    let mut v = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let frobenius = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
    // Below the smallest normal number, `threshold` would let entries sink into subnormals.
    let threshold = (NEGLIGIBLE * frobenius).max(f64::MIN_POSITIVE);
    for _ in 0..MAX_SWEEPS {
        let rotated = round(&mut a, &mut v, [0, 1, 2, 3], threshold)
            | round(&mut a, &mut v, [0, 2, 1, 3], threshold)
            | round(&mut a, &mut v, [0, 3, 1, 2], threshold);
        if !rotated {
            break;
        }
    }
    Eigen4 {
        values: [a[0][0], a[1][1], a[2][2], a[3][3]],
        vectors: v,
    }
}

/// `(c, s, t)` of the Jacobi rotation that zeroes `a[p][q]` (Golub and Van Loan, algorithm
/// 8.5.1), `t = tan(theta)` the smaller root of `t^2 + 2 tau t - 1 = 0`; the identity when
/// `|a_pq| <= threshold`.
#[inline(always)]
fn rotation(a: &Sym4, p: usize, q: usize, threshold: f64) -> Option<(f64, f64, f64)> {
    let apq = a[p][q];
    if apq.abs() <= threshold {
        return None;
    }
    let tau = (a[q][q] - a[p][p]) / (2.0 * apq);
    // For huge tau, 1 / (2 tau) avoids overflowing tau^2.
    let t = if tau.abs() > 1e150 {
        0.5 / tau
    } else {
        let root = tau.abs() + (1.0 + tau * tau).sqrt();
        if tau >= 0.0 { 1.0 / root } else { -1.0 / root }
    };
    let c = 1.0 / (1.0 + t * t).sqrt();
    Some((c, t * c, t))
}

/// One round: the commuting rotations of the disjoint pairs `(p, q)` and `(r, s)`, with
/// `[p, q, r, s]` a permutation of `0..4`. Returns whether either rotated.
#[inline(always)]
fn round(a: &mut Sym4, v: &mut [[f64; 4]; 4], [p, q, r, s]: [usize; 4], threshold: f64) -> bool {
    let first = rotation(a, p, q, threshold);
    let second = rotation(a, r, s, threshold);
    if first.is_none() && second.is_none() {
        return false;
    }
    let (c1, s1, t1) = first.unwrap_or((1.0, 0.0, 0.0));
    let (c2, s2, t2) = second.unwrap_or((1.0, 0.0, 0.0));
    // Diagonal 2x2 blocks: eigenvalues of each block, off-diagonal exactly zero.
    let (apq, ars) = (a[p][q], a[r][s]);
    a[p][p] -= t1 * apq;
    a[q][q] += t1 * apq;
    a[r][r] -= t2 * ars;
    a[s][s] += t2 * ars;
    a[p][q] = 0.0;
    a[q][p] = 0.0;
    a[r][s] = 0.0;
    a[s][r] = 0.0;
    // Off-diagonal block B = A[{p,q}, {r,s}] becomes J1^T B J2, where a rotation maps
    // (x_p, x_q) to (c x_p - s x_q, s x_p + c x_q).
    let (bpr, bps, bqr, bqs) = (a[p][r], a[p][s], a[q][r], a[q][s]);
    let (upr, ups) = (c1 * bpr - s1 * bqr, c1 * bps - s1 * bqs);
    let (uqr, uqs) = (s1 * bpr + c1 * bqr, s1 * bps + c1 * bqs);
    let new = [
        (p, r, c2 * upr - s2 * ups),
        (p, s, s2 * upr + c2 * ups),
        (q, r, c2 * uqr - s2 * uqs),
        (q, s, s2 * uqr + c2 * uqs),
    ];
    for (i, j, x) in new {
        a[i][j] = x;
        a[j][i] = x;
    }
    for row in v.iter_mut() {
        let (vp, vq, vr, vs) = (row[p], row[q], row[r], row[s]);
        row[p] = c1 * vp - s1 * vq;
        row[q] = s1 * vp + c1 * vq;
        row[r] = c2 * vr - s2 * vs;
        row[s] = s2 * vr + c2 * vs;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use nalgebra::{Matrix4, SymmetricEigen};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn to_matrix(a: &Sym4) -> Matrix4<f64> {
        Matrix4::from_fn(|r, c| a[r][c])
    }

    #[allow(clippy::needless_range_loop)] // filling both triangles needs the indices
    fn random_symmetric(rng: &mut ChaCha8Rng) -> Sym4 {
        let mut a = [[0.0; 4]; 4];
        for r in 0..4 {
            for c in r..4 {
                let x = rng.random_range(-1.0..1.0);
                a[r][c] = x;
                a[c][r] = x;
            }
        }
        a
    }

    #[test]
    fn reconstructs_random_matrices_and_matches_nalgebra() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..500 {
            let a = random_symmetric(&mut rng);
            let e = symmetric_eigen4(a);
            let v = Matrix4::from_fn(|r, c| e.vectors[r][c]);
            let d = Matrix4::from_diagonal(&nalgebra::Vector4::from(e.values));
            // A = V D V^T and V orthonormal, both to a few ulps of ||A|| ~ 1.
            assert_abs_diff_eq!(v * d * v.transpose(), to_matrix(&a), epsilon = 1e-14);
            assert_abs_diff_eq!(v.transpose() * v, Matrix4::identity(), epsilon = 1e-14);
            let mut ours = e.values;
            ours.sort_by(f64::total_cmp);
            let mut reference: Vec<f64> = SymmetricEigen::new(to_matrix(&a))
                .eigenvalues
                .iter()
                .copied()
                .collect();
            reference.sort_by(f64::total_cmp);
            for (x, y) in ours.iter().zip(&reference) {
                assert_abs_diff_eq!(x, y, epsilon = 1e-14);
            }
        }
    }

    #[test]
    fn diagonal_and_zero_matrices_need_no_rotation() {
        let a = [
            [3.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 4.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let e = symmetric_eigen4(a);
        assert_eq!(e.values, [3.0, 1.0, 4.0, 1.0]);
        assert_eq!(e.descending_order(), [2, 0, 1, 3]);
        let z = symmetric_eigen4([[0.0; 4]; 4]);
        assert_eq!(z.values, [0.0; 4]);
    }

    #[test]
    fn nan_input_terminates() {
        let mut a = [[0.0; 4]; 4];
        a[0][1] = f64::NAN;
        a[1][0] = f64::NAN;
        let e = symmetric_eigen4(a);
        assert!(e.values.iter().any(|x| x.is_nan()));
    }
}
