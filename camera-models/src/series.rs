//! Small trigonometric helpers that stay accurate near zero, where the direct formulas cancel.
//! The Jacobians use them so they are exact on the optical axis.

/// Below this argument the series are used (their truncation error is under 1e-17 there).
const SERIES_LIMIT: f64 = 1.0;

/// Terms of each series (enough for 1e-17 relative at `SERIES_LIMIT`).
const SERIES_TERMS: usize = 10;

/// sin(x) / x, with sinc(0) = 1.
#[inline]
pub fn sinc(x: f64) -> f64 {
    if x == 0.0 { 1.0 } else { x.sin() / x }
}

/// (x - sin x) / x^3 = 1/3! - x^2/5! + x^4/7! - ...
#[inline]
pub fn x_minus_sin_over_cube(x: f64) -> f64 {
    if x.abs() >= SERIES_LIMIT {
        return (x - x.sin()) / (x * x * x);
    }
    // Term k (from 1): (-1)^(k+1) x^(2k-2) / (2k+1)!
    let x2 = x * x;
    let mut term = 1.0 / 6.0;
    let mut sum = term;
    for k in 2..=SERIES_TERMS {
        let kf = k as f64;
        term *= -x2 / ((2.0 * kf) * (2.0 * kf + 1.0));
        sum += term;
    }
    sum
}

/// (sin x - x cos x) / x^3 = 1/3 - x^2/30 + x^4/840 - ...
#[inline]
pub fn sin_minus_x_cos_over_cube(x: f64) -> f64 {
    if x.abs() >= SERIES_LIMIT {
        let (s, c) = x.sin_cos();
        return (s - x * c) / (x * x * x);
    }
    // Term k (from 1): (-1)^(k+1) 2k x^(2k-2) / (2k+1)!
    let x2 = x * x;
    let mut fact_term = 1.0 / 6.0; // (-1)^(k+1) x^(2k-2) / (2k+1)!
    let mut sum = 2.0 * fact_term;
    for k in 2..=SERIES_TERMS {
        let kf = k as f64;
        fact_term *= -x2 / ((2.0 * kf) * (2.0 * kf + 1.0));
        sum += 2.0 * kf * fact_term;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn series_match_direct_formulas_where_both_are_accurate() {
        for &x in &[0.3_f64, 0.7, 0.999, 1.0, 1.5, 3.0] {
            assert_relative_eq!(
                x_minus_sin_over_cube(x),
                (x - x.sin()) / x.powi(3),
                max_relative = 1e-12
            );
            assert_relative_eq!(
                sin_minus_x_cos_over_cube(x),
                (x.sin() - x * x.cos()) / x.powi(3),
                max_relative = 1e-12
            );
        }
        assert_relative_eq!(x_minus_sin_over_cube(0.0), 1.0 / 6.0);
        assert_relative_eq!(sin_minus_x_cos_over_cube(0.0), 1.0 / 3.0);
        // Continuity across the switch point.
        let below = x_minus_sin_over_cube(1.0 - 1e-15);
        assert_relative_eq!(below, x_minus_sin_over_cube(1.0), max_relative = 1e-14);
    }
}
