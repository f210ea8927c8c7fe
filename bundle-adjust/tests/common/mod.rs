//! Synthetic problems shared by the integration tests.
#![allow(clippy::unwrap_used, clippy::expect_used, dead_code)]

use ibc_bundle_adjust::{
    BalObservation, BalProblem, CostFunction, Jacobians, ParameterBlockId, Problem, RobustLoss,
    Se3Manifold,
};
use nalgebra::{Isometry3, Matrix2x3, Matrix3, SMatrix, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Path of a BAL file kept in `tests/data` (see its README for the sources); the tests
/// need it, so an absent file fails them rather than skipping them.
pub fn bal_path(name: &str) -> std::path::PathBuf {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    assert!(
        path.is_file(),
        "{} is missing from the repository",
        path.display()
    );
    path
}

/// A random BAL-like scene: cameras on a circle looking at a cloud of points.
pub fn synthetic_bal(seed: u64, cameras: usize, points: usize, noise: f64) -> BalProblem {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let pixel_noise = Normal::new(0.0, noise.max(1e-300)).unwrap();
    let mut cams = Vec::new();
    for i in 0..cameras {
        let angle = i as f64 * 0.35;
        // BAL cameras look down −z: camera_from_world maps the cloud to negative z.
        let center = Vector3::new(
            6.0 * angle.sin(),
            0.3 * rng.random_range(-1.0..1.0),
            6.0 * angle.cos(),
        );
        let look = UnitQuaternion::face_towards(&(-center), &Vector3::y());
        // face_towards maps z to the direction to the cloud; BAL wants −z there.
        let flip = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
        let world_from_camera = Isometry3::from_parts(Translation3::from(center), look * flip);
        let camera_from_world = world_from_camera.inverse();
        let w = camera_from_world.rotation.scaled_axis();
        let t = camera_from_world.translation.vector;
        let f = 500.0 + rng.random_range(-20.0..20.0);
        cams.push([
            w.x,
            w.y,
            w.z,
            t.x,
            t.y,
            t.z,
            f,
            rng.random_range(-0.05..0.05),
            0.0,
        ]);
    }
    let mut pts = Vec::new();
    for _ in 0..points {
        pts.push([
            rng.random_range(-1.5..1.5),
            rng.random_range(-1.5..1.5),
            rng.random_range(-1.5..1.5),
        ]);
    }
    let mut observations = Vec::new();
    for p in 0..points {
        let first = rng.random_range(0..cameras);
        let count = rng.random_range(2..=cameras.min(5));
        for k in 0..count {
            let c = (first + k * 2) % cameras;
            if observations
                .iter()
                .any(|o: &BalObservation| o.camera == c && o.point == p)
            {
                continue;
            }
            observations.push(BalObservation {
                camera: c,
                point: p,
                pixel: [0.0, 0.0],
            });
        }
    }
    let mut bal = BalProblem {
        cameras: cams,
        points: pts,
        observations,
    };
    for i in 0..bal.observations.len() {
        let r = bal.residual(i).unwrap();
        let o = &mut bal.observations[i];
        o.pixel = [
            r[0] + pixel_noise.sample(&mut rng),
            r[1] + pixel_noise.sample(&mut rng),
        ];
    }
    bal
}

/// Adds noise to every camera and point of a BAL problem.
pub fn perturb(bal: &mut BalProblem, seed: u64, rotation: f64, translation: f64, point: f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for c in &mut bal.cameras {
        for v in &mut c[0..3] {
            *v += rng.random_range(-rotation..rotation);
        }
        for v in &mut c[3..6] {
            *v += rng.random_range(-translation..translation);
        }
    }
    for p in &mut bal.points {
        for v in p.iter_mut() {
            *v += rng.random_range(-point..point);
        }
    }
}

/// The BAL residual with the camera split into an SE(3) pose `camera_from_world` (7 values on
/// [`Se3Manifold`]) and intrinsics `[f, k1, k2]`: arguments `[pose, intrinsics, point]`.
pub struct SplitReprojection {
    pub observed: [f64; 2],
}

impl CostFunction for SplitReprojection {
    fn num_residuals(&self) -> usize {
        2
    }
    fn parameter_block_sizes(&self) -> &[usize] {
        &[7, 3, 3]
    }
    fn evaluate(&self, p: &[&[f64]], r: &mut [f64], j: Option<&mut Jacobians<'_>>) -> bool {
        let Some(pose) = Se3Manifold::pose(p[0]) else {
            return false;
        };
        let (f, k1, k2) = (p[1][0], p[1][1], p[1][2]);
        let x = Vector3::new(p[2][0], p[2][1], p[2][2]);
        let q = pose.rotation * x + pose.translation.vector;
        let (u, v) = (-q.x / q.z, -q.y / q.z);
        let r2 = u * u + v * v;
        let d = 1.0 + r2 * (k1 + k2 * r2);
        r[0] = f * d * u - self.observed[0];
        r[1] = f * d * v - self.observed[1];
        let Some(j) = j else { return true };
        let dd = 2.0 * (k1 + 2.0 * k2 * r2);
        let a = nalgebra::Matrix2::new(
            f * (d + dd * u * u),
            f * dd * u * v,
            f * dd * u * v,
            f * (d + dd * v * v),
        );
        let iz = -1.0 / q.z;
        let b = Matrix2x3::new(iz, 0.0, u * iz, 0.0, iz, v * iz);
        let m = a * b;
        let rot: Matrix3<f64> = pose.rotation.to_rotation_matrix().into_inner();
        let mut jp = SMatrix::<f64, 2, 6>::zeros();
        jp.fixed_view_mut::<2, 3>(0, 0).copy_from(&(m * rot));
        jp.fixed_view_mut::<2, 3>(0, 3)
            .copy_from(&(-m * rot * x.cross_matrix()));
        j.set(0, &jp);
        j.set(
            1,
            &SMatrix::<f64, 2, 3>::new(
                d * u,
                f * r2 * u,
                f * r2 * r2 * u,
                d * v,
                f * r2 * v,
                f * r2 * r2 * v,
            ),
        );
        j.set(2, &(m * rot));
        true
    }
}

/// Ids of a split problem's blocks.
pub struct SplitBlocks {
    pub poses: Vec<ParameterBlockId>,
    pub intrinsics: Vec<ParameterBlockId>,
    pub points: Vec<ParameterBlockId>,
}

/// A problem with SE(3) poses, separate intrinsics and points from a BAL problem: residuals
/// with two reduced arguments, a manifold, and a dynamic-size Schur complement.
pub fn split_problem(bal: &BalProblem, loss: RobustLoss) -> (Problem, SplitBlocks) {
    let mut problem = Problem::new();
    let mut poses = Vec::new();
    let mut intrinsics = Vec::new();
    for c in &bal.cameras {
        let w = Vector3::new(c[0], c[1], c[2]);
        let pose = Isometry3::from_parts(
            Translation3::new(c[3], c[4], c[5]),
            UnitQuaternion::from_scaled_axis(w),
        );
        poses.push(
            problem
                .add_manifold_block(&Se3Manifold::params(&pose), Se3Manifold)
                .unwrap(),
        );
        intrinsics.push(problem.add_parameter_block(&c[6..9]).unwrap());
    }
    let points: Vec<_> = bal
        .points
        .iter()
        .map(|p| problem.add_parameter_block(p).unwrap())
        .collect();
    for o in &bal.observations {
        problem
            .add_residual_block(
                SplitReprojection { observed: o.pixel },
                loss,
                &[poses[o.camera], intrinsics[o.camera], points[o.point]],
            )
            .unwrap();
    }
    (
        problem,
        SplitBlocks {
            poses,
            intrinsics,
            points,
        },
    )
}
