//! Synthetic two-view scenes shared by the relative-pose tests: a pinhole-like setup (the EPnP
//! paper's box of points seen by two cameras with f = 800 equivalent), a wide one with rays
//! over 190 degrees, planar scenes and pure rotations, with angular noise and outliers.
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Focal length in pixels of the f = 800 equivalent camera.
pub const FOCAL: f64 = 800.0;

/// Two views of the same points: `a[i]` and `b[i]` are the bearings of point `i` (unless it
/// is an outlier), `b_from_a` the truth.
pub struct TwoView {
    pub a: Vec<Vector3<f64>>,
    pub b: Vec<Vector3<f64>>,
    pub b_from_a: Isometry3<f64>,
    /// Which correspondences are outliers.
    pub outlier: Vec<bool>,
}

/// A uniformly random rotation.
pub fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let normal = Normal::new(0.0, 1.0).unwrap();
    UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        normal.sample(rng),
        normal.sample(rng),
        normal.sample(rng),
        normal.sample(rng),
    ))
}

/// A uniformly random unit vector.
pub fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    let normal = Normal::new(0.0, 1.0).unwrap();
    Vector3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng)).normalize()
}

/// A rotation by an angle uniform in `[0, max_angle]` about a random axis.
pub fn small_rotation(rng: &mut ChaCha8Rng, max_angle: f64) -> UnitQuaternion<f64> {
    let axis = Unit::new_normalize(random_unit(rng));
    UnitQuaternion::from_axis_angle(&axis, rng.random_range(0.0..max_angle))
}

/// Rotates `f` by a random small angle: tangent-plane Gaussian noise of `sigma` radians per
/// axis, the angular counterpart of pixel noise `sigma * FOCAL`.
pub fn perturb(rng: &mut ChaCha8Rng, f: &Vector3<f64>, sigma: f64) -> Vector3<f64> {
    if sigma == 0.0 {
        return *f;
    }
    let noise = Normal::new(0.0, sigma).unwrap();
    let helper = if f.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = f.cross(&helper).normalize();
    let e2 = f.cross(&e1);
    let tangent = e1 * noise.sample(rng) + e2 * noise.sample(rng);
    let angle = tangent.norm();
    if angle == 0.0 {
        return *f;
    }
    let axis = Unit::new_normalize(f.cross(&tangent));
    Rotation3::from_axis_angle(&axis, angle) * f
}

/// A random direction within `half_angle` radians of +z, uniform over that spherical cap.
pub fn direction_in_cap(rng: &mut ChaCha8Rng, half_angle: f64) -> Vector3<f64> {
    let z = rng.random_range(half_angle.cos()..1.0);
    let phi = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Bearings of `points` (frame a) in both views, with noise, and `outliers` of them (the
/// first ones) replaced in view b by random directions within `outlier_cap` of +z.
fn views(
    rng: &mut ChaCha8Rng,
    points: &[Point3<f64>],
    b_from_a: Isometry3<f64>,
    sigma: f64,
    outliers: usize,
    outlier_cap: f64,
) -> TwoView {
    let mut a = Vec::new();
    let mut b = Vec::new();
    let mut outlier = Vec::new();
    for (i, p) in points.iter().enumerate() {
        let fa = p.coords.normalize();
        let fb = (b_from_a * p).coords.normalize();
        a.push(perturb(rng, &fa, sigma));
        if i < outliers {
            b.push(direction_in_cap(rng, outlier_cap));
            outlier.push(true);
        } else {
            b.push(perturb(rng, &fb, sigma));
            outlier.push(false);
        }
    }
    TwoView {
        a,
        b,
        b_from_a,
        outlier,
    }
}

/// Two pinhole-like views (f = 800 equivalent) of points uniform in
/// `[-2, 2] x [-2, 2] x [4, 8]` of frame a; the second camera rotated by up to 15 degrees
/// and moved by 1 m in a random direction; angular noise `sigma` radians per axis;
/// `outliers` correspondences with a random direction in view b (within 30 degrees of the
/// axis, the image of a 60 degree camera).
pub fn pinhole_pair(rng: &mut ChaCha8Rng, n: usize, sigma: f64, outliers: usize) -> TwoView {
    let rotation = small_rotation(rng, 15f64.to_radians());
    let t = random_unit(rng);
    let b_from_a = Isometry3::from_parts(Translation3::from(t), rotation);
    let points: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(4.0..8.0),
            )
        })
        .collect();
    views(rng, &points, b_from_a, sigma, outliers, 30f64.to_radians())
}

/// Two views with rays over a 190 degree field of view in view a (up to 95 degrees from the
/// axis, behind the z = 0 plane), points at distances uniform in [4, 8]; a random rotation
/// and a 1 m translation in a random direction.
pub fn wide_pair(rng: &mut ChaCha8Rng, n: usize, sigma: f64, outliers: usize) -> TwoView {
    let b_from_a =
        Isometry3::from_parts(Translation3::from(random_unit(rng)), random_rotation(rng));
    let points: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::from(direction_in_cap(rng, 95f64.to_radians()) * rng.random_range(4.0..8.0))
        })
        .collect();
    views(
        rng,
        &points,
        b_from_a,
        sigma,
        outliers,
        std::f64::consts::PI,
    )
}

/// A planar scene: points on the plane z = 6 - 0.3 x + 0.2 y of frame a, seen by the pinhole
/// pair's cameras.
pub fn planar_pair(rng: &mut ChaCha8Rng, n: usize, sigma: f64, outliers: usize) -> TwoView {
    let rotation = small_rotation(rng, 15f64.to_radians());
    let t = random_unit(rng);
    let b_from_a = Isometry3::from_parts(Translation3::from(t), rotation);
    let points: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            let (x, y) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            Point3::new(x, y, 6.0 - 0.3 * x + 0.2 * y)
        })
        .collect();
    views(rng, &points, b_from_a, sigma, outliers, 30f64.to_radians())
}

/// A pure rotation (up to 15 degrees) of the pinhole setup: no translation.
pub fn rotation_pair(rng: &mut ChaCha8Rng, n: usize, sigma: f64, outliers: usize) -> TwoView {
    let rotation = small_rotation(rng, 15f64.to_radians());
    let b_from_a = Isometry3::from_parts(Translation3::identity(), rotation);
    let points: Vec<Point3<f64>> = (0..n)
        .map(|_| {
            Point3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(4.0..8.0),
            )
        })
        .collect();
    views(rng, &points, b_from_a, sigma, outliers, 30f64.to_radians())
}

/// Rotation error in radians.
pub fn rotation_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    estimate.rotation.angle_to(&truth.rotation)
}

/// Angle in radians between the translation directions (0 when both vanish).
pub fn translation_direction_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    let (u, v) = (estimate.translation.vector, truth.translation.vector);
    if u.norm() == 0.0 && v.norm() == 0.0 {
        return 0.0;
    }
    u.cross(&v).norm().atan2(u.dot(&v))
}

/// The median of a sample.
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
