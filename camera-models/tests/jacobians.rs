//! All four analytic Jacobians against central finite differences (relative 1e-6), at the
//! optical axis, mid-field, near the fold and near the Mei limit: one generic harness for every
//! model.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{all_cameras, assert_columns_close, central_difference, direction, max_theta};
use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Vector2, Vector3};

const REL: f64 = 1e-6;

/// Columns of a nalgebra matrix (first `n`).
fn columns<const R: usize, const C: usize>(
    m: &nalgebra::SMatrix<f64, R, C>,
    n: usize,
) -> Vec<[f64; R]> {
    (0..n).map(|j| std::array::from_fn(|r| m[(r, j)])).collect()
}

/// Check the four Jacobians of `camera` at the point `p` (which must be in the domain).
/// Returns the worst relative column error.
fn check_at<C: CameraModel + Clone>(name: &str, camera: &C, p: &Vector3<f64>) -> f64 {
    let n = camera.num_params();
    let params = camera.params().to_vec();
    let with_params = |q: &[f64]| {
        let mut c = camera.clone();
        c.set_params(q).ok().map(|()| c)
    };
    let param_steps: Vec<f64> = params.iter().map(|v| 1e-3 * v.abs().max(0.1)).collect();
    let what = |s: &str| format!("{name} at {p:?}: {s}");

    // Projection.
    let j = camera.project_with_jacobians(p).unwrap();
    assert_eq!(j.pixel, camera.project(p).unwrap());
    let (px2, jp2) = camera.project_with_point_jacobian(p).unwrap();
    assert_eq!((px2, jp2), (j.pixel, j.d_pixel_d_point));
    for c in n..ibc_camera_models::MAX_PARAMS {
        assert_eq!(j.d_pixel_d_params.column(c).norm(), 0.0);
    }
    let x = [p.x, p.y, p.z];
    let h = [1e-5 * p.norm(); 3];
    let num = central_difference::<2>(&x, &h, |v| {
        camera
            .project(&Vector3::new(v[0], v[1], v[2]))
            .ok()
            .map(|q| [q.x, q.y])
    })
    .expect("point steps stay in the domain");
    let mut worst = assert_columns_close(
        &what("d pixel/d point"),
        &columns(&j.d_pixel_d_point, 3),
        &num,
        REL,
    );
    let num = central_difference::<2>(&params, &param_steps, |q| {
        with_params(q)?.project(p).ok().map(|q| [q.x, q.y])
    })
    .expect("parameter steps stay valid");
    worst = worst.max(assert_columns_close(
        &what("d pixel/d params"),
        &columns(&j.d_pixel_d_params, n),
        &num,
        REL,
    ));

    // Unprojection at the projected pixel.
    let pixel = j.pixel;
    let u = camera.unproject_with_jacobians(&pixel).unwrap();
    assert!((u.ray.into_inner() - camera.unproject(&pixel).unwrap().into_inner()).norm() < 1e-15);
    let (_, jpix) = camera.unproject_with_pixel_jacobian(&pixel).unwrap();
    assert_eq!(jpix, u.d_ray_d_pixel);
    // Far-field pixels of a Mei camera near its limit are huge: steps relative to them.
    let hp = [1e-3 * (1e-3 * (pixel - camera.principal_point()).norm()).max(1.0); 2];
    let num = central_difference::<3>(&[pixel.x, pixel.y], &hp, |v| {
        camera
            .unproject(&Vector2::new(v[0], v[1]))
            .ok()
            .map(|r| [r.x, r.y, r.z])
    })
    .expect("pixel steps stay in the domain");
    worst = worst.max(assert_columns_close(
        &what("d ray/d pixel"),
        &columns(&u.d_ray_d_pixel, 2),
        &num,
        REL,
    ));
    let num = central_difference::<3>(&params, &param_steps, |q| {
        with_params(q)?
            .unproject(&pixel)
            .ok()
            .map(|r| [r.x, r.y, r.z])
    })
    .expect("parameter steps stay valid");
    worst = worst.max(assert_columns_close(
        &what("d ray/d params"),
        &columns(&u.d_ray_d_params, n),
        &num,
        REL,
    ));
    // The ray is unit, so d ray is orthogonal to it.
    let dr = u.ray.transpose() * u.d_ray_d_pixel;
    assert!(
        dr.norm() <= 1e-9 * u.d_ray_d_pixel.norm(),
        "{name}: d ray not tangent"
    );
    worst
}

/// The test points of a model: the axis, points next to it, mid-field, and near the limit.
fn test_points(camera: &Camera) -> Vec<Vector3<f64>> {
    let limit = match camera {
        Camera::PinholeRadtan(_) => 70f64.to_radians(),
        _ => max_theta(camera),
    };
    let mut pts = vec![
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.0, 0.0, 3.5),
        direction(1e-9, 0.3),
        direction(1e-4, 2.0) * 2.0,
    ];
    for f in [0.25, 0.5, 0.75, 0.9] {
        pts.push(direction(f * limit, 0.9) * 1.7);
        pts.push(direction(f * limit, -2.4) * 0.3);
    }
    // Near the fold / Mei limit / pi.
    for margin in [3e-2, 1e-2] {
        pts.push(direction(limit - margin, 0.35));
    }
    pts
}

#[test]
fn jacobians_match_central_differences_for_every_model() {
    for (name, camera) in all_cameras() {
        let mut worst: f64 = 0.0;
        for p in test_points(&camera) {
            worst = worst.max(check_at(name, &camera, &p));
        }
        println!("{name}: worst relative Jacobian column error {worst:.2e}");
    }
}

#[test]
fn jacobians_are_finite_on_the_axis() {
    for (name, camera) in all_cameras() {
        let p = Vector3::new(0.0, 0.0, 2.0);
        let j = camera.project_with_jacobians(&p).unwrap();
        assert!(j.d_pixel_d_point.iter().all(|v| v.is_finite()), "{name}");
        assert!(j.d_pixel_d_params.iter().all(|v| v.is_finite()), "{name}");
        let u = camera
            .unproject_with_jacobians(&camera.principal_point())
            .unwrap();
        assert!(u.d_ray_d_pixel.iter().all(|v| v.is_finite()), "{name}");
        assert!(u.d_ray_d_params.iter().all(|v| v.is_finite()), "{name}");
        // On the axis d pixel / d point is diag(f, f) / z (up to the model's focal scale).
        assert_eq!(j.d_pixel_d_point[(0, 1)], 0.0);
        assert!(camera.radians_per_pixel(&camera.principal_point()).unwrap() > 0.0);
    }
}

#[test]
fn radians_per_pixel_matches_the_focal_length_at_the_centre() {
    for (name, camera) in all_cameras() {
        let at = camera.radians_per_pixel(&camera.principal_point()).unwrap();
        let nominal = camera.radians_per_pixel_at_center();
        approx::assert_relative_eq!(at, nominal, max_relative = 1e-9);
        let _ = name;
    }
}
