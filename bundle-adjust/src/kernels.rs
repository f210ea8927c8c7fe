//! Small dense kernels on flat slices, written so that with sizes known at compile time (a
//! [`Shape`] of constants, after inlining) LLVM unrolls them and vectorizes the contiguous
//! inner loops.
//!
//! Storage conventions: Jacobian blocks are row-major (`rows × cols`); every other block
//! (JᵀJ blocks, V = W L⁻ᵀ, Cholesky factors, reduced-system blocks) is column-major with a
//! leading dimension `ld`.

use crate::simd::MulAdd;

/// Block sizes of the Schur kernels: compile-time constants for the common shapes, runtime
/// values otherwise. Each method returns its constant, or the `actual` runtime size.
pub(crate) trait Shape: Copy + Send + Sync {
    /// Residual rows.
    fn rows(self, actual: usize) -> usize;
    /// Eliminated-block size.
    fn e(self, actual: usize) -> usize;
    /// Reduced-block size.
    fn f(self, actual: usize) -> usize;
}

/// Dispatches `$body` with `$shape` bound to the [`Shape`] of a `ShapeKind`.
macro_rules! with_shape {
    ($kind:expr, $shape:ident => $body:expr) => {
        match $kind {
            $crate::program::ShapeKind::R2E3F9 => {
                let $shape = $crate::kernels::Fixed::<2, 3, 9>;
                $body
            }
            $crate::program::ShapeKind::R2E3F6 => {
                let $shape = $crate::kernels::Fixed::<2, 3, 6>;
                $body
            }
            $crate::program::ShapeKind::R2E6F6 => {
                let $shape = $crate::kernels::Fixed::<2, 6, 6>;
                $body
            }
            $crate::program::ShapeKind::Dynamic => {
                let $shape = $crate::kernels::Dynamic;
                $body
            }
        }
    };
}
pub(crate) use with_shape;

/// Sizes fixed at compile time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fixed<const R: usize, const E: usize, const F: usize>;

impl<const R: usize, const E: usize, const F: usize> Shape for Fixed<R, E, F> {
    #[inline(always)]
    fn rows(self, _: usize) -> usize {
        R
    }
    #[inline(always)]
    fn e(self, _: usize) -> usize {
        E
    }
    #[inline(always)]
    fn f(self, _: usize) -> usize {
        F
    }
}

/// Sizes read at run time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Dynamic;

impl Shape for Dynamic {
    #[inline(always)]
    fn rows(self, actual: usize) -> usize {
        actual
    }
    #[inline(always)]
    fn e(self, actual: usize) -> usize {
        actual
    }
    #[inline(always)]
    fn f(self, actual: usize) -> usize {
        actual
    }
}

/// Columns up to this length are accumulated in a local array, which LLVM keeps in
/// registers and vectorizes (it cannot for slices it must assume may alias each other).
const LOCAL: usize = 16;

/// col(m) ← col + Σ_k a_k c_k for the columns a_k of A (`m × e`, packed column-major) and
/// the coefficients `coef(k)`.
#[inline(always)]
fn axpy_columns<M: MulAdd>(
    col: &mut [f64],
    a: &[f64],
    m: usize,
    e: usize,
    coef: impl Fn(usize) -> f64,
) {
    axpy_columns_from::<M>(col, a, m, e, coef, true);
}

/// [`axpy_columns`] from `col` when `load`, else from zero (col ← Σ_k a_k c_k, the same
/// operations as on a zeroed `col`, without reading it).
#[inline(always)]
fn axpy_columns_from<M: MulAdd>(
    col: &mut [f64],
    a: &[f64],
    m: usize,
    e: usize,
    coef: impl Fn(usize) -> f64,
    load: bool,
) {
    let col = &mut col[..m];
    if !load && m > LOCAL {
        col.fill(0.0);
    }
    if m <= LOCAL {
        let mut acc = [0.0; LOCAL];
        if load {
            acc[..m].copy_from_slice(col);
        }
        for k in 0..e {
            let c = coef(k);
            let ak = &a[k * m..k * m + m];
            for i in 0..m {
                acc[i] = M::madd(ak[i], c, acc[i]);
            }
        }
        col.copy_from_slice(&acc[..m]);
    } else {
        for k in 0..e {
            let c = coef(k);
            for (o, &av) in col.iter_mut().zip(&a[k * m..k * m + m]) {
                *o = M::madd(av, c, *o);
            }
        }
    }
}

/// out(m × n, column-major at `base`, leading dimension `ld`) += Aᵀ B, with A (`r × m`) and
/// B (`r × n`) row-major.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn add_at_b<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    a: &[f64],
    b: &[f64],
    r: usize,
    m: usize,
    n: usize,
) {
    at_b::<M>(out, base, (ld, m, n), a, b, r, true);
}

/// out(m × n, column-major at `base`, leading dimension `ld`) = Aᵀ B: [`add_at_b`] on a zeroed
/// `out`, operation for operation, without zeroing or reading it first.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn set_at_b<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    a: &[f64],
    b: &[f64],
    r: usize,
    m: usize,
    n: usize,
) {
    at_b::<M>(out, base, (ld, m, n), a, b, r, false);
}

/// [`add_at_b`] (`load`) or [`set_at_b`]; `dims` = (ld, m, n).
#[inline(always)]
fn at_b<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    (ld, m, n): (usize, usize, usize),
    a: &[f64],
    b: &[f64],
    r: usize,
    load: bool,
) {
    let a = &a[..r * m];
    let b = &b[..r * n];
    for j in 0..n {
        // Rows of A are its columns as an m × r column-major matrix.
        axpy_columns_from::<M>(&mut out[base + j * ld..], a, m, r, |k| b[k * n + j], load);
    }
}

/// out(m × n, column-major at `base`, leading dimension `ld`) −= A Bᵀ, with A (`m × e`) and
/// B (`n × e`) column-major and packed.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn sub_a_bt<M: MulAdd>(
    out: &mut [f64],
    base: usize,
    ld: usize,
    a: &[f64],
    b: &[f64],
    m: usize,
    n: usize,
    e: usize,
) {
    let a = &a[..m * e];
    let b = &b[..n * e];
    for j in 0..n {
        axpy_columns::<M>(&mut out[base + j * ld..], a, m, e, |k| -b[j + n * k]);
    }
}

/// In-place Cholesky A = L Lᵀ of a packed column-major `n × n` matrix (lower triangle read
/// and written). Returns false if A is not numerically positive definite.
#[inline(always)]
pub(crate) fn cholesky(a: &mut [f64], n: usize) -> bool {
    let a = &mut a[..n * n];
    for j in 0..n {
        let mut d = a[j + j * n];
        for k in 0..j {
            d -= a[j + k * n] * a[j + k * n];
        }
        // NaN (from non-finite input) fails too.
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let ljj = d.sqrt();
        a[j + j * n] = ljj;
        let inv = 1.0 / ljj;
        for i in j + 1..n {
            let mut s = a[i + j * n];
            for k in 0..j {
                s -= a[i + k * n] * a[j + k * n];
            }
            a[i + j * n] = s * inv;
        }
    }
    true
}

/// Solves L x = b in place (L packed column-major lower, `n × n`).
#[inline(always)]
pub(crate) fn solve_lower(l: &[f64], x: &mut [f64], n: usize) {
    let l = &l[..n * n];
    let x = &mut x[..n];
    for j in 0..n {
        let v = x[j] / l[j + j * n];
        x[j] = v;
        for i in j + 1..n {
            x[i] -= l[i + j * n] * v;
        }
    }
}

/// Solves Lᵀ x = b in place.
#[inline(always)]
pub(crate) fn solve_lower_transpose(l: &[f64], x: &mut [f64], n: usize) {
    let l = &l[..n * n];
    let x = &mut x[..n];
    for j in (0..n).rev() {
        let mut v = x[j];
        for i in j + 1..n {
            v -= l[i + j * n] * x[i];
        }
        x[j] = v / l[j + j * n];
    }
}

/// W ← W L⁻ᵀ in place, W packed column-major `m × e`, L packed lower `e × e`.
#[inline(always)]
pub(crate) fn right_solve_lower_transpose<M: MulAdd>(w: &mut [f64], l: &[f64], m: usize, e: usize) {
    let w = &mut w[..m * e];
    let l = &l[..e * e];
    for j in 0..e {
        let (done, rest) = w.split_at_mut(j * m);
        let col = &mut rest[..m];
        axpy_columns::<M>(col, done, m, j, |k| -l[j + k * e]);
        let inv = 1.0 / l[j + j * e];
        for c in col.iter_mut() {
            *c *= inv;
        }
    }
}

/// y(m) += A x, A packed column-major `m × e`.
#[inline(always)]
pub(crate) fn add_a_x<M: MulAdd>(y: &mut [f64], a: &[f64], x: &[f64], m: usize, e: usize) {
    axpy_columns::<M>(y, a, m, e, |k| x[k]);
}

/// y(m) −= A x, A packed column-major `m × e`.
#[inline(always)]
pub(crate) fn sub_a_x<M: MulAdd>(y: &mut [f64], a: &[f64], x: &[f64], m: usize, e: usize) {
    axpy_columns::<M>(y, a, m, e, |k| -x[k]);
}

/// z(e) += Aᵀ x, A packed column-major `m × e`.
#[inline(always)]
pub(crate) fn add_at_x<M: MulAdd>(z: &mut [f64], a: &[f64], x: &[f64], m: usize, e: usize) {
    let x = &x[..m];
    for (k, zk) in z[..e].iter_mut().enumerate() {
        let mut s = 0.0;
        for (&av, &xv) in a[k * m..k * m + m].iter().zip(x) {
            s = M::madd(av, xv, s);
        }
        *zk += s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::Plain;
    use approx::assert_relative_eq;
    use nalgebra::{DMatrix, DVector};

    fn sample(rows: usize, cols: usize, seed: f64) -> DMatrix<f64> {
        DMatrix::from_fn(rows, cols, |i, j| {
            ((i * 7 + j * 3) as f64 * 0.37 + seed).sin()
        })
    }

    fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
        m.transpose().as_slice().to_vec()
    }

    #[test]
    fn products_match_nalgebra() {
        let a = sample(2, 9, 0.1);
        let b = sample(2, 3, 0.7);
        let mut out = vec![1.0; 9 * 3];
        add_at_b::<Plain>(&mut out, 0, 9, &row_major(&a), &row_major(&b), 2, 9, 3);
        let expected = a.transpose() * &b + DMatrix::from_element(9, 3, 1.0);
        assert_relative_eq!(
            DMatrix::from_column_slice(9, 3, &out),
            expected,
            epsilon = 1e-14
        );

        let v = sample(9, 3, 0.2);
        let w = sample(6, 3, 0.5);
        let mut big = vec![0.0; 20 * 20];
        sub_a_bt::<Plain>(
            &mut big,
            2 + 3 * 20,
            20,
            v.as_slice(),
            w.as_slice(),
            9,
            6,
            3,
        );
        let prod = &v * w.transpose();
        for j in 0..6 {
            for i in 0..9 {
                assert_relative_eq!(big[2 + i + (3 + j) * 20], -prod[(i, j)], epsilon = 1e-14);
            }
        }
    }

    /// `set_at_b` writes what `add_at_b` adds to a zeroed block, bit for bit, whatever the
    /// block held (short columns in registers, long ones in place).
    #[test]
    fn set_at_b_is_add_at_b_on_zero() {
        for (m, n) in [(6, 3), (9, 8), (20, 3)] {
            let a = row_major(&sample(2, m, 0.3));
            let b = row_major(&sample(2, n, 0.8));
            let ld = m + 2;
            let mut added = vec![0.0; ld * n + 1];
            add_at_b::<Plain>(&mut added, 1, ld, &a, &b, 2, m, n);
            let mut set = vec![f64::NAN; ld * n + 1];
            set_at_b::<Plain>(&mut set, 1, ld, &a, &b, 2, m, n);
            for j in 0..n {
                for i in 0..m {
                    let k = 1 + i + j * ld;
                    assert_eq!(
                        set[k].to_bits(),
                        added[k].to_bits(),
                        "({i}, {j}) of {m} x {n}"
                    );
                }
            }
            // Outside the block: untouched.
            assert!(set[0].is_nan() && set[1 + m].is_nan());
        }
    }

    #[test]
    fn cholesky_solves() {
        let m = sample(5, 5, 0.3);
        let a = &m * m.transpose() + DMatrix::identity(5, 5);
        let mut l = a.as_slice().to_vec();
        assert!(cholesky(&mut l, 5));
        let b = DVector::from_fn(5, |i, _| i as f64 - 1.5);
        let mut x = b.as_slice().to_vec();
        solve_lower(&l, &mut x, 5);
        solve_lower_transpose(&l, &mut x, 5);
        assert_relative_eq!(&a * DVector::from_vec(x), b, epsilon = 1e-12);

        // W L^-T: (W L^-T) L^T = W.
        let w = sample(4, 5, 0.9);
        let mut v = w.as_slice().to_vec();
        right_solve_lower_transpose::<Plain>(&mut v, &l, 4, 5);
        let lm = DMatrix::from_column_slice(5, 5, &l).lower_triangle();
        let back = DMatrix::from_column_slice(4, 5, &v) * lm.transpose();
        assert_relative_eq!(back, w, epsilon = 1e-12);

        let mut bad = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky(&mut bad, 2));
        let mut nan = vec![f64::NAN];
        assert!(!cholesky(&mut nan, 1));
    }

    #[test]
    fn matrix_vector_products() {
        let a = sample(7, 3, 0.4);
        let x = DVector::from_vec(vec![0.5, -1.0, 2.0]);
        let mut y = vec![1.0; 7];
        add_a_x::<Plain>(&mut y, a.as_slice(), x.as_slice(), 7, 3);
        let expected = &a * &x + DVector::from_element(7, 1.0);
        assert_relative_eq!(DVector::from_vec(y.clone()), expected, epsilon = 1e-14);
        sub_a_x::<Plain>(&mut y, a.as_slice(), x.as_slice(), 7, 3);
        assert_relative_eq!(
            DVector::from_vec(y),
            DVector::from_element(7, 1.0),
            epsilon = 1e-14
        );
        let xs = DVector::from_fn(7, |i, _| i as f64);
        let mut z = vec![0.0; 3];
        add_at_x::<Plain>(&mut z, a.as_slice(), xs.as_slice(), 7, 3);
        assert_relative_eq!(DVector::from_vec(z), a.transpose() * xs, epsilon = 1e-13);
    }
}
