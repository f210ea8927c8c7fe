//! CamOdoCal and Kalibr files: reading, writing, round trips, and bad files.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use ibc_camera_models::camodocal::{
    format_camera, format_extrinsics, parse_camera, parse_extrinsics, read_camera, write_camera,
};
use ibc_camera_models::{Camera, CameraFileError, CameraModel, Rig, RigCamera};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

/// CamOdoCal's Kannala-Brandt test camera as OpenCV FileStorage writes it.
const CAMODOCAL_KB: &str = "%YAML:1.0
---
model_type: KANNALA_BRANDT
camera_name: camera
image_width: 1280
image_height: 800
projection_parameters:
   k2: -1.6480000000000000e-02
   k3: -2.0300000000000001e-03
   k4: 6.8999999999999997e-04
   k5: -4.8000000000000001e-04
   mu: 4.1922826000000000e+02
   mv: 4.2042160000000001e+02
   u0: 6.5545487000000003e+02
   v0: 3.8966377000000000e+02
";

const CAMODOCAL_MEI: &str = "%YAML:1.0
---
model_type: MEI
camera_name: camera
image_width: 1280
image_height: 800
mirror_parameters:
   xi: 8.9497500000000003e-01
distortion_parameters:
   k1: -3.4450400000000000e-01
   k2: 9.8455199999999998e-02
   p1: -4.0399500000000003e-03
   p2: 6.1036400000000002e-03
projection_parameters:
   gamma1: 7.5835500000000002e+02
   gamma2: 7.5761500000000001e+02
   u0: 6.4672000000000003e+02
   v0: 3.9500100000000003e+02
";

/// The TrimBot2020 camchain (`tests/data/README.md`).
const TRIMBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/trimbot-camchain.yaml"
);

fn trimbot() -> String {
    std::fs::read_to_string(TRIMBOT).expect("the Kalibr fixture in tests/data")
}

#[test]
fn camodocal_yaml_reads_the_opencv_header_and_matches_the_fixtures() {
    let kb = parse_camera(CAMODOCAL_KB).unwrap();
    assert_eq!(kb.name, "camera");
    assert_eq!(kb.camera, Camera::from(common::camodocal_kb()));
    let mei = parse_camera(CAMODOCAL_MEI).unwrap();
    for (a, b) in mei
        .camera
        .params()
        .iter()
        .zip(common::camodocal_mei().params())
    {
        approx::assert_relative_eq!(*a, *b, max_relative = 1e-15);
    }
    // Case-insensitive model names, and k2..k5 under distortion_parameters.
    let moved = CAMODOCAL_KB
        .replace("KANNALA_BRANDT", "kannala_brandt")
        .replace(
            "projection_parameters:\n   k2",
            "distortion_parameters:\n   k2",
        )
        .replace("   mu:", "projection_parameters:\n   mu:");
    assert_eq!(parse_camera(&moved).unwrap().camera, kb.camera);
}

#[test]
fn camodocal_yaml_round_trips_every_model_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for (name, camera) in common::all_cameras() {
        let text = format_camera(name, &camera);
        assert!(text.starts_with("%YAML:1.0\n---\n"));
        let back = parse_camera(&text).unwrap();
        assert_eq!(back.name, name);
        // 17 significant digits: every parameter comes back bit for bit.
        assert_eq!(back.camera.params(), camera.params(), "{name}");
        let path = dir.path().join(format!("{name}_camera_calib.yaml"));
        write_camera(&path, name, &camera).unwrap();
        assert_eq!(read_camera(&path).unwrap().camera, camera);
    }
}

#[test]
fn camodocal_yaml_errors_name_the_problem() {
    let missing = CAMODOCAL_KB.replace("   mu: 4.1922826000000000e+02\n", "");
    match parse_camera(&missing) {
        Err(CameraFileError::MissingKey { key }) => assert_eq!(key, "projection_parameters.mu"),
        other => panic!("{other:?}"),
    }
    let unknown = CAMODOCAL_KB.replace("KANNALA_BRANDT", "FISHEYE_9000");
    assert!(matches!(
        parse_camera(&unknown),
        Err(CameraFileError::UnknownModel { .. })
    ));
    let scaramuzza = CAMODOCAL_KB.replace("KANNALA_BRANDT", "SCARAMUZZA");
    assert!(matches!(
        parse_camera(&scaramuzza),
        Err(CameraFileError::UnsupportedModel { .. })
    ));
    let wrong_type = CAMODOCAL_KB.replace("mu: 4.1922826000000000e+02", "mu: [1, 2]");
    assert!(matches!(
        parse_camera(&wrong_type),
        Err(CameraFileError::WrongType { .. })
    ));
    let bad_focal = CAMODOCAL_KB.replace("mu: 4.1922826000000000e+02", "mu: -4.0");
    assert!(matches!(
        parse_camera(&bad_focal),
        Err(CameraFileError::Parameters { .. })
    ));
    assert!(matches!(parse_camera(""), Err(CameraFileError::Empty)));
    assert!(matches!(
        parse_camera("%YAML:1.0\n---\n"),
        Err(CameraFileError::Empty)
    ));
    assert!(matches!(
        parse_camera("model_type: [unclosed"),
        Err(CameraFileError::Yaml { .. })
    ));
    // Every truncation of the file is an error or (past the last key) the camera: no panic.
    for cut in 0..CAMODOCAL_MEI.len() {
        if let Ok(c) = parse_camera(&CAMODOCAL_MEI[..cut]) {
            assert!(
                cut > CAMODOCAL_MEI.len() - 30,
                "accepted a truncated file at {cut}"
            );
            assert_eq!(c.camera.num_params(), 9);
        }
    }
    assert!(matches!(
        read_camera("/nonexistent/x.yaml"),
        Err(CameraFileError::Io { .. })
    ));
}

#[test]
fn extrinsic_txt_round_trips_and_rejects_bad_rows() {
    let a = Isometry3::from_parts(
        Translation3::new(0.1, -0.2, 0.3),
        UnitQuaternion::from_euler_angles(0.1, -0.7, 2.9),
    );
    let b = Isometry3::identity();
    let text = format_extrinsics([("front", &a), ("rear", &b)]);
    let back = parse_extrinsics(&text).unwrap();
    assert_eq!(back.len(), 2);
    assert_eq!(back[0].0, "front");
    assert!(
        (back[0].1.to_homogeneous() - a.to_homogeneous())
            .abs()
            .max()
            < 1e-15
    );
    // CamOdoCal writes 10 decimals; its files read too.
    let camodocal = "cam_a\n1.0000000000 0.0000000000 0.0000000000 0.5000000000\n\
                     0.0000000000 1.0000000000 0.0000000000 0.0000000000\n\
                     0.0000000000 0.0000000000 1.0000000000 0.0000000000\n\n";
    let p = parse_extrinsics(camodocal).unwrap();
    assert_eq!(p[0].1.translation.vector, Vector3::new(0.5, 0.0, 0.0));
    let truncated = &text[..text.len() / 3];
    assert!(matches!(
        parse_extrinsics(truncated),
        Err(CameraFileError::Malformed { .. })
    ));
    let nan = "x\nnan 0 0 0\n0 1 0 0\n0 0 1 0\n";
    assert!(matches!(
        parse_extrinsics(nan),
        Err(CameraFileError::Malformed { .. })
    ));
    let not_rigid = "x\n2 0 0 0\n0 1 0 0\n0 0 1 0\n";
    assert!(matches!(
        parse_extrinsics(not_rigid),
        Err(CameraFileError::Malformed { .. })
    ));
}

#[test]
fn trimbot_camchain_reads_converts_and_round_trips() {
    let rig = Rig::from_kalibr_str(&trimbot()).unwrap();
    assert_eq!(rig.cameras.len(), 2);
    let cam0 = rig.cameras[0].camera.as_pinhole_radtan().unwrap();
    assert_eq!(cam0.fx(), 538.3498428066779);
    assert_eq!(cam0.distortion()[0], -0.35995268092519617);
    assert_eq!((cam0.width(), cam0.height()), (752, 480));
    assert_eq!(
        rig.cameras[1].topic.as_deref(),
        Some("/uvc_camera/cam_1/image_raw")
    );
    assert_eq!(rig.cameras[0].overlaps, vec![1, 2, 3, 8, 9]);
    // cam1's T_cn_cnm1 maps cam0 into cam1: rig (= cam0) from cam1 is its inverse, a 3 cm
    // baseline.
    let cam1_from_cam0 = rig.camera_from_camera("cam1", "cam0").unwrap();
    assert!((cam1_from_cam0.translation.vector.x + 0.03170587862687098).abs() < 1e-15);
    let baseline = rig.cameras[1].rig_from_camera.translation.vector.norm();
    assert!((baseline - 0.0317).abs() < 1e-3, "{baseline}");

    // Kalibr -> text -> Kalibr: intrinsics bit for bit, poses to 1e-15.
    let again = Rig::from_kalibr_str(&rig.to_kalibr_string()).unwrap();
    for (a, b) in rig.cameras.iter().zip(&again.cameras) {
        assert_eq!(a.camera, b.camera);
        assert_eq!((&a.topic, &a.overlaps), (&b.topic, &b.overlaps));
        let d = a.rig_from_camera.to_homogeneous() - b.rig_from_camera.to_homogeneous();
        assert!(d.abs().max() < 1e-15);
    }
    // Kalibr -> CamOdoCal directory -> Kalibr file.
    let dir = tempfile::tempdir().unwrap();
    rig.write_camodocal_dir(dir.path()).unwrap();
    let from_camodocal = Rig::read_camodocal_dir(dir.path()).unwrap();
    assert_eq!(from_camodocal.cameras[1].name, "cam1");
    assert_eq!(from_camodocal.cameras[1].camera, rig.cameras[1].camera);
    let file = dir.path().join("camchain.yaml");
    from_camodocal.write_kalibr(&file).unwrap();
    let back = Rig::read_kalibr(&file).unwrap();
    let d = back.cameras[1].rig_from_camera.to_homogeneous()
        - rig.cameras[1].rig_from_camera.to_homogeneous();
    assert!(d.abs().max() < 1e-15);
}

#[test]
fn kalibr_models_map_to_ours_and_others_are_refused() {
    let block = |model: &str, intr: &str, dist: &str, coeffs: &str| {
        format!(
            "cam0:\n  camera_model: {model}\n  intrinsics: {intr}\n  distortion_model: {dist}\n  \
             distortion_coeffs: {coeffs}\n  resolution: [512, 512]\n"
        )
    };
    let kb = Rig::from_kalibr_str(&block(
        "pinhole",
        "[190.98, 190.98, 254.93, 254.93]",
        "equidistant",
        "[0.0034824, 0.00071503, -0.0020532, 0.00020294]",
    ))
    .unwrap();
    assert_eq!(kb.cameras[0].camera, Camera::from(common::tum_kb()));
    let omni = Rig::from_kalibr_str(&block(
        "omni",
        "[1.82, 820.0, 821.0, 376.0, 240.0]",
        "radtan",
        "[-0.12, 0.02, -0.0001, 0.0001]",
    ))
    .unwrap();
    assert_eq!(omni.cameras[0].camera.as_unified().unwrap().xi(), 1.82);
    let omni_none = Rig::from_kalibr_str(&block("omni", "[0.9, 500, 500, 256, 256]", "none", "[]"));
    assert_eq!(
        omni_none.unwrap().cameras[0].camera.params()[1..5],
        [0.0; 4]
    );
    for (model, dist) in [
        ("ds", "none"),
        ("eucm", "none"),
        ("pinhole", "fov"),
        ("omni", "equidistant"),
    ] {
        let r = Rig::from_kalibr_str(&block(model, "[1, 1, 1, 1, 1, 1]", dist, "[0.1]"));
        assert!(
            matches!(r, Err(CameraFileError::UnsupportedModel { .. })),
            "{model} {dist}: {r:?}"
        );
    }
    let r = Rig::from_kalibr_str(&block("mystery", "[1, 1, 1, 1]", "none", "[]"));
    assert!(matches!(r, Err(CameraFileError::UnknownModel { .. })));
    // Missing keys, gaps in the chain, a broken transform, truncation: errors, never panics.
    let r = Rig::from_kalibr_str("cam0:\n  camera_model: pinhole\n");
    assert!(matches!(r, Err(CameraFileError::MissingKey { .. })));
    let text = trimbot();
    let gap = text.replace("cam1:", "cam2:");
    assert!(matches!(
        Rig::from_kalibr_str(&gap),
        Err(CameraFileError::Rig { .. })
    ));
    let bent = text.replace("[0.9999646166488014,", "[1.9999646166488014,");
    assert!(matches!(
        Rig::from_kalibr_str(&bent),
        Err(CameraFileError::Rig { .. })
    ));
    let no_t = text.replace("  T_cn_cnm1:", "  T_other:");
    assert!(Rig::from_kalibr_str(&no_t).is_err());
    for cut in (0..text.len()).step_by(7) {
        let _ = Rig::from_kalibr_str(&text[..cut]);
    }
}

#[test]
fn rig_writers_refuse_duplicate_names() {
    let cam = Camera::from(common::euroc_cam0());
    let rig = Rig::new(vec![
        RigCamera::new("a", cam.clone(), Isometry3::identity()),
        RigCamera::new("a", cam, Isometry3::identity()),
    ]);
    let dir = tempfile::tempdir().unwrap();
    assert!(matches!(
        rig.write_camodocal_dir(dir.path()),
        Err(CameraFileError::Rig { .. })
    ));
}

#[cfg(feature = "serde")]
#[test]
fn serde_round_trips_cameras_and_rigs_and_validates() {
    // serde_json's default float parser may be 1 ulp off: compare to 1e-15.
    let close = |a: &Camera, b: &Camera| {
        a.model_name() == b.model_name()
            && a.params()
                .iter()
                .zip(b.params())
                .all(|(x, y)| (x - y).abs() <= 1e-15 * y.abs())
    };
    for (_, camera) in common::all_cameras() {
        let json = serde_json::to_string(&camera).unwrap();
        let back: Camera = serde_json::from_str(&json).unwrap();
        assert!(close(&back, &camera));
    }
    let json = serde_json::to_string(&Camera::from(common::euroc_cam0())).unwrap();
    assert!(json.contains("\"model\":\"pinhole_radtan\""));
    let bad = json.replace("\"fx\":458.654", "\"fx\":-1.0");
    assert!(serde_json::from_str::<Camera>(&bad).is_err());
    let rig = Rig::from_kalibr_str(&trimbot()).unwrap();
    let json = serde_json::to_string(&rig).unwrap();
    assert!(json.contains("rotation_wxyz"));
    let back: Rig = serde_json::from_str(&json).unwrap();
    assert!(close(&back.cameras[0].camera, &rig.cameras[0].camera));
    let d = back.cameras[1].rig_from_camera.to_homogeneous()
        - rig.cameras[1].rig_from_camera.to_homogeneous();
    assert!(d.abs().max() < 1e-15);
}

#[cfg(feature = "glam")]
#[test]
fn glam_conversions_agree_with_nalgebra() {
    use ibc_camera_models::glam::{CameraModelGlam, isometry_from_glam, isometry_to_glam};
    let cam = common::tum_kb();
    let p = glam::DVec3::new(0.3, -0.4, 0.8);
    let px = cam.project_glam(p).unwrap();
    let ray = cam.unproject_glam(px).unwrap();
    assert!((ray - p.normalize()).length() < 1e-12);
    let pose = Isometry3::from_parts(
        Translation3::new(1.0, 2.0, 3.0),
        UnitQuaternion::from_euler_angles(0.3, 0.2, 0.1),
    );
    let (q, t) = isometry_to_glam(&pose);
    let v = glam::DVec3::new(0.5, -1.0, 2.0);
    let a = q * v + t;
    let b = pose * nalgebra::Point3::new(0.5, -1.0, 2.0);
    assert!((a - glam::DVec3::new(b.x, b.y, b.z)).length() < 1e-12);
    let back = isometry_from_glam(q, t);
    assert!((back.to_homogeneous() - pose.to_homogeneous()).abs().max() < 1e-15);
}
