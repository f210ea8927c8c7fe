//! Fixtures and the generic harness shared by the integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use nalgebra::{Vector2, Vector3};

/// CamOdoCal's Kannala-Brandt test camera (camodocal `EquidistantCamera` unit test).
pub fn camodocal_kb() -> KannalaBrandt {
    KannalaBrandt::new(
        1280,
        800,
        [
            -0.01648, -0.00203, 0.00069, -0.00048, 419.22826, 420.42160, 655.45487, 389.66377,
        ],
    )
    .unwrap()
}

/// CamOdoCal's Mei test camera (camodocal `CataCamera` unit test).
pub fn camodocal_mei() -> Unified {
    Unified::new(
        1280,
        800,
        [
            0.894975,
            -0.344504,
            0.0984552,
            -0.00403995,
            0.00610364,
            758.355,
            757.615,
            646.72,
            395.001,
        ],
    )
    .unwrap()
}

/// CamOdoCal's pinhole test camera (camodocal `PinholeCamera` unit test).
pub fn camodocal_pinhole() -> PinholeRadtan {
    PinholeRadtan::new(
        752,
        480,
        [
            -0.473, 0.273, -0.001, 0.001, 712.557492, 714.825860, 370.075592, 244.759309,
        ],
    )
    .unwrap()
}

/// A 195-degree fisheye (TUM-VI-like values from the issue).
pub fn tum_kb() -> KannalaBrandt {
    KannalaBrandt::new(
        512,
        512,
        [
            0.0034824, 0.00071503, -0.0020532, 0.00020294, 190.98, 190.98, 254.93, 254.93,
        ],
    )
    .unwrap()
}

/// A Kannala-Brandt camera with interior zero coefficients (k2 = k3 = 0), which makes
/// CamOdoCal's degree-by-counting-zeros backprojection divide by zero.
pub fn kb_interior_zero() -> KannalaBrandt {
    KannalaBrandt::new(
        1280,
        800,
        [0.05, 0.0, 0.0, -0.001, 350.0, 350.0, 640.0, 400.0],
    )
    .unwrap()
}

/// EuRoC MAV cam0 (Burri et al. 2016, `cam0/sensor.yaml`).
pub fn euroc_cam0() -> PinholeRadtan {
    PinholeRadtan::new(
        752,
        480,
        [
            -0.28340811,
            0.07395907,
            0.00019359,
            1.76187114e-05,
            458.654,
            457.296,
            367.215,
            248.375,
        ],
    )
    .unwrap()
}

/// Unified cameras with xi > 1 (the regime of real wide-angle files with xi = 1.45 and 1.82).
pub fn mei_xi_145() -> Unified {
    Unified::new(
        1280,
        1024,
        [1.45, -0.21, 0.045, 2e-4, -3e-4, 980.0, 978.0, 641.5, 509.0],
    )
    .unwrap()
}

/// Unified camera with xi = 1.82.
pub fn mei_xi_182() -> Unified {
    Unified::new(
        752,
        480,
        [1.82, -0.12, 0.02, -1e-4, 1e-4, 820.0, 821.0, 376.0, 240.0],
    )
    .unwrap()
}

/// Every fixture, as `(name, Camera)`.
pub fn all_cameras() -> Vec<(&'static str, Camera)> {
    vec![
        ("camodocal_kb", camodocal_kb().into()),
        ("camodocal_mei", camodocal_mei().into()),
        ("camodocal_pinhole", camodocal_pinhole().into()),
        ("tum_kb_195", tum_kb().into()),
        ("kb_interior_zero", kb_interior_zero().into()),
        ("euroc_cam0", euroc_cam0().into()),
        ("mei_xi_1.45", mei_xi_145().into()),
        ("mei_xi_1.82", mei_xi_182().into()),
    ]
}

/// Angle between two vectors (atan2 form, accurate for tiny angles).
pub fn angle(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b))
}

/// A direction at angle `theta` from the optical axis and azimuth `phi`.
pub fn direction(theta: f64, phi: f64) -> Vector3<f64> {
    let (s, c) = theta.sin_cos();
    Vector3::new(s * phi.cos(), s * phi.sin(), c)
}

/// The largest angle of incidence a model accepts (approximately, from its domain).
pub fn max_theta(camera: &Camera) -> f64 {
    match camera {
        Camera::KannalaBrandt(c) => c.theta_max(),
        Camera::PinholeRadtan(_) => std::f64::consts::FRAC_PI_2,
        Camera::Unified(c) => c.cos_theta_limit().acos(),
        _ => unreachable!(),
    }
}

/// A pixel grid over the image with the corners, the borders and points 1e-12 px from the
/// principal point.
pub fn pixel_grid<C: CameraModel>(camera: &C, steps: u32) -> Vec<Vector2<f64>> {
    let w = f64::from(camera.width()) - 1.0;
    let h = f64::from(camera.height()) - 1.0;
    let mut v = Vec::new();
    for i in 0..=steps {
        for j in 0..=steps {
            v.push(Vector2::new(
                w * f64::from(i) / f64::from(steps),
                h * f64::from(j) / f64::from(steps),
            ));
        }
    }
    for c in [
        (-0.5, -0.5),
        (w + 0.5, -0.5),
        (-0.5, h + 0.5),
        (w + 0.5, h + 0.5),
    ] {
        v.push(Vector2::new(c.0, c.1));
    }
    let pp = camera.principal_point();
    v.push(pp);
    for d in [
        Vector2::new(1e-12, 0.0),
        Vector2::new(0.0, -1e-12),
        Vector2::new(7e-13, 7e-13),
    ] {
        v.push(pp + d);
    }
    v
}

/// Central-difference Jacobian of `f: R^n -> R^m` at `x`, starting from per-coordinate steps
/// `h`: each column is the Richardson extrapolation (4 D(h/2) - D(h)) / 3 (error O(h^4)),
/// with the step divided by 4 until two successive estimates agree to 1e-9 relative (strongly
/// curved maps near a fold need small steps) or a step leaves the domain and a smaller one does
/// not.
pub fn central_difference<const M: usize>(
    x: &[f64],
    h: &[f64],
    f: impl Fn(&[f64]) -> Option<[f64; M]>,
) -> Option<Vec<[f64; M]>> {
    let diff = |i: usize, step: f64| -> Option<[f64; M]> {
        let mut xp = x.to_vec();
        let mut xm = x.to_vec();
        xp[i] += step;
        xm[i] -= step;
        let fp = f(&xp)?;
        let fm = f(&xm)?;
        Some(std::array::from_fn(|r| (fp[r] - fm[r]) / (xp[i] - xm[i])))
    };
    let richardson = |i: usize, step: f64| -> Option<[f64; M]> {
        let (d1, d2) = (diff(i, step)?, diff(i, 0.5 * step)?);
        Some(std::array::from_fn(|r| (4.0 * d2[r] - d1[r]) / 3.0))
    };
    let norm = |c: &[f64; M]| c.iter().map(|v| v * v).sum::<f64>().sqrt();
    let f0 = norm(&f(x)?);
    let mut cols = Vec::with_capacity(x.len());
    for (i, &h_i) in h.iter().enumerate().take(x.len()) {
        // Keep the estimate with the smallest change from its predecessor plus rounding bound
        // (4 eps |f| / step): too large a step gives truncation error, too small rounding.
        let mut step = h_i;
        let mut prev: Option<[f64; M]> = None;
        let mut best: Option<([f64; M], f64)> = None;
        for _ in 0..10 {
            match richardson(i, step) {
                Some(est) => {
                    if let Some(p) = prev {
                        let d: [f64; M] = std::array::from_fn(|r| est[r] - p[r]);
                        let score = norm(&d) + 4.0 * f64::EPSILON * f0 / step;
                        if best.is_none_or(|(_, c)| score < c) {
                            best = Some((est, score));
                        }
                        if norm(&d) <= 1e-10 * norm(&est) {
                            break;
                        }
                    }
                    prev = Some(est);
                }
                None if prev.is_some() => break,
                None => {}
            }
            step *= 0.25;
        }
        let best = best.map(|(e, _)| e).or(prev);
        cols.push(best?);
    }
    Some(cols)
}

/// Compare an analytic Jacobian (given by columns) with central differences: every column
/// within `rel` of its own norm, plus `rel * 1e-2` of the largest column (for columns that are
/// zero or nearly so analytically, where rounding of the function values dominates). Returns the worst relative error seen.
pub fn assert_columns_close<const M: usize>(
    what: &str,
    analytic: &[[f64; M]],
    numeric: &[[f64; M]],
    rel: f64,
) -> f64 {
    let norm = |c: &[f64; M]| c.iter().map(|x| x * x).sum::<f64>().sqrt();
    let scale = analytic.iter().map(norm).fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    for (j, (a, n)) in analytic.iter().zip(numeric).enumerate() {
        let diff: [f64; M] = std::array::from_fn(|r| a[r] - n[r]);
        let err = norm(&diff);
        let bound = rel * norm(a) + rel * 1e-2 * scale;
        worst = worst.max(err / (norm(a) + 1e-2 * scale));
        assert!(
            err <= bound,
            "{what}: column {j} analytic {a:?} vs numeric {n:?} (error {err:e} > {bound:e})"
        );
    }
    worst
}
