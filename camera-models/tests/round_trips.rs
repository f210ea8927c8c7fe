//! Round trips over each model's whole valid domain, one generic harness for every model.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{all_cameras, angle, direction, max_theta, pixel_grid};
use ibc_camera_models::{Camera, CameraModel, UnprojectionError};
use nalgebra::Vector3;

/// pixel -> ray -> pixel over the image grid (corners and points 1e-12 px from the principal
/// point included): <= 1e-9 px wherever the pixel has a ray; where it has none the error must
/// be a domain reason, never a wrong ray. Returns (worst error, pixels with no ray).
fn pixel_round_trip<C: CameraModel>(name: &str, camera: &C) -> (f64, usize) {
    let mut worst: f64 = 0.0;
    let mut refused = 0;
    for px in pixel_grid(camera, 40) {
        match camera.unproject(&px) {
            Ok(ray) => {
                assert!((ray.norm() - 1.0).abs() < 1e-15, "{name}: ray not unit");
                let fast = camera.unproject_fast(&px).unwrap();
                assert!(
                    angle(&ray, &fast) <= 1e-12,
                    "{name}: fast path disagrees at {px}"
                );
                let back = camera.project(&ray).unwrap();
                let err = (back - px).norm();
                worst = worst.max(err);
                assert!(
                    err <= 1e-9,
                    "{name}: pixel {px} -> {back}, error {err:e} px"
                );
            }
            Err(
                UnprojectionError::BeyondFold { .. }
                | UnprojectionError::OutsideMeiDomain { .. }
                | UnprojectionError::BeyondInjectiveRadius { .. },
            ) => refused += 1,
            Err(e) => panic!("{name}: pixel {px}: unexpected error {e}"),
        }
    }
    (worst, refused)
}

/// ray -> pixel -> ray over the valid domain (theta from 0 to just inside the limit, all
/// azimuths): <= 1e-12 rad. Returns the worst error.
fn ray_round_trip<C: CameraModel>(name: &str, camera: &C, theta_limit: f64) -> f64 {
    let mut worst: f64 = 0.0;
    let n_theta = 120;
    for i in 0..=n_theta {
        // Up to 1e-3 rad inside the limit; the fold itself is tested separately.
        let theta = (theta_limit - 1e-3) * f64::from(i) / f64::from(n_theta);
        for j in 0..24 {
            let phi = std::f64::consts::TAU * f64::from(j) / 24.0 + 0.1;
            let p = direction(theta, phi) * (0.5 + f64::from(j));
            let pixel = match camera.project(&p) {
                Ok(px) => px,
                // Radial-tangential models may refuse past the injective radius.
                Err(e) => panic!("{name}: theta {theta}: {e}"),
            };
            let ray = camera.unproject(&pixel).unwrap();
            let err = angle(&ray, &p);
            worst = worst.max(err);
            assert!(err <= 1e-12, "{name}: theta {theta} phi {phi}: {err:e} rad");
        }
    }
    worst
}

#[test]
fn every_model_round_trips_pixels_and_rays() {
    for (name, camera) in all_cameras() {
        let (px_err, refused) = pixel_round_trip(name, &camera);
        // Pinhole: the grid stops short of 90 degrees (tan blows up); test to 80.
        let limit = match &camera {
            Camera::PinholeRadtan(_) => 80f64.to_radians(),
            _ => max_theta(&camera),
        };
        let ray_err = ray_round_trip(name, &camera, limit);
        println!(
            "{name}: pixel round trip {px_err:.2e} px ({refused} grid pixels beyond the domain), \
             ray round trip {ray_err:.2e} rad"
        );
    }
}

#[test]
fn generic_code_and_the_enum_agree() {
    let kb = common::camodocal_kb();
    let cam = Camera::from(kb.clone());
    let p = Vector3::new(0.3, -0.2, 0.9);
    assert_eq!(kb.project(&p).unwrap(), cam.project(&p).unwrap());
    assert_eq!(
        kb.project_with_jacobians(&p).unwrap(),
        cam.project_with_jacobians(&p).unwrap()
    );
    assert_eq!(cam.num_params(), 8);
    assert_eq!(cam.param_names()[4], "mu");
}

#[test]
fn kb_beyond_180_degrees() {
    // The 195-degree lens of the issue: no fold before pi, so theta_max = pi.
    let kb = common::tum_kb();
    assert!(!kb.has_fold());
    assert_eq!(kb.theta_max(), std::f64::consts::PI);
    for deg in [90.0_f64, 97.5, 120.0, 170.0, 179.9] {
        let p = direction(deg.to_radians(), 0.7);
        let px = kb.project(&p).unwrap();
        let ray = kb.unproject(&px).unwrap();
        assert!(angle(&ray, &p) < 1e-12, "{deg} deg");
        // The 97.5-degree half-angle (195 degrees of field) lands inside the 512x512 image.
        if deg <= 97.5 {
            assert!(kb.in_image(&px), "{deg} deg -> {px}");
        }
    }
}

#[test]
fn kb_near_the_fold() {
    // r within 1e-10 relative of r(theta_max): ray -> pixel -> ray <= 1e-9 rad.
    for kb in [common::camodocal_kb(), common::kb_interior_zero()] {
        assert!(kb.has_fold());
        let tm = kb.theta_max();
        let r_max = kb.max_radius();
        assert!(kb.radius_derivative(tm).abs() < 1e-9);
        // theta with r(theta) = r_max (1 - 1e-10), by bisection on the increasing branch.
        let (mut lo, mut hi) = (0.0, tm);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if kb.radius(mid) < r_max * (1.0 - 1e-10) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        for theta in [lo, tm] {
            for phi in [0.0, 1.0, 2.5, 4.0] {
                let p = direction(theta, phi);
                let px = kb.project(&p).unwrap();
                let ray = kb.unproject(&px).unwrap();
                let err = angle(&ray, &p);
                assert!(err <= 1e-9, "theta {theta}: {err:e} rad");
                let fast = kb.unproject_fast(&px).unwrap();
                assert!(angle(&fast, &p) <= 1e-9);
            }
        }
    }
}

#[test]
fn mei_near_its_limit() {
    // z/|P| just above -w, for xi < 1 and xi > 1.
    for mei in [
        common::camodocal_mei(),
        common::mei_xi_145(),
        common::mei_xi_182(),
    ] {
        let theta_lim = mei.cos_theta_limit().acos();
        for margin in [1e-2, 1e-4] {
            let p = direction(theta_lim - margin, 0.4);
            let px = mei.project(&p).unwrap();
            let ray = mei.unproject(&px).unwrap();
            let err = angle(&ray, &p);
            // Conditioning near the limit costs digits: 1e-9 rad at 1e-4 rad from it.
            assert!(err <= 1e-9, "xi {}: {err:e}", mei.xi());
        }
    }
}
