//! Where CamOdoCal's methods are wrong, ours must be exact or flag. CamOdoCal's methods are
//! re-implemented here from their description (degree by counting zero coefficients, the
//! `theta = d` fallback, 8 fixed-point undistortion steps) to measure the difference on its own
//! test cameras.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{angle, pixel_grid};
use ibc_camera_models::{CameraModel, UnprojectionError};
use nalgebra::{Vector2, Vector3};

#[test]
fn kb_corners_beyond_the_fold_are_flagged_not_guessed() {
    let kb = common::camodocal_kb();
    assert!(kb.has_fold());
    let corners = [
        Vector2::new(0.0, 0.0),
        Vector2::new(1279.0, 0.0),
        Vector2::new(0.0, 799.0),
        Vector2::new(1279.0, 799.0),
    ];
    for c in corners {
        assert!(matches!(
            kb.unproject(&c),
            Err(UnprojectionError::BeyondFold { .. })
        ));
        assert!(matches!(
            kb.unproject_fast(&c),
            Err(UnprojectionError::BeyondFold { .. })
        ));
        let fb = kb.backproject_with_fallback(&c).unwrap();
        assert!(fb.fallback, "corner {c} must be flagged");
        // The fallback angle theta = d is past the fold: its true image is elsewhere. The pixel
        // that CamOdoCal's ray stands for is mu r(d) from the centre, not mu d.
        let m = Vector2::new((c.x - kb.u0()) / kb.mu(), (c.y - kb.v0()) / kb.mv());
        let d = m.norm();
        let off_px = (kb.radius(d) - d).abs() * kb.mu();
        println!(
            "corner ({}, {}): d = {d:.4} > r_max = {:.4}; theta = d misplaces it by {off_px:.1} px",
            c.x,
            c.y,
            kb.max_radius()
        );
        assert!(off_px > 50.0);
    }
    // Inside the fold, the companion path never falls back.
    let fb = kb.backproject_with_fallback(&kb.principal_point()).unwrap();
    assert!(!fb.fallback);
}

#[test]
fn kb_with_an_interior_zero_coefficient_is_solved_exactly() {
    // CamOdoCal picks the polynomial degree by counting zero coefficients: with
    // k = [0.05, 0, 0, -0.001] it divides by zero and returns theta = d.
    let kb = common::kb_interior_zero();
    let mut worst_camodocal: f64 = 0.0;
    for px in pixel_grid(&kb, 30) {
        let Ok(ray) = kb.unproject(&px) else { continue };
        let m = Vector2::new((px.x - kb.u0()) / kb.mu(), (px.y - kb.v0()) / kb.mv());
        let d = m.norm();
        let theta = ray.z.acos();
        assert!(
            (kb.radius(theta) - d).abs() <= 1e-14 * (1.0 + d),
            "r(theta) != d at {px}"
        );
        worst_camodocal = worst_camodocal.max((theta - d).abs());
    }
    println!("theta = d (CamOdoCal's result here) is up to {worst_camodocal:.4} rad wrong");
    assert!(worst_camodocal > 0.05);
}

/// CamOdoCal's radtan inverse: 8 fixed-point steps m <- md - (D(m) - m).
fn camodocal_undistort(k: [f64; 4], md: Vector2<f64>) -> Vector2<f64> {
    let delta = |m: Vector2<f64>| {
        let r2 = m.norm_squared();
        let radial = k[0] * r2 + k[1] * r2 * r2;
        Vector2::new(
            m.x * radial + 2.0 * k[2] * m.x * m.y + k[3] * (r2 + 2.0 * m.x * m.x),
            m.y * radial + k[2] * (r2 + 2.0 * m.y * m.y) + 2.0 * k[3] * m.x * m.y,
        )
    };
    let mut m = md - delta(md);
    for _ in 1..8 {
        m = md - delta(m);
    }
    m
}

#[test]
fn radtan_newton_is_exact_where_eight_fixed_point_steps_are_not() {
    let cam = common::euroc_cam0();
    let [k1, k2, p1, p2, fx, fy, cx, cy] = cam.params_array();
    let (mut ours, mut theirs): (f64, f64) = (0.0, 0.0);
    for px in pixel_grid(&cam, 40) {
        let ray = cam.unproject(&px).unwrap();
        ours = ours.max((cam.project(&ray).unwrap() - px).norm());
        let md = Vector2::new((px.x - cx) / fx, (px.y - cy) / fy);
        let m = camodocal_undistort([k1, k2, p1, p2], md);
        theirs = theirs.max((cam.project(&Vector3::new(m.x, m.y, 1.0)).unwrap() - px).norm());
    }
    println!("EuRoC cam0: Newton {ours:.2e} px, 8 fixed-point steps {theirs:.3} px");
    assert!(ours <= 1e-9);
    assert!(theirs > 0.1, "the reference's error should show: {theirs}");
}

#[test]
fn mei_newton_is_exact_where_eight_fixed_point_steps_are_not() {
    let cam = common::camodocal_mei();
    let [xi, k1, k2, p1, p2, g1, g2, u0, v0] = cam.params_array();
    let (mut ours, mut theirs): (f64, f64) = (0.0, 0.0);
    let mut worst_angle: f64 = 0.0;
    for px in pixel_grid(&cam, 40) {
        let ray = cam.unproject(&px).unwrap();
        ours = ours.max((cam.project(&ray).unwrap() - px).norm());
        let md = Vector2::new((px.x - u0) / g1, (px.y - v0) / g2);
        let m = camodocal_undistort([k1, k2, p1, p2], md);
        let r2 = m.norm_squared();
        let f = (xi + (1.0 + (1.0 - xi * xi) * r2).sqrt()) / (1.0 + r2);
        let lifted = Vector3::new(f * m.x, f * m.y, f - xi);
        if let Ok(back) = cam.project(&lifted) {
            theirs = theirs.max((back - px).norm());
            worst_angle = worst_angle.max(angle(&lifted, &ray));
        }
    }
    println!(
        "CamOdoCal Mei camera: Newton {ours:.2e} px, 8 fixed-point steps {theirs:.3} px \
         ({worst_angle:.2e} rad)"
    );
    assert!(ours <= 1e-9);
    assert!(theirs > 0.5, "the reference's error should show: {theirs}");
}
