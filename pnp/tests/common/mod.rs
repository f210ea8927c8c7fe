//! Synthetic scenes shared by the integration tests: the EPnP paper's setup (Lepetit,
//! Moreno-Noguer and Fua, IJCV 2009, section 4.1) and a wide-angle variant.
#![allow(dead_code)]

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Focal length in pixels of the EPnP paper's virtual camera.
pub const FOCAL: f64 = 800.0;
/// Principal point of the 640 x 480 image.
pub const CENTRE: (f64, f64) = (320.0, 240.0);

/// Correspondences with the pose that generated them.
pub struct Scene {
    pub bearings: Vec<Vector3<f64>>,
    pub points: Vec<Point3<f64>>,
    pub camera_from_world: Isometry3<f64>,
}

/// A uniformly random rotation and a translation uniform in [-10, 10]^3.
pub fn random_pose(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    let normal = Normal::new(0.0, 1.0).unwrap();
    let q = nalgebra::Quaternion::new(
        normal.sample(rng),
        normal.sample(rng),
        normal.sample(rng),
        normal.sample(rng),
    );
    let t = Vector3::from_fn(|_, _| rng.random_range(-10.0..10.0));
    Isometry3::from_parts(Translation3::from(t), UnitQuaternion::from_quaternion(q))
}

/// Bearing of a pixel of the paper's pinhole camera.
pub fn bearing_of_pixel(u: f64, v: f64) -> Vector3<f64> {
    Vector3::new((u - CENTRE.0) / FOCAL, (v - CENTRE.1) / FOCAL, 1.0).normalize()
}

/// Turns camera-frame points and their bearings into a scene with a random pose.
fn finish(rng: &mut ChaCha8Rng, camera: Vec<Point3<f64>>, bearings: Vec<Vector3<f64>>) -> Scene {
    let camera_from_world = random_pose(rng);
    let world_from_camera = camera_from_world.inverse();
    Scene {
        bearings,
        points: camera.iter().map(|p| world_from_camera * p).collect(),
        camera_from_world,
    }
}

/// The EPnP paper's setup: points uniform in [-2, 2] x [-2, 2] x [4, 8] in the camera frame,
/// projected with f = 800 and principal point (320, 240), Gaussian pixel noise `sigma`.
/// Like the paper, points projecting outside 640 x 480 are kept.
pub fn pinhole_scene(rng: &mut ChaCha8Rng, n: usize, sigma: f64) -> Scene {
    pinhole_scene_in_box(rng, n, sigma, [-2.0, 2.0], [4.0, 8.0])
}

/// Like [`pinhole_scene`] with another lateral range and depth range.
pub fn pinhole_scene_in_box(
    rng: &mut ChaCha8Rng,
    n: usize,
    sigma: f64,
    lateral: [f64; 2],
    depth: [f64; 2],
) -> Scene {
    let noise = Normal::new(0.0, sigma.max(f64::MIN_POSITIVE)).unwrap();
    let mut camera = Vec::with_capacity(n);
    let mut bearings = Vec::with_capacity(n);
    for _ in 0..n {
        let p = Point3::new(
            rng.random_range(lateral[0]..lateral[1]),
            rng.random_range(lateral[0]..lateral[1]),
            rng.random_range(depth[0]..depth[1]),
        );
        let mut u = FOCAL * p.x / p.z + CENTRE.0;
        let mut v = FOCAL * p.y / p.z + CENTRE.1;
        if sigma > 0.0 {
            u += noise.sample(rng);
            v += noise.sample(rng);
        }
        camera.push(p);
        bearings.push(bearing_of_pixel(u, v));
    }
    finish(rng, camera, bearings)
}

/// Rotates `f` by a random small angle: tangent-plane Gaussian noise of `sigma` radians per
/// axis, the angular counterpart of pixel noise `sigma * FOCAL`.
pub fn perturb_bearing(rng: &mut ChaCha8Rng, f: &Vector3<f64>, sigma: f64) -> Vector3<f64> {
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
    let axis = nalgebra::Unit::new_normalize(f.cross(&tangent));
    nalgebra::Rotation3::from_axis_angle(&axis, angle) * f
}

/// A random direction within `half_angle` radians of the optical axis (+z), uniform over
/// that spherical cap.
pub fn direction_in_cap(rng: &mut ChaCha8Rng, half_angle: f64) -> Vector3<f64> {
    let cos_min = half_angle.cos();
    let z = rng.random_range(cos_min..1.0);
    let phi = rng.random_range(0.0..std::f64::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Rays spread uniformly over a field of view of `fov` radians (190 degrees gives rays up to
/// 95 degrees from the axis), points at distances uniform in [4, 8] along them, angular noise
/// `sigma` radians per tangent axis.
pub fn wide_scene(rng: &mut ChaCha8Rng, n: usize, fov: f64, sigma: f64) -> Scene {
    let mut camera = Vec::with_capacity(n);
    let mut bearings = Vec::with_capacity(n);
    for _ in 0..n {
        let f = direction_in_cap(rng, fov / 2.0);
        let distance = rng.random_range(4.0..8.0);
        camera.push(Point3::from(f * distance));
        bearings.push(perturb_bearing(rng, &f, sigma));
    }
    finish(rng, camera, bearings)
}

/// Rotation error in degrees.
pub fn rotation_error_deg(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    estimate.rotation.angle_to(&truth.rotation).to_degrees()
}

/// The rotation error of the PnP benchmark toolboxes, degrees: the largest angle between a
/// column of the estimated rotation matrix and the same column of the true one,
/// `max_k acos(r_k . r_k_true)` (S. Li, C. Xu and M. Xie, "A Robust O(n) Solution to the
/// Perspective-n-Point Problem", TPAMI 34(7), 2012, section 5; used by the OPnP and SQPnP
/// evaluations). Never larger than the geodesic angle of [`rotation_error_deg`].
pub fn column_rotation_error_deg(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    let a = estimate.rotation.to_rotation_matrix().into_inner();
    let b = truth.rotation.to_rotation_matrix().into_inner();
    (0..3)
        .map(|k| {
            let (u, v) = (a.column(k), b.column(k));
            u.cross(&v).norm().atan2(u.dot(&v))
        })
        .fold(0.0, f64::max)
        .to_degrees()
}

/// Translation error relative to the true translation's norm.
pub fn translation_error(estimate: &Isometry3<f64>, truth: &Isometry3<f64>) -> f64 {
    (estimate.translation.vector - truth.translation.vector).norm()
}

/// The q-quantile (0..=1) of a sample, by sorting.
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let pos = q * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
}

pub fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

/// Points of the paper's box flattened onto a random plane through (0, 0, 6) whose normal is
/// within 60 degrees of the optical axis, then spread by `thickness` metres (uniform) along
/// the normal: `thickness = 0` is an exactly planar set. Pixel noise `sigma`.
pub fn planar_scene(rng: &mut ChaCha8Rng, n: usize, sigma: f64, thickness: f64) -> Scene {
    let normal = -direction_in_cap(rng, 60f64.to_radians());
    let centre = Vector3::new(0.0, 0.0, 6.0);
    let noise = Normal::new(0.0, sigma.max(f64::MIN_POSITIVE)).unwrap();
    let mut camera = Vec::with_capacity(n);
    let mut bearings = Vec::with_capacity(n);
    while camera.len() < n {
        let p = Vector3::new(
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            rng.random_range(4.0..8.0),
        );
        let offset = if thickness > 0.0 {
            rng.random_range(-0.5..0.5) * thickness
        } else {
            0.0
        };
        let q = p - normal * (p - centre).dot(&normal) + normal * offset;
        if q.z < 1.0 {
            continue;
        }
        let mut u = FOCAL * q.x / q.z + CENTRE.0;
        let mut v = FOCAL * q.y / q.z + CENTRE.1;
        if sigma > 0.0 {
            u += noise.sample(rng);
            v += noise.sample(rng);
        }
        camera.push(Point3::from(q));
        bearings.push(bearing_of_pixel(u, v));
    }
    finish(rng, camera, bearings)
}

/// Median over scenes of the rotation error (degrees) drawn from the Cramer-Rao bound: for
/// each noise-free scene the Fisher information of the six pose parameters under isotropic
/// pixel noise `sigma` (pinhole, f = 800) is inverted, and one rotation error is sampled from
/// the Gaussian with that covariance. No unbiased estimator can do better on average.
pub fn crlb_median_rotation_error(scenes: &[Scene], sigma: f64, rng: &mut ChaCha8Rng) -> f64 {
    use nalgebra::{Matrix3, Matrix3x6, Matrix6};
    let normal = Normal::new(0.0, 1.0).unwrap();
    let errors: Vec<f64> = scenes
        .iter()
        .map(|s| {
            let mut fisher = Matrix6::zeros();
            for (b, x) in s.bearings.iter().zip(&s.points) {
                let p = (s.camera_from_world * x).coords;
                let u = p.normalize();
                let projector = (Matrix3::identity() - u * u.transpose()) / p.norm();
                let mut j = Matrix3x6::zeros();
                j.fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&(-(projector * p.cross_matrix())));
                j.fixed_view_mut::<3, 3>(0, 3).copy_from(&projector);
                fisher += j.transpose() * ibc_pnp::pinhole_information(b, FOCAL) * j;
            }
            let covariance = fisher.try_inverse().unwrap() * (sigma * sigma);
            let rotation: Matrix3<f64> = covariance.fixed_view::<3, 3>(0, 0).into_owned();
            let l = rotation.cholesky().unwrap().l();
            let z = Vector3::from_fn(|_, _| normal.sample(rng));
            (l * z).norm().to_degrees()
        })
        .collect();
    median(&errors)
}
