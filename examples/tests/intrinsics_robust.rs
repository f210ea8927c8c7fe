//! Corners that do not fit (issue 14): a garbage view is excluded, a few wrong corners are
//! found and excluded without moving the intrinsics, an image with too few corners is
//! skipped, and a calibration the data do not support is marked poor, with its own exit code
//! through `ibc intrinsics`.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod intrinsics_common;

use ibc_camera_models::CameraModel;
use ibc_pipeline::intrinsics::simulate::BoardSimulationOptions;
use ibc_pipeline::intrinsics::{
    ImageStatus, IntrinsicCalibration, IntrinsicModel, IntrinsicsOptions, IntrinsicsStatus,
    IntrinsicsWarning, calibrate_intrinsics,
};
use intrinsics_common::{simulated, simulated_with};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const MODELS: [IntrinsicModel; 2] = [IntrinsicModel::KannalaBrandt, IntrinsicModel::PinholeRadtan];

fn calibrate(
    corners: &ibc_pipeline::intrinsics::CornerSet,
    model: IntrinsicModel,
) -> IntrinsicCalibration {
    calibrate_intrinsics(
        corners,
        &corners.board.unwrap(),
        model,
        &IntrinsicsOptions::default(),
    )
    .unwrap()
}

/// The largest difference between two calibrations' parameters in units of the first's
/// standard deviations.
fn sigmas_apart(a: &IntrinsicCalibration, b: &IntrinsicCalibration) -> f64 {
    (0..8)
        .map(|i| (a.camera.params()[i] - b.camera.params()[i]).abs() / a.std_devs[i])
        .fold(0.0, f64::max)
}

#[test]
fn a_view_of_garbage_corners_is_excluded() {
    for model in MODELS {
        let sim = simulated(model, 6, 9, 11);
        let clean = calibrate(&sim.corners, model);
        assert_eq!(clean.status(), IntrinsicsStatus::Ok, "{:?}", clean.warnings);
        assert_eq!(clean.outlier_corners, 0);
        // View 7's corners replaced by random pixels of the image (a detector that matched
        // the wrong pattern).
        let mut corners = sim.corners.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (w, h) = (f64::from(corners.width), f64::from(corners.height));
        for c in &mut corners.images[7].corners {
            c.u = rng.random_range(0.0..w - 1.0);
            c.v = rng.random_range(0.0..h - 1.0);
        }
        let robust = calibrate(&corners, model);
        assert_eq!(
            robust.per_image[7].status,
            ImageStatus::Outliers,
            "{model:?}"
        );
        assert!(
            robust
                .per_image
                .iter()
                .enumerate()
                .all(|(i, e)| i == 7 || e.status == ImageStatus::Used)
        );
        // The other views calibrate as if the garbage had never been there.
        let apart = sigmas_apart(&clean, &robust);
        println!(
            "{model:?}: garbage view excluded, {apart:.3} sigma from the clean calibration, RMS {:.3} px",
            robust.rms_px
        );
        assert!(apart < 1.0, "{model:?}: {apart} sigma");
        assert!(robust.rms_px < 1.2 * clean.rms_px);
        assert_eq!(
            robust.status(),
            IntrinsicsStatus::Ok,
            "{:?}",
            robust.warnings
        );
    }
}

#[test]
fn a_few_wrong_corners_are_found_and_do_not_move_the_intrinsics() {
    for model in MODELS {
        let sim = simulated(model, 6, 9, 12);
        let clean = calibrate(&sim.corners, model);
        // Six corners in six views displaced by 4 to 12 px: a reflection, a mismatch.
        let mut corners = sim.corners.clone();
        let moved = [
            (1, 3, 4.0),
            (4, 10, -6.0),
            (6, 20, 8.0),
            (9, 7, -10.0),
            (13, 30, 12.0),
            (16, 2, 5.0),
        ];
        for &(image, corner, shift) in &moved {
            corners.images[image].corners[corner].u += shift;
            corners.images[image].corners[corner].v -= 0.5 * shift;
        }
        let robust = calibrate(&corners, model);
        for &(image, corner, _) in &moved {
            assert!(
                robust.per_image[image].residuals[corner].outlier,
                "{model:?}: image {image} corner {corner}"
            );
        }
        assert_eq!(
            robust.outlier_corners,
            moved.len(),
            "{model:?}: only the moved corners"
        );
        let apart = sigmas_apart(&clean, &robust);
        println!(
            "{model:?}: 6 wrong corners excluded, {apart:.3} sigma from the clean calibration"
        );
        assert!(apart < 0.5, "{model:?}: {apart} sigma");
        assert_eq!(robust.status(), IntrinsicsStatus::Ok);
        // Every corner's residual is reported, the outliers flagged.
        let listed: usize = robust.per_image.iter().map(|e| e.residuals.len()).sum();
        assert_eq!(listed, corners.num_corners());
    }
}

#[test]
fn a_calibration_the_data_do_not_support_is_poor() {
    // Corners far noisier than a detector's: the RMS gate.
    let model = IntrinsicModel::PinholeRadtan;
    let options = BoardSimulationOptions {
        noise_px: 3.0,
        ..BoardSimulationOptions::for_model(model)
    };
    let noisy = calibrate(&simulated_with(model, 6, 9, &options).corners, model);
    assert_eq!(noisy.status(), IntrinsicsStatus::Poor);
    assert!(
        noisy
            .warnings
            .iter()
            .any(|w| matches!(w, IntrinsicsWarning::HighRms { .. })),
        "{:?}",
        noisy.warnings
    );
    // Three views of a small board barely tilted (3 to 6 degrees): the focal length is not
    // determined. (At 8 to 12 degrees Zhang's start fell into a false minimum that was flagged
    // too; the centred start finds the true one, determined to 0.8 %, within the gate.)
    let options = BoardSimulationOptions {
        views: 3,
        max_tilt_deg: 6.0,
        min_tilt_deg: 3.0,
        noise_px: 0.5,
        ..BoardSimulationOptions::for_model(model)
    };
    let weak = calibrate(&simulated_with(model, 4, 5, &options).corners, model);
    println!(
        "weak: std {:?}, warnings {:?} init {:?} params {:?}",
        weak.std_devs, weak.warnings, weak.initialization, weak.camera
    );
    assert!(
        weak.warnings
            .iter()
            .any(|w| matches!(w, IntrinsicsWarning::Undetermined { .. })),
        "{:?}",
        weak.warnings
    );
}

#[test]
fn ibc_intrinsics_exits_3_on_a_poor_calibration_and_is_quiet_when_asked() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("noisy");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ibc"))
        .args([
            "intrinsics",
            "--simulate",
            "--model",
            "pinhole",
            "--noise",
            "3",
            "--quiet",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{stderr}");
    assert!(o.stdout.is_empty(), "--quiet prints nothing");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("intrinsics_report.json")).unwrap())
            .unwrap();
    assert_eq!(report["status"], "poor");
    assert_eq!(report["warnings"][0]["kind"], "high_rms");
    assert!(report["images"][0]["residuals"][0]["du"].is_number());
    let plot = std::fs::read_to_string(out.join("residuals.svg")).unwrap();
    for label in [
        ">u [px]<",
        ">v [px]<",
        "outlier corner (excluded)",
        "principal point",
    ] {
        assert!(plot.contains(label), "residual plot: {label}");
    }
    let ok = dir.path().join("ok");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_ibc"))
        .args(["intrinsics", "--simulate", "--model", "kb", "--out"])
        .arg(&ok)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("status: ok"));
}
