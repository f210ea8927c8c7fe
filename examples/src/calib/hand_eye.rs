//! Hand-eye calibration between the rig and its odometry (the paper's section IV-E), by
//! `ibc-hand-eye`.
//!
//! The rig poses are the refined `world_from_rig` of the frame sets (rig frame = camera 0),
//! the odometry poses the log's `world_from_odometry` of the same frames; `A X = X B` with
//! `A = rig_k_from_rig_l`, `B = odometry_k_from_odometry_l` and `X = rig_from_odometry`.
//!
//! 1. The motions are those between each frame set and each of the next 8 sets
//!    ([`pairing`](HandEyeOptions::pairing), `ibc_hand_eye::Pairing::Window`: `A = P_k^-1 P_l`,
//!    `B = O_k^-1 O_l`), short enough that the odometry's drift stays small.
//! 2. The linear solution: Guo, Mirzaei and Roumeliotis's planar method (ICRA 2012) for a
//!    ground vehicle, whose odometry cannot tell the rig's height above its plane, or
//!    Daniilidis's dual quaternions (IJRR 1999) for 6-DoF odometry. Its residuals give the
//!    predicted standard deviations.
//! 3. With [`refine`](HandEyeOptions::refine), it is refined on the absolute trajectories of
//!    every frame set (`ibc_hand_eye::refine_trajectories`, planar when the odometry is).

use ibc_hand_eye::{
    DaniilidisOptions, HandEyeError, Height, PlanarOptions, TrajectoryOptions, Uncertainty,
    daniilidis, guo_planar, refine_trajectories, relative_motions,
};
use nalgebra::Isometry3;

use super::options::{HandEyeMethod, HandEyeOptions};
use crate::data::OdometryKind;

/// The method a hand-eye result was computed with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HandEyeSolver {
    /// Guo et al.'s planar method.
    Planar,
    /// Daniilidis's dual-quaternion method.
    Daniilidis,
}

impl HandEyeSolver {
    /// The name in reports: `"guo-planar"` or `"daniilidis"`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Planar => "guo-planar",
            Self::Daniilidis => "daniilidis",
        }
    }
}

/// A hand-eye calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct HandEye {
    /// The method.
    pub solver: HandEyeSolver,
    /// The estimate `rig_from_odometry` (rig frame = camera 0). With the planar method, the
    /// height of the rig above the odometry plane is not observable: it is zero in
    /// `odometry_from_rig`.
    pub rig_from_odometry: Isometry3<f64>,
    /// Whether the height (z of `odometry_from_rig`) was determined.
    pub height_observable: bool,
    /// Residual RMS and predicted standard deviations of `odometry_from_rig` (rotation about
    /// the odometry axes, radians; translation in the odometry frame, metres; infinite for an
    /// unobservable component).
    pub uncertainty: Uncertainty,
    /// Poses (frame sets with odometry) used.
    pub poses: usize,
    /// Motions in the linear solution.
    pub motions: usize,
}

/// Why no hand-eye result was computed, when one was asked for.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HandEyeFailure {
    /// Too few frame sets have an odometry pose.
    #[error("only {found} frame sets have odometry, at least 3 are needed")]
    TooFewPoses {
        /// Frame sets with odometry.
        found: usize,
    },
    /// The solver refused the motions (degenerate motion, too little rotation).
    #[error("{0}")]
    Solver(#[from] HandEyeError),
}

/// Which solver the options and the odometry kind ask for; `None` for no hand-eye.
pub fn choose_solver(method: HandEyeMethod, kind: OdometryKind) -> Option<HandEyeSolver> {
    match (method, kind) {
        (HandEyeMethod::Skip, _) | (HandEyeMethod::Auto, OdometryKind::None) => None,
        (HandEyeMethod::Planar, _) | (HandEyeMethod::Auto, OdometryKind::Planar) => {
            Some(HandEyeSolver::Planar)
        }
        (HandEyeMethod::Daniilidis, _) | (HandEyeMethod::Auto, OdometryKind::SixDof) => {
            Some(HandEyeSolver::Daniilidis)
        }
    }
}

/// Hand-eye calibration from synchronized rig and odometry poses (see the module docs).
///
/// `poses` pairs `world_from_rig` with `world_from_odometry` at the same instants.
///
/// # Errors
/// [`HandEyeFailure::TooFewPoses`] with fewer than three poses, [`HandEyeFailure::Solver`]
/// when the solver refuses the motions.
pub fn calibrate_hand_eye(
    solver: HandEyeSolver,
    poses: &[(Isometry3<f64>, Isometry3<f64>)],
    options: &HandEyeOptions,
) -> Result<HandEye, HandEyeFailure> {
    if poses.len() < 3 {
        return Err(HandEyeFailure::TooFewPoses { found: poses.len() });
    }
    let rig: Vec<Isometry3<f64>> = poses.iter().map(|p| p.0).collect();
    let odometry: Vec<Isometry3<f64>> = poses.iter().map(|p| p.1).collect();
    let motions = relative_motions(&rig, &odometry, options.pairing)?;
    let (linear, height_observable, uncertainty) = match solver {
        HandEyeSolver::Planar => {
            let s = guo_planar(&motions, &PlanarOptions::default())?;
            (s.a_from_b, s.height != Height::Unobservable, s.uncertainty)
        }
        HandEyeSolver::Daniilidis => {
            let s = daniilidis(&motions, &DaniilidisOptions::default())?;
            (s.a_from_b, true, s.uncertainty)
        }
    };
    let (rig_from_odometry, uncertainty) = if options.refine {
        let trajectory = match solver {
            HandEyeSolver::Planar => TrajectoryOptions::planar(false, 1.0),
            HandEyeSolver::Daniilidis => TrajectoryOptions::default(),
        };
        let fit = refine_trajectories(&rig, &odometry, &linear, &trajectory)?;
        (fit.a_from_b, fit.uncertainty)
    } else {
        (linear, uncertainty)
    };
    Ok(HandEye {
        solver,
        rig_from_odometry,
        height_observable,
        uncertainty,
        poses: poses.len(),
        motions: motions.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn the_solver_follows_the_odometry_unless_told() {
        use HandEyeMethod as M;
        use OdometryKind as K;
        assert_eq!(
            choose_solver(M::Auto, K::Planar),
            Some(HandEyeSolver::Planar)
        );
        assert_eq!(
            choose_solver(M::Auto, K::SixDof),
            Some(HandEyeSolver::Daniilidis)
        );
        assert_eq!(choose_solver(M::Auto, K::None), None);
        assert_eq!(choose_solver(M::Skip, K::Planar), None);
        assert_eq!(
            choose_solver(M::Daniilidis, K::Planar),
            Some(HandEyeSolver::Daniilidis)
        );
    }

    #[test]
    fn recovers_a_planar_mount_from_exact_poses() {
        let rig_from_odometry =
            Isometry3::new(Vector3::new(-1.2, 0.1, -0.8), Vector3::new(1.3, -0.2, 0.4));
        let poses: Vec<_> = (0..40)
            .map(|k| {
                let t = f64::from(k) * 0.2;
                let odo = Isometry3::new(
                    Vector3::new(10.0 * t.cos(), 6.0 * t.sin(), 0.0),
                    Vector3::new(0.0, 0.0, t + 0.3 * (2.0 * t).sin()),
                );
                (odo * rig_from_odometry.inverse(), odo)
            })
            .collect();
        let h =
            calibrate_hand_eye(HandEyeSolver::Planar, &poses, &HandEyeOptions::default()).unwrap();
        let estimate = h.rig_from_odometry.inverse();
        let truth = rig_from_odometry.inverse();
        assert!(estimate.rotation.angle_to(&truth.rotation) < 1e-8);
        assert!((estimate.translation.vector.xy() - truth.translation.vector.xy()).norm() < 1e-8);
        assert!(!h.height_observable);
    }

    #[test]
    fn too_few_poses_is_an_error() {
        let p = (Isometry3::identity(), Isometry3::identity());
        let e = calibrate_hand_eye(
            HandEyeSolver::Daniilidis,
            &[p, p],
            &HandEyeOptions::default(),
        );
        assert_eq!(e, Err(HandEyeFailure::TooFewPoses { found: 2 }));
    }
}
