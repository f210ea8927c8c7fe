//! Real polynomial roots through the eigenvalues of the companion matrix, on the stack.
//!
//! The companion matrix of a monic polynomial is upper Hessenberg, so its eigenvalues come from
//! the Francis double-shift QR iteration directly (Francis 1961; Golub and Van Loan, *Matrix
//! Computations*, 4th ed., section 7.5), after a Parlett-Reinsch balancing (Parlett and Reinsch
//! 1969). The iteration is bounded ([`MAX_ITERATIONS_PER_EIGENVALUE`] per eigenvalue, with
//! exceptional shifts at 10 and 20 iterations), so it always returns: nalgebra's general Schur
//! decomposition has been reported to hang on companion-like matrices (nalgebra issues 611,
//! 764, 1291, 1528), which is why it is not used here.
//!
//! Everything lives in a fixed `[[f64; MAX_DEGREE]; MAX_DEGREE]` array: no heap allocation.

/// Largest polynomial degree supported (the Kannala-Brandt polynomial has degree 9).
pub const MAX_DEGREE: usize = 9;

/// Iteration bound per eigenvalue (EISPACK's `hqr` uses 30 with the same exceptional shifts).
pub const MAX_ITERATIONS_PER_EIGENVALUE: usize = 30;

/// The eigenvalue iteration reached its bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IterationLimit {
    /// Total iterations run.
    pub iterations: usize,
}

/// Complex roots `(re, im)` of a polynomial, and how many there are.
#[derive(Clone, Copy, Debug)]
pub struct Roots {
    /// Real parts; entries `0..len` are valid.
    pub re: [f64; MAX_DEGREE],
    /// Imaginary parts; entries `0..len` are valid.
    pub im: [f64; MAX_DEGREE],
    /// Number of roots (the polynomial's degree).
    pub len: usize,
}

/// Roots of `sum_i coeffs[i] x^i`. The degree is that of the highest non-zero coefficient (so a
/// zero leading coefficient never divides by zero); coefficients beyond index [`MAX_DEGREE`]
/// must be zero. A polynomial of degree 0 has no roots.
///
/// # Errors
/// [`IterationLimit`] if the QR iteration did not converge within its bound.
pub fn roots(coeffs: &[f64]) -> Result<Roots, IterationLimit> {
    let mut out = Roots {
        re: [0.0; MAX_DEGREE],
        im: [0.0; MAX_DEGREE],
        len: 0,
    };
    let Some(degree) = coeffs.iter().rposition(|&c| c != 0.0) else {
        return Ok(out);
    };
    let degree = degree.min(MAX_DEGREE);
    out.len = degree;
    if degree == 0 {
        return Ok(out);
    }
    let lead = coeffs[degree];
    if degree == 1 {
        out.re[0] = -coeffs[0] / lead;
        return Ok(out);
    }
    // Companion matrix in upper Hessenberg form: ones on the subdiagonal, the last column holds
    // -c_i / c_n. Its characteristic polynomial is the monic polynomial.
    let mut a = [[0.0; MAX_DEGREE]; MAX_DEGREE];
    for i in 0..degree {
        if i > 0 {
            a[i][i - 1] = 1.0;
        }
        a[i][degree - 1] = -coeffs[i] / lead;
    }
    balance(&mut a, degree);
    hessenberg_eigenvalues(&mut a, degree, &mut out.re, &mut out.im)?;
    Ok(out)
}

/// Parlett-Reinsch balancing with powers of two (exact in floating point): a diagonal
/// similarity that makes row and column norms comparable, which keeps the eigenvalues of
/// badly scaled companion matrices accurate. It preserves the Hessenberg form.
// Index loops mirror the matrix formulas; iterators would hide which row and column is which.
#[allow(clippy::needless_range_loop)]
fn balance(a: &mut [[f64; MAX_DEGREE]; MAX_DEGREE], n: usize) {
    const RADIX: f64 = 2.0;
    const RADIX2: f64 = RADIX * RADIX;
    // Each pass changes scales by powers of two; the loop stops once no scale changes, and a
    // bound keeps it finite whatever the input.
    for _ in 0..64 {
        let mut done = true;
        for i in 0..n {
            let mut r = 0.0;
            let mut c = 0.0;
            for j in 0..n {
                if j != i {
                    c += a[j][i].abs();
                    r += a[i][j].abs();
                }
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let s = c + r;
            let mut g = r / RADIX;
            let mut f = 1.0;
            let mut c2 = c;
            while c2 < g {
                f *= RADIX;
                c2 *= RADIX2;
            }
            g = r * RADIX;
            while c2 > g {
                f /= RADIX;
                c2 /= RADIX2;
            }
            if (c2 + r / f) / f < 0.95 * s {
                done = false;
                let g = 1.0 / f;
                for j in 0..n {
                    a[i][j] *= g;
                }
                for row in a.iter_mut().take(n) {
                    row[i] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
}

/// Eigenvalues of the upper Hessenberg matrix `a[0..n][0..n]` by the Francis double-shift QR
/// iteration with deflation. `a` is overwritten.
#[allow(clippy::needless_range_loop)] // as for `balance`
fn hessenberg_eigenvalues(
    a: &mut [[f64; MAX_DEGREE]; MAX_DEGREE],
    n: usize,
    wr: &mut [f64; MAX_DEGREE],
    wi: &mut [f64; MAX_DEGREE],
) -> Result<(), IterationLimit> {
    let eps = f64::EPSILON;
    let mut anorm = 0.0;
    for i in 0..n {
        for j in i.saturating_sub(1)..n {
            anorm += a[i][j].abs();
        }
    }
    let mut total = 0usize;
    // `hi` is the index of the last row of the active block (the block still to deflate).
    let mut hi = n as isize - 1;
    // Accumulated exceptional shifts.
    let mut shift = 0.0;
    while hi >= 0 {
        let h = hi as usize;
        let mut its = 0usize;
        loop {
            // Find the start `lo` of the unreduced block ending at `h`.
            let mut lo = h;
            while lo >= 1 {
                let mut s = a[lo - 1][lo - 1].abs() + a[lo][lo].abs();
                if s == 0.0 {
                    s = anorm;
                }
                if a[lo][lo - 1].abs() <= eps * s {
                    a[lo][lo - 1] = 0.0;
                    break;
                }
                lo -= 1;
            }
            let mut x = a[h][h];
            if lo == h {
                // A 1x1 block: one real eigenvalue.
                wr[h] = x + shift;
                wi[h] = 0.0;
                hi -= 1;
                break;
            }
            let mut y = a[h - 1][h - 1];
            let mut w = a[h][h - 1] * a[h - 1][h];
            if lo == h - 1 {
                // A 2x2 block: a real pair or a complex-conjugate pair.
                let p = 0.5 * (y - x);
                let q = p * p + w;
                let z = q.abs().sqrt();
                x += shift;
                if q >= 0.0 {
                    let z = p + z.copysign(p);
                    wr[h - 1] = x + z;
                    wr[h] = if z != 0.0 { x - w / z } else { x + z };
                    wi[h - 1] = 0.0;
                    wi[h] = 0.0;
                } else {
                    wr[h - 1] = x + p;
                    wr[h] = x + p;
                    wi[h - 1] = -z;
                    wi[h] = z;
                }
                hi -= 2;
                break;
            }
            if its == MAX_ITERATIONS_PER_EIGENVALUE {
                return Err(IterationLimit { iterations: total });
            }
            if its == 10 || its == 20 {
                // Exceptional shift (Wilkinson), breaks cycles of the standard shift.
                shift += x;
                for (i, row) in a.iter_mut().enumerate().take(h + 1) {
                    row[i] -= x;
                }
                let s = a[h][h - 1].abs() + a[h - 1][h - 2].abs();
                x = 0.75 * s;
                y = x;
                w = -0.4375 * s * s;
            }
            its += 1;
            total += 1;
            francis_step(a, lo, h, x, y, w);
        }
    }
    Ok(())
}

/// One implicit double-shift QR step on rows and columns `lo..=h`, with the shifts given by the
/// trailing 2x2 block (`x = a[h][h]`, `y = a[h-1][h-1]`, `w = a[h][h-1] a[h-1][h]`).
fn francis_step(
    a: &mut [[f64; MAX_DEGREE]; MAX_DEGREE],
    lo: usize,
    h: usize,
    x: f64,
    y: f64,
    w: f64,
) {
    let eps = f64::EPSILON;
    // Look for two consecutive small subdiagonal elements to start the bulge lower.
    let mut m = h - 2;
    let (mut p, mut q, mut r);
    loop {
        let z = a[m][m];
        let rr = x - z;
        let s = y - z;
        p = (rr * s - w) / a[m + 1][m] + a[m][m + 1];
        q = a[m + 1][m + 1] - z - rr - s;
        r = a[m + 2][m + 1];
        let inv = 1.0 / (p.abs() + q.abs() + r.abs());
        p *= inv;
        q *= inv;
        r *= inv;
        if m == lo {
            break;
        }
        let u = a[m][m - 1].abs() * (q.abs() + r.abs());
        let v = p.abs() * (a[m - 1][m - 1].abs() + z.abs() + a[m + 1][m + 1].abs());
        if u <= eps * v {
            break;
        }
        m -= 1;
    }
    for i in (m + 2)..=h {
        a[i][i - 2] = 0.0;
        if i != m + 2 {
            a[i][i - 3] = 0.0;
        }
    }
    // Chase the bulge with 3x3 Householder reflections.
    let mut xs = 0.0;
    for k in m..h {
        if k != m {
            p = a[k][k - 1];
            q = a[k + 1][k - 1];
            r = if k != h - 1 { a[k + 2][k - 1] } else { 0.0 };
            xs = p.abs() + q.abs() + r.abs();
            if xs != 0.0 {
                let inv = 1.0 / xs;
                p *= inv;
                q *= inv;
                r *= inv;
            }
        }
        let s = (p * p + q * q + r * r).sqrt().copysign(p);
        if s == 0.0 {
            continue;
        }
        if k == m {
            if lo != m {
                a[k][k - 1] = -a[k][k - 1];
            }
        } else {
            a[k][k - 1] = -s * xs;
        }
        p += s;
        let inv_s = 1.0 / s;
        let inv_p = 1.0 / p;
        let hx = p * inv_s;
        let hy = q * inv_s;
        let hz = r * inv_s;
        let q2 = q * inv_p;
        let r2 = r * inv_p;
        // Row update of rows k, k+1 (and k+2) over columns k..=h, on disjoint row slices so the
        // loop has no bounds checks.
        let (upper, lower) = a.split_at_mut(k + 1);
        let row_k = &mut upper[k][k..=h];
        let (row_k1, rest) = lower.split_at_mut(1);
        let row_k1 = &mut row_k1[0][k..=h];
        if k != h - 1 {
            let row_k2 = &mut rest[0][k..=h];
            for ((x0, x1), x2) in row_k
                .iter_mut()
                .zip(row_k1.iter_mut())
                .zip(row_k2.iter_mut())
            {
                let t = *x0 + q2 * *x1 + r2 * *x2;
                *x2 -= t * hz;
                *x1 -= t * hy;
                *x0 -= t * hx;
            }
        } else {
            for (x0, x1) in row_k.iter_mut().zip(row_k1.iter_mut()) {
                let t = *x0 + q2 * *x1;
                *x1 -= t * hy;
                *x0 -= t * hx;
            }
        }
        let last = h.min(k + 3);
        for row in a.iter_mut().take(last + 1).skip(lo) {
            let mut t = hx * row[k] + hy * row[k + 1];
            if k != h - 1 {
                t += hz * row[k + 2];
                row[k + 2] -= t * r2;
            }
            row[k + 1] -= t * q2;
            row[k] -= t;
        }
    }
}

/// Evaluate `sum_i coeffs[i] x^i` (Horner).
pub fn eval(coeffs: &[f64], x: f64) -> f64 {
    coeffs.iter().rev().fold(0.0, |acc, &c| acc * x + c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn sorted_real(r: &Roots) -> Vec<f64> {
        let mut v: Vec<f64> = (0..r.len)
            .filter(|&i| r.im[i] == 0.0)
            .map(|i| r.re[i])
            .collect();
        v.sort_by(f64::total_cmp);
        v
    }

    #[test]
    fn roots_of_products_of_known_factors() {
        // (x - 1)(x - 2)(x + 3)(x - 0.5) = x^4 - 0.5x^3 - 7x^2 + 9.5x - 3
        let r = roots(&[-3.0, 9.5, -7.0, -0.5, 1.0]).unwrap();
        let v = sorted_real(&r);
        assert_eq!(v.len(), 4);
        for (got, want) in v.iter().zip([-3.0, 0.5, 1.0, 2.0]) {
            assert_relative_eq!(*got, want, epsilon = 1e-12);
        }
    }

    #[test]
    fn complex_pair_and_degree_from_highest_nonzero() {
        // x^2 + 1 with trailing zero coefficients: degree 2, roots +-i.
        let r = roots(&[1.0, 0.0, 1.0, 0.0, 0.0]).unwrap();
        assert_eq!(r.len, 2);
        for i in 0..2 {
            assert_relative_eq!(r.re[i], 0.0, epsilon = 1e-14);
            assert_relative_eq!(r.im[i].abs(), 1.0, epsilon = 1e-14);
        }
    }

    #[test]
    fn degree_nine_with_interior_zeros() {
        // Roots 1..=9 built by multiplying out (x - k).
        let mut c = vec![1.0];
        for k in 1..=9 {
            let mut n = vec![0.0; c.len() + 1];
            for (i, &ci) in c.iter().enumerate() {
                n[i + 1] += ci;
                n[i] -= f64::from(k) * ci;
            }
            c = n;
        }
        let r = roots(&c).unwrap();
        let v = sorted_real(&r);
        assert_eq!(v.len(), 9);
        for (i, got) in v.iter().enumerate() {
            // The Wilkinson-like polynomial is ill-conditioned: 1e-6 is the honest bound.
            assert_relative_eq!(*got, (i + 1) as f64, epsilon = 1e-6);
        }
    }

    #[test]
    fn zero_and_constant_polynomials_have_no_roots() {
        assert_eq!(roots(&[0.0; 4]).unwrap().len, 0);
        assert_eq!(roots(&[2.0, 0.0]).unwrap().len, 0);
    }
}
