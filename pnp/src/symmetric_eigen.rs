//! Eigen-decomposition of small dense symmetric matrices held in fixed-size arrays.
//!
//! G. H. Golub and C. F. Van Loan, "Matrix Computations", 4th edition, Johns Hopkins, 2013:
//! Householder tridiagonalization (algorithm 8.3.1) and the implicit symmetric QR step with
//! Wilkinson shift (algorithm 8.3.2), iterated with deflation (algorithm 8.3.3). The
//! tridiagonal matrix is kept as its diagonal and off-diagonal, so a QR step costs O(N); the
//! reflectors and rotations are recorded and applied at the end to the wanted eigenvectors
//! only.
//!
//! The index loops follow the textbook algorithms over fixed-size arrays (clippy's
//! `needless_range_loop` is allowed for that reason).
//!
//! EPnP needs the four smallest eigenvectors of a 9 x 9 matrix on every call: stack arrays,
//! no allocation but the rotation log, and no work on the five unwanted eigenvectors.

#![allow(clippy::needless_range_loop)]

/// Sweeps allowed per eigenvalue before giving up (convergence is cubic; a handful suffice).
const MAX_STEPS_PER_EIGENVALUE: usize = 30;

/// A Householder reflector `I - beta v v^T` acting on entries `first..N`.
#[derive(Clone, Copy)]
struct Reflector<const N: usize> {
    v: [f64; N],
    beta: f64,
    first: usize,
}

impl<const N: usize> Reflector<N> {
    fn apply(&self, x: &mut [f64; N]) {
        let s: f64 = (self.first..N).map(|i| self.v[i] * x[i]).sum::<f64>() * self.beta;
        for i in self.first..N {
            x[i] -= s * self.v[i];
        }
    }
}

/// A Givens rotation on entries `(k, k + 1)`.
#[derive(Clone, Copy)]
struct Rotation {
    k: usize,
    c: f64,
    s: f64,
}

/// The `COUNT` smallest eigenvalues of the symmetric matrix `a`, increasing, and their unit
/// eigenvectors (`vectors[j]` belongs to `values[j]`). `None` if the input is not finite or
/// the QR iteration does not converge (not observed for finite input).
///
/// The eigenvectors are not accumulated during the iteration: the reflectors and rotations
/// are recorded and applied to the `COUNT` wanted unit vectors only, in reverse order, which
/// for EPnP's four of nine saves most of the work.
pub(crate) fn smallest_eigenpairs<const N: usize, const COUNT: usize>(
    mut a: [[f64; N]; N],
) -> Option<([f64; COUNT], [[f64; N]; COUNT])> {
    if COUNT > N || !a.iter().flatten().all(|v| v.is_finite()) {
        return None;
    }
    let mut reflectors = [Reflector {
        v: [0.0; N],
        beta: 0.0,
        first: 0,
    }; N];
    let reflector_count = tridiagonalize(&mut a, &mut reflectors);
    let mut d = [0.0; N];
    let mut e = [0.0; N];
    for i in 0..N {
        d[i] = a[i][i];
        if i + 1 < N {
            e[i] = a[i + 1][i];
        }
    }
    let mut rotations = Vec::with_capacity(16 * N);
    diagonalize(&mut d, &mut e, &mut rotations)?;
    let mut order: [usize; N] = core::array::from_fn(|i| i);
    order.sort_unstable_by(|&i, &j| d[i].total_cmp(&d[j]));
    let mut values = [0.0; COUNT];
    let mut vectors = [[0.0; N]; COUNT];
    for ((value, vector), &j) in values.iter_mut().zip(vectors.iter_mut()).zip(&order) {
        *value = d[j];
        // Column j of Q_H G_1 .. G_m: apply G_m first, the reflectors last.
        vector[j] = 1.0;
        for r in rotations.iter().rev() {
            let (u, v) = (vector[r.k], vector[r.k + 1]);
            vector[r.k] = r.c * u + r.s * v;
            vector[r.k + 1] = r.c * v - r.s * u;
        }
        for reflector in reflectors[..reflector_count].iter().rev() {
            reflector.apply(vector);
        }
    }
    Some((values, vectors))
}

/// Householder reduction of `a` to tridiagonal form, `a <- H^T a H` with
/// `H = H_0 H_1 ..`; records the reflectors and returns their number.
fn tridiagonalize<const N: usize>(
    a: &mut [[f64; N]; N],
    reflectors: &mut [Reflector<N>; N],
) -> usize {
    let mut count = 0;
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
        // p = beta A22 v, w = p - (beta / 2)(p . v) v, A22 <- A22 - v w^T - w v^T.
        let mut p = [0.0; N];
        for i in k + 1..N {
            let mut s = 0.0;
            for j in k + 1..N {
                s += a[i][j] * v[j];
            }
            p[i] = beta * s;
        }
        let pv: f64 = (k + 1..N).map(|i| p[i] * v[i]).sum();
        let mut w = [0.0; N];
        for i in k + 1..N {
            w[i] = p[i] - 0.5 * beta * pv * v[i];
        }
        for i in k + 1..N {
            for j in k + 1..N {
                a[i][j] -= v[i] * w[j] + w[i] * v[j];
            }
        }
        let new = if x0 >= 0.0 { -alpha } else { alpha };
        a[k + 1][k] = new;
        a[k][k + 1] = new;
        for i in k + 2..N {
            a[i][k] = 0.0;
            a[k][i] = 0.0;
        }
        reflectors[count] = Reflector {
            v,
            beta,
            first: k + 1,
        };
        count += 1;
    }
    count
}

/// Implicit symmetric QR with Wilkinson shifts and deflation on the tridiagonal `(d, e)`
/// until `e` vanishes; records every rotation.
fn diagonalize<const N: usize>(
    d: &mut [f64; N],
    e: &mut [f64; N],
    rotations: &mut Vec<Rotation>,
) -> Option<()> {
    let norm = d
        .iter()
        .chain(e.iter())
        .fold(0.0_f64, |m, v| m.max(v.abs()));
    let floor = f64::EPSILON * f64::EPSILON * norm;
    let mut m = N.saturating_sub(1);
    let mut steps = 0;
    while m > 0 {
        // Deflate from the bottom: shrink the active block while its last off-diagonal is
        // negligible.
        let negligible = |e: f64, a: f64, b: f64| {
            e.abs() <= f64::EPSILON * (a.abs() + b.abs()) || e.abs() <= floor
        };
        if negligible(e[m - 1], d[m - 1], d[m]) {
            e[m - 1] = 0.0;
            m -= 1;
            continue;
        }
        let mut l = m - 1;
        while l > 0 && !negligible(e[l - 1], d[l - 1], d[l]) {
            l -= 1;
        }
        if l > 0 {
            e[l - 1] = 0.0;
        }
        steps += 1;
        if steps > MAX_STEPS_PER_EIGENVALUE * N {
            return None;
        }
        qr_step(d, e, rotations, l, m);
    }
    Some(())
}

/// `(c, s)` with `[c s; -s c]^T [a; b] = [r; 0]` (Golub and Van Loan, algorithm 5.1.3).
fn givens(a: f64, b: f64) -> (f64, f64) {
    if b == 0.0 {
        (1.0, 0.0)
    } else if b.abs() > a.abs() {
        let tau = -a / b;
        let s = 1.0 / (1.0 + tau * tau).sqrt();
        (s * tau, s)
    } else {
        let tau = -b / a;
        let c = 1.0 / (1.0 + tau * tau).sqrt();
        (c, c * tau)
    }
}

/// One implicit symmetric QR step with Wilkinson shift on the unreduced block `l..=m` of the
/// tridiagonal matrix `(d, e)`, chasing the bulge down; the rotations `G_k` (acting on the
/// eigenvector matrix as `Q <- Q G_k`) are recorded.
fn qr_step<const N: usize>(
    d: &mut [f64; N],
    e: &mut [f64; N],
    rotations: &mut Vec<Rotation>,
    l: usize,
    m: usize,
) {
    let delta = 0.5 * (d[m - 1] - d[m]);
    let off = e[m - 1];
    let sign = if delta >= 0.0 { 1.0 } else { -1.0 };
    let denominator = delta + sign * delta.hypot(off);
    let mu = if denominator == 0.0 {
        d[m]
    } else {
        d[m] - off * off / denominator
    };
    let mut x = d[l] - mu;
    let mut z = e[l];
    for k in l..m {
        let (c, s) = givens(x, z);
        if k > l {
            e[k - 1] = c * e[k - 1] - s * z;
        }
        let (a, b, cc) = (d[k], e[k], d[k + 1]);
        d[k] = c * c * a - 2.0 * c * s * b + s * s * cc;
        d[k + 1] = s * s * a + 2.0 * c * s * b + c * c * cc;
        e[k] = c * s * (a - cc) + (c * c - s * s) * b;
        if k + 1 < m {
            z = -s * e[k + 1];
            e[k + 1] *= c;
            x = e[k];
        }
        rotations.push(Rotation { k, c, s });
    }
}

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

    fn random_symmetric(rng: &mut ChaCha8Rng) -> [[f64; 9]; 9] {
        let mut a = [[0.0; 9]; 9];
        for i in 0..9 {
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
