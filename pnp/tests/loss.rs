//! The robust loss, which the bundle adjuster uses too: `evaluate` gives Ceres's formulas with
//! its floor on rho' (bit for bit what `ibc-bundle-adjust`'s own loss gave before it took this
//! type), agrees with the textbook definitions, and refuses bad scales with a typed error.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use ibc_pnp::{PnpError, RobustLoss};

/// Ceres's floor on rho' (`f64::MIN_POSITIVE`), as in the bundle adjuster.
const MIN_RHO_PRIME: f64 = f64::MIN_POSITIVE;

/// The bundle adjuster's expressions, operation for operation (the values that must not
/// change when it switches to this crate's type).
fn bundle_adjuster(loss: &RobustLoss, s: f64) -> [f64; 3] {
    match *loss {
        RobustLoss::Trivial => [s, 1.0, 0.0],
        RobustLoss::Huber { scale: a } => {
            let b = a * a;
            if s > b {
                let r = s.sqrt();
                let rho1 = (a / r).max(MIN_RHO_PRIME);
                [2.0 * a * r - b, rho1, -rho1 / (2.0 * s)]
            } else {
                [s, 1.0, 0.0]
            }
        }
        RobustLoss::Cauchy { scale: a } => {
            let b = a * a;
            let c = 1.0 / b;
            let sum = 1.0 + s * c;
            let inv = 1.0 / sum;
            let x = s * c;
            let log = if x < 1e-3 { x.ln_1p() } else { sum.ln() };
            [b * log, inv.max(MIN_RHO_PRIME), -c * inv * inv]
        }
        RobustLoss::SoftL1 { scale: a } => {
            let b = a * a;
            let c = 1.0 / b;
            let sum = 1.0 + s * c;
            let tmp = sum.sqrt();
            let rho1 = (1.0 / tmp).max(MIN_RHO_PRIME);
            [2.0 * s / (tmp + 1.0), rho1, -(c * rho1) / (2.0 * sum)]
        }
        _ => unreachable!("a loss the bundle adjuster does not have"),
    }
}

/// The definitions as written in the docs (Ceres Solver's `LossFunction` documentation),
/// with their derivatives in s.
fn textbook(loss: &RobustLoss, s: f64) -> [f64; 3] {
    match *loss {
        RobustLoss::Trivial => [s, 1.0, 0.0],
        RobustLoss::Huber { scale: a } => {
            if s <= a * a {
                [s, 1.0, 0.0]
            } else {
                [
                    2.0 * a * s.sqrt() - a * a,
                    a / s.sqrt(),
                    -a / (2.0 * s * s.sqrt()),
                ]
            }
        }
        RobustLoss::Cauchy { scale: a } => {
            let b = a * a;
            // ln(1 + x) by ln_1p: the same function, without the rounding of 1 + x.
            [
                b * (s / b).ln_1p(),
                1.0 / (1.0 + s / b),
                -1.0 / (b * (1.0 + s / b).powi(2)),
            ]
        }
        RobustLoss::SoftL1 { scale: a } => {
            let b = a * a;
            let root = (1.0 + s / b).sqrt();
            // sqrt(1 + x) - 1 as expm1(ln_1p(x) / 2): the same function, without the
            // cancellation of the difference for small x.
            [
                2.0 * b * (0.5 * (s / b).ln_1p()).exp_m1(),
                1.0 / root,
                -1.0 / (2.0 * b * root * root * root),
            ]
        }
        _ => unreachable!(),
    }
}

fn losses() -> Vec<RobustLoss> {
    let mut all = vec![RobustLoss::Trivial];
    for scale in [1e-3, 0.3, 1.0, 2.5, 40.0] {
        all.extend([
            RobustLoss::Huber { scale },
            RobustLoss::Cauchy { scale },
            RobustLoss::SoftL1 { scale },
        ]);
    }
    all
}

/// Squared norms from zero through the scales' squares (both sides of Huber's knee and of
/// the Cauchy log's switch at s = 1e-3 a^2) to huge residuals.
fn grid() -> Vec<f64> {
    let mut s = vec![
        0.0, 1e-300, 1e-20, 1e-12, 1e-9, 1e-7, 1e-6, 9.99e-4, 1e-3, 1.001e-3,
    ];
    s.extend([
        0.01, 0.0899, 0.09, 0.0901, 0.5, 0.999, 1.0, 1.001, 2.0, 6.25, 7.0,
    ]);
    s.extend([100.0, 1599.0, 1600.0, 1601.0, 1e4, 1e8, 1e20, 1e300]);
    s
}

#[test]
fn evaluate_is_the_bundle_adjusters_loss_bit_for_bit() {
    for loss in losses() {
        for s in grid() {
            let got = loss.evaluate(s);
            let expected = bundle_adjuster(&loss, s);
            for k in 0..3 {
                assert_eq!(
                    got[k].to_bits(),
                    expected[k].to_bits(),
                    "{loss:?} at s = {s:e}, entry {k}: {} vs {}",
                    got[k],
                    expected[k]
                );
            }
            assert_eq!(loss.rho(s).to_bits(), expected[0].to_bits());
            assert_eq!(loss.weight(s).to_bits(), expected[1].to_bits());
        }
    }
}

#[test]
fn evaluate_matches_the_textbook_definitions() {
    for loss in losses() {
        for s in grid() {
            let got = loss.evaluate(s);
            let expected = textbook(&loss, s);
            for k in 0..3 {
                let (g, e) = (got[k], expected[k]);
                // Relative 1e-12 (the bundle adjuster's ln(1 + x) for x >= 1e-3 is within
                // 1e-13), and an absolute 1e-300 where either side underflows.
                assert!(
                    (g - e).abs() <= 1e-12 * e.abs() + 1e-300,
                    "{loss:?} at s = {s:e}, entry {k}: {g:e} vs {e:e}"
                );
            }
        }
    }
}

#[test]
fn trivial_is_plain_least_squares_and_the_default() {
    assert_eq!(RobustLoss::default(), RobustLoss::Trivial);
    assert!(RobustLoss::Trivial.is_trivial());
    assert!(!RobustLoss::Huber { scale: 1.0 }.is_trivial());
    assert_eq!(RobustLoss::Trivial.evaluate(3.5), [3.5, 1.0, 0.0]);
}

#[test]
fn invalid_scales_are_typed_errors_carrying_the_scale() {
    for scale in [0.0, -1.0, f64::INFINITY, f64::NEG_INFINITY] {
        for loss in [
            RobustLoss::Huber { scale },
            RobustLoss::Cauchy { scale },
            RobustLoss::SoftL1 { scale },
        ] {
            assert_eq!(loss.validate(), Err(PnpError::InvalidLossScale { scale }));
        }
    }
    let nan = RobustLoss::Cauchy { scale: f64::NAN }
        .validate()
        .unwrap_err();
    assert!(matches!(nan, PnpError::InvalidLossScale { scale } if scale.is_nan()));
    assert!(nan.to_string().contains("NaN"), "{nan}");
    assert_eq!(RobustLoss::Trivial.validate(), Ok(()));
    for loss in losses() {
        assert_eq!(loss.validate(), Ok(()));
    }
}
