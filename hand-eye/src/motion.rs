//! Motion pairs `(A_i, B_i)` and the helper that forms them from two synchronized trajectories.
//!
//! Convention (the whole crate): sensor `a` moves by `A_i = a_k_from_a_l` while sensor `b`
//! moves by `B_i = b_k_from_b_l` over the same interval; the unknown is `X = a_from_b`, and
//! `A_i X = X B_i` because both sides equal `a_k_from_b_l`.

use nalgebra::Isometry3;

use crate::error::{HandEyeError, Result, Sensor};

/// Largest deviation from 1 accepted for the norm of an input quaternion. `Isometry3` built
/// from rotation matrices, Euler angles or axis-angle vectors is unit to about 1e-15; a larger
/// deviation means the quaternion was built with `new_unchecked` from something else.
pub const UNIT_QUATERNION_TOLERANCE: f64 = 1e-6;

/// One relative motion seen by both sensors over the same time interval.
///
/// `a` is `A_i = a_k_from_a_l` (in the pipeline `rig_k_from_rig_l`), `b` is
/// `B_i = b_k_from_b_l` (in the pipeline `odometry_k_from_odometry_l`). They satisfy
/// `A_i X = X B_i` with `X = a_from_b` (`rig_from_odometry`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionPair {
    /// Motion of sensor `a`: `a_k_from_a_l`.
    pub a: Isometry3<f64>,
    /// Motion of sensor `b` over the same interval: `b_k_from_b_l`.
    pub b: Isometry3<f64>,
}

impl MotionPair {
    /// A motion pair from the motion `a_k_from_a_l` of sensor `a` and the motion
    /// `b_k_from_b_l` of sensor `b`.
    #[must_use]
    pub fn new(a: Isometry3<f64>, b: Isometry3<f64>) -> Self {
        Self { a, b }
    }

    /// The same motion with the roles of the sensors exchanged: solving with swapped pairs
    /// gives `b_from_a = X⁻¹`.
    #[must_use]
    pub fn swapped(&self) -> Self {
        Self {
            a: self.b,
            b: self.a,
        }
    }
}

/// Which pairs of poses of two synchronized trajectories become motions.
///
/// Each pair `(k, l)`, `k < l`, gives the motion from pose `k` to pose `l`; the variants differ
/// in how far apart `k` and `l` may be. [`Pairing::Window`] covers the other two:
/// [`Pairing::Consecutive`] is `Window { size: 1 }` and [`Pairing::All`] a window longer than
/// the trajectory (both kept as the names of the two common cases).
///
/// Which to use depends on how the errors of the poses behave:
///
/// - Independent errors on every pose (a camera localized against a target, a robot arm's
///   forward kinematics, OpenCV's hand-eye simulation): [`Pairing::All`]. Distant poses give
///   large rotations, and large rotations determine `X` best; the crate's accuracy figures use
///   all pairs.
/// - Errors that accumulate along the trajectory (dead-reckoned wheel odometry, visual
///   odometry): [`Pairing::Window`]. A motion over a long stretch carries the drift accumulated
///   over it; a few poses ahead it is still small while the motion already rotates enough. On
///   the default scenario of the ibc pipeline (a car with wheel odometry), the planar method's
///   in-plane translation error is 52 mm with all pairs and 3.3 mm with a window of 8.
/// - [`Pairing::Consecutive`] gives the fewest motions (`n - 1` for `n` poses) and independent
///   noise, but closely spaced poses then give motions that rotate little, which determine `X`
///   poorly (the solvers' screening leaves out those under 2 degrees, see
///   [`crate::MotionScreening`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum Pairing {
    /// Poses `k` and `k + 1`: `n - 1` motions from `n` poses, independent noise. The same as
    /// `Window { size: 1 }`.
    #[default]
    Consecutive,
    /// Every pair `k < l`: `n (n - 1) / 2` motions from `n` poses. Uses large rotations
    /// between distant poses; the motions share poses, so their noise is correlated.
    All,
    /// Every pair `(k, l)` with `k < l <= k + size`: each pose with each of the next `size`
    /// poses, `size (n - size) + size (size - 1) / 2` motions from `n > size` poses. `size` must
    /// be at least 1 ([`HandEyeError::InvalidWindow`]).
    Window {
        /// How many of the following poses each pose is paired with (at least 1).
        size: usize,
    },
}

impl Pairing {
    /// The largest `l - k` of a pair, validated.
    fn window(self) -> Result<usize> {
        match self {
            Pairing::Consecutive => Ok(1),
            Pairing::All => Ok(usize::MAX),
            Pairing::Window { size: 0 } => Err(HandEyeError::InvalidWindow { size: 0 }),
            Pairing::Window { size } => Ok(size),
        }
    }
}

/// Forms the relative motions of two synchronized absolute trajectories.
///
/// `world_from_a[k]` and `world_from_b[k]` are the poses of the two sensors at the same time
/// `k` (in the pipeline `world_from_rig` from the calibration and `world_from_odometry` from
/// the odometry log). The two "world" frames need not be the same. Each motion is
/// `A = world_from_a[k]⁻¹ · world_from_a[l]` (`a_k_from_a_l`) with the matching `B`, for the
/// pairs `(k, l)` chosen by `pairing`, in increasing order of `k` then `l`. Fewer than two
/// poses give no motion.
///
/// # Errors
/// [`HandEyeError::InvalidWindow`] for a window of size zero,
/// [`HandEyeError::MismatchedLengths`] if the trajectories differ in length,
/// [`HandEyeError::NonFinite`] or [`HandEyeError::NotUnitQuaternion`] for an invalid pose.
pub fn relative_motions(
    world_from_a: &[Isometry3<f64>],
    world_from_b: &[Isometry3<f64>],
    pairing: Pairing,
) -> Result<Vec<MotionPair>> {
    let window = pairing.window()?;
    check_trajectories(world_from_a, world_from_b)?;
    let n = world_from_a.len();
    let motions = (0..n)
        .flat_map(|k| {
            (k + 1..n.min(k.saturating_add(window).saturating_add(1))).map(move |l| (k, l))
        })
        .map(|(k, l)| MotionPair {
            a: world_from_a[k].inv_mul(&world_from_a[l]),
            b: world_from_b[k].inv_mul(&world_from_b[l]),
        })
        .collect();
    Ok(motions)
}

/// Checks that a pose has finite values and a unit quaternion.
pub(crate) fn check_pose(pose: &Isometry3<f64>, index: usize, sensor: Sensor) -> Result<()> {
    let q = pose.rotation.quaternion();
    let finite = pose.translation.vector.iter().all(|v| v.is_finite())
        && q.coords.iter().all(|v| v.is_finite());
    if !finite {
        return Err(HandEyeError::NonFinite { index, sensor });
    }
    let norm = q.norm();
    if (norm - 1.0).abs() > UNIT_QUATERNION_TOLERANCE {
        return Err(HandEyeError::NotUnitQuaternion {
            index,
            sensor,
            norm,
        });
    }
    Ok(())
}

/// Checks that two trajectories have the same length and valid poses.
pub(crate) fn check_trajectories(
    world_from_a: &[Isometry3<f64>],
    world_from_b: &[Isometry3<f64>],
) -> Result<()> {
    if world_from_a.len() != world_from_b.len() {
        return Err(HandEyeError::MismatchedLengths {
            a: world_from_a.len(),
            b: world_from_b.len(),
        });
    }
    for (index, (pose_a, pose_b)) in world_from_a.iter().zip(world_from_b).enumerate() {
        check_pose(pose_a, index, Sensor::A)?;
        check_pose(pose_b, index, Sensor::B)?;
    }
    Ok(())
}

/// Checks every motion pair of a solver's input.
pub(crate) fn check_pairs(pairs: &[MotionPair]) -> Result<()> {
    for (index, pair) in pairs.iter().enumerate() {
        check_pose(&pair.a, index, Sensor::A)?;
        check_pose(&pair.b, index, Sensor::B)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Quaternion, Translation3, UnitQuaternion};

    fn pose(k: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(k, 2.0 * k, -k),
            UnitQuaternion::from_euler_angles(0.1 * k, -0.2 * k, 0.3 * k),
        )
    }

    #[test]
    fn pair_counts_and_order() {
        let a: Vec<_> = (0..5).map(|k| pose(k as f64)).collect();
        let b: Vec<_> = (0..5).map(|k| pose(0.5 * k as f64)).collect();
        let consecutive = relative_motions(&a, &b, Pairing::Consecutive).unwrap();
        assert_eq!(consecutive.len(), 4);
        let all = relative_motions(&a, &b, Pairing::All).unwrap();
        assert_eq!(all.len(), 10);
        // The third of all pairs is (0, 3): a_0_from_a_3 maps a point of frame a_3 into a_0.
        let p = nalgebra::Point3::new(0.3, -1.0, 2.0);
        assert_relative_eq!(all[2].a * p, a[0].inverse() * (a[3] * p), epsilon = 1e-12);
        assert_relative_eq!(all[2].b * p, b[0].inverse() * (b[3] * p), epsilon = 1e-12);
        assert_eq!(consecutive[1], all[4]);
        assert!(
            relative_motions(&a[..1], &b[..1], Pairing::All)
                .unwrap()
                .is_empty()
        );
        // Windows: 1 is consecutive, 4 or more (n - 1) is every pair; 2 skips (0, 3).
        let window = |size| relative_motions(&a, &b, Pairing::Window { size }).unwrap();
        assert_eq!(window(1), consecutive);
        assert_eq!(window(4), all);
        assert_eq!(window(usize::MAX), all);
        let two = window(2);
        assert_eq!(two.len(), 7);
        assert_eq!(two[2], all[4]);
        assert_eq!(
            relative_motions(&a, &b, Pairing::Window { size: 0 }),
            Err(HandEyeError::InvalidWindow { size: 0 })
        );
    }

    #[test]
    fn rejects_invalid_trajectories() {
        let a: Vec<_> = (0..3).map(|k| pose(k as f64)).collect();
        assert_eq!(
            relative_motions(&a, &a[..2], Pairing::All),
            Err(HandEyeError::MismatchedLengths { a: 3, b: 2 })
        );
        let mut bad = a.clone();
        bad[1].translation.vector.y = f64::NAN;
        assert_eq!(
            relative_motions(&a, &bad, Pairing::All),
            Err(HandEyeError::NonFinite {
                index: 1,
                sensor: Sensor::B
            })
        );
        bad[1] = pose(1.0);
        bad[2].rotation = UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0));
        assert!(matches!(
            relative_motions(&bad, &a, Pairing::Consecutive),
            Err(HandEyeError::NotUnitQuaternion {
                index: 2,
                sensor: Sensor::A,
                ..
            })
        ));
    }

    #[test]
    fn swapped_exchanges_roles() {
        let pair = MotionPair::new(pose(1.0), pose(2.0));
        assert_eq!(pair.swapped().a, pair.b);
        assert_eq!(pair.swapped().swapped(), pair);
    }
}
