//! Refinement of a hand-eye estimate on the two absolute trajectories.
//!
//! When the synchronized trajectories `world_a_from_a_k` and `world_b_from_b_k` are at hand
//! (the pipeline's rig poses and odometry log), the statistically right residual is not that of
//! the relative motions, whose noise is correlated between pairs and inflated by the lever arm
//! of every rotation error, but the error of each measured pose. The model is
//!
//! ```text
//! world_a_from_a_k = W · world_b_from_b_k · Y,    Y = b_from_a = X⁻¹,  W = world_a_from_world_b
//! ```
//!
//! (Zhuang's `AX = ZB` form of hand-eye calibration, with the unknown alignment `W` of the two
//! world frames), and the residual of pose `k` compares the measured `a_k_from_world_a`
//! (`M_k`, the inverse of the caller's `world_from_a[k]`, as a pose estimator such as PnP
//! reports it) with the predicted `P_k = (W O_k Y)⁻¹`:
//!
//! ```text
//! r_rot,k = log(R_Mk R_Pkᵀ)            r_trans,k = t_Mk - t_Pk / s
//! ```
//!
//! — the rotation and translation errors of the measured pose in its own frame, independent of
//! the distance to the world origin. `s` is the optional scale of the translations of `a`.
//! Levenberg-Marquardt with analytic Jacobians updates `R_Y ← exp(α) R_Y`, `t_Y ← t_Y + Δy`
//! (frame `b`), `W ← (exp(β), Δw) · W`, and `s`, with the weights of [`crate::RefineOptions`].
//! For planar motion of `b` its poses are reduced to yaw and `xy` position and `t_Y,z` is held.
//!
//! Which poses are noisy is [`TrajectoryOptions::noise`]. By default ([`NoiseModel::A`] with
//! [`PoseFrame::SensorFromWorld`]) `r` itself is minimized: the maximum-likelihood estimate for
//! independent errors of `a_k_from_world_a` and exact poses of `b`. For the other models `r` is
//! mapped, pose by pose, onto the errors of the noisy poses (`J⁻¹ r`), or whitened by its
//! covariance when both trajectories are noisy (`L⁻¹ r`); see [`NoiseModel`] for the matrices.
//!
//! Measured on OpenCV's hand-eye simulation (10 poses, the camera as `a`), this refinement
//! brings the median translation error of the Daniilidis estimate from 11.6 mm to 9.1 mm; with
//! the camera as `b` it needs [`NoiseModel::B`] to do as well (see the crate docs and
//! `tests/noise_role.rs`).

use nalgebra::{Isometry3, Matrix6, SMatrix, SVector, Translation3, UnitQuaternion, Vector3};

use crate::NonExhaustive;
use crate::error::{Decomposition, HandEyeError, OptionField, Result, Sensor};
use crate::guo_planar::DEFAULT_MAX_OUT_OF_PLANE;
use crate::least_squares::{Model, assess, minimize, standard_deviations};
use crate::motion::check_trajectories;
use crate::noise::{NoiseModel, PoseContext, PoseFrame, translation_error, whitening};
use crate::plane::reduce_to_plane;
use crate::refine::{RefineOptions, Uncertainty};

/// Options of [`refine_trajectories`].
///
/// Write them as `TrajectoryOptions { field: value, ..Default::default() }`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryOptions {
    /// Sensor `b` moves in the `xy` plane of its world frame: its poses are reduced to yaw and
    /// `xy` position, and the height `t_Y,z` of the starting estimate (which the motion cannot
    /// tell) is held. Default `false`.
    pub planar: bool,
    /// With `planar`, the largest tilt of a pose of `b` and elevation (RMS) of its positions
    /// accepted, radians. Default [`DEFAULT_MAX_OUT_OF_PLANE`].
    pub max_out_of_plane: f64,
    /// Estimate the scale `s` of the translations of sensor `a` (metric translation `s t`).
    /// Default `false` (`s` held at `initial_scale`).
    pub estimate_scale: bool,
    /// Starting (or fixed) scale, positive. Default 1.
    pub initial_scale: f64,
    /// Which trajectory's poses are noisy, and how. Default
    /// `NoiseModel::A(PoseFrame::SensorFromWorld)`: noise on the poses of `a` as
    /// `a_k_from_world_a`, those of `b` exact.
    pub noise: NoiseModel,
    /// Iterations and weights of the Levenberg-Marquardt runs. Default
    /// [`RefineOptions::default()`]. Its standard deviations, if given, are those of the noisy
    /// poses (not used with [`NoiseModel::Both`]).
    pub refine: RefineOptions,
    /// Keeps the struct open to new fields; use `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for TrajectoryOptions {
    fn default() -> Self {
        Self {
            planar: false,
            max_out_of_plane: DEFAULT_MAX_OUT_OF_PLANE,
            estimate_scale: false,
            initial_scale: 1.0,
            noise: NoiseModel::default(),
            refine: RefineOptions::default(),
            non_exhaustive: NonExhaustive(()),
        }
    }
}

impl TrajectoryOptions {
    /// Options for the planar case, starting from a planar solution's scale (estimated if
    /// `estimate_scale`).
    #[must_use]
    pub fn planar(estimate_scale: bool, initial_scale: f64) -> Self {
        Self {
            planar: true,
            estimate_scale,
            initial_scale,
            ..Self::default()
        }
    }
}

/// The result of [`refine_trajectories`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryFit {
    /// `X = a_from_b` (`rig_from_odometry`).
    pub a_from_b: Isometry3<f64>,
    /// `Y = X⁻¹ = b_from_a` (`odometry_from_rig`).
    pub b_from_a: Isometry3<f64>,
    /// `W = world_a_from_world_b`: the world frame of `b` in that of `a` (in the pipeline
    /// `map_from_odometry_world`).
    pub world_a_from_world_b: Isometry3<f64>,
    /// Scale of the translations of `a` (the initial scale unless estimated).
    pub scale: f64,
    /// Residual RMS over the poses and predicted standard deviations of `Y = b_from_a`:
    /// rotation about the axes of frame `b` (`z` is the yaw), translation in frame `b`, `z`
    /// infinite when `planar`. The residuals are the errors of the noisy poses in the form of
    /// the noise model (radians; the unit of the noisy trajectory), or with
    /// [`NoiseModel::Both`] the errors in units of their standard deviations (about 1.7 each
    /// if the given standard deviations are right).
    pub uncertainty: Uncertainty,
    /// Levenberg-Marquardt iterations (all runs).
    pub iterations: usize,
    /// The single-trajectory noise model ([`NoiseModel::A`] or [`NoiseModel::B`], either
    /// [`PoseFrame`]) under which the errors of the poses at the estimate are smallest (RMS of
    /// their translation, in the unit of `b`; their rotation errors have the same RMS under
    /// each). When it differs from the model of the options, the data contradict that model:
    /// refine again with this one (or give [`NoiseModel::Both`] if both sensors are noisy).
    pub likeliest_noise: NoiseModel,
}

/// Refines `X = a_from_b` (from [`crate::daniilidis`] or [`crate::guo_planar`] on the
/// relative motions of the same trajectories) on the absolute poses, estimating the alignment
/// of the world frames with it (see the module docs).
///
/// `world_from_a[k]` and `world_from_b[k]` are synchronized poses, as for
/// [`crate::relative_motions`]; at least three are needed. [`TrajectoryOptions::noise`] says
/// which of them are noisy: the default suits a camera rig localized against a map or target as
/// `a` and exact poses of `b`; see [`NoiseModel`] for the others, and
/// [`TrajectoryFit::likeliest_noise`] for what the data say.
///
/// # Errors
/// [`HandEyeError::MismatchedLengths`], [`HandEyeError::NonFinite`],
/// [`HandEyeError::NotUnitQuaternion`], [`HandEyeError::InvalidOptions`] for invalid input;
/// [`HandEyeError::TooFewMotions`] for fewer than three poses; [`HandEyeError::NotPlanar`] if
/// `planar` and the poses of `b` leave the plane; [`HandEyeError::NoConvergence`] if the
/// covariance of a pose cannot be factored (non-finite values during the refinement).
pub fn refine_trajectories(
    world_from_a: &[Isometry3<f64>],
    world_from_b: &[Isometry3<f64>],
    a_from_b: &Isometry3<f64>,
    options: &TrajectoryOptions,
) -> Result<TrajectoryFit> {
    check_trajectories(world_from_a, world_from_b)?;
    crate::motion::check_pose(a_from_b, 0, Sensor::A)?;
    if !(options.initial_scale > 0.0 && options.initial_scale.is_finite()) {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::InitialScale,
            value: options.initial_scale,
        });
    }
    options.noise.validate()?;
    if world_from_a.len() < 3 {
        return Err(HandEyeError::too_few_motions(
            world_from_a.len().saturating_sub(1),
        ));
    }
    let odometry = if options.planar {
        planar_poses(world_from_b, options.max_out_of_plane)?
    } else {
        world_from_b.to_vec()
    };
    let mut model = Trajectories {
        measured: world_from_a.iter().map(Isometry3::inverse).collect(),
        odometry,
        free: [
            true,
            true,
            true,
            true,
            true,
            !options.planar,
            true,
            true,
            true,
            true,
            true,
            true,
            options.estimate_scale,
        ],
        length: rms_position(world_from_a),
        whitening: None,
    };
    let y = a_from_b.inverse();
    let start = State {
        y,
        w: initial_alignment(world_from_a, &model.odometry, &y, options.initial_scale),
        scale: options.initial_scale,
    };
    let (state, iterations) = if options.noise.is_identity() {
        minimize(&model, start, &options.refine)?
    } else {
        // The weights depend on the estimate: from the start, then again from the first result.
        let refine = match options.noise {
            NoiseModel::Both { .. } => RefineOptions {
                rotation_sigma: Some(1.0),
                translation_sigma: Some(1.0),
                ..options.refine
            },
            _ => options.refine,
        };
        model.whitening = Some(model.whitening(&options.noise, &start)?);
        let (first, n1) = minimize(&model, start, &refine)?;
        model.whitening = Some(model.whitening(&options.noise, &first)?);
        let (second, n2) = minimize(&model, first, &refine)?;
        (second, n1 + n2)
    };
    let assessment = assess(&model, &state);
    let mut translation_std = standard_deviations(&assessment.covariance, 3);
    if options.planar {
        translation_std.z = f64::INFINITY;
    }
    Ok(TrajectoryFit {
        a_from_b: state.y.inverse(),
        b_from_a: state.y,
        world_a_from_world_b: state.w,
        scale: state.scale,
        uncertainty: Uncertainty {
            rotation_rms: assessment.rotation_rms,
            translation_rms: assessment.translation_rms,
            rotation_std: standard_deviations(&assessment.covariance, 0),
            translation_std,
            scale_std: options
                .estimate_scale
                .then(|| standard_deviations(&assessment.covariance, 10).z),
        },
        iterations,
        likeliest_noise: likeliest_noise(&mut model, &state),
    })
}

/// The single-trajectory model that gives the smallest translation errors at `state` (the
/// default model if none gives finite errors).
fn likeliest_noise(model: &mut Trajectories, state: &State) -> NoiseModel {
    model.whitening = None;
    let residuals: Vec<_> = (0..model.blocks())
        .map(|k| model.residual(state, k))
        .collect();
    let x_rotation = state.y.rotation.inverse();
    let mut best = (f64::INFINITY, NoiseModel::default());
    for (sensor, frame) in [
        (Sensor::A, PoseFrame::SensorFromWorld),
        (Sensor::A, PoseFrame::WorldFromSensor),
        (Sensor::B, PoseFrame::SensorFromWorld),
        (Sensor::B, PoseFrame::WorldFromSensor),
    ] {
        let mut sum = 0.0;
        for (k, (r_rot, r_trans)) in residuals.iter().enumerate() {
            let pose = PoseContext {
                measured: &model.measured[k],
                odometry: &model.odometry[k],
                x_rotation: &x_rotation,
                w: &state.w,
                scale: state.scale,
            };
            sum += translation_error(sensor, frame, &pose, r_rot, r_trans)
                .map_or(f64::NAN, |e| e.norm_squared());
        }
        // Translation errors of `a` are in its unit: metric (the unit of `b`) times the scale.
        let metric = match sensor {
            Sensor::A => sum * state.scale * state.scale,
            Sensor::B => sum,
        };
        if metric < best.0 {
            best = (
                metric,
                match sensor {
                    Sensor::A => NoiseModel::A(frame),
                    Sensor::B => NoiseModel::B(frame),
                },
            );
        }
    }
    best.1
}

/// Poses of `b` reduced to yaw and `xy` position, after checking that they stay in the plane.
fn planar_poses(world_from_b: &[Isometry3<f64>], tolerance: f64) -> Result<Vec<Isometry3<f64>>> {
    if !(tolerance >= 0.0 && tolerance.is_finite()) {
        return Err(HandEyeError::InvalidOptions {
            field: OptionField::TrajectoryMaxOutOfPlane,
            value: tolerance,
        });
    }
    reduce_to_plane(world_from_b.iter(), &mean_position(world_from_b), tolerance)
}

/// Mean of the positions of a non-empty trajectory.
fn mean_position(world_from: &[Isometry3<f64>]) -> Vector3<f64> {
    world_from
        .iter()
        .map(|p| p.translation.vector)
        .sum::<Vector3<f64>>()
        / world_from.len() as f64
}

/// RMS distance of the positions of `a` from their mean (1 if they coincide).
fn rms_position(world_from_a: &[Isometry3<f64>]) -> f64 {
    let n = world_from_a.len() as f64;
    let mean = mean_position(world_from_a);
    let rms = (world_from_a
        .iter()
        .map(|p| (p.translation.vector - mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    if rms > 0.0 { rms } else { 1.0 }
}

/// `W` as the mean over the poses of `world_a_from_a_k · Y⁻¹ · world_b_from_b_k⁻¹` (rotation:
/// normalized sum of sign-aligned quaternions; translation: mean), `a` scaled to metric.
fn initial_alignment(
    world_from_a: &[Isometry3<f64>],
    odometry: &[Isometry3<f64>],
    y: &Isometry3<f64>,
    scale: f64,
) -> Isometry3<f64> {
    let x = y.inverse();
    let candidates: Vec<Isometry3<f64>> = world_from_a
        .iter()
        .zip(odometry)
        .map(|(a, b)| {
            let mut metric = *a;
            metric.translation.vector *= scale;
            metric * x * b.inverse()
        })
        .collect();
    let first = candidates[0].rotation.into_inner();
    let sum = candidates
        .iter()
        .fold(nalgebra::Quaternion::identity() * 0.0, |sum, c| {
            let q = c.rotation.into_inner();
            if q.dot(&first) < 0.0 {
                sum - q
            } else {
                sum + q
            }
        });
    let translation = candidates
        .iter()
        .map(|c| c.translation.vector)
        .sum::<Vector3<f64>>()
        / candidates.len() as f64;
    Isometry3::from_parts(
        Translation3::from(translation),
        UnitQuaternion::new_normalize(sum),
    )
}

/// Unknowns: `Y = b_from_a`, `W = world_a_from_world_b`, scale `s`.
#[derive(Debug, Clone, Copy)]
struct State {
    y: Isometry3<f64>,
    w: Isometry3<f64>,
    scale: f64,
}

/// Measured `a_k_from_world_a` and odometry `world_b_from_b_k`.
struct Trajectories {
    measured: Vec<Isometry3<f64>>,
    odometry: Vec<Isometry3<f64>>,
    free: [bool; 13],
    length: f64,
    /// Per pose, the matrix applied to the residual and its Jacobian (the noise model; `None`
    /// for the identity).
    whitening: Option<Vec<Matrix6<f64>>>,
}

impl Trajectories {
    /// The whitening matrices of `noise` at `state`.
    fn whitening(&self, noise: &NoiseModel, state: &State) -> Result<Vec<Matrix6<f64>>> {
        let x_rotation = state.y.rotation.inverse();
        self.measured
            .iter()
            .zip(&self.odometry)
            .map(|(measured, odometry)| {
                let pose = PoseContext {
                    measured,
                    odometry,
                    x_rotation: &x_rotation,
                    w: &state.w,
                    scale: state.scale,
                };
                whitening(noise, &pose).ok_or(HandEyeError::NoConvergence {
                    what: Decomposition::NoiseCovariance,
                })
            })
            .collect()
    }

    /// The residual as the noise model weighs it.
    fn weighted(&self, k: usize, r: Vector3<f64>, t: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        match &self.whitening {
            None => (r, t),
            Some(w) => {
                let e = w[k] * SVector::<f64, 6>::from_iterator(r.iter().chain(t.iter()).copied());
                (
                    e.fixed_rows::<3>(0).into_owned(),
                    e.fixed_rows::<3>(3).into_owned(),
                )
            }
        }
    }

    /// Predicted `a_k_from_world_a` (metric).
    fn predicted(&self, state: &State, k: usize) -> Isometry3<f64> {
        (state.w * self.odometry[k] * state.y).inverse()
    }
}

impl Model<13> for Trajectories {
    type State = State;

    fn blocks(&self) -> usize {
        self.measured.len()
    }

    fn residual(&self, state: &State, k: usize) -> (Vector3<f64>, Vector3<f64>) {
        let m = &self.measured[k];
        let p = self.predicted(state, k);
        self.weighted(
            k,
            (m.rotation * p.rotation.inverse()).scaled_axis(),
            m.translation.vector - p.translation.vector / state.scale,
        )
    }

    fn jacobian(&self, state: &State, k: usize) -> SMatrix<f64, 6, 13> {
        let p = self.predicted(state, k);
        let o = &self.odometry[k];
        let r_yt = state.y.rotation.to_rotation_matrix().transpose();
        let r_p = p.rotation.to_rotation_matrix();
        // t_P = -R_Yᵀ w with w = t_Y + R_Oᵀ t_O + R_Oᵀ R_Wᵀ t_W.
        let w = state.y.translation.vector
            + o.rotation.inverse()
                * (o.translation.vector + state.w.rotation.inverse() * state.w.translation.vector);
        let inv_s = 1.0 / state.scale;
        let mut j = SMatrix::<f64, 6, 13>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0).copy_from(r_yt.matrix());
        j.fixed_view_mut::<3, 3>(0, 6).copy_from(r_p.matrix());
        j.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(r_yt.matrix() * w.cross_matrix() * inv_s));
        j.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(r_yt.matrix() * inv_s));
        j.fixed_view_mut::<3, 3>(3, 9)
            .copy_from(&(r_p.matrix() * inv_s));
        j.fixed_view_mut::<3, 1>(3, 12)
            .copy_from(&(p.translation.vector * (inv_s * inv_s)));
        match &self.whitening {
            None => j,
            Some(w) => w[k] * j,
        }
    }

    fn apply(&self, state: &State, step: &SVector<f64, 13>) -> State {
        let y = Isometry3::from_parts(
            Translation3::from(state.y.translation.vector + step.fixed_rows::<3>(3)),
            UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(0)) * state.y.rotation,
        );
        let update = Isometry3::from_parts(
            Translation3::from(step.fixed_rows::<3>(9).into_owned()),
            UnitQuaternion::from_scaled_axis(step.fixed_rows::<3>(6)),
        );
        State {
            y,
            w: update * state.w,
            scale: state.scale + step[12],
        }
    }

    fn free(&self) -> [bool; 13] {
        self.free
    }

    fn length(&self) -> f64 {
        self.length
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::noise::noise_jacobian;
    use crate::test_support::iso;
    use approx::assert_relative_eq;

    /// An error `(ω, v)` of a pose in the given form: `sensor_from_world` as
    /// `(exp(ω) R, t + v)`, `world_from_sensor` as `(R exp(ω), t + v)`, where `pose` is
    /// `sensor_from_world`.
    fn perturbed(
        sensor_from_world: &Isometry3<f64>,
        frame: PoseFrame,
        error: &SVector<f64, 6>,
    ) -> Isometry3<f64> {
        let omega = UnitQuaternion::from_scaled_axis(error.fixed_rows::<3>(0).into_owned());
        let v = error.fixed_rows::<3>(3).into_owned();
        match frame {
            PoseFrame::SensorFromWorld => Isometry3::from_parts(
                Translation3::from(sensor_from_world.translation.vector + v),
                omega * sensor_from_world.rotation,
            ),
            PoseFrame::WorldFromSensor => {
                let w = sensor_from_world.inverse();
                Isometry3::from_parts(
                    Translation3::from(w.translation.vector + v),
                    w.rotation * omega,
                )
                .inverse()
            }
        }
    }

    /// The noise Jacobians of `noise.rs` against finite differences of the residual under
    /// errors of the measured poses of `a` and `b`, in both forms.
    #[test]
    fn noise_jacobians_match_finite_differences() {
        let odometry = iso([2.0, 1.0, 0.5], [0.1, -0.2, 0.9]);
        let state = State {
            y: iso([0.2, -0.3, 0.8], [0.4, -0.1, 0.3]),
            w: iso([1.5, -2.0, 0.7], [-0.2, 0.5, 1.1]),
            scale: 1.3,
        };
        // Consistent data (zero residual), the translation of `a` in its own unit.
        let mut measured = (state.w * odometry * state.y).inverse();
        measured.translation.vector /= state.scale;
        let model = |m: Isometry3<f64>, o: Isometry3<f64>| Trajectories {
            measured: vec![m],
            odometry: vec![o],
            free: [true; 13],
            length: 1.0,
            whitening: None,
        };
        let residual = |m: Isometry3<f64>, o: Isometry3<f64>| {
            let (r, t) = model(m, o).residual(&state, 0);
            SVector::<f64, 6>::from_iterator(r.iter().chain(t.iter()).copied())
        };
        let x_rotation = state.y.rotation.inverse();
        let pose = PoseContext {
            measured: &measured,
            odometry: &odometry,
            x_rotation: &x_rotation,
            w: &state.w,
            scale: state.scale,
        };
        assert!(residual(measured, odometry).norm() < 1e-14);
        let h = 1e-6;
        for sensor in [Sensor::A, Sensor::B] {
            for frame in [PoseFrame::SensorFromWorld, PoseFrame::WorldFromSensor] {
                let j = noise_jacobian(sensor, frame, &pose).matrix();
                for c in 0..6 {
                    let mut e = SVector::<f64, 6>::zeros();
                    e[c] = h;
                    let moved = |e: &SVector<f64, 6>| match sensor {
                        Sensor::A => residual(perturbed(&measured, frame, e), odometry),
                        Sensor::B => {
                            residual(measured, perturbed(&odometry.inverse(), frame, e).inverse())
                        }
                    };
                    let numeric = (moved(&e) - moved(&-e)) / (2.0 * h);
                    assert_relative_eq!(j.column(c).into_owned(), numeric, epsilon = 1e-7);
                }
            }
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let model = Trajectories {
            measured: vec![
                iso([0.3, -1.0, 2.0], [0.2, 0.1, -0.4]),
                iso([1.0, 0.5, -0.3], [-0.6, 0.3, 0.2]),
            ],
            odometry: vec![
                iso([2.0, 1.0, 0.5], [0.1, -0.2, 0.9]),
                iso([-1.0, 0.4, 0.2], [0.3, 0.1, -1.2]),
            ],
            free: [true; 13],
            length: 1.0,
            whitening: None,
        };
        let state = State {
            y: iso([0.2, -0.3, 0.8], [0.4, -0.1, 0.3]),
            w: iso([1.5, -2.0, 0.7], [-0.2, 0.5, 1.1]),
            scale: 1.3,
        };
        let h = 1e-7;
        for k in 0..2 {
            let j = model.jacobian(&state, k);
            let (er, _) = model.residual(&state, k);
            for c in 0..13 {
                let mut step = SVector::<f64, 13>::zeros();
                step[c] = h;
                let (rp, tp) = model.residual(&model.apply(&state, &step), k);
                let (rm, tm) = model.residual(&model.apply(&state, &-step), k);
                assert_relative_eq!(
                    j.fixed_view::<3, 1>(3, c).into_owned(),
                    (tp - tm) / (2.0 * h),
                    epsilon = 1e-6
                );
                // The analytic rotation rows omit the inverse right Jacobian of the residual
                // (the identity up to |r_rot| / 2).
                let tolerance = 1e-6 + er.norm();
                assert_relative_eq!(
                    j.fixed_view::<3, 1>(0, c).into_owned(),
                    (rp - rm) / (2.0 * h),
                    epsilon = tolerance
                );
            }
        }
    }
}
