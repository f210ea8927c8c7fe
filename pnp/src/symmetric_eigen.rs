//! Eigen-decomposition of small dense symmetric matrices held in fixed-size arrays.
//!
//! G. H. Golub and C. F. Van Loan, "Matrix Computations", 4th edition, Johns Hopkins, 2013:
//! Householder tridiagonalization (algorithm 8.3.1), then the implicit symmetric QL iteration
//! with Wilkinson shifts in the form of R. S. Martin, C. Reinsch and J. H. Wilkinson, "The QR
//! and QL algorithms for symmetric matrices", Numerische Mathematik 11, 1968 (`tql2`), run on
//! the tridiagonal matrix in reversed order (so it deflates from the bottom, like the QR
//! iteration of algorithm 8.3.3). The tridiagonal matrix is kept as its diagonal and
//! off-diagonal, so a step costs O(N); the reflectors and rotations are recorded and applied
//! at the end to the wanted eigenvectors only.
//!
//! The index loops follow the textbook algorithms over fixed-size arrays (clippy's
//! `needless_range_loop` is allowed for that reason).
//!
//! EPnP needs the four smallest eigenvectors of a 9 x 9 matrix on every call (twice with the
//! depth reweighting), so the solver is built for that: stack arrays only (no allocation), the
//! rotations logged in a fixed buffer (folded into an accumulated basis in the rare event it
//! fills), and the wanted eigenvectors carried side by side (`[[f64; COUNT]; N]`, one row per
//! coordinate) so that every rotation and reflector updates them all with short vector
//! operations. The rotations of an iteration form one chain of dependent square roots and
//! divisions, which bounds the speed (about 50 cycles a rotation, 50 to 100 rotations for
//! EPnP's matrices).

#![allow(clippy::needless_range_loop)]

/// Sweeps allowed per eigenvalue before giving up (convergence is cubic; a handful suffice).
const MAX_STEPS_PER_EIGENVALUE: usize = 30;

/// Rotations logged before the log is folded into an accumulated basis. A 9 x 9 EPnP matrix
/// takes 40 to 90 rotations, so the fold (an `N x N` matrix update) almost never runs.
const LOG_CAPACITY: usize = 120;

/// The Givens rotations `G_1, G_2, ..` of the QL iteration, each acting on coordinates
/// `(k, k + 1)` as `x_k <- c x_k + s x_k+1`, `x_k+1 <- c x_k+1 - s x_k`; the eigenvector
/// matrix of the tridiagonal matrix is their product `G_1 G_2 ..`.
struct RotationLog<const N: usize> {
    k: [u8; LOG_CAPACITY],
    c: [f64; LOG_CAPACITY],
    s: [f64; LOG_CAPACITY],
    len: usize,
    /// The product of the rotations folded so far (`None`: the identity), row-major.
    folded: Option<[[f64; N]; N]>,
}

impl<const N: usize> RotationLog<N> {
    fn new() -> Self {
        Self {
            k: [0; LOG_CAPACITY],
            c: [0.0; LOG_CAPACITY],
            s: [0.0; LOG_CAPACITY],
            len: 0,
            folded: None,
        }
    }

    /// `folded <- folded G_1 .. G_len` (column operations), and an empty log.
    #[cold]
    fn fold(&mut self) {
        let mut q = self.folded.unwrap_or_else(|| {
            let mut identity = [[0.0; N]; N];
            for (i, row) in identity.iter_mut().enumerate() {
                row[i] = 1.0;
            }
            identity
        });
        for r in 0..self.len {
            let (k, c, s) = (self.k[r] as usize, self.c[r], self.s[r]);
            // Columns k, k + 1 of Q G: (c q_k - s q_k+1, s q_k + c q_k+1).
            for row in q.iter_mut() {
                let (u, v) = (row[k], row[k + 1]);
                row[k] = c * u - s * v;
                row[k + 1] = s * u + c * v;
            }
        }
        self.folded = Some(q);
        self.len = 0;
    }

    /// `x <- folded G_1 .. G_len x` for `COUNT` vectors side by side (row `i` holds coordinate
    /// `i` of each).
    fn apply<const COUNT: usize>(&self, x: &mut [[f64; COUNT]; N]) {
        for r in (0..self.len).rev() {
            let (k, c, s) = (self.k[r] as usize, self.c[r], self.s[r]);
            let (u, v) = (x[k], x[k + 1]);
            for j in 0..COUNT {
                x[k][j] = c * u[j] + s * v[j];
                x[k + 1][j] = c * v[j] - s * u[j];
            }
        }
        if let Some(q) = &self.folded {
            let y = *x;
            for (row, q_row) in x.iter_mut().zip(q) {
                let mut sum = [0.0; COUNT];
                for (qi, yi) in q_row.iter().zip(&y) {
                    for j in 0..COUNT {
                        sum[j] += qi * yi[j];
                    }
                }
                *row = sum;
            }
        }
    }
}

/// The `COUNT` smallest eigenvalues of the symmetric matrix `a`, increasing, and their unit
/// eigenvectors (`vectors[j]` belongs to `values[j]`). `None` if the input is not finite or
/// the QR iteration does not converge (not observed for finite input). `a` must hold both
/// triangles: the reduction reads whole rows.
///
/// The eigenvectors are not accumulated during the iteration: the reflectors and rotations
/// are recorded and applied to the `COUNT` wanted unit vectors only, in reverse order, which
/// for EPnP's four of nine saves most of the work.
pub(crate) fn smallest_eigenpairs<const N: usize, const COUNT: usize>(
    mut a: [[f64; N]; N],
) -> Option<([f64; COUNT], [[f64; N]; COUNT])> {
    // `sum * 0` is zero exactly when every entry is finite.
    let sum: f64 = a.iter().flatten().sum();
    if COUNT > N || N > usize::from(u8::MAX) || sum * 0.0 != 0.0 {
        return None;
    }
    // Householder vectors, one per row (`v[k]` acts on entries `k + 1..N`), and their betas.
    let mut householder = [[0.0; N]; N];
    let mut betas = [0.0; N];
    tridiagonalize(&mut a, &mut householder, &mut betas);
    // The tridiagonal matrix in reversed order (d[i] = T[N-1-i][N-1-i]): the QL iteration on
    // it is the QR iteration on T, whose bottom-up deflation suits the Householder reduction
    // from the top (about 30 % fewer rotations on EPnP's matrices than QL on T).
    let mut d = [0.0; N];
    let mut e = [0.0; N];
    for i in 0..N {
        d[i] = a[N - 1 - i][N - 1 - i];
        if i + 1 < N {
            e[i] = a[N - 1 - i][N - 2 - i];
        }
    }
    let mut log = RotationLog::<N>::new();
    diagonalize(&mut d, &mut e, &mut log)?;
    // The COUNT smallest, by a partial selection sort (stable: ties keep their index order).
    let mut order: [usize; N] = core::array::from_fn(|i| i);
    for j in 0..COUNT {
        let mut best = j;
        for i in j + 1..N {
            if d[order[i]].total_cmp(&d[order[best]]).is_lt() {
                best = i;
            }
        }
        order[j..=best].rotate_right(1);
    }
    let mut values = [0.0; COUNT];
    // The wanted eigenvectors side by side: x[i][j] is coordinate i of vector j.
    let mut x = [[0.0; COUNT]; N];
    for (j, value) in values.iter_mut().enumerate() {
        *value = d[order[j]];
        x[order[j]][j] = 1.0;
    }
    // Column order[j] of Q_H P G_1 .. G_m (P the order reversal): the rotations first (last
    // one first), then the reversal, then the reflectors, last one first.
    log.apply(&mut x);
    x.reverse();
    for k in (0..N.saturating_sub(2)).rev() {
        let beta = betas[k];
        if beta == 0.0 {
            continue;
        }
        let v = &householder[k];
        let mut dot = [0.0; COUNT];
        for i in k + 1..N {
            for j in 0..COUNT {
                dot[j] += v[i] * x[i][j];
            }
        }
        for j in 0..COUNT {
            dot[j] *= beta;
        }
        for i in k + 1..N {
            for j in 0..COUNT {
                x[i][j] -= dot[j] * v[i];
            }
        }
    }
    let mut vectors = [[0.0; N]; COUNT];
    for (i, row) in x.iter().enumerate() {
        for j in 0..COUNT {
            vectors[j][i] = row[j];
        }
    }
    Some((values, vectors))
}

/// Householder reduction of `a` to tridiagonal form, `a <- H^T a H` with `H = H_0 H_1 ..`,
/// `H_k = I - beta_k v_k v_k^T`; records `v_k` (zero in entries `0..=k`) and `beta_k` (0 when
/// column `k` is already reduced). On return `a[i][i]` and `a[i + 1][i]` hold the
/// tridiagonal matrix.
///
/// Each step is the two-sided update `H A H = A - v w^T - w v^T` with `p = beta A v` and
/// `w = p - (beta / 2)(p . v) v`, done with full-width rows (the zeros of `v` make it exact on
/// the reduced part), which keeps every inner loop a fixed-length vector operation. Rows
/// above `k` are untouched (`v` and `w` vanish there); row and column `k` are set to their
/// exact tridiagonal form.
fn tridiagonalize<const N: usize>(
    a: &mut [[f64; N]; N],
    householder: &mut [[f64; N]; N],
    betas: &mut [f64; N],
) {
    for k in 0..N.saturating_sub(2) {
        let mut v = [0.0; N];
        let mut tail = 0.0;
        for i in k + 2..N {
            v[i] = a[i][k];
            tail += v[i] * v[i];
        }
        if tail == 0.0 {
            continue;
        }
        let x0 = a[k + 1][k];
        let alpha = (x0 * x0 + tail).sqrt();
        let v0 = if x0 >= 0.0 { x0 + alpha } else { x0 - alpha };
        v[k + 1] = v0;
        let beta = 2.0 / (v0 * v0 + tail);
        // p = beta A v, from the rows k + 1.. (A is symmetric: row j is column j).
        let mut p = [0.0; N];
        for j in k + 1..N {
            let scale = beta * v[j];
            let row = &a[j];
            for i in 0..N {
                p[i] += scale * row[i];
            }
        }
        let mut pv = 0.0;
        for i in 0..N {
            pv += p[i] * v[i];
        }
        let half = 0.5 * beta * pv;
        let mut w = [0.0; N];
        for i in 0..N {
            w[i] = p[i] - half * v[i];
        }
        for i in k + 1..N {
            let (vi, wi) = (v[i], w[i]);
            let row = &mut a[i];
            for j in 0..N {
                row[j] -= vi * w[j] + wi * v[j];
            }
        }
        let off = if x0 >= 0.0 { -alpha } else { alpha };
        for j in k + 1..N {
            a[k][j] = 0.0;
            a[j][k] = 0.0;
        }
        a[k][k + 1] = off;
        a[k + 1][k] = off;
        householder[k] = v;
        betas[k] = beta;
    }
}

/// Implicit QL iteration with Wilkinson shifts (the `tql2` form of R. S. Martin, C. Reinsch
/// and J. H. Wilkinson, "The QR and QL algorithms for symmetric matrices", Numerische
/// Mathematik 11, 1968) on the tridiagonal `(d, e)`, `e[i]` coupling `d[i]` and `d[i + 1]`,
/// until `e` vanishes; logs every rotation. The eigenvalues converge at the top of the active
/// block, which then moves down.
fn diagonalize<const N: usize>(
    d: &mut [f64; N],
    e: &mut [f64; N],
    log: &mut RotationLog<N>,
) -> Option<()> {
    let norm = d
        .iter()
        .chain(e.iter())
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    let floor = f64::EPSILON * f64::EPSILON * norm;
    let mut len = log.len;
    let mut steps = 0;
    for l in 0..N {
        loop {
            // The first negligible coupling at or below l ends the active block l..=m.
            let mut m = l;
            while m + 1 < N {
                let coupling = e[m].abs();
                if coupling <= floor || coupling <= f64::EPSILON * (d[m].abs() + d[m + 1].abs()) {
                    break;
                }
                m += 1;
            }
            if m == l {
                break;
            }
            steps += 1;
            if steps > MAX_STEPS_PER_EIGENVALUE * N {
                log.len = len;
                return None;
            }
            // Wilkinson shift from the top 2 x 2 of the block, as g = d[m] - shift:
            // shift = d[l] - e^2 / (delta + sign(delta) sqrt(delta^2 + e^2)) with
            // delta = (d[l + 1] - d[l]) / 2, one division on the chain.
            let delta = 0.5 * (d[l + 1] - d[l]);
            let h = norm2(delta, e[l]);
            let mut g = d[m] - d[l] + e[l] * e[l] / (delta + h.copysign(delta));
            let (mut s, mut c, mut p) = (1.0, 1.0, 0.0);
            let mut underflow = false;
            for i in (l..m).rev() {
                let f = s * e[i];
                let b = c * e[i];
                let r = norm2(f, g);
                e[i + 1] = r;
                if r == 0.0 {
                    // The rotation underflowed: split the block here and start over.
                    d[i + 1] -= p;
                    e[m] = 0.0;
                    underflow = true;
                    break;
                }
                // Two independent divisions: shorter than a reciprocal and two products on
                // the chain of dependent rotations.
                s = f / r;
                c = g / r;
                g = d[i + 1] - p;
                let r = (d[i] - g) * s + 2.0 * c * b;
                p = s * r;
                d[i + 1] = g + p;
                g = c * r - b;
                // Q <- Q G on columns (i, i + 1): (c q_i - s q_i+1, s q_i + c q_i+1).
                if len == LOG_CAPACITY {
                    log.len = len;
                    log.fold();
                    len = 0;
                }
                // i < N <= 255 (checked by the caller).
                log.k[len] = i as u8;
                log.c[len] = c;
                log.s[len] = s;
                len += 1;
            }
            if !underflow {
                d[l] -= p;
                e[l] = g;
                e[m] = 0.0;
            }
        }
    }
    log.len = len;
    Some(())
}

/// `sqrt(a^2 + b^2)`, without overflow or underflow: directly when the squares are safely
/// representable (always, for EPnP's matrices), by `hypot` otherwise.
#[inline]
fn norm2(a: f64, b: f64) -> f64 {
    let squares = a * a + b * b;
    if squares > SAFE_SQUARES.0 && squares < SAFE_SQUARES.1 {
        squares.sqrt()
    } else {
        a.hypot(b)
    }
}

/// Range of `a^2 + b^2` in which [`norm2`] takes the square root directly: far from the
/// underflow and overflow thresholds, so the squares lose no accuracy.
const SAFE_SQUARES: (f64, f64) = (1e-280, 1e280);

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Eigenpairs satisfy `A v = lambda v` to round-off, are orthonormal, and are the smallest
    /// of nalgebra's spectrum.
    fn check<const N: usize, const COUNT: usize>(a: [[f64; N]; N]) {
        let (values, vectors) = smallest_eigenpairs::<N, COUNT>(a).unwrap();
        let m = DMatrix::from_fn(N, N, |i, j| a[i][j]);
        let scale = m.norm().max(1.0);
        let mut theirs: Vec<f64> = m.clone().symmetric_eigenvalues().iter().copied().collect();
        theirs.sort_by(f64::total_cmp);
        for j in 0..COUNT {
            let v = DVector::from_column_slice(&vectors[j]);
            assert!((v.norm() - 1.0).abs() < 1e-13);
            assert!((&m * &v - &v * values[j]).norm() < 1e-13 * scale);
            assert!((values[j] - theirs[j]).abs() < 1e-12 * scale);
            for i in 0..j {
                let u = DVector::from_column_slice(&vectors[i]);
                assert!(u.dot(&v).abs() < 1e-13);
            }
        }
    }

    fn random_symmetric<const N: usize>(rng: &mut ChaCha8Rng) -> [[f64; N]; N] {
        let mut a = [[0.0; N]; N];
        for i in 0..N {
            for j in 0..=i {
                let v = rng.random_range(-1.0..1.0);
                a[i][j] = v;
                a[j][i] = v;
            }
        }
        a
    }

    #[test]
    fn random_symmetric_matrices_decompose_to_round_off() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..200 {
            check::<9, 4>(random_symmetric(&mut rng));
            check::<9, 9>(random_symmetric(&mut rng));
        }
    }

    /// A 20 x 20 matrix takes several hundred rotations, so the log is folded into the
    /// accumulated basis (the path EPnP's 9 x 9 matrices almost never take).
    #[test]
    fn large_matrices_fold_the_rotation_log() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for _ in 0..20 {
            check::<20, 5>(random_symmetric(&mut rng));
        }
    }

    #[test]
    fn rank_deficient_and_repeated_spectra() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        for rank in [0usize, 1, 3, 5, 8] {
            // A = B B^T with B 9 x rank: PSD with a (9 - rank)-fold zero eigenvalue.
            let b = DMatrix::from_fn(9, 9, |_, j| {
                if j < rank {
                    rng.random_range(-1.0..1.0)
                } else {
                    0.0
                }
            });
            let m = &b * b.transpose();
            check::<9, 4>(core::array::from_fn(|i| {
                core::array::from_fn(|j| m[(i, j)])
            }));
        }
        check::<3, 3>([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]);
        check::<4, 2>([[0.0; 4]; 4]);
        assert!(smallest_eigenpairs::<2, 1>([[f64::NAN, 0.0], [0.0, 1.0]]).is_none());
    }
}
