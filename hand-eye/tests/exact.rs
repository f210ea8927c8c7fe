//! Exact data: both methods recover `X` to 1e-12 rad and 1e-12 m, whatever the signs of the
//! input quaternions.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{Mount, flip_signs, general, planar, rng, rotation_error, translation_error};
use ibc_hand_eye::{
    DaniilidisOptions, HandEyeError, Height, Pairing, PlanarOptions, TrajectoryOptions, daniilidis,
    guo_planar, refine_trajectories, relative_motions,
};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

const TOLERANCE: f64 = 1e-12;

proptest! {
    #![proptest_config(common::proptest_config())]

    /// OpenCV's simulation without noise, every quaternion's sign flipped at random.
    #[test]
    fn daniilidis_is_exact_on_exact_data(seed in any::<u64>(), poses in 3usize..12, all in any::<bool>()) {
        let mut r = rng(seed);
        let sim = general(&mut r, poses, false);
        let pairing = if all { Pairing::All } else { Pairing::Consecutive };
        let pairs = relative_motions(&sim.world_from_rig, &sim.world_from_odometry, pairing).unwrap();
        let pairs = flip_signs(&mut r, &pairs);
        let solution = match daniilidis(&pairs, &DaniilidisOptions::default()) {
            // Few poses can leave fewer than two motions in the 2 to 175 degree range.
            Err(HandEyeError::TooFewMotions { .. }) => return Ok(()),
            other => other.unwrap(),
        };
        // Rounding perturbs the null space by about ε σ₁ / σ₆: 1e-12 holds unless the two
        // most different rotation axes are within a fraction of a degree of each other.
        let sv = solution.singular_values;
        let tolerance = TOLERANCE * (1e-3 * sv[0] / sv[5]).max(1.0);
        prop_assert!(rotation_error(&solution.a_from_b, &sim.rig_from_odometry) < tolerance);
        prop_assert!(translation_error(&solution.a_from_b, &sim.rig_from_odometry) < tolerance);
        prop_assert!(solution.uncertainty.translation_rms < tolerance);
    }

    /// A vehicle without noise, both mounts (including the camera x axis vertical, where the
    /// zero-yaw constraint of the paper degenerates), a random scale of the rig's translations
    /// and random signs. With the true height as prior the whole transform is exact.
    #[test]
    fn guo_planar_is_exact_on_exact_data(
        seed in any::<u64>(),
        poses in 3usize..12,
        vertical in any::<bool>(),
        scale in 0.5f64..2.0,
    ) {
        let mut r = rng(seed);
        let mount = if vertical { Mount::XAxisVertical } else { Mount::Forward };
        let sim = planar(&mut r, poses, false, scale, mount);
        let pairs = relative_motions(&sim.world_from_rig, &sim.world_from_odometry, Pairing::All).unwrap();
        let pairs = flip_signs(&mut r, &pairs);
        let truth = sim.rig_from_odometry.inverse();
        let options = PlanarOptions {
            estimate_scale: true,
            height_prior: Some(truth.translation.vector.z),
            ..Default::default()
        };
        let solution = match guo_planar(&pairs, &options) {
            // Few poses can leave no motion in the 2 to 175 degree range.
            Err(HandEyeError::TooFewMotions { .. } | HandEyeError::NoRotation { .. }) => return Ok(()),
            other => other.unwrap(),
        };
        prop_assert!(rotation_error(&solution.a_from_b, &sim.rig_from_odometry) < TOLERANCE);
        prop_assert!(translation_error(&solution.a_from_b, &sim.rig_from_odometry) < TOLERANCE);
        prop_assert!((solution.scale - scale).abs() < TOLERANCE * scale);
        prop_assert_eq!(solution.height, Height::Prior(truth.translation.vector.z));

        // Without the prior the in-plane part is still exact and the height is flagged.
        let options = PlanarOptions {
            height_prior: None,
            ..options
        };
        let solution = guo_planar(&pairs, &options).unwrap();
        prop_assert_eq!(solution.height, Height::Unobservable);
        let t = solution.b_from_a.translation.vector;
        prop_assert!((t.xy() - truth.translation.vector.xy()).norm() < TOLERANCE);
        prop_assert_eq!(t.z, 0.0);
        prop_assert!(solution.uncertainty.translation_std.z.is_infinite());
    }

    /// The refinement on the absolute trajectories keeps exact solutions exact and finds the
    /// alignment of the two world frames.
    #[test]
    fn trajectory_refinement_is_exact_on_exact_data(seed in any::<u64>(), poses in 3usize..12) {
        let mut r = rng(seed);
        let sim = general(&mut r, poses, false);
        let pairs = relative_motions(&sim.world_from_rig, &sim.world_from_odometry, Pairing::All).unwrap();
        let linear = match daniilidis(&pairs, &DaniilidisOptions::default()) {
            Err(HandEyeError::TooFewMotions { .. }) => return Ok(()),
            other => other.unwrap(),
        };
        let fit = refine_trajectories(&sim.world_from_rig, &sim.world_from_odometry, &linear.a_from_b, &TrajectoryOptions::default()).unwrap();
        // The same conditioning as the linear problem (nearly parallel axes).
        let sv = linear.singular_values;
        let tolerance = TOLERANCE * (1e-3 * sv[0] / sv[5]).max(1.0);
        prop_assert!(rotation_error(&fit.a_from_b, &sim.rig_from_odometry) < tolerance);
        prop_assert!(translation_error(&fit.a_from_b, &sim.rig_from_odometry) < tolerance);
        for (a, b) in sim.world_from_rig.iter().zip(&sim.world_from_odometry) {
            let predicted = fit.world_a_from_world_b * b * fit.b_from_a;
            prop_assert!(translation_error(&predicted, a) < 10.0 * tolerance);
            prop_assert!(rotation_error(&predicted, a) < tolerance);
        }
    }
}

fn rotation(rows: [f64; 9]) -> UnitQuaternion<f64> {
    let m = Matrix3::from_row_slice(&rows);
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m))
}

fn pose(rows: [f64; 9], t: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(Vector3::from(t)), rotation(rows))
}

/// The data of OpenCV's test `Calib3d_CalibrateHandEye.regression_24871`
/// (`modules/calib3d/test/test_calibration_hand_eye.cpp`), on which OpenCV's methods returned
/// wrong answers until their quaternion signs were fixed; OpenCV requires every method to
/// match the true `cam2gripper` to 1e-12. Camera = sensor `a`, gripper = sensor `b`.
#[test]
fn opencv_regression_24871() {
    let target2cam = [
        pose(
            [
                0.04964505493834381,
                0.5136826827431226,
                0.8565427426404346,
                -0.3923117691818854,
                0.7987004864191318,
                -0.4562554205214679,
                -0.9184916136152514,
                -0.3133809733274676,
                0.2411752915926112,
            ],
            [-1.588728904724121, 0.07843752950429916, -1.002813339233398],
        ),
        pose(
            [
                -0.3048000068139332,
                0.6971848192711539,
                0.6488684640388026,
                -0.9377589344241749,
                -0.3387497187353627,
                -0.07652979135179161,
                0.1664486009369332,
                -0.6318084803439735,
                0.7570422097951847,
            ],
            [-1.906493663787842, -0.07281044125556946, 0.6088893413543701],
        ),
        pose(
            [
                -0.590234879685801,
                -0.7051138289845309,
                -0.3929850823848928,
                0.6017371069678565,
                -0.7088332765096816,
                0.3680595606834615,
                -0.5380847896941907,
                -0.01923211603859842,
                0.8426712792141644,
            ],
            [
                -0.9809040427207947,
                -0.2707894444465637,
                -0.2577074766159058,
            ],
        ),
        pose(
            [
                0.7643667483125168,
                -0.08523002870239212,
                0.63912386614923,
                -0.2583463792779588,
                0.8676987164647345,
                0.424683512464778,
                -0.5907627462764713,
                -0.489729292214425,
                0.6412211770980741,
            ],
            [-1.58987033367157, -1.924914002418518, -0.3109001517295837],
        ),
    ];
    let gripper2base = [
        pose(
            [
                -0.4143743581399177,
                -0.6105088815982459,
                -0.6749613298595637,
                -0.1598851232573451,
                -0.6812625208693498,
                0.71436554019614,
                -0.895952364066927,
                0.4039310376145889,
                0.1846864320259794,
            ],
            [-1.249274406461827, -1.916570771580279, 2.005069553422765],
        ),
        pose(
            [
                0.7262439860936567,
                -0.201662933718935,
                -0.6571923111439066,
                -0.4640017362244384,
                -0.8491808316335328,
                -0.2521791108852766,
                -0.5072199339965884,
                0.4880819361030014,
                -0.7102844234575628,
            ],
            [-0.7375172846804027, -2.579760910816792, 1.336561572270101],
        ),
        pose(
            [
                0.2541996332132083,
                0.6186461729765909,
                0.7434106934499181,
                0.2194912986375709,
                0.711701808961156,
                -0.6673111005698995,
                -0.9419161938817396,
                0.3328024155303503,
                0.04512688689130734,
            ],
            [-1.040123533893404, -0.1303773962721222, 1.068029475621886],
        ),
        pose(
            [
                0.116348305340805,
                -0.9917998080681939,
                0.0528792261688552,
                -0.2760629007224059,
                0.01884966191381591,
                0.9609547154213178,
                -0.9540714578526358,
                -0.1264034452126562,
                -0.2716060057313114,
            ],
            [-2.551899142554571, -2.986937398237611, 1.317613923218308],
        ),
    ];
    let cam2gripper_true = pose(
        [0.0, 0.0, -1.0, 1.0, 0.0, 0.0, 0.0, -1.0, 0.0],
        [0.1, 0.2, 0.3],
    );
    let world_from_camera: Vec<_> = target2cam.iter().map(Isometry3::inverse).collect();
    let pairs = relative_motions(&world_from_camera, &gripper2base, Pairing::All).unwrap();
    let solution = daniilidis(&pairs, &DaniilidisOptions::default()).unwrap();
    // X = camera_from_gripper; OpenCV's answer is its inverse.
    let cam2gripper = solution.a_from_b.inverse();
    let r_true = cam2gripper_true.rotation.to_rotation_matrix();
    let r = cam2gripper.rotation.to_rotation_matrix();
    assert!((r.matrix() - r_true.matrix()).norm() < 1e-12);
    assert!(translation_error(&cam2gripper, &cam2gripper_true) < 1e-12);
}
