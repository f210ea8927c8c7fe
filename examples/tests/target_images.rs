#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! Calibration from rendered AprilGrid images (issue 20): detection against the rendered
//! truth, intrinsics from pixels for a pinhole, a 190-degree Kannala-Brandt fisheye and a
//! unified (Mei) fisheye, the extrinsics of a stereo pair from shared views, and bad input.

use ibc_pipeline::ibc_camera_models::{CameraModel, Rig, RigCamera};
use ibc_pipeline::intrinsics::simulate::preset_camera;
use ibc_pipeline::intrinsics::{IntrinsicModel, IntrinsicsOptions, calibrate_intrinsics};
use ibc_pipeline::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use ibc_pipeline::target::command::simulate_scene;
use ibc_pipeline::target::*;
use intrinsics_common::max_projection_difference;

mod intrinsics_common;

/// Kalibr's default grid shrunk to a hand-held size: 6 x 6 tags of 5 cm, 0.3 apart.
fn grid() -> AprilGrid {
    AprilGrid::new(6, 6, 0.05, 0.3).unwrap()
}

fn single(model: IntrinsicModel) -> Rig {
    Rig::new(vec![RigCamera::new(
        "cam0",
        preset_camera(model).unwrap(),
        Isometry3::identity(),
    )])
}

/// Detections of one camera of a simulation, with the camera's index.
fn detect_all(sim: &SimulatedTargetImages, camera: usize) -> Vec<(usize, Detection)> {
    sim.images[camera]
        .iter()
        .enumerate()
        .filter_map(|(t, image)| image.as_ref().map(|i| (t, i)))
        .map(|(t, image)| {
            (
                t,
                detect_april_grid(image, &sim.grid, &sim.times[t]).unwrap(),
            )
        })
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Detection against the rendered truth, also on grids whose tag spacing is not Kalibr's
/// default 0.3 (the board is grown with the grid's own ratio).
#[test]
fn rendered_corners_are_detected_within_a_tenth_of_a_pixel() {
    for (model, grid) in [
        (IntrinsicModel::PinholeRadtan, grid()),
        (IntrinsicModel::KannalaBrandt, grid()),
        (
            IntrinsicModel::PinholeRadtan,
            AprilGrid::new(6, 6, 0.05, 0.2).unwrap(),
        ),
        (
            IntrinsicModel::PinholeRadtan,
            AprilGrid::new(6, 6, 0.05, 0.5).unwrap(),
        ),
    ] {
        let model_spacing = format!("{model:?}, spacing {}", grid.tag_spacing);
        let rig = single(model);
        let options = TargetSimulationOptions {
            views_per_camera: 6,
            seed: 11,
            ..Default::default()
        };
        let sim = simulate_target_images(&rig, &grid, &options).unwrap();
        let target = sim.grid.planar_target();
        let camera = &rig.cameras[0].camera;
        let (mut errors, mut truth_count) = (Vec::new(), 0);
        for (t, detection) in detect_all(&sim, 0) {
            let pose = sim.camera_from_board[0][t].unwrap();
            let truth = rendered_corners(camera, &pose, &target, 2.0);
            truth_count += truth.len();
            for c in &detection.corners {
                let tc = truth.iter().find(|tc| (tc.row, tc.col) == (c.row, c.col));
                // A corner the detector returns must be the one it names (no swapped ids).
                let tc = tc.unwrap_or_else(|| panic!("{model_spacing}: corner {c:?} not in view"));
                errors.push((tc.pixel() - c.pixel()).norm());
            }
            assert_eq!(detection.foreign_tags, 0);
        }
        let found = errors.len() as f64 / truth_count as f64;
        let med = median(errors.clone());
        let max = errors.iter().copied().fold(0.0, f64::max);
        println!(
            "{model_spacing}: {} of {truth_count} corners found, median error {med:.3} px, max \
             {max:.3} px",
            errors.len()
        );
        assert!(med < 0.1, "{model_spacing}: median {med}");
        assert!(max < 0.5, "{model_spacing}: max {max}");
        assert!(found > 0.7, "{model_spacing}: found {found}");
    }
}

/// The corners of every image of camera `camera` as a corner set.
fn corner_set(sim: &SimulatedTargetImages, camera: usize) -> ibc_pipeline::intrinsics::CornerSet {
    let cam = &sim.rig.cameras[camera].camera;
    ibc_pipeline::intrinsics::CornerSet {
        width: cam.width(),
        height: cam.height(),
        board: Some(sim.grid.planar_target()),
        images: detect_all(sim, camera)
            .into_iter()
            .map(|(t, d)| ibc_pipeline::intrinsics::ImageCorners {
                name: sim.times[t].clone(),
                corners: d.corners,
            })
            .collect(),
    }
}

#[test]
fn intrinsics_from_rendered_images_are_within_a_tenth_of_a_pixel() {
    for (model, max_deg) in [
        (IntrinsicModel::PinholeRadtan, 90.0),
        (IntrinsicModel::KannalaBrandt, 80.0),
        (IntrinsicModel::Unified, 80.0),
    ] {
        let rig = single(model);
        let options = TargetSimulationOptions {
            // The unified model's xi, gamma and k1 trade off against each other: from the
            // same 24 views its projection differed from the truth by up to 0.114 px within
            // 80 degrees (the other models 0.02-0.06 px); 40 views bring it to 0.061 px.
            views_per_camera: if model == IntrinsicModel::Unified {
                40
            } else {
                24
            },
            seed: 5,
            placement: ibc_pipeline::intrinsics::simulate::BoardSimulationOptions {
                max_incidence_deg: Some(if model == IntrinsicModel::PinholeRadtan {
                    90.0
                } else {
                    85.0
                }),
                ..TargetSimulationOptions::default().placement
            },
            ..Default::default()
        };
        let sim = simulate_target_images(&rig, &grid(), &options).unwrap();
        let corners = corner_set(&sim, 0);
        let target = sim.grid.planar_target();
        let cal =
            calibrate_intrinsics(&corners, &target, model, &IntrinsicsOptions::default()).unwrap();
        let truth = &rig.cameras[0].camera;
        let (t, e) = (truth.params(), cal.camera.params());
        // Every model keeps [.., fx, fy, cx, cy] last.
        let f = t.len() - 4;
        let f_err = (e[f] - t[f]).abs().max((e[f + 1] - t[f + 1]).abs());
        let c_err = (e[f + 2] - t[f + 2]).abs().max((e[f + 3] - t[f + 3]).abs());
        let field = max_projection_difference(truth, &cal.camera, max_deg);
        println!(
            "{model:?}: {} images, rms {:.3} px, focal error {f_err:.3} px, centre error {c_err:.3} px, \
             largest projection difference within {max_deg} deg {field:.3} px, std f {:.3} c {:.3}",
            corners.images.len(),
            cal.rms_px,
            cal.std_devs[f],
            cal.std_devs[f + 2]
        );
        assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
        assert!(c_err < 0.1, "{model:?}: {c_err}");
        // The unified model's gamma trades off against xi (standard deviation well above
        // 0.1 px, see intrinsics_accuracy.rs): its bar is the projection below, and gamma
        // within 4 standard deviations.
        if model == IntrinsicModel::Unified {
            assert!(f_err < 4.0 * cal.std_devs[f], "{model:?}: {f_err}");
        } else {
            assert!(f_err < 0.1, "{model:?}: {f_err}");
        }
        assert!(field < 0.1, "{model:?}: {field}");
    }
}

/// A stereo pair: the right camera 11 cm to the right, turned 2 degrees about y.
fn stereo(model: IntrinsicModel) -> Rig {
    let camera = preset_camera(model).unwrap();
    let right = Isometry3::from_parts(
        Translation3::new(0.11, 0.002, -0.001),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 2f64.to_radians()),
    );
    Rig::new(vec![
        RigCamera::new("left", camera.clone(), Isometry3::identity()),
        RigCamera::new("right", camera, right),
    ])
}

/// Worst rotation (degrees) and translation (metres) error of the extrinsics.
fn extrinsic_errors(truth: &Rig, estimate: &[Isometry3<f64>]) -> (f64, f64) {
    truth
        .cameras
        .iter()
        .zip(estimate)
        .map(|(t, e)| {
            let d = t.rig_from_camera.inverse() * e;
            (d.rotation.angle().to_degrees(), d.translation.vector.norm())
        })
        .fold((0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)))
}

#[test]
fn a_stereo_pair_is_calibrated_from_shared_views() {
    let rig = stereo(IntrinsicModel::PinholeRadtan);
    let options = TargetSimulationOptions {
        views_per_camera: 12,
        seed: 21,
        ..Default::default()
    };
    let sim = simulate_target_images(&rig, &grid(), &options).unwrap();
    let cameras: Vec<CameraCorners> = (0..2)
        .map(|c| CameraCorners {
            name: rig.cameras[c].name.clone(),
            model: IntrinsicModel::PinholeRadtan,
            corners: corner_set(&sim, c),
        })
        .collect();
    let cal = calibrate_rig_from_target(
        &cameras,
        &sim.grid.planar_target(),
        &TargetCalibrationOptions::default(),
    )
    .unwrap();
    let (rot, trans) = extrinsic_errors(&rig, &cal.rig_from_camera);
    let (rot0, trans0) = extrinsic_errors(&rig, &cal.initial_rig_from_camera);
    let std = cal.extrinsic_std[1].unwrap();
    println!(
        "stereo: {} shared views, {} times, rms {:?} px; extrinsic error {rot:.4} deg / {:.3} mm \
         (from the shared views alone {rot0:.4} deg / {:.3} mm), std {:.4} deg / {:.3} mm",
        cal.links[1].shared_views,
        cal.times,
        cal.rms_px,
        trans * 1e3,
        trans0 * 1e3,
        std.0,
        std.1 * 1e3
    );
    assert!(cal.warnings().is_empty(), "{:?}", cal.warnings());
    assert!(rot < 0.01 && trans < 0.5e-3, "{rot} deg {trans} m");
    for (c, truth) in rig.cameras.iter().enumerate() {
        let field = max_projection_difference(&truth.camera, &cal.cameras[c], 90.0);
        assert!(field < 0.1, "{}: {field}", truth.name);
    }
}

/// A car's four cameras looking front, left, back and right from a 2 m x 1 m rectangle
/// (x forward, y left, z up in the rig frame; each camera's z along its view, y down), each
/// about 90 degrees wide: no two ever see one board.
fn car_rig() -> Rig {
    let camera = preset_camera(IntrinsicModel::PinholeRadtan).unwrap();
    let look = |yaw_deg: f64| {
        // Camera z forward, x right, y down, turned by yaw about the rig's z (up).
        let base =
            UnitQuaternion::from_basis_unchecked(&[-Vector3::y(), -Vector3::z(), Vector3::x()]);
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians()) * base
    };
    let place = |name: &str, x: f64, y: f64, z: f64, yaw: f64| {
        RigCamera::new(
            name,
            camera.clone(),
            Isometry3::from_parts(Translation3::new(x, y, z), look(yaw)),
        )
    };
    Rig::new(vec![
        place("front", 1.0, 0.0, 0.6, 0.0),
        place("left", 0.1, 0.5, 0.9, 90.0),
        place("rear", -1.0, 0.02, 0.7, 180.0),
        place("right", 0.12, -0.5, 0.92, -90.0),
    ])
}

#[test]
fn cameras_that_never_share_a_view_are_calibrated_from_the_rigs_motion() {
    let rig = car_rig();
    let sim = simulate_static_boards(
        &rig,
        &grid(),
        &StaticBoardOptions {
            times: 40,
            seed: 3,
            ..Default::default()
        },
    )
    .unwrap();
    // The rig frame is the front camera's, as the calibration's.
    let front = rig.cameras[0].rig_from_camera.inverse();
    let truth = Rig::new(
        rig.cameras
            .iter()
            .map(|c| RigCamera::new(c.name.clone(), c.camera.clone(), front * c.rig_from_camera))
            .collect(),
    );
    let cameras: Vec<CameraCorners> = (0..4)
        .map(|c| CameraCorners {
            name: rig.cameras[c].name.clone(),
            model: IntrinsicModel::PinholeRadtan,
            corners: corner_set(&sim, c),
        })
        .collect();
    for c in &cameras {
        let seen = c
            .corners
            .images
            .iter()
            .filter(|i| !i.corners.is_empty())
            .count();
        println!("{}: {seen} images with corners", c.name);
    }
    let cal = calibrate_rig_from_target(
        &cameras,
        &sim.grid.planar_target(),
        &TargetCalibrationOptions::default(),
    )
    .unwrap();
    assert!(cal.warnings().is_empty(), "{:?}", cal.warnings());
    assert!(cal.overlaps.is_empty(), "{:?}", cal.overlaps);
    assert!(
        cal.links.iter().skip(1).all(|l| l.hand_eye),
        "{:?}",
        cal.links
    );
    let (rot, trans) = extrinsic_errors(&truth, &cal.rig_from_camera);
    let (rot0, trans0) = extrinsic_errors(&truth, &cal.initial_rig_from_camera);
    println!(
        "car rig: {} times, rms {:?} px; extrinsic error {rot:.4} deg / {:.3} mm (hand-eye alone \
         {rot0:.4} deg / {:.3} mm), std {:?}",
        cal.times,
        cal.rms_px,
        trans * 1e3,
        trans0 * 1e3,
        cal.extrinsic_std
    );
    assert!(cal.converged);
    assert!(rot < 0.01 && trans < 0.5e-3, "{rot} deg {trans} m");
}

/// The same image gives the same corners on every call. The detection crate's own entry point
/// chose its start orientation by hash-map order, so on these fisheye views one image gave 24
/// corners in one run and 72 in another (a test of four Kannala-Brandt views here had passed
/// by luck); the detection composed in `ibc` orders every choice.
#[test]
fn detection_gives_the_same_corners_every_time() {
    let sim = simulate_scene("mei", 0, None).unwrap();
    let images: Vec<_> = sim.images[0].iter().flatten().collect();
    assert!(images.len() >= 30, "{}", images.len());
    let mut found = 0;
    for (k, image) in images.iter().enumerate() {
        let first = detect_april_grid(image, &sim.grid, "view").unwrap();
        for _ in 0..3 {
            assert_eq!(
                detect_april_grid(image, &sim.grid, "view").unwrap(),
                first,
                "view {k}"
            );
        }
        found += first.corners.len();
    }
    // Most views see most of the board (6 x 6 tags, 144 corners).
    assert!(
        found > 60 * images.len(),
        "{found} corners in {} views",
        images.len()
    );
}
