//! Small trigonometric helpers that stay accurate near zero, where the direct formulas cancel.
//! The Jacobians use them so they are exact on the optical axis.

/// Below this argument the series are used (their truncation error is under 1e-17 there).
const SERIES_LIMIT: f64 = 1.0;

/// Terms of each series (enough for 1e-17 relative at `SERIES_LIMIT`).
const SERIES_TERMS: usize = 10;

/// Coefficients of (x - sin x) / x^3 in powers of x^2: (-1)^j / (2j + 3)!.
const X_MINUS_SIN_SERIES: [f64; SERIES_TERMS] = series_coefficients(false);

/// Coefficients of (sin x - x cos x) / x^3 in powers of x^2: (-1)^j 2 (j + 1) / (2j + 3)!.
const SIN_MINUS_X_COS_SERIES: [f64; SERIES_TERMS] = series_coefficients(true);

/// The two coefficient tables above, computed at compile time.
const fn series_coefficients(times_2k: bool) -> [f64; SERIES_TERMS] {
    let mut c = [0.0; SERIES_TERMS];
    let mut inv_factorial = 1.0 / 6.0; // 1 / 3!
    let mut j = 0;
    while j < SERIES_TERMS {
        let sign = if j % 2 == 0 { 1.0 } else { -1.0 };
        let factor = if times_2k {
            2.0 * (j as f64 + 1.0)
        } else {
            1.0
        };
        c[j] = sign * factor * inv_factorial;
        inv_factorial /= (2.0 * j as f64 + 4.0) * (2.0 * j as f64 + 5.0);
        j += 1;
    }
    c
}

/// `sum_j c[j] y^j` (Horner).
#[inline]
fn horner(c: &[f64; SERIES_TERMS], y: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &cj| acc * y + cj)
}

/// sin(x) / x from a known `sin_x = sin(x)`, with sinc(0) = 1.
#[inline]
pub fn sinc_with(x: f64, sin_x: f64) -> f64 {
    if x == 0.0 { 1.0 } else { sin_x / x }
}

/// (x - sin x) / x^3 = 1/3! - x^2/5! + x^4/7! - ..., from a known `sin_x = sin(x)` (used only
/// where the direct formula does not cancel, |x| >= 1).
#[inline]
pub fn x_minus_sin_over_cube(x: f64, sin_x: f64) -> f64 {
    if x.abs() >= SERIES_LIMIT {
        (x - sin_x) / (x * x * x)
    } else {
        horner(&X_MINUS_SIN_SERIES, x * x)
    }
}

/// (sin x - x cos x) / x^3 = 1/3 - x^2/30 + x^4/840 - ..., from known `(sin x, cos x)` (used
/// only where the direct formula does not cancel, |x| >= 1).
#[inline]
pub fn sin_minus_x_cos_over_cube(x: f64, (sin_x, cos_x): (f64, f64)) -> f64 {
    if x.abs() >= SERIES_LIMIT {
        (sin_x - x * cos_x) / (x * x * x)
    } else {
        horner(&SIN_MINUS_X_COS_SERIES, x * x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn series_match_direct_formulas_where_both_are_accurate() {
        for &x in &[0.3_f64, 0.7, 0.999, 1.0, 1.5, 3.0] {
            assert_relative_eq!(
                x_minus_sin_over_cube(x, x.sin()),
                (x - x.sin()) / x.powi(3),
                max_relative = 1e-12
            );
            assert_relative_eq!(
                sin_minus_x_cos_over_cube(x, x.sin_cos()),
                (x.sin() - x * x.cos()) / x.powi(3),
                max_relative = 1e-12
            );
        }
        assert_relative_eq!(x_minus_sin_over_cube(0.0, 0.0), 1.0 / 6.0);
        assert_relative_eq!(sin_minus_x_cos_over_cube(0.0, (0.0, 1.0)), 1.0 / 3.0);
        // Continuity across the switch point.
        let below = x_minus_sin_over_cube(1.0 - 1e-15, (1.0 - 1e-15_f64).sin());
        assert_relative_eq!(
            below,
            x_minus_sin_over_cube(1.0, 1.0_f64.sin()),
            max_relative = 1e-14
        );
        let below = sin_minus_x_cos_over_cube(1.0 - 1e-15, (1.0 - 1e-15_f64).sin_cos());
        assert_relative_eq!(
            below,
            sin_minus_x_cos_over_cube(1.0, 1.0_f64.sin_cos()),
            max_relative = 1e-14
        );
        assert_relative_eq!(sinc_with(0.0, 0.0), 1.0);
        assert_relative_eq!(sinc_with(0.5, 0.5_f64.sin()), 0.5_f64.sin() / 0.5);
    }
}
