//! Helpers shared by the integration tests: random rotations and a synthetic multi-camera rig.
#![allow(dead_code)]

use ibc_rig_averaging::Observation;
use nalgebra::{
    Isometry3, Matrix3, Point2, Point3, Quaternion, Rotation3, UnitQuaternion, Vector3,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A rotation uniformly distributed on SO(3) (normalized 4-D Gaussian).
pub fn uniform_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let n = Normal::new(0.0, 1.0).unwrap();
    UnitQuaternion::from_quaternion(Quaternion::new(
        n.sample(rng),
        n.sample(rng),
        n.sample(rng),
        n.sample(rng),
    ))
}

/// `exp(n)` with `n ~ N(0, sigma^2 I_3)`: isotropic rotation noise of `sigma` rad per axis.
pub fn rotation_noise(rng: &mut ChaCha8Rng, sigma: f64) -> UnitQuaternion<f64> {
    let n = Normal::new(0.0, sigma).unwrap();
    UnitQuaternion::from_scaled_axis(Vector3::new(n.sample(rng), n.sample(rng), n.sample(rng)))
}

/// The same rotation with a random quaternion sign.
pub fn random_sign(rng: &mut ChaCha8Rng, q: UnitQuaternion<f64>) -> UnitQuaternion<f64> {
    if rng.random::<bool>() {
        UnitQuaternion::new_unchecked(-q.into_inner())
    } else {
        q
    }
}

/// Projection of `sum_i w_i R_i` onto SO(3) by SVD: `U diag(1, 1, det(U V^T)) V^T`.
pub fn chordal_svd_mean(rotations: &[UnitQuaternion<f64>], weights: &[f64]) -> UnitQuaternion<f64> {
    let mut m = Matrix3::zeros();
    for (q, w) in rotations.iter().zip(weights) {
        m += *w * q.to_rotation_matrix().into_inner();
    }
    let svd = m.svd(true, true);
    let u = svd.u.unwrap();
    let v_t = svd.v_t.unwrap();
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
}

/// Pinhole intrinsics of the synthetic cameras.
pub const FOCAL: f64 = 400.0;
pub const CX: f64 = 320.0;
pub const CY: f64 = 240.0;
pub const WIDTH: f64 = 640.0;
pub const HEIGHT: f64 = 480.0;

/// Ideal pinhole projection (all synthetic cameras share it); `None` behind the camera.
pub fn pinhole(_camera: usize, p: &Point3<f64>) -> Option<Point2<f64>> {
    (p.z > 1e-6).then(|| Point2::new(FOCAL * p.x / p.z + CX, FOCAL * p.y / p.z + CY))
}

/// A synthetic calibration: true extrinsics and rig poses, the camera poses given to the
/// initialization, and observations.
pub struct SyntheticRig {
    /// True `rig_from_camera` (camera 0 deliberately not at the identity).
    pub rig_from_camera: Vec<Isometry3<f64>>,
    /// True `world_from_rig` per set.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// `camera_from_world` per set and camera as given to the initialization (noisy, some
    /// `None`).
    pub sets: Vec<Vec<Option<Isometry3<f64>>>>,
    /// Observations per set and camera (also for images that are not localized).
    pub images: Vec<Vec<Vec<Observation>>>,
}

impl SyntheticRig {
    /// The true extrinsics in the gauge of the initialization (rig frame = camera 0).
    pub fn gauge_rig_from_camera(&self) -> Vec<Isometry3<f64>> {
        let camera0_from_rig = self.rig_from_camera[0].inverse();
        self.rig_from_camera
            .iter()
            .map(|e| camera0_from_rig * e)
            .collect()
    }

    /// The true rig poses in the gauge of the initialization.
    pub fn gauge_world_from_rig(&self) -> Vec<Isometry3<f64>> {
        self.world_from_rig
            .iter()
            .map(|p| p * self.rig_from_camera[0])
            .collect()
    }

    /// Indices of the complete sets.
    pub fn complete_sets(&self) -> Vec<usize> {
        (0..self.sets.len())
            .filter(|&s| self.sets[s].iter().all(Option::is_some))
            .collect()
    }
}

/// Four cameras looking forward, left, back and right from a 1 m x 0.6 m rig; `sets` frame sets
/// along a wavy path; `points_per_image` observations per image; camera poses perturbed by
/// `sigma_rotation` rad per axis and `sigma_translation` m per axis (in the camera frame),
/// pixels by `sigma_pixel`. By `s % 10`, sets 1 miss camera 2, 3 miss camera 0, 6 miss
/// cameras 1 and 3, 8 miss cameras 0 and 2: 60 % complete, 20 % without camera 0.
pub fn synthetic_rig(
    seed: u64,
    sets: usize,
    points_per_image: usize,
    sigma_rotation: f64,
    sigma_translation: f64,
    sigma_pixel: f64,
) -> SyntheticRig {
    let mut rng = rng(seed);
    // Camera z forward, x right, y down; rig x forward, y left, z up.
    let base = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0),
    ));
    let placements = [
        (Vector3::new(0.5, 0.1, 0.3), 0.0),
        (Vector3::new(0.0, 0.3, 0.35), std::f64::consts::FRAC_PI_2),
        (Vector3::new(-0.5, 0.0, 0.3), std::f64::consts::PI),
        (Vector3::new(0.0, -0.3, 0.32), -std::f64::consts::FRAC_PI_2),
    ];
    let rig_from_camera: Vec<Isometry3<f64>> = placements
        .iter()
        .enumerate()
        .map(|(c, (t, yaw))| {
            let tilt = UnitQuaternion::from_euler_angles(0.02 * c as f64, -0.05, 0.03 * c as f64);
            let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), *yaw) * tilt * base;
            Isometry3::from_parts((*t).into(), r)
        })
        .collect();
    let world_from_rig: Vec<Isometry3<f64>> = (0..sets)
        .map(|s| {
            let s = s as f64;
            Isometry3::new(
                Vector3::new(0.8 * s, 3.0 * (0.1 * s).sin(), 0.1 * (0.3 * s).sin()),
                Vector3::new(
                    0.02 * (0.5 * s).sin(),
                    0.03 * (0.2 * s).cos(),
                    0.3 * (0.1 * s).cos(),
                ),
            )
        })
        .collect();
    let rot_noise = sigma_rotation;
    let trans = Normal::new(0.0, sigma_translation.max(f64::MIN_POSITIVE)).unwrap();
    let pix = Normal::new(0.0, sigma_pixel.max(f64::MIN_POSITIVE)).unwrap();
    let mut frame_sets = Vec::with_capacity(sets);
    let mut images = Vec::with_capacity(sets);
    for (s, p) in world_from_rig.iter().enumerate() {
        let mut set = Vec::new();
        let mut set_images = Vec::new();
        for (c, e) in rig_from_camera.iter().enumerate() {
            let world_from_camera = p * e;
            let missing = match s % 10 {
                1 => c == 2,
                3 => c == 0,
                6 => c == 1 || c == 3,
                8 => c == 0 || c == 2,
                _ => false,
            };
            let truth = world_from_camera.inverse();
            let noisy = if sigma_rotation > 0.0 || sigma_translation > 0.0 {
                let dr = rotation_noise(&mut rng, rot_noise);
                let dt = if sigma_translation > 0.0 {
                    Vector3::new(
                        trans.sample(&mut rng),
                        trans.sample(&mut rng),
                        trans.sample(&mut rng),
                    )
                } else {
                    Vector3::zeros()
                };
                Isometry3::from_parts(dt.into(), dr) * truth
            } else {
                truth
            };
            set.push((!missing).then_some(noisy));
            let observations = (0..points_per_image)
                .map(|_| {
                    let u = rng.random_range(0.0..WIDTH);
                    let v = rng.random_range(0.0..HEIGHT);
                    let depth = rng.random_range(2.0..20.0);
                    let in_camera =
                        Point3::new((u - CX) / FOCAL * depth, (v - CY) / FOCAL * depth, depth);
                    let (du, dv) = if sigma_pixel > 0.0 {
                        (pix.sample(&mut rng), pix.sample(&mut rng))
                    } else {
                        (0.0, 0.0)
                    };
                    Observation {
                        point_in_world: world_from_camera * in_camera,
                        pixel: Point2::new(u + du, v + dv),
                    }
                })
                .collect();
            set_images.push(observations);
        }
        frame_sets.push(set);
        images.push(set_images);
    }
    SyntheticRig {
        rig_from_camera,
        world_from_rig,
        sets: frame_sets,
        images,
    }
}

/// Rotation angle and translation distance between two poses.
pub fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        a.rotation.angle_to(&b.rotation),
        (a.translation.vector - b.translation.vector).norm(),
    )
}
