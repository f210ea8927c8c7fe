//! The noise models of [`crate::refine_trajectories`]: which trajectory's poses carry the
//! errors, and how an error of a pose enters its residual.
//!
//! The residual of pose `k` is the error of the measured `M_k = a_k_from_world_a` against the
//! prediction `P_k = (W O_k Y)⁻¹` (see [`crate::refine_trajectories`]):
//! `r = (log(R_M R_Pᵀ), t_M - t_P / s)`. An error `(ω, v)` of one measured pose moves it, to
//! first order, by `J (ω, v)`, with a `6 × 6` matrix `J` per pose and per kind of error:
//!
//! - error of `M_k = a_k_from_world_a` itself, `M' = (exp(ω) R_M, t_M + v)`: `J = I`;
//! - error of `M_k⁻¹ = world_a_from_a_k`, `(R_A exp(ω), t_A + v)`:
//!   `J = [-I 0; [t_M]× -R_M]` (a rotation of the sensor about its origin swings the world
//!   origin, at `t_M` in its frame);
//! - error of `N_k = b_k_from_world_b = O_k⁻¹`, `N' = (exp(ω) R_N, t_N + v)`:
//!   `J = [-R_X 0; R_X [g]× / s  -R_X / s]`, where `g = R_N t(W⁻¹)` is the origin of world
//!   `a` seen from `b_k`, less that of world `b`;
//! - error of `O_k = world_b_from_b_k`, `(R_O exp(ω), t_O + v)`: the previous `J` times
//!   `[-I 0; [t_N]× -R_N]`.
//!
//! With the noise on one trajectory, the refinement minimizes `J⁻¹ r`: the errors of that
//! trajectory's poses in the form they were measured in, with rotation and translation weights
//! estimated as for the default model. With noise on both, `r` has the covariance
//! `Σ = J_a D_a J_aᵀ + J_b D_b J_bᵀ` (`D` the diagonal covariances of the given standard
//! deviations) and the refinement minimizes `L⁻¹ r` with `L Lᵀ = Σ`, which is, to first order,
//! the maximum-likelihood estimate with both trajectories' errors. `J` depends on `X`, `W` and
//! `s`: it is evaluated at the starting estimate, then again at the result of a first
//! refinement, which is refined once more.

use nalgebra::{Isometry3, Matrix3, Matrix6, UnitQuaternion, Vector3};

use crate::error::{HandEyeError, OptionField, Result, Sensor};

/// Which pose of a sensor the errors of its trajectory are errors of.
///
/// A pose has the same error in either form only if the sensor sits at the world origin:
/// otherwise a rotation error of `sensor_from_world` moves the sensor's position in the world by
/// the rotation error times its distance from the origin, and a rotation error of
/// `world_from_sensor` moves the world origin in the sensor's frame by as much.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PoseFrame {
    /// Errors of `sensor_k_from_world`: the world (a calibration target, a map) seen from the
    /// sensor, as PnP or a bundle adjustment localizes a camera (OpenCV's `target2cam`): a
    /// rotation error turns the world about the sensor, a translation error moves the world
    /// origin in the sensor's frame.
    SensorFromWorld,
    /// Errors of `world_from_sensor_k`: the sensor in its world, as a robot arm's forward
    /// kinematics (OpenCV's `gripper2base`) or an odometry reports it: a rotation error turns
    /// the sensor about its own origin, a translation error moves it in the world.
    WorldFromSensor,
}

/// Standard deviations of the errors of one trajectory's poses, per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseNoise {
    /// Which pose the errors are errors of.
    pub frame: PoseFrame,
    /// Rotation error per axis, radians (positive).
    pub rotation: f64,
    /// Translation error per axis, in the unit of the trajectory (positive).
    pub translation: f64,
}

impl PoseNoise {
    /// Noise of the given pose form with the given rotation (radians) and translation standard
    /// deviations.
    #[must_use]
    pub fn new(frame: PoseFrame, rotation: f64, translation: f64) -> Self {
        Self {
            frame,
            rotation,
            translation,
        }
    }
}

/// Which trajectory's poses [`crate::refine_trajectories`] treats as noisy, and how.
///
/// The refinement improves on the linear solution only with the model that matches the data.
/// On OpenCV's hand-eye simulation (`tests/noise_role.rs`, the crate docs have the table), with
/// the noise on the camera's poses only, the default model cuts the median translation error
/// from 11.5 to 8.1 mm when the camera is `a`, and does nothing (11.4 to 11.8 mm) when it is
/// `b`, where `NoiseModel::B(PoseFrame::SensorFromWorld)` cuts it to 8.1 mm; with the noise on
/// the robot's poses only, the default model makes it worse (1.9 to 4.5 mm) and the model of
/// the robot's errors (`WorldFromSensor`) better (1.5 mm). [`crate::TrajectoryFit::likeliest_noise`]
/// tells which single-trajectory model the residuals favour.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum NoiseModel {
    /// Only the poses of sensor `a` are noisy, with errors of the given form; those of `b` are
    /// exact. The rotation and translation standard deviations are estimated from the residuals
    /// (or taken from [`crate::RefineOptions`]).
    A(PoseFrame),
    /// Only the poses of sensor `b` are noisy, with errors of the given form; those of `a` are
    /// exact. Standard deviations as for [`NoiseModel::A`], of the poses of `b`.
    B(PoseFrame),
    /// Both trajectories are noisy, with the given standard deviations (the sigmas of
    /// [`crate::RefineOptions`] are not used).
    Both {
        /// The noise of the poses of sensor `a`.
        a: PoseNoise,
        /// The noise of the poses of sensor `b`, in the unit of `b`.
        b: PoseNoise,
    },
}

impl Default for NoiseModel {
    /// [`NoiseModel::A`] with [`PoseFrame::SensorFromWorld`]: noise on the camera rig's poses
    /// as a localization reports them, exact odometry.
    fn default() -> Self {
        NoiseModel::A(PoseFrame::SensorFromWorld)
    }
}

impl NoiseModel {
    /// Checks the standard deviations of [`NoiseModel::Both`].
    pub(crate) fn validate(&self) -> Result<()> {
        if let NoiseModel::Both { a, b } = self {
            for (noise, sensor) in [(a, Sensor::A), (b, Sensor::B)] {
                let valid = |s: f64| s > 0.0 && s.is_finite();
                if !valid(noise.rotation) {
                    return Err(HandEyeError::InvalidOptions {
                        field: OptionField::NoiseRotation(sensor),
                        value: noise.rotation,
                    });
                }
                if !valid(noise.translation) {
                    return Err(HandEyeError::InvalidOptions {
                        field: OptionField::NoiseTranslation(sensor),
                        value: noise.translation,
                    });
                }
            }
        }
        Ok(())
    }

    /// Whether the residual is used as it is (noise on `a_k_from_world_a` only).
    pub(crate) fn is_identity(&self) -> bool {
        *self == NoiseModel::A(PoseFrame::SensorFromWorld)
    }
}

/// What the noise Jacobians depend on for one pose: the measured `M_k = a_k_from_world_a`, the
/// pose `O_k = world_b_from_b_k` and the current estimate.
pub(crate) struct PoseContext<'a> {
    pub(crate) measured: &'a Isometry3<f64>,
    pub(crate) odometry: &'a Isometry3<f64>,
    /// `R_X`, the rotation of `a_from_b`.
    pub(crate) x_rotation: &'a UnitQuaternion<f64>,
    /// `W = world_a_from_world_b`.
    pub(crate) w: &'a Isometry3<f64>,
    pub(crate) scale: f64,
}

/// A block lower-triangular `6 × 6` matrix `[a 0; c d]` (`3 × 3` blocks), the form of every
/// noise Jacobian: its inverse is `[a⁻¹ 0; -d⁻¹ c a⁻¹ d⁻¹]`, two `3 × 3` inverses.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlockLower {
    a: Matrix3<f64>,
    c: Matrix3<f64>,
    d: Matrix3<f64>,
}

impl BlockLower {
    fn identity() -> Self {
        Self {
            a: Matrix3::identity(),
            c: Matrix3::zeros(),
            d: Matrix3::identity(),
        }
    }

    /// `[-I 0; [t_S]× -R_S]`: an error of a pose in the form `world_from_sensor` as an error of
    /// `sensor_from_world = (R_S, t_S)`.
    fn world_from_sensor(sensor_from_world: &Isometry3<f64>) -> Self {
        Self {
            a: -Matrix3::identity(),
            c: sensor_from_world.translation.vector.cross_matrix(),
            d: -sensor_from_world.rotation.to_rotation_matrix().into_inner(),
        }
    }

    fn mul(&self, other: &Self) -> Self {
        Self {
            a: self.a * other.a,
            c: self.c * other.a + self.d * other.c,
            d: self.d * other.d,
        }
    }

    /// The inverse, `None` if a diagonal block is singular (non-finite input).
    fn inverse(&self) -> Option<Self> {
        let a = self.a.try_inverse()?;
        let d = self.d.try_inverse()?;
        Some(Self {
            a,
            c: -(d * self.c * a),
            d,
        })
    }

    pub(crate) fn matrix(&self) -> Matrix6<f64> {
        let mut m = Matrix6::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.a);
        m.fixed_view_mut::<3, 3>(3, 0).copy_from(&self.c);
        m.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.d);
        m
    }
}

/// How an error of the poses of `sensor` in the form `frame` moves the residual (module docs).
pub(crate) fn noise_jacobian(
    sensor: Sensor,
    frame: PoseFrame,
    pose: &PoseContext<'_>,
) -> BlockLower {
    match sensor {
        Sensor::A => match frame {
            PoseFrame::SensorFromWorld => BlockLower::identity(),
            PoseFrame::WorldFromSensor => BlockLower::world_from_sensor(pose.measured),
        },
        Sensor::B => {
            let n = pose.odometry.inverse();
            let r_x = pose.x_rotation.to_rotation_matrix().into_inner();
            let g = n.rotation * pose.w.inverse().translation.vector;
            let inv_s = 1.0 / pose.scale;
            let j = BlockLower {
                a: -r_x,
                c: r_x * g.cross_matrix() * inv_s,
                d: -r_x * inv_s,
            };
            match frame {
                PoseFrame::SensorFromWorld => j,
                PoseFrame::WorldFromSensor => j.mul(&BlockLower::world_from_sensor(&n)),
            }
        }
    }
}

/// The translation error of a pose of `sensor`, in the form `frame`, that explains the residual
/// `(r_rot, r_trans)` of the pose alone (the translation rows of `J⁻¹ r`); `None` for
/// non-finite input.
pub(crate) fn translation_error(
    sensor: Sensor,
    frame: PoseFrame,
    pose: &PoseContext<'_>,
    r_rot: &Vector3<f64>,
    r_trans: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let inverse = noise_jacobian(sensor, frame, pose).inverse()?;
    Some(inverse.c * r_rot + inverse.d * r_trans)
}

/// The matrix that maps the residual of one pose onto what the refinement minimizes (module
/// docs); `None` if it cannot be formed (non-finite input).
pub(crate) fn whitening(model: &NoiseModel, pose: &PoseContext<'_>) -> Option<Matrix6<f64>> {
    match model {
        NoiseModel::A(frame) => Some(noise_jacobian(Sensor::A, *frame, pose).inverse()?.matrix()),
        NoiseModel::B(frame) => Some(noise_jacobian(Sensor::B, *frame, pose).inverse()?.matrix()),
        NoiseModel::Both { a, b } => {
            let covariance = |sensor, noise: &PoseNoise| {
                let j = noise_jacobian(sensor, noise.frame, pose).matrix();
                let mut d = Matrix6::zeros();
                for k in 0..3 {
                    d[(k, k)] = noise.rotation * noise.rotation;
                    d[(k + 3, k + 3)] = noise.translation * noise.translation;
                }
                j * d * j.transpose()
            };
            let sigma = covariance(Sensor::A, a) + covariance(Sensor::B, b);
            let l = sigma.cholesky()?.l();
            l.solve_lower_triangular(&Matrix6::identity())
        }
    }
}
