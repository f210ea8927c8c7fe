//! Rig files: CamOdoCal folders in both naming schemes, Kalibr camchain-imucam fields, errors
//! that name the file once, and implausible cameras refused on load.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;

use ibc_camera_models::camodocal::{
    EXTRINSIC_FILE_NAME, calib_file_name, camera_calib_file_name, format_camera, parse_camera,
    read_camera,
};
use ibc_camera_models::{Camera, CameraFileError, PlausibilityError, Rig, RigCamera};
use nalgebra::Isometry3;

/// The TrimBot2020 camchain (`tests/data/README.md`).
const TRIMBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/trimbot-camchain.yaml"
);

/// A camera YAML as OpenCV FileStorage writes CamOdoCal's EuRoC-like pinhole, with the given
/// `camera_name` line.
fn pinhole_yaml(name_line: &str, fx: f64) -> String {
    format!(
        "%YAML:1.0\n---\nmodel_type: PINHOLE\n{name_line}\nimage_width: 752\nimage_height: 480\n\
         distortion_parameters:\n   k1: -2.8340811000000001e-01\n   k2: 7.3959069999999996e-02\n   \
         p1: 1.9358999999999999e-04\n   p2: 1.7618711400000000e-05\nprojection_parameters:\n   \
         fx: {fx:.16e}\n   fy: 4.5729599999999999e+02\n   cx: 3.6721499999999998e+02\n   \
         cy: 2.4837500000000000e+02\n"
    )
}

/// `extrinsic.txt` as CamOdoCal's `CameraSystem::writePosesToTextFile` writes it: fixed 10
/// decimals, five lines per camera.
const CAMERA_SYSTEM_EXTRINSIC: &str = "camera_0
1.0000000000 0.0000000000 0.0000000000 0.0000000000
0.0000000000 1.0000000000 0.0000000000 0.0000000000
0.0000000000 0.0000000000 1.0000000000 0.0000000000

camera_1
1.0000000000 0.0000000000 0.0000000000 0.1100000000
0.0000000000 1.0000000000 0.0000000000 0.0000000000
0.0000000000 0.0000000000 1.0000000000 0.0000000000

";

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).unwrap();
}

/// The text of `e` names `path` exactly once.
fn names_once(e: &CameraFileError, path: &Path) {
    let text = e.to_string();
    let p = path.display().to_string();
    assert_eq!(text.matches(&p).count(), 1, "{text}");
}

#[test]
fn file_name_helpers_follow_camodocal() {
    assert_eq!(calib_file_name("camera_0"), "camera_0_calib.yaml");
    assert_eq!(camera_calib_file_name("front"), "front_camera_calib.yaml");
    assert_eq!(EXTRINSIC_FILE_NAME, "extrinsic.txt");
}

#[test]
fn a_camera_system_folder_with_unnamed_cameras_reads() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "extrinsic.txt", CAMERA_SYSTEM_EXTRINSIC);
    // OpenCV writes an empty name as "" (or a bare key).
    write(
        dir.path(),
        "camera_0_calib.yaml",
        &pinhole_yaml("camera_name: \"\"", 458.654),
    );
    write(
        dir.path(),
        "camera_1_calib.yaml",
        &pinhole_yaml("camera_name:", 458.654),
    );
    let rig = Rig::read_camodocal_dir(dir.path()).unwrap();
    assert_eq!(rig.cameras.len(), 2);
    assert_eq!(rig.cameras[0].name, "camera_0");
    assert_eq!(rig.cameras[1].name, "camera_1");
    assert_eq!(rig.cameras[0].camera, Camera::from(common::euroc_cam0()));
    assert_eq!(rig.cameras[1].rig_from_camera.translation.vector.x, 0.11);
}

#[test]
fn both_file_names_must_agree() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "extrinsic.txt", CAMERA_SYSTEM_EXTRINSIC);
    write(
        dir.path(),
        "camera_0_calib.yaml",
        &pinhole_yaml("camera_name: camera_0", 458.654),
    );
    // camera_1 only under the intrinsic tool's name.
    write(
        dir.path(),
        "camera_1_camera_calib.yaml",
        &pinhole_yaml("camera_name: camera_1", 458.654),
    );
    // The same camera under both names of camera_0 is fine.
    write(
        dir.path(),
        "camera_0_camera_calib.yaml",
        &pinhole_yaml("camera_name: camera_0", 458.654),
    );
    assert_eq!(
        Rig::read_camodocal_dir(dir.path()).unwrap().cameras.len(),
        2
    );
    // Different cameras under the two names: an error naming both files.
    write(
        dir.path(),
        "camera_0_camera_calib.yaml",
        &pinhole_yaml("camera_name: camera_0", 460.0),
    );
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    match &e {
        CameraFileError::ConflictingCameraFiles {
            camera,
            first,
            second,
        } => {
            assert_eq!(camera, "camera_0");
            assert_eq!(first, &dir.path().join("camera_0_calib.yaml"));
            assert_eq!(second, &dir.path().join("camera_0_camera_calib.yaml"));
        }
        other => panic!("{other}"),
    }
    names_once(&e, &dir.path().join("camera_0_calib.yaml"));
    names_once(&e, &dir.path().join("camera_0_camera_calib.yaml"));
}

#[test]
fn a_camera_without_a_file_or_with_another_name_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "extrinsic.txt", CAMERA_SYSTEM_EXTRINSIC);
    write(
        dir.path(),
        "camera_0_calib.yaml",
        &pinhole_yaml("camera_name: camera_0", 458.654),
    );
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    let extrinsic = dir.path().join("extrinsic.txt");
    assert!(
        matches!(&e, CameraFileError::InFile { path, source }
            if path == &extrinsic && matches!(**source, CameraFileError::Rig { .. })),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("camera_1_calib.yaml") && text.contains("camera_1_camera_calib.yaml"),
        "{text}"
    );
    // A non-empty camera_name that differs from extrinsic.txt's.
    let wrong = dir.path().join("camera_1_calib.yaml");
    std::fs::write(&wrong, pinhole_yaml("camera_name: left", 458.654)).unwrap();
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::InFile { path, .. } if path == &wrong),
        "{e}"
    );
    assert!(e.to_string().contains("`left`"), "{e}");
    names_once(&e, &wrong);
}

#[test]
fn written_folders_have_camera_systems_layout_and_read_back() {
    let rig = Rig::read_kalibr(TRIMBOT).unwrap();
    let dir = tempfile::tempdir().unwrap();
    rig.write_camodocal_dir(dir.path()).unwrap();
    for name in ["cam0", "cam1"] {
        assert!(dir.path().join(calib_file_name(name)).is_file());
        assert!(!dir.path().join(camera_calib_file_name(name)).exists());
    }
    // CameraSystem's reader counts lines in fives: name (first word), three rows, one skipped.
    let text = std::fs::read_to_string(dir.path().join("extrinsic.txt")).unwrap();
    let lines: Vec<&str> = text.split('\n').collect();
    assert_eq!(lines.len(), 5 * rig.cameras.len() + 1, "{text:?}");
    for (i, c) in rig.cameras.iter().enumerate() {
        let block = &lines[5 * i..5 * i + 5];
        assert_eq!(block[0].split_whitespace().next(), Some(c.name.as_str()));
        assert_eq!(block[4], "");
        let h = c.rig_from_camera.to_homogeneous();
        for r in 0..3 {
            let row: Vec<f64> = block[1 + r]
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            assert_eq!(row.len(), 4);
            for (k, v) in row.iter().enumerate() {
                assert!((v - h[(r, k)]).abs() < 1e-15);
            }
        }
    }
    let back = Rig::read_camodocal_dir(dir.path()).unwrap();
    for (a, b) in rig.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.camera, b.camera);
        let d = a.rig_from_camera.to_homogeneous() - b.rig_from_camera.to_homogeneous();
        assert!(d.abs().max() < 1e-15);
    }
    // Rewriting the same folder is fine (poses to rounding: the rotation is re-projected).
    back.write_camodocal_dir(dir.path()).unwrap();
    let again = Rig::read_camodocal_dir(dir.path()).unwrap();
    for (a, b) in back.cameras.iter().zip(&again.cameras) {
        assert_eq!((&a.name, &a.camera), (&b.name, &b.camera));
        let d = a.rig_from_camera.to_homogeneous() - b.rig_from_camera.to_homogeneous();
        assert!(d.abs().max() < 1e-15);
    }
}

#[test]
fn names_a_camodocal_folder_cannot_hold_are_refused() {
    let cam = Camera::from(common::euroc_cam0());
    let dir = tempfile::tempdir().unwrap();
    for name in ["front left", "a/b"] {
        let rig = Rig::new(vec![RigCamera::new(
            name,
            cam.clone(),
            Isometry3::identity(),
        )]);
        assert!(
            matches!(
                rig.write_camodocal_dir(dir.path()),
                Err(CameraFileError::Rig { .. })
            ),
            "{name}"
        );
    }
    write(
        dir.path(),
        "extrinsic.txt",
        "../x\n1 0 0 0\n0 1 0 0\n0 0 1 0\n\n",
    );
    assert!(Rig::read_camodocal_dir(dir.path()).is_err());
}

#[test]
fn errors_of_readers_name_the_file_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    // A camera file missing a key.
    let left = dir.path().join("left_calib.yaml");
    let missing =
        pinhole_yaml("camera_name: left", 458.654).replace("   fy: 4.5729599999999999e+02\n", "");
    std::fs::write(&left, &missing).unwrap();
    let e = read_camera(&left).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{}: missing key `projection_parameters.fy`", left.display())
    );
    assert_eq!(e.path(), Some(left.as_path()));
    // The same file inside a rig folder: the folder's reader names it, once.
    write(
        dir.path(),
        "extrinsic.txt",
        "left\n1 0 0 0\n0 1 0 0\n0 0 1 0\n\n",
    );
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{}: missing key `projection_parameters.fy`", left.display())
    );
    // A malformed extrinsic.txt names itself and the line.
    write(dir.path(), "extrinsic.txt", "left\n1 0 0 0\n0 1 0\n");
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    let extrinsic = dir.path().join("extrinsic.txt");
    assert!(
        e.to_string()
            .starts_with(&format!("{}: line 3:", extrinsic.display())),
        "{e}"
    );
    // A Kalibr file.
    let chain = dir.path().join("camchain.yaml");
    std::fs::write(&chain, "cam0:\n  camera_model: pinhole\n").unwrap();
    let e = Rig::read_kalibr(&chain).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!("{}: missing key `cam0.distortion_model`", chain.display())
    );
    // An I/O error names its path already and is not wrapped again.
    let nothing = dir.path().join("nothing.yaml");
    let e = read_camera(&nothing).unwrap_err();
    assert!(matches!(e, CameraFileError::Io { .. }), "{e}");
    names_once(&e, &nothing);
    let e = Rig::read_camodocal_dir(dir.path().join("no-such-folder")).unwrap_err();
    assert!(matches!(e, CameraFileError::Io { .. }), "{e}");
}

#[test]
fn implausible_cameras_are_refused_on_load() {
    // CamOdoCal YAML with v0 = -476 px.
    let text = format_camera("front", &Camera::from(common::camodocal_kb()))
        .replace("v0: 3.8966377000000000e+02", "v0: -4.7600000000000000e+02");
    let e = parse_camera(&text).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Implausible { camera, source: PlausibilityError::PrincipalPoint { name: "v0", .. } }
            if camera == "front"),
        "{e}"
    );
    // In a rig folder: the file is named.
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "front_calib.yaml", &text);
    write(
        dir.path(),
        "extrinsic.txt",
        "front\n1 0 0 0\n0 1 0 0\n0 0 1 0\n\n",
    );
    let e = Rig::read_camodocal_dir(dir.path()).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::InFile { path, source }
            if path == &dir.path().join("front_calib.yaml")
                && matches!(**source, CameraFileError::Implausible { .. })),
        "{e}"
    );
    // Kalibr: fu = 3.4e38 in cam1, named by its key.
    let chain = std::fs::read_to_string(TRIMBOT)
        .unwrap()
        .replace("[541.6460202751782,", "[3.4e38,");
    let e = Rig::from_kalibr_str(&chain).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Implausible { camera, source: PlausibilityError::FocalLength { name: "fx", .. } }
            if camera == "cam1"),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with("camera `cam1` is implausible: parameter fx = 3.4e38"),
        "{e}"
    );
    // k2 = 4.3e9 in cam0.
    let chain = std::fs::read_to_string(TRIMBOT)
        .unwrap()
        .replace("0.11030211900967231", "4.3e9");
    let e = Rig::from_kalibr_str(&chain).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Implausible { source, .. } if source.parameter() == "k2"),
        "{e}"
    );
    // Built in code, the same camera is accepted: constructors do not judge plausibility.
    assert!(
        ibc_camera_models::PinholeRadtan::new(
            752,
            480,
            [0.0, 0.0, 0.0, 0.0, 3.4e38, 1.0, 0.0, 0.0]
        )
        .is_ok()
    );
}

/// The TrimBot camchain with Kalibr's camchain-imucam fields.
fn imucam() -> String {
    std::fs::read_to_string(TRIMBOT)
        .unwrap()
        .replace(
            "cam0:\n",
            "cam0:\n  T_cam_imu:\n  - [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975]\n  \
             - [0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768]\n  \
             - [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949]\n  \
             - [0.0, 0.0, 0.0, 1.0]\n  timeshift_cam_imu: 0.0016542\n",
        )
        .replace("cam1:\n", "cam1:\n  timeshift_cam_imu: -2.5e-3\n")
}

#[test]
fn camchain_imucam_fields_round_trip() {
    let rig = Rig::from_kalibr_str(&imucam()).unwrap();
    let cam0 = &rig.cameras[0];
    let t = cam0.camera_from_imu.unwrap();
    assert!((t.translation.vector.x + 0.0216401454975).abs() < 1e-15);
    assert!((t.to_homogeneous()[(0, 1)] + 0.999880929698).abs() < 1e-6);
    assert_eq!(cam0.timeshift_cam_imu_s, Some(0.0016542));
    assert_eq!(rig.cameras[1].camera_from_imu, None);
    assert_eq!(rig.cameras[1].timeshift_cam_imu_s, Some(-2.5e-3));
    let text = rig.to_kalibr_string();
    assert!(text.contains("  T_cam_imu:\n") && text.contains("  timeshift_cam_imu: "));
    let back = Rig::from_kalibr_str(&text).unwrap();
    for (a, b) in rig.cameras.iter().zip(&back.cameras) {
        assert_eq!(a.timeshift_cam_imu_s, b.timeshift_cam_imu_s);
        match (a.camera_from_imu, b.camera_from_imu) {
            (None, None) => {}
            (Some(x), Some(y)) => {
                assert!((x.to_homogeneous() - y.to_homogeneous()).abs().max() < 1e-15);
            }
            other => panic!("{other:?}"),
        }
    }
    // A rig without them writes neither key.
    let plain = Rig::read_kalibr(TRIMBOT).unwrap().to_kalibr_string();
    assert!(!plain.contains("T_cam_imu") && !plain.contains("timeshift"));
    let built = RigCamera::new(
        "x",
        Camera::from(common::euroc_cam0()),
        Isometry3::identity(),
    );
    assert_eq!(
        (built.camera_from_imu, built.timeshift_cam_imu_s),
        (None, None)
    );
}

#[test]
fn malformed_imu_fields_are_errors_naming_the_key() {
    let text = imucam();
    // Not a rotation.
    let bent = text.replace("[0.0148655429818,", "[1.5,");
    let e = Rig::from_kalibr_str(&bent).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::Rig { message } if message.contains("cam0.T_cam_imu")),
        "{e}"
    );
    // Three rows.
    let short = text.replace(
        "  - [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949]\n",
        "",
    );
    let e = Rig::from_kalibr_str(&short).unwrap_err();
    assert!(
        matches!(&e, CameraFileError::WrongType { key, .. } if key == "cam0.T_cam_imu"),
        "{e}"
    );
    // A bad last row.
    let last = text.replacen(
        "  - [0.0, 0.0, 0.0, 1.0]\n  timeshift",
        "  - [0.0, 0.0, 1.0, 1.0]\n  timeshift",
        1,
    );
    let e = Rig::from_kalibr_str(&last).unwrap_err();
    assert!(e.to_string().contains("cam0.T_cam_imu"), "{e}");
    // A time shift that is not a finite number.
    for bad in ["soon", ".nan", ".inf", "[1]"] {
        let t = text.replace(
            "timeshift_cam_imu: -2.5e-3",
            &format!("timeshift_cam_imu: {bad}"),
        );
        let e = Rig::from_kalibr_str(&t).unwrap_err();
        assert!(
            matches!(&e, CameraFileError::WrongType { key, .. } if key == "cam1.timeshift_cam_imu"),
            "{bad}: {e}"
        );
    }
}

#[cfg(feature = "serde")]
#[test]
fn serde_keeps_the_imu_fields_and_reads_rigs_without_them() {
    let rig = Rig::from_kalibr_str(&imucam()).unwrap();
    let json = serde_json::to_string(&rig).unwrap();
    let back: Rig = serde_json::from_str(&json).unwrap();
    assert_eq!(back.cameras[0].timeshift_cam_imu_s, Some(0.0016542));
    let (a, b) = (
        rig.cameras[0].camera_from_imu.unwrap(),
        back.cameras[0].camera_from_imu.unwrap(),
    );
    assert!((a.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-15);
    assert_eq!(back.cameras[1].camera_from_imu, None);
    // JSON written before the fields existed still reads.
    let old = serde_json::to_string(&Rig::read_kalibr(TRIMBOT).unwrap()).unwrap();
    assert!(!old.contains("camera_from_imu"));
    let read: Rig = serde_json::from_str(&old).unwrap();
    assert_eq!(read.cameras[0].timeshift_cam_imu_s, None);
}

/// Written files take the modes any program's files take (`0666` less the umask), not the
/// `0600` of temporary-file libraries, so that another account (a ROS node) can read them.
#[cfg(unix)]
#[test]
fn written_files_take_the_umask_modes() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("reference");
    std::fs::write(&reference, b"").unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let rig = Rig::from_kalibr_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/trimbot-camchain.yaml"
        ))
        .unwrap(),
    )
    .unwrap();
    let camchain = dir.path().join("camchain.yaml");
    rig.write_kalibr(&camchain).unwrap();
    assert_eq!(mode(&camchain), mode(&reference));
    rig.write_camodocal_dir(dir.path().join("rig")).unwrap();
    for entry in std::fs::read_dir(dir.path().join("rig")).unwrap() {
        let path = entry.unwrap().path();
        assert_eq!(mode(&path), mode(&reference), "{}", path.display());
    }
    // No temporary file is left next to the outputs.
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}
