//! Shared helpers of the `calib_*` integration tests.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use ibc_pipeline::calib::accuracy::relative_to_first;
use ibc_pipeline::calib::{Accuracy, Calibration, CalibrationOptions, calibrate};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

/// A built-in scenario simulated at `scale`, calibrated with the default options, and scored.
pub fn run(name: &str, scale: f64) -> (SimulatedWorld, Calibration, Accuracy) {
    run_with(name, scale, &CalibrationOptions::default())
}

/// As [`run`] with the given options.
pub fn run_with(
    name: &str,
    scale: f64,
    options: &CalibrationOptions,
) -> (SimulatedWorld, Calibration, Accuracy) {
    let scenario = Scenario::builtin(name).unwrap().with_scale(scale);
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let calibration = calibrate(&world.map, &world.log, &world.map_rig, options).unwrap();
    let accuracy = calibration.accuracy(&world.truth).unwrap();
    (world, calibration, accuracy)
}

/// The largest rotation error (degrees) and translation error (metres) over the cameras.
pub fn worst(accuracy: &Accuracy) -> (f64, f64) {
    accuracy
        .cameras
        .iter()
        .flatten()
        .fold((0.0f64, 0.0f64), |(r, t), a| {
            (r.max(a.rotation_error_deg), t.max(a.translation_error_m))
        })
}

/// Prints the per-camera errors (shown with `--nocapture`).
pub fn print(name: &str, calibration: &Calibration, accuracy: &Accuracy) {
    println!(
        "{name}: {} frame sets, {} correspondences, reprojection {:.4} -> {:.4} px (truth {:.4})",
        calibration.frame_sets_used(),
        calibration.correspondences(),
        calibration.initial_error_px(),
        calibration.final_error_px(),
        accuracy.reprojection_error_at_truth_px
    );
    for (c, a) in accuracy.cameras.iter().enumerate() {
        if let Some(a) = a {
            println!(
                "  {:<12} rotation {:.5} deg, direction {:.4} deg, translation {:.3} mm",
                calibration.camera_names[c],
                a.rotation_error_deg,
                a.translation_error_deg,
                a.translation_error_m * 1000.0
            );
        }
    }
    if let Some(h) = &accuracy.hand_eye {
        println!(
            "  hand-eye: rotation {:.4} deg, yaw {:.4} deg, in-plane {:.2} mm, translation {:.2} mm",
            h.rotation_error_deg,
            h.yaw_error_deg,
            h.in_plane_translation_error_m * 1000.0,
            h.translation_error_m * 1000.0
        );
    }
}

/// The change of camera `camera` between two rigs, relative to camera 0: (rotation angle in
/// degrees, translation of the camera centre in the camera-0 frame).
pub fn change(
    before: &[nalgebra::Isometry3<f64>],
    after: &[nalgebra::Isometry3<f64>],
    camera: usize,
) -> (nalgebra::UnitQuaternion<f64>, nalgebra::Vector3<f64>) {
    let (b, a) = (relative_to_first(before), relative_to_first(after));
    (
        b[camera].rotation.inverse() * a[camera].rotation,
        a[camera].translation.vector - b[camera].translation.vector,
    )
}

/// The kind and camera of every warning of a calibration.
pub fn flagged(calibration: &Calibration) -> Vec<(&'static str, String)> {
    calibration
        .quality
        .warnings
        .iter()
        .map(|w| (w.kind(), w.camera().unwrap_or("").to_owned()))
        .collect()
}
