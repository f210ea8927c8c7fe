//! The constraint step shared by both methods: a unit combination `λ₁ v₁ + λ₂ v₂` of a
//! two-dimensional null space that satisfies a homogeneous quadratic constraint
//! `a λ₁² + b λ₁λ₂ + c λ₂² = 0` (Daniilidis 1999, eq. 35-36; Guo et al. 2012, the roll-pitch
//! step).

/// The two directions `(λ₁, λ₂)` (unit norm, each up to sign) on which
/// `a λ₁² + b λ₁λ₂ + c λ₂² = 0`, or the discriminant `b² - 4ac` if it is negative (no real
/// direction). A discriminant negative only by rounding (relative `1e-12`) counts as zero.
///
/// Each root is computed without cancellation: the quadratic is solved for whichever of
/// `λ₁/λ₂` and `λ₂/λ₁` has the larger leading coefficient, with the stable pair
/// `q = -(b + sign(b) √Δ) / 2`, roots `q / a` and `c / q`.
pub(crate) fn unit_circle_roots(a: f64, b: f64, c: f64) -> Result<[(f64, f64); 2], f64> {
    let mut discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        if discriminant >= -1e-12 * (b * b + 4.0 * (a * c).abs()) {
            discriminant = 0.0;
        } else {
            return Err(discriminant);
        }
    }
    let root = discriminant.sqrt();
    let q = -0.5 * (b + root.copysign(b));
    let normalize = |x: f64, y: f64| {
        let n = x.hypot(y);
        (x / n, y / n)
    };
    if a == 0.0 && c == 0.0 {
        // b λ₁ λ₂ = 0 (b ≠ 0 here, or every direction is a root and both axes serve).
        return Ok([(1.0, 0.0), (0.0, 1.0)]);
    }
    if a.abs() >= c.abs() {
        // a s² + b s + c = 0 with s = λ₁ / λ₂; q ≠ 0 because |a| > 0 forces b or √Δ non-zero
        // unless the only root is double at s = 0 (then c = 0 and q = 0).
        let s1 = q / a;
        let s2 = if q == 0.0 { s1 } else { c / q };
        Ok([normalize(s1, 1.0), normalize(s2, 1.0)])
    } else {
        // c r² + b r + a = 0 with r = λ₂ / λ₁.
        let r1 = q / c;
        let r2 = if q == 0.0 { r1 } else { a / q };
        Ok([normalize(1.0, r1), normalize(1.0, r2)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn value(a: f64, b: f64, c: f64, (x, y): (f64, f64)) -> f64 {
        a * x * x + b * x * y + c * y * y
    }

    #[test]
    fn special_cases() {
        // λ₁ λ₂ = 0: the two axes.
        let roots = unit_circle_roots(0.0, 1.0, 0.0).unwrap();
        assert!(roots.contains(&(1.0, 0.0)) && roots.contains(&(0.0, 1.0)));
        // λ₁² + λ₂² = 0 has no real root.
        assert_eq!(unit_circle_roots(1.0, 0.0, 1.0), Err(-4.0));
        // (λ₁ - λ₂)² = 0: double root at 45 degrees.
        let roots = unit_circle_roots(1.0, -2.0, 1.0).unwrap();
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((roots[0].0 - h).abs() < 1e-15 && (roots[1].1 - h).abs() < 1e-15);
    }

    proptest! {
        #[test]
        fn roots_are_unit_and_satisfy_the_quadratic(
            t1 in 0.0..std::f64::consts::PI, t2 in 0.0..std::f64::consts::PI, k in 0.01f64..100.0
        ) {
            // The quadratic k (λ₁ sin t1 - λ₂ cos t1)(λ₁ sin t2 - λ₂ cos t2) vanishes at the
            // directions t1 and t2.
            let (s1, c1, s2, c2) = (t1.sin(), t1.cos(), t2.sin(), t2.cos());
            let (a, b, c) = (k * s1 * s2, -k * (s1 * c2 + c1 * s2), k * c1 * c2);
            let roots = unit_circle_roots(a, b, c).unwrap();
            for root in roots {
                prop_assert!((root.0.hypot(root.1) - 1.0).abs() < 1e-14);
                prop_assert!(value(a, b, c, root).abs() < 1e-12 * k);
            }
            let hits = |t: f64| roots.iter().any(|r| (r.0 * t.sin() - r.1 * t.cos()).abs() < 1e-7);
            prop_assert!(hits(t1) && hits(t2));
        }
    }
}
