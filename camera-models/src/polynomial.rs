//! Real polynomial roots through the eigenvalues of the companion matrix, on the stack.
//!
//! The companion matrix of a monic polynomial is upper Hessenberg, so its eigenvalues come from
//! the Francis double-shift QR iteration directly (Francis 1961; Golub and Van Loan, *Matrix
//! Computations*, 4th ed., section 7.5), after a Parlett-Reinsch balancing (Parlett and Reinsch
//! 1969). The iteration is bounded ([`MAX_ITERATIONS_PER_EIGENVALUE`] per eigenvalue, with
//! exceptional shifts at 10 and 20 iterations), so it always returns: nalgebra's general Schur
//! decomposition has been reported to hang on companion-like matrices (nalgebra issues 611,
//! 764, 1291, 1528), which is why it is not used here. Only eigenvalues are computed (no Schur
//! vectors), and each double-shift step works on the active block alone (EISPACK `hqr`).
//!
//! [`roots`] returns every root, from the companion matrix with the coefficients in its last
//! column, with the classical `hqr` choices (balancing to convergence, bulge started below
//! two consecutive small subdiagonal entries when there are such). The Kannala-Brandt
//! backprojection, which needs one real root, uses `first_root_where` instead, tuned for
//! that: the companion matrix with the coefficients in its first row (the form of MATLAB's
//! `compan`), whose zero trailing block draws the bottom of the iteration to the smallest
//! roots; a first double shift at the root of the polynomial's linear part, `-c_0 / c_1`; one
//! balancing pass that visits only the matrix's non-zeros; and a stop at the first eigenvalue
//! the caller accepts, so the others are never computed.
//!
//! Everything lives in a fixed `[[f64; MAX_DEGREE]; MAX_DEGREE]` array: no heap allocation.

/// Largest polynomial degree supported (the Kannala-Brandt polynomial has degree 9).
pub const MAX_DEGREE: usize = 9;

/// Iteration bound per eigenvalue (EISPACK's `hqr` uses 30 with the same exceptional shifts).
pub const MAX_ITERATIONS_PER_EIGENVALUE: usize = 30;

/// Balancing passes allowed in [`roots`] (each pass changes scales by powers of two; the loop
/// stops at the first pass that changes none, and this bound keeps it finite whatever the
/// input).
const MAX_BALANCING_PASSES: usize = 64;

/// A `MAX_DEGREE x MAX_DEGREE` matrix on the stack, row-major; the leading `n x n` block is used.
type Matrix = [[f64; MAX_DEGREE]; MAX_DEGREE];

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
    balance(&mut a, degree, MAX_BALANCING_PASSES);
    hessenberg_eigenvalues(&mut a, degree, Strategy::CLASSICAL, |i, re, im| {
        out.re[i] = re;
        out.im[i] = im;
        false
    })?;
    Ok(out)
}

/// The first root `(re, im)` of `sum_i coeffs[i] x^i` that `accept` takes, in the order the
/// eigenvalue iteration finds them; the iteration stops there. `Ok(None)` if every root was
/// found and none was accepted (also for a polynomial of degree 0). The degree is that of the
/// highest non-zero coefficient, as for [`roots`].
///
/// The companion matrix is the one with `-c_{n-1-j} / c_n` in its first row and ones on its
/// subdiagonal (similar to the transpose of the one [`roots`] uses, so it has the same
/// eigenvalues). Its trailing 2x2 block is zero, so the plain Francis shifts would start at
/// zero and draw the bottom of the iteration to the smallest roots; the first step uses the
/// double shift `(s, s)` with `s = -c_0 / c_1` (the root of the linear part, where the smallest
/// root is when it dominates) instead, and the later steps the usual shifts. It is balanced by
/// one Parlett-Reinsch pass: that pass removes the large scale differences of a companion
/// matrix, and further passes changed neither the convergence nor the accuracy of the
/// Kannala-Brandt roots in our tests. Each step starts its bulge at the top of the active
/// block. No allocation.
///
/// # Errors
/// [`IterationLimit`] if the QR iteration did not converge within its bound.
pub(crate) fn first_root_where(
    coeffs: &[f64],
    mut accept: impl FnMut(f64, f64) -> bool,
) -> Result<Option<(f64, f64)>, IterationLimit> {
    let Some(degree) = coeffs.iter().rposition(|&c| c != 0.0) else {
        return Ok(None);
    };
    let n = degree.min(MAX_DEGREE);
    if n == 0 {
        return Ok(None);
    }
    let lead = coeffs[n];
    if n == 1 {
        let re = -coeffs[0] / lead;
        return Ok(accept(re, 0.0).then_some((re, 0.0)));
    }
    // The first row and the subdiagonal are the only non-zeros, and balancing keeps it so.
    let mut top = [0.0; MAX_DEGREE];
    let mut sub = [1.0; MAX_DEGREE];
    for (j, t) in top.iter_mut().enumerate().take(n) {
        *t = -coeffs[n - 1 - j] / lead;
    }
    balance_top_row_once(&mut top, &mut sub, n);
    let mut a = [[0.0; MAX_DEGREE]; MAX_DEGREE];
    a[0][..n].copy_from_slice(&top[..n]);
    for i in 1..n {
        a[i][i - 1] = sub[i];
    }
    let linear_root = -coeffs[0] / coeffs[1];
    let strategy = Strategy {
        first_shift: linear_root.is_finite().then_some(linear_root),
        start_bulge_lower: false,
    };
    let mut found = None;
    hessenberg_eigenvalues(&mut a, n, strategy, |_, re, im| {
        let take = accept(re, im);
        if take {
            found = Some((re, im));
        }
        take
    })?;
    Ok(found)
}

/// The power of two `f` by which Parlett-Reinsch balancing scales column `i` (and row `i` by
/// `1 / f`), from the off-diagonal norms `c` of the column and `r` of the row; `None` when the
/// pair is balanced enough (or a norm is zero or not finite, where no scaling can help).
#[inline]
fn balance_factor(c: f64, r: f64) -> Option<f64> {
    const RADIX: f64 = 2.0;
    const RADIX2: f64 = RADIX * RADIX;
    // A non-finite norm would never settle: the scaling loops cannot move an infinity.
    if c == 0.0 || r == 0.0 || !(c.is_finite() && r.is_finite()) {
        return None;
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
    ((c2 + r / f) / f < 0.95 * s).then_some(f)
}

/// Parlett-Reinsch balancing with powers of two (exact in floating point): a diagonal
/// similarity that makes row and column norms comparable, which keeps the eigenvalues of
/// badly scaled companion matrices accurate. It preserves the Hessenberg form. At most
/// `passes` passes; it stops after a pass that changes nothing.
// Index loops mirror the matrix formulas; iterators would hide which row and column is which.
#[allow(clippy::needless_range_loop)]
fn balance(a: &mut Matrix, n: usize, passes: usize) {
    for _ in 0..passes {
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
            if let Some(f) = balance_factor(c, r) {
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

/// One pass of [`balance`] on a matrix whose only non-zeros are its first row `top` and its
/// subdiagonal (`sub[i]` is entry `(i, i - 1)`), visiting those alone: O(n) instead of
/// O(n^2). The norms add the same non-zero terms in the same order as [`balance`] does, so the
/// result is the same bit for bit (tested).
fn balance_top_row_once(top: &mut [f64; MAX_DEGREE], sub: &mut [f64; MAX_DEGREE], n: usize) {
    for i in 0..n {
        // Column i: top[i] in row 0 (off the diagonal for i > 0), sub[i + 1] below.
        // Row i: the rest of the first row for i = 0, sub[i] otherwise.
        let below = if i + 1 < n { sub[i + 1].abs() } else { 0.0 };
        let (c, r) = if i == 0 {
            (below, top[1..n].iter().fold(0.0, |acc, v| acc + v.abs()))
        } else {
            (top[i].abs() + below, sub[i].abs())
        };
        if let Some(f) = balance_factor(c, r) {
            let g = 1.0 / f;
            if i == 0 {
                for v in &mut top[..n] {
                    *v *= g;
                }
                top[0] *= f;
            } else {
                sub[i] *= g;
                top[i] *= f;
            }
            if i + 1 < n {
                sub[i + 1] *= f;
            }
        }
    }
}

/// Choices of the eigenvalue iteration that change its path but not what it converges to.
#[derive(Clone, Copy)]
struct Strategy {
    /// Replaces the shifts of the very first step by the double shift `(s, s)`.
    first_shift: Option<f64>,
    /// Start each bulge below two consecutive small subdiagonal entries when there are such
    /// (EISPACK `hqr`), rather than at the top of the active block.
    start_bulge_lower: bool,
}

impl Strategy {
    /// EISPACK `hqr`'s choices, which [`roots`] keeps.
    const CLASSICAL: Self = Self {
        first_shift: None,
        start_bulge_lower: true,
    };
}

/// Eigenvalues of the upper Hessenberg matrix `a[0..n][0..n]` by the Francis double-shift QR
/// iteration with deflation; `a` is overwritten. Each eigenvalue is passed to
/// `found(index, re, im)` as it deflates (from the bottom up; a complex pair as two calls), and
/// the iteration stops as soon as `found` returns true. Returns whether `found` stopped it.
#[allow(clippy::needless_range_loop)] // as for `balance`
fn hessenberg_eigenvalues(
    a: &mut Matrix,
    n: usize,
    strategy: Strategy,
    mut found: impl FnMut(usize, f64, f64) -> bool,
) -> Result<bool, IterationLimit> {
    let eps = f64::EPSILON;
    let n = n.min(MAX_DEGREE);
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
                if found(h, x + shift, 0.0) {
                    return Ok(true);
                }
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
                let (first, second) = if q >= 0.0 {
                    let z = p + z.copysign(p);
                    let second = if z != 0.0 { x - w / z } else { x + z };
                    ((x + z, 0.0), (second, 0.0))
                } else {
                    ((x + p, -z), (x + p, z))
                };
                if found(h - 1, first.0, first.1) || found(h, second.0, second.1) {
                    return Ok(true);
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
            if total == 0
                && let Some(s) = strategy.first_shift
            {
                // The double shift (s, s): x + y = 2 s, x y - w = s^2.
                (x, y, w) = (s, s, 0.0);
            }
            its += 1;
            total += 1;
            francis_step(a, lo, h, (x, y, w), strategy.start_bulge_lower);
        }
    }
    Ok(false)
}

/// One implicit double-shift QR step on rows and columns `lo..=h`, with the shifts given as
/// those of a trailing 2x2 block (`x = a[h][h]`, `y = a[h-1][h-1]`, `w = a[h][h-1] a[h-1][h]`).
/// Dispatches on `h` so that each block size gets a copy of the step with constant loop
/// bounds. (Not inlined: inlined into the iteration it measured slower.)
#[inline(never)]
fn francis_step(a: &mut Matrix, lo: usize, h: usize, shifts: (f64, f64, f64), lower: bool) {
    match h {
        8 => francis_step_to::<8>(a, lo, shifts, lower),
        7 => francis_step_to::<7>(a, lo, shifts, lower),
        6 => francis_step_to::<6>(a, lo, shifts, lower),
        5 => francis_step_to::<5>(a, lo, shifts, lower),
        4 => francis_step_to::<4>(a, lo, shifts, lower),
        3 => francis_step_to::<3>(a, lo, shifts, lower),
        // The caller only steps blocks of three rows or more (h >= 2), and h < MAX_DEGREE.
        _ => francis_step_to::<2>(a, lo, shifts, lower),
    }
}

/// [`francis_step`] for the block ending at row `H`; `lower` as
/// [`Strategy::start_bulge_lower`].
#[inline(always)]
fn francis_step_to<const H: usize>(
    a: &mut Matrix,
    lo: usize,
    (x, y, w): (f64, f64, f64),
    lower: bool,
) {
    let eps = f64::EPSILON;
    let h = H;
    // Look for two consecutive small subdiagonal elements to start the bulge lower.
    let mut m = if lower { h - 2 } else { lo };
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
        if m <= lo {
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
        let three = k + 2 <= h;
        if k != m {
            p = a[k][k - 1];
            q = a[k + 1][k - 1];
            r = if three { a[k + 2][k - 1] } else { 0.0 };
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
        // loop has no bounds checks; then the column update of columns k, k+1 (and k+2) over
        // rows lo..=min(k+3, h).
        let (upper, lower) = a.split_at_mut(k + 1);
        let row_k = &mut upper[k][k..=h];
        let (row_k1, rest) = lower.split_at_mut(1);
        let row_k1 = &mut row_k1[0][k..=h];
        if three {
            let row_k2 = &mut rest[0][k..=h];
            reflect_rows(row_k, row_k1, row_k2, (q2, r2), (hx, hy, hz));
            reflect_columns(a, (lo, h.min(k + 3)), k, (q2, r2), (hx, hy, hz));
        } else {
            for (x0, x1) in row_k.iter_mut().zip(row_k1.iter_mut()) {
                let t = *x0 + q2 * *x1;
                *x1 -= t * hy;
                *x0 -= t * hx;
            }
            for row in &mut a[lo..=h] {
                let c = &mut row[k..k + 2];
                let t = hx * c[0] + hy * c[1];
                c[1] -= t * q2;
                c[0] -= t;
            }
        }
    }
}

/// The 3x3 Householder reflection of a Francis step applied from the left to three row
/// slices: each column `(x0, x1, x2)` loses `t (hx, hy, hz)` with `t = x0 + q2 x1 + r2 x2`.
/// Two columns per iteration, so the compiler can pair them in SIMD lanes (the arithmetic of
/// each column is unchanged).
#[inline(always)]
fn reflect_rows(
    r0: &mut [f64],
    r1: &mut [f64],
    r2: &mut [f64],
    (q2, s2): (f64, f64),
    (hx, hy, hz): (f64, f64, f64),
) {
    let mut c0 = r0.chunks_exact_mut(2);
    let mut c1 = r1.chunks_exact_mut(2);
    let mut c2 = r2.chunks_exact_mut(2);
    for ((x0, x1), x2) in (&mut c0).zip(&mut c1).zip(&mut c2) {
        let t0 = x0[0] + q2 * x1[0] + s2 * x2[0];
        let t1 = x0[1] + q2 * x1[1] + s2 * x2[1];
        x2[0] -= t0 * hz;
        x2[1] -= t1 * hz;
        x1[0] -= t0 * hy;
        x1[1] -= t1 * hy;
        x0[0] -= t0 * hx;
        x0[1] -= t1 * hx;
    }
    let (x0, x1, x2) = (
        c0.into_remainder(),
        c1.into_remainder(),
        c2.into_remainder(),
    );
    for ((x0, x1), x2) in x0.iter_mut().zip(x1.iter_mut()).zip(x2.iter_mut()) {
        let t = *x0 + q2 * *x1 + s2 * *x2;
        *x2 -= t * hz;
        *x1 -= t * hy;
        *x0 -= t * hx;
    }
}

/// The same reflection applied from the right to columns `k, k+1, k+2` of rows
/// `first..=last`: each row's `(c0, c1, c2)` loses `t (1, q2, r2)` with
/// `t = hx c0 + hy c1 + hz c2`. Two rows per iteration, as in [`reflect_rows`].
#[inline(always)]
fn reflect_columns(
    a: &mut Matrix,
    (first, last): (usize, usize),
    k: usize,
    (q2, s2): (f64, f64),
    (hx, hy, hz): (f64, f64, f64),
) {
    let mut i = first;
    while i < last {
        let (first, second) = a.split_at_mut(i + 1);
        let (a, b) = (&mut first[i][k..k + 3], &mut second[0][k..k + 3]);
        let ta = hx * a[0] + hy * a[1] + hz * a[2];
        let tb = hx * b[0] + hy * b[1] + hz * b[2];
        a[2] -= ta * s2;
        b[2] -= tb * s2;
        a[1] -= ta * q2;
        b[1] -= tb * q2;
        a[0] -= ta;
        b[0] -= tb;
        i += 2;
    }
    if i == last {
        let c = &mut a[i][k..k + 3];
        let t = hx * c[0] + hy * c[1] + hz * c[2];
        c[2] -= t * s2;
        c[1] -= t * q2;
        c[0] -= t;
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
    fn sparse_balancing_pass_matches_the_dense_one_bit_for_bit() {
        // Top-row companion matrices of polynomials with coefficients over six decades.
        let mut scaled = 0;
        for (t, scale) in [(0.3_f64, 1e-3_f64), (1.7, 1.0), (-2.2, 1e3)] {
            for n in 2..=MAX_DEGREE {
                let mut top = [0.0; MAX_DEGREE];
                for (j, v) in top.iter_mut().enumerate().take(n) {
                    *v = (t * (j as f64 + 1.0)).sin() * scale.powi(j as i32 % 3);
                }
                let mut sub = [1.0; MAX_DEGREE];
                let mut dense = [[0.0; MAX_DEGREE]; MAX_DEGREE];
                dense[0][..n].copy_from_slice(&top[..n]);
                for i in 1..n {
                    dense[i][i - 1] = 1.0;
                }
                balance(&mut dense, n, 1);
                balance_top_row_once(&mut top, &mut sub, n);
                let mut sparse = [[0.0; MAX_DEGREE]; MAX_DEGREE];
                sparse[0][..n].copy_from_slice(&top[..n]);
                for i in 1..n {
                    sparse[i][i - 1] = sub[i];
                }
                assert_eq!(dense, sparse, "n = {n}, t = {t}");
                if sub[1..n].iter().any(|&v| v != 1.0) {
                    scaled += 1;
                }
            }
        }
        // Most of these matrices needed scaling (so the comparison covered the scaling code).
        assert!(scaled >= 12, "{scaled} of 24 scaled");
    }

    #[test]
    fn first_root_where_stops_at_the_accepted_root_and_agrees_with_roots() {
        // (x - 0.5)(x - 2)(x + 3)(x^2 + 1): accept the real roots above 1 only.
        let c = [3.0, -6.5, 3.5, -5.5, 0.5, 1.0];
        let (re, im) = first_root_where(&c, |re, im| im == 0.0 && re > 1.0)
            .unwrap()
            .unwrap();
        assert_relative_eq!(re, 2.0, epsilon = 1e-12);
        assert_eq!(im, 0.0);
        // Nothing acceptable: every root is visited and none returned.
        assert!(first_root_where(&c, |re, _| re > 10.0).unwrap().is_none());
        // The Kannala-Brandt polynomial of CamOdoCal's test camera at d = 0.8 has two real
        // roots in [0, pi], on either side of its fold at 1.958: the one below the fold is the
        // smallest real root `roots` finds there.
        let k = [-0.01648, -0.00203, 0.00069, -0.00048];
        let c = [-0.8, 1.0, 0.0, k[0], 0.0, k[1], 0.0, k[2], 0.0, k[3]];
        let all = roots(&c).unwrap();
        let want = (0..all.len)
            .filter(|&i| all.im[i] == 0.0 && (0.0..=std::f64::consts::PI).contains(&all.re[i]))
            .map(|i| all.re[i])
            .fold(f64::INFINITY, f64::min);
        let (got, _) = first_root_where(&c, |re, im| im == 0.0 && (0.0..=1.95).contains(&re))
            .unwrap()
            .unwrap();
        assert_relative_eq!(got, want, epsilon = 1e-13);
    }

    #[test]
    fn zero_and_constant_polynomials_have_no_roots() {
        assert_eq!(roots(&[0.0; 4]).unwrap().len, 0);
        assert_eq!(roots(&[2.0, 0.0]).unwrap().len, 0);
    }
}
