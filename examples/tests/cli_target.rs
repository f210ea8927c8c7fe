#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! `ibc target` through the binary (issue 20): a simulated stereo pair rendered, detected and
//! calibrated end to end with its files, and a unified (Mei) fisheye; and bad input: an unreadable image, images without
//! the target, a target file that disagrees with the images, a target that is not an
//! AprilGrid. Each failure is one line naming the culprit, a non-zero exit, and nothing
//! written.

mod cli_common;

use std::path::Path;

use cli_common::{check_failure, entries, ibc, stderr, stdout};
use ibc_pipeline::ibc_camera_models::Rig;
use ibc_pipeline::nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// `ibc target --simulate stereo` into `dir/sim`: the images and target file it rendered.
fn stereo_images(dir: &Path) -> (String, String) {
    let out = dir.join("sim");
    let o = ibc(&[
        "target",
        "--simulate",
        "stereo",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let images = out.join("images");
    let target = images.join("target.yaml");
    (
        images.to_str().unwrap().to_owned(),
        target.to_str().unwrap().to_owned(),
    )
}

/// Runs `ibc` with `--json` among `args`, which must succeed with status `ok`: its report.
fn ok_report(args: &[&str]) -> serde_json::Value {
    let o = ibc(args);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(report["status"], "ok", "{report}");
    report
}

#[test]
fn a_rendered_stereo_pair_is_calibrated_from_its_image_folders() {
    let dir = tempfile::tempdir().unwrap();
    let (images, target) = stereo_images(dir.path());
    let out = dir.path().join("out");
    let report = ok_report(&[
        "target",
        "--images",
        &images,
        "--target",
        &target,
        "--model",
        "left=pinhole,right=pinhole",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    let right = &report["cameras"][1];
    assert_eq!(right["linked_by"], "shared_views");
    // Against the truth the simulation wrote (left is the rig frame in both).
    let truth = Rig::read_kalibr(dir.path().join("sim").join("truth_camchain.yaml")).unwrap();
    let t = truth.cameras[1].rig_from_camera;
    let q = &right["rig_from_camera"]["quaternion_xyzw"];
    let p = &right["rig_from_camera"]["translation_m"];
    let estimate = Isometry3::from_parts(
        Translation3::new(
            p[0].as_f64().unwrap(),
            p[1].as_f64().unwrap(),
            p[2].as_f64().unwrap(),
        ),
        UnitQuaternion::from_quaternion(Quaternion::new(
            q[3].as_f64().unwrap(),
            q[0].as_f64().unwrap(),
            q[1].as_f64().unwrap(),
            q[2].as_f64().unwrap(),
        )),
    );
    let d = t.inverse() * estimate;
    assert!(d.rotation.angle().to_degrees() < 0.01, "{d:?}");
    assert!(d.translation.vector.norm() < 0.5e-3, "{d:?}");
    let mut files = entries(&out);
    files.sort();
    assert_eq!(
        files,
        [
            "camchain.yaml",
            "left_camera_calib.yaml",
            "left_residuals.svg",
            "rig_top_view.svg",
            "right_camera_calib.yaml",
            "right_residuals.svg",
            "target_report.json"
        ]
    );
    let top = std::fs::read_to_string(out.join("rig_top_view.svg")).unwrap();
    assert!(
        top.starts_with("<svg") && top.contains("right (std"),
        "{top}"
    );
    // The camchain says which cameras overlap and reads back.
    let chain = Rig::read_kalibr(out.join("camchain.yaml")).unwrap();
    assert_eq!(chain.cameras[0].overlaps, vec![1]);
    assert_eq!(chain.cameras[1].topic.as_deref(), Some("/right/image_raw"));
}

/// A 190-degree unified (Mei) lens from its rendered images through the whole command: the
/// model's own initialization, the joint refinement with 9 intrinsics, and Kalibr's `omni`.
#[test]
fn a_rendered_unified_fisheye_is_calibrated_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mei");
    let report = ok_report(&[
        "target",
        "--simulate",
        "mei",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]);
    let camera = &report["cameras"][0];
    assert_eq!(camera["model"], "mei");
    let error = |i: usize| camera["error"]["params"][i].as_f64().unwrap().abs();
    let std = |i: usize| camera["param_std"][i].as_f64().unwrap();
    // xi, and gamma1 and gamma2 (which trade off against xi) within 4 standard deviations; the
    // principal point within 0.1 px.
    for i in [0, 5, 6] {
        assert!(
            error(i) < 4.0 * std(i),
            "parameter {i}: {} vs {}",
            error(i),
            std(i)
        );
    }
    assert!(error(7) < 0.1 && error(8) < 0.1, "{camera}");
    let chain = std::fs::read_to_string(out.join("camchain.yaml")).unwrap();
    assert!(chain.contains("camera_model: omni"), "{chain}");
}

#[test]
fn bad_images_and_target_files_are_named_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let (images, target) = stereo_images(dir.path());
    let out = dir.path().join("out");
    let run = |images: &str, target: &str| {
        ibc(&[
            "target",
            "--images",
            images,
            "--target",
            target,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    // A target file for a grid of 2 x 2 tags: the images show 36.
    let small = dir.path().join("small.yaml");
    std::fs::write(
        &small,
        "target_type: 'aprilgrid'\ntagCols: 2\ntagRows: 2\ntagSize: 0.05\ntagSpacing: 0.3\n",
    )
    .unwrap();
    check_failure(
        &run(&images, small.to_str().unwrap()),
        &["`left`", "2 x 2", "disagrees"],
    );
    // A chessboard definition.
    let chess = dir.path().join("chess.yaml");
    std::fs::write(
        &chess,
        "target_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\n",
    )
    .unwrap();
    check_failure(
        &run(&images, chess.to_str().unwrap()),
        &["chess.yaml", "checkerboard"],
    );
    // An image file that is not an image.
    let broken = dir.path().join("broken");
    std::fs::create_dir_all(broken.join("cam0")).unwrap();
    std::fs::write(broken.join("cam0").join("t0000.png"), b"not a png").unwrap();
    check_failure(
        &run(broken.to_str().unwrap(), &target),
        &["t0000.png", "not a readable image"],
    );
    // Images without the target.
    let blank = dir.path().join("blank");
    std::fs::create_dir_all(blank.join("cam0")).unwrap();
    for k in 0..3 {
        image::GrayImage::from_pixel(64, 48, image::Luma([128]))
            .save(blank.join("cam0").join(format!("t{k}.png")))
            .unwrap();
    }
    check_failure(
        &run(blank.to_str().unwrap(), &target),
        &["`cam0`", "no AprilGrid", "3 images"],
    );
    // A folder without images.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    check_failure(
        &run(empty.to_str().unwrap(), &target),
        &["empty", "no images"],
    );
    assert!(entries(&out).is_empty(), "{:?}", entries(&out));
}
