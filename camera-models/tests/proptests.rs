//! Random valid parameters and points for every model (proptest).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{angle, direction};
use ibc_camera_models::{CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use proptest::prelude::*;

fn kb_params() -> impl Strategy<Value = [f64; 8]> {
    (
        -0.05..0.05f64,
        -0.01..0.01f64,
        -0.005..0.005f64,
        -0.001..0.001f64,
        100.0..1000.0f64,
        100.0..1000.0f64,
        0.0..1000.0f64,
        0.0..1000.0f64,
    )
        .prop_map(|(a, b, c, d, e, f, g, h)| [a, b, c, d, e, f, g, h])
}

fn radtan_coeffs() -> impl Strategy<Value = [f64; 4]> {
    (-0.5..0.5f64, -0.3..0.3f64, -0.01..0.01f64, -0.01..0.01f64)
        .prop_map(|(a, b, c, d)| [a, b, c, d])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn kb_round_trips_and_fast_path_agrees(
        params in kb_params(),
        t in 0.0..0.995f64,
        phi in 0.0..std::f64::consts::TAU,
        scale in 0.01..100.0f64,
    ) {
        let kb = KannalaBrandt::new(1000, 1000, params).unwrap();
        let p = direction(t * kb.theta_max(), phi) * scale;
        let px = kb.project(&p).unwrap();
        let ray = kb.unproject(&px).unwrap();
        prop_assert!(angle(&ray, &p) <= 1e-12, "{}", angle(&ray, &p));
        // Fast path vs companion, on the angle itself: 1e-12 rad.
        let d = t * kb.max_radius();
        let a = kb.theta_from_radius(d).unwrap();
        let b = kb.theta_from_radius_fast(d).unwrap();
        prop_assert!((a - b).abs() <= 1e-12, "{a} vs {b}");
        // The residual is at the rounding level of evaluating r near a (a few ulps of the terms).
        let ulps = f64::EPSILON * (d + a * kb.radius_derivative(a));
        prop_assert!((kb.radius(a) - d).abs() <= 8.0 * ulps);
    }

    #[test]
    fn pinhole_round_trips(
        k in radtan_coeffs(),
        f in 200.0..1000.0f64,
        frac in 0.0..0.9f64,
        phi in 0.0..std::f64::consts::TAU,
    ) {
        let cam = PinholeRadtan::new(800, 600, [k[0], k[1], k[2], k[3], f, f * 1.01, 400.0, 300.0]).unwrap();
        // Up to 0.9 of the injective radius (or 60 degrees when the distortion never folds).
        let r = frac * cam.injective_radius().min(60f64.to_radians().tan());
        let p = nalgebra::Vector3::new(r * phi.cos(), r * phi.sin(), 1.0);
        let px = cam.project(&p).unwrap();
        let ray = cam.unproject(&px).unwrap();
        prop_assert!(angle(&ray, &p) <= 1e-12, "{}", angle(&ray, &p));
        let back = cam.project(&ray).unwrap();
        prop_assert!((back - px).norm() <= 1e-9);
    }

    #[test]
    fn unified_round_trips(
        xi in 0.0..2.5f64,
        k in radtan_coeffs(),
        g in 200.0..1200.0f64,
        frac in 0.0..0.9f64,
        phi in 0.0..std::f64::consts::TAU,
    ) {
        let cam = Unified::new(1000, 1000, [xi, k[0] * 0.5, k[1] * 0.2, k[2], k[3], g, g, 500.0, 500.0]).unwrap();
        let theta = frac * cam.cos_theta_limit().acos();
        let p = direction(theta, phi);
        let px = match cam.project(&p) {
            Ok(px) => px,
            // Strong random distortion can fold before the Mei limit: then refusing is right.
            Err(ibc_camera_models::ProjectionError::BeyondInjectiveRadius { .. }) => return Ok(()),
            Err(e) => return Err(TestCaseError::fail(format!("{e}"))),
        };
        let ray = cam.unproject(&px).unwrap();
        prop_assert!(angle(&ray, &p) <= 1e-10, "{}", angle(&ray, &p));
    }
}
