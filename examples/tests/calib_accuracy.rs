#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! The accuracy bars on the paper's default scenario, the TrimBot2020 pentagon rig and
//! a handheld 6-DoF rig (run with `--nocapture` to see the figures).
//!
//! Bars (issue 8): per camera, relative to camera 0, rotation error <= 0.005 degrees and
//! translation error <= 1 mm against ground truth; the final mean reprojection error within
//! 10% of what the pixel noise alone gives (the mean error at the true poses); planar
//! hand-eye yaw <= 0.1 degrees and in-plane translation <= 1 cm. The worlds are smaller than
//! the paper's (see each test) so the suite stays fast; BENCHMARKS.md has the full-size
//! figures.

mod calib_common;

use calib_common::{print, run, worst};
use ibc_pipeline::calib::HandEyeSolver;

/// Rotation bar, degrees.
const ROTATION_BAR_DEG: f64 = 0.005;
/// Translation bar, metres.
const TRANSLATION_BAR_M: f64 = 0.001;

fn check_extrinsics(
    name: &str,
    scale: f64,
) -> (
    ibc_pipeline::calib::Calibration,
    ibc_pipeline::calib::Accuracy,
) {
    let (world, calibration, accuracy) = run(name, scale);
    print(name, &calibration, &accuracy);
    assert_eq!(accuracy.cameras.len(), world.log.camera_names.len());
    assert!(accuracy.cameras[0].is_none(), "camera 0 is the reference");
    let (rotation, translation) = worst(&accuracy);
    assert!(
        rotation <= ROTATION_BAR_DEG,
        "{name}: rotation error {rotation} deg"
    );
    assert!(
        translation <= TRANSLATION_BAR_M,
        "{name}: translation error {translation} m"
    );
    let (fin, truth) = (
        calibration.final_error_px(),
        accuracy.reprojection_error_at_truth_px,
    );
    assert!(
        (fin - truth).abs() <= 0.1 * truth,
        "{name}: final {fin} px, noise alone {truth} px"
    );
    // With sigma = 0.5 px per axis, the noise alone gives sigma sqrt(pi / 2) = 0.627 px.
    assert!(
        (truth - 0.5 * (std::f64::consts::PI / 2.0).sqrt()).abs() < 0.02,
        "{truth}"
    );
    (calibration, accuracy)
}

#[test]
fn default_scenario_meets_the_papers_bars() {
    // The garage with the car's four fisheyes at half size: 250 frames of a 150 m loop.
    let (calibration, accuracy) = check_extrinsics("garage", 0.5);
    assert_eq!(calibration.hand_eye_solver, Some(HandEyeSolver::Planar));
    let h = accuracy
        .hand_eye
        .expect("planar odometry gives a hand-eye result");
    assert!(
        h.yaw_error_deg <= 0.1,
        "hand-eye yaw error {} deg",
        h.yaw_error_deg
    );
    assert!(
        h.in_plane_translation_error_m <= 0.01,
        "hand-eye in-plane translation error {} m",
        h.in_plane_translation_error_m
    );
    assert_eq!(
        h.height_error_m, None,
        "the height is unobservable with planar motion"
    );
    // Every image of the exact-map world is localized and every set is complete.
    assert_eq!(
        calibration.localizations.localized_count(),
        calibration.localizations.image_count()
    );
    assert!((calibration.mean_poses_per_set() - 4.0).abs() < 1e-12);
}

#[test]
fn pentagon_rig_meets_the_same_bars() {
    // Ten pinhole cameras in five stereo pairs, the full 300 frames of the garden loop.
    let (calibration, accuracy) = check_extrinsics("garden-pentagon", 1.0);
    assert_eq!(calibration.cameras.len(), 10);
    let h = accuracy
        .hand_eye
        .expect("wheel odometry gives a hand-eye result");
    assert!(h.yaw_error_deg <= 0.1, "{}", h.yaw_error_deg);
    assert!(
        h.in_plane_translation_error_m <= 0.01,
        "{}",
        h.in_plane_translation_error_m
    );
}

#[test]
fn handheld_six_dof_rig_meets_the_same_bars() {
    // Three fisheyes and a 6-DoF pose tracker, walked through the garage (300 frames).
    let (calibration, accuracy) = check_extrinsics("handheld-6dof", 1.0);
    assert_eq!(calibration.hand_eye_solver, Some(HandEyeSolver::Daniilidis));
    let h = accuracy
        .hand_eye
        .expect("the pose tracker gives a hand-eye result");
    assert!(
        h.height_error_m.is_some(),
        "6-DoF motion determines the full translation"
    );
    assert!(h.rotation_error_deg <= 0.1, "{}", h.rotation_error_deg);
    assert!(h.translation_error_m <= 0.01, "{}", h.translation_error_m);
}
