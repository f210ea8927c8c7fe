#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! Intrinsics refined with the extrinsics against the map (issue 18): a camera file whose
//! focal lengths and principal points are off is corrected, a single wrong camera is found
//! alone, and exact intrinsics are left where they are. The lens changes come from the
//! simulator (`CameraChange::lens`): the map was built, and the camera file written, with the
//! old intrinsics; the log is rendered with the new ones.
//!
//! Bars: focal lengths within 0.05 px and principal points within 0.2 px of the truth; the
//! extrinsics within 1 mm, and within 0.005 deg or three of their standard deviations (with
//! the principal points free a rotation is no better than they are: 0.011 deg at 250 frames,
//! against 0.001 deg with them held; see [`assert_extrinsics_within_bars`]); without the
//! refinement the gates name the cameras. The garage at half size (250 frames, sigma 0.5 px).

mod calib_common;

use calib_common::{flagged, print, worst};
use ibc_bundle_adjust::IntrinsicsSelection;
use ibc_pipeline::calib::{
    Accuracy, Calibration, CalibrationOptions, RefinementOptions, Status, calibrate,
};
use ibc_pipeline::sim::{CameraChange, Scenario, SimulatedWorld};

/// The garage at `scale` with `changes` to the lenses, calibrated with `selection`.
fn run(
    scale: f64,
    changes: Vec<CameraChange>,
    selection: IntrinsicsSelection,
) -> (SimulatedWorld, Calibration, Accuracy) {
    let mut scenario = Scenario::builtin("garage").unwrap().with_scale(scale);
    scenario.changes = changes;
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let options = CalibrationOptions {
        refinement: RefinementOptions {
            intrinsics: selection,
            ..Default::default()
        },
        ..Default::default()
    };
    let calibration = calibrate(&world.map, &world.log, &world.map_rig, &options).unwrap();
    let accuracy = calibration.accuracy(&world.truth).unwrap();
    print("garage", &calibration, &accuracy);
    for (c, a) in accuracy.intrinsics.iter().enumerate() {
        if let Some(a) = a {
            println!(
                "  {:<6} focal error {:+.4} {:+.4} px, principal point error {:+.4} {:+.4} px",
                calibration.camera_names[c],
                a.focal_error_px[0],
                a.focal_error_px[1],
                a.principal_point_error_px[0],
                a.principal_point_error_px[1]
            );
        }
    }
    for w in &calibration.quality.warnings {
        println!("  {}: {w}", w.kind());
    }
    (world, calibration, accuracy)
}

/// Every camera's lens: the camera file's focal lengths 1 % long and principal point 3 px
/// right and down of the truth.
fn every_lens_changed() -> Vec<CameraChange> {
    ["front", "left", "rear", "right"]
        .iter()
        .map(|name| CameraChange::lens(name, 1.0 / 1.01 - 1.0, [-3.0, -3.0]))
        .collect()
}

/// With the principal points free, a camera's rotation is only as good as the principal
/// points' standard deviations allow (a horizontal shift of the principal point is nearly a
/// turn of the camera: 0.07 px across a 395 px focal length is 0.010 deg, measured at 250
/// frames), and the reference camera's turn moves the others' centres across the rig's
/// lever arms (0.01 deg over the rear camera's 4 m is 0.7 mm). So the bars are 0.005 deg and
/// 1 mm, or three reported standard deviations (the norm of the per-axis ones), whichever is
/// larger.
fn assert_extrinsics_within_bars(calibration: &Calibration, accuracy: &Accuracy) {
    let stds = calibration.refinement.rig_from_camera_std.clone().unwrap();
    for (c, a) in accuracy.cameras.iter().enumerate() {
        let Some(a) = a else { continue };
        let std_deg = stds[c].rotation_rad.norm().to_degrees();
        let std_m = stds[c].translation_m.norm();
        println!(
            "  camera {c}: rotation {:.5} deg (std {std_deg:.5}), translation {:.3} mm (std {:.3})",
            a.rotation_error_deg,
            a.translation_error_m * 1e3,
            std_m * 1e3
        );
        assert!(
            a.rotation_error_deg <= 0.005f64.max(3.0 * std_deg),
            "camera {c}: rotation error {} deg, std {std_deg} deg",
            a.rotation_error_deg
        );
        assert!(
            a.translation_error_m <= 0.001f64.max(3.0 * std_m),
            "camera {c}: translation error {} m, std {std_m} m",
            a.translation_error_m
        );
    }
}

#[test]
fn a_stale_camera_file_is_corrected_and_named() {
    let (_, calibration, accuracy) = run(
        0.5,
        every_lens_changed(),
        IntrinsicsSelection::FocalAndCenter,
    );
    for (c, a) in accuracy.intrinsics.iter().enumerate() {
        let a = a.unwrap();
        assert!(a.max_focal_error_px() <= 0.05, "camera {c}: {a:?}");
        assert!(a.max_principal_point_error_px() <= 0.2, "camera {c}: {a:?}");
    }
    assert_extrinsics_within_bars(&calibration, &accuracy);
    // Each camera named twice: its focal length and its principal point moved.
    assert_eq!(calibration.quality.status(), Status::Ok);
    for name in &calibration.camera_names {
        let mine = flagged(&calibration)
            .iter()
            .filter(|(k, c)| *k == "intrinsics_changed" && c == name)
            .count();
        assert_eq!(mine, 2, "{name}: {:?}", calibration.quality.warnings);
    }
    let message = calibration.quality.warnings[0].to_string();
    assert!(
        message.contains("focal length 0.99% shorter than its camera file"),
        "{message}"
    );
    // The refined intrinsics are what the calibration carries.
    for (camera, intrinsics) in calibration
        .cameras
        .iter()
        .zip(&calibration.refinement.intrinsics)
    {
        assert_eq!(intrinsics.refined.len(), 4);
        assert!(intrinsics.held.is_empty());
        for p in &intrinsics.refined {
            assert_eq!(
                ibc_camera_models::CameraModel::params(camera)[p.index],
                p.value
            );
            assert!(p.std > 0.0 && p.std < 0.1, "{p:?}");
        }
    }

    // Held intrinsics: the extrinsics are centimetres off and the gates name every camera.
    let (_, held, accuracy) = run(0.5, every_lens_changed(), IntrinsicsSelection::None);
    assert!(worst(&accuracy).1 > 0.01);
    assert_eq!(held.quality.status(), Status::Poor);
    for name in &held.camera_names {
        assert!(
            flagged(&held).contains(&("systematic_residuals", name.clone())),
            "{name}: {:?}",
            held.quality.warnings
        );
    }
}

#[test]
fn one_wrong_focal_length_is_found_and_fixed_alone() {
    let (_, calibration, accuracy) = run(
        0.5,
        vec![CameraChange::lens("left", 1.0 / 1.01 - 1.0, [0.0, 0.0])],
        IntrinsicsSelection::FocalAndCenter,
    );
    assert_eq!(
        flagged(&calibration),
        vec![("intrinsics_changed", "left".to_owned())]
    );
    assert_extrinsics_within_bars(&calibration, &accuracy);
    let left = accuracy.intrinsics[1].unwrap();
    assert!(left.max_focal_error_px() <= 0.05, "{left:?}");
    // The others stay within three standard deviations of their (exact) camera file.
    for (c, intrinsics) in calibration.refinement.intrinsics.iter().enumerate() {
        if c == 1 {
            continue;
        }
        for p in &intrinsics.refined {
            assert!(
                (p.value - p.prior).abs() <= 3.0 * p.std,
                "camera {c}: {p:?}"
            );
        }
    }
}

#[test]
fn refining_exact_intrinsics_changes_nothing_beyond_its_standard_deviations() {
    let (_, held, held_accuracy) = run(0.5, Vec::new(), IntrinsicsSelection::None);
    let (_, free, free_accuracy) = run(0.5, Vec::new(), IntrinsicsSelection::FocalAndCenter);
    assert_eq!(
        free.quality.status(),
        Status::Ok,
        "{:?}",
        free.quality.warnings
    );
    assert!(flagged(&free).is_empty());
    for intrinsics in &free.refinement.intrinsics {
        for p in &intrinsics.refined {
            assert!((p.value - p.prior).abs() <= 3.0 * p.std, "{p:?}");
        }
    }
    assert_extrinsics_within_bars(&free, &free_accuracy);
    // The extrinsics move by less than three of their standard deviations.
    let stds = free.refinement.rig_from_camera_std.clone().unwrap();
    for (c, ((a, b), std)) in held
        .rig_from_camera
        .iter()
        .zip(&free.rig_from_camera)
        .zip(&stds)
        .enumerate()
        .skip(1)
    {
        let moved = a.translation.vector - b.translation.vector;
        for axis in 0..3 {
            assert!(
                moved[axis].abs() <= 3.0 * std.translation_m[axis],
                "camera {c} axis {axis}: {} m against {} m",
                moved[axis],
                std.translation_m[axis]
            );
        }
    }
    // The focal lengths alone free cost the extrinsics nothing measurable: the default bars
    // hold as they do with every intrinsic held.
    let (_, focal, focal_accuracy) = run(0.5, Vec::new(), IntrinsicsSelection::Focal);
    assert_eq!(focal.quality.status(), Status::Ok);
    for (name, accuracy) in [("held", &held_accuracy), ("focal", &focal_accuracy)] {
        let (rotation, translation) = worst(accuracy);
        assert!(rotation <= 0.005, "{name}: {rotation} deg");
        assert!(translation <= 0.001, "{name}: {translation} m");
    }
}
