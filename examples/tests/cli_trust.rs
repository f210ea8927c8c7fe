#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! What a user gets wrong in practice, through the `ibc` binary (issue 14): absurd camera
//! files, cameras listed in another order, a camera file or truth of another rig, inputs
//! that are not files, and intrinsics that do not fit: each a typed error naming the culprit
//! (exit 1), or a result marked poor (exit 3), never a confident garbage answer.

mod cli_common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use cli_common::{check_failure, entries, files, ibc, stderr, stdout};
use ibc_camera_models::{Camera, CameraModel, Rig};

/// Runs `ibc` with a deadline: a run that blocks (on a FIFO, say) fails the test instead of
/// hanging it.
fn ibc_within(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ibc"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("ibc {args:?} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `ibc calibrate` on the small world with `cameras` (and optionally `truth`), into `out`.
fn calibrate(
    f: &cli_common::Files,
    cameras: &Path,
    truth: Option<&Path>,
    out: &Path,
    extra: &[&str],
) -> Output {
    let mut args = vec![
        "calibrate",
        "--map",
        s(&f.map),
        "--log",
        s(&f.log),
        "--cameras",
        s(cameras),
        "--out",
        s(out),
    ];
    if let Some(t) = truth {
        args.extend(["--truth", s(t)]);
    }
    args.extend(extra);
    ibc_within(&args, Duration::from_secs(120))
}

/// The small world's camchain with camera 1's parameters changed by `edit`, written to `name`.
fn edited_camchain(
    f: &cli_common::Files,
    name: &str,
    edit: impl Fn(&mut Vec<f64>),
) -> std::path::PathBuf {
    let mut rig = Rig::read_kalibr(&f.cameras).unwrap();
    let camera: &mut Camera = &mut rig.cameras[1].camera;
    let mut p = camera.params().to_vec();
    edit(&mut p);
    camera.set_params(&p).unwrap();
    let path = f.dir.join(name);
    std::fs::write(&path, rig.to_kalibr_string()).unwrap();
    path
}

#[test]
fn absurd_camera_files_are_refused_naming_the_camera_and_the_parameter() {
    let f = files();
    let out = f.dir.join("out");
    // Kannala-Brandt parameters: [k1, k2, k3, k4, mu, mv, u0, v0]; Kalibr calls the second
    // camera `cam1`, `mu` fu, `k2` the second equidistant coefficient.
    for (name, index, value, expected) in [
        ("fu-max.yaml", 4, 3.4e38, "mu"),
        ("fu-big.yaml", 4, 4.3e9, "mu"),
        ("k2-big.yaml", 1, 4.3e9, "k2"),
        ("v0-out.yaml", 7, -476.0, "v0"),
    ] {
        let cameras = edited_camchain(&f, name, |p| p[index] = value);
        let o = calibrate(&f, &cameras, None, &out, &[]);
        check_failure(&o, &["cam1", expected, name]);
        assert!(!out.exists(), "{name}: output written");
    }
}

#[test]
fn a_camodocal_folder_in_another_order_is_matched_by_name() {
    let f = files();
    let mut rig = Rig::read_kalibr(&f.cameras).unwrap();
    // The simulated world's names, in the log's order, then the file listed front, right, rear,
    // left.
    for (c, name) in rig
        .cameras
        .iter_mut()
        .zip(["front", "left", "rear", "right"])
    {
        c.name = name.to_owned();
    }
    let reordered = Rig::new(
        [0, 3, 2, 1]
            .iter()
            .map(|&i| rig.cameras[i].clone())
            .collect(),
    );
    let folder = f.dir.join("camodocal");
    reordered.write_camodocal_dir(&folder).unwrap();
    let out = f.dir.join("out");
    let o = calibrate(&f, &folder, Some(&f.truth), &out, &["--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(report.get("notes").is_none(), "matched by name: no note");
    for (c, name) in report["cameras"]
        .as_array()
        .unwrap()
        .iter()
        .zip(["front", "left", "rear", "right"])
    {
        assert_eq!(c["name"], name);
        // Nothing moved: the prior is the map's own rig.
        assert!(
            c["change_from_prior"]["distance_m"].as_f64().unwrap() < 0.005,
            "{c}"
        );
        assert!(
            c["translation_error_m"].as_f64().unwrap_or(0.0) < 0.005,
            "{c}"
        );
    }
    // A folder that names another camera is an error listing both sets.
    let mut renamed = reordered.clone();
    renamed.cameras[3].name = "lefty".to_owned();
    let folder = f.dir.join("renamed");
    renamed.write_camodocal_dir(&folder).unwrap();
    let o = calibrate(&f, &folder, None, &out, &[]);
    check_failure(
        &o,
        &["front, right, rear, lefty", "front, left, rear, right"],
    );
}

#[cfg(unix)]
#[test]
fn inputs_that_are_not_regular_files_are_refused_at_once() {
    let f = files();
    let fifo = f.dir.join("fifo");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let out = f.dir.join("out");
    let quick = Duration::from_secs(20);
    for special in [fifo.as_path(), Path::new("/dev/zero")] {
        let map = [
            "calibrate",
            "--map",
            s(special),
            "--log",
            s(&f.log),
            "--cameras",
            s(&f.cameras),
            "--out",
            s(&out),
        ];
        check_failure(&ibc_within(&map, quick), &["not a regular file"]);
        let log = [
            "calibrate",
            "--map",
            s(&f.map),
            "--log",
            s(special),
            "--cameras",
            s(&f.cameras),
            "--out",
            s(&out),
        ];
        check_failure(&ibc_within(&log, quick), &["not a regular file"]);
        check_failure(
            &calibrate(&f, special, None, &out, &[]),
            &["not a regular file"],
        );
        check_failure(
            &calibrate(&f, &f.cameras, Some(special), &out, &[]),
            &["not a regular file"],
        );
        check_failure(
            &calibrate(&f, &f.cameras, None, &out, &["--vocabulary", s(special)]),
            &["not a regular file"],
        );
        check_failure(
            &ibc_within(&["demo", "--scenario", s(special)], quick),
            &["not a regular file"],
        );
        check_failure(
            &ibc_within(
                &[
                    "intrinsics",
                    "--corners",
                    s(special),
                    "--board",
                    "6x9",
                    "--square",
                    "0.04",
                    "--out",
                    s(&out),
                ],
                quick,
            ),
            &["not a regular file"],
        );
        assert!(!out.exists());
    }
}

/// Nine levels of nine aliases: 9^9 leaves if expanded.
fn alias_bomb() -> String {
    let mut s = String::from("a0: &a0 [x, x, x, x, x, x, x, x, x]\n");
    for i in 1..9 {
        let p = format!("*a{}", i - 1);
        s.push_str(&format!("a{i}: &a{i} [{}]\n", [p.as_str(); 9].join(", ")));
    }
    s
}

#[test]
fn yaml_alias_bombs_are_refused() {
    let f = files();
    let bomb = f.dir.join("bomb.yaml");
    std::fs::write(&bomb, alias_bomb()).unwrap();
    let out = f.dir.join("out");
    let quick = Duration::from_secs(20);
    check_failure(
        &calibrate(&f, &bomb, None, &out, &[]),
        &["bomb.yaml", "alias"],
    );
    let scenario = f.dir.join("scenario.yaml");
    std::fs::write(
        &scenario,
        format!("version: 1\nbase: garage\n{}", alias_bomb()),
    )
    .unwrap();
    check_failure(
        &ibc_within(&["demo", "--scenario", s(&scenario)], quick),
        &["scenario.yaml", "alias"],
    );
    // An oversized scenario file is refused before it is parsed.
    let big = f.dir.join("big.yaml");
    std::fs::write(&big, format!("version: 1\n#{}\n", "x".repeat(2 << 20))).unwrap();
    check_failure(
        &ibc_within(&["demo", "--scenario", s(&big)], quick),
        &["big.yaml", "over the 1048576-byte limit"],
    );
}

#[test]
fn a_truth_of_another_log_is_refused() {
    let f = files();
    let out = f.dir.join("out");
    // The truth of a longer drive (50 frames against the log's 25).
    let other = tempfile::tempdir().unwrap();
    let scenario = ibc_pipeline::sim::Scenario::builtin("garage")
        .unwrap()
        .with_scale(0.1);
    let longer = ibc_pipeline::sim::SimulatedWorld::simulate(&scenario)
        .unwrap()
        .write(other.path())
        .unwrap();
    let o = calibrate(&f, &f.cameras, Some(&longer.truth), &out, &[]);
    check_failure(
        &o,
        &["ground truth", "truth.json", "50 frames but the rig log 25"],
    );
    // The truth of a rig with other camera names.
    let text = std::fs::read_to_string(&f.truth)
        .unwrap()
        .replace("\"left\"", "\"port\"");
    let renamed = f.dir.join("renamed-truth.json");
    std::fs::write(&renamed, text).unwrap();
    let o = calibrate(&f, &f.cameras, Some(&renamed), &out, &[]);
    check_failure(
        &o,
        &[
            "renamed-truth.json",
            "front, port, rear, right",
            "front, left, rear, right",
        ],
    );
    assert!(!out.exists());
}

#[test]
fn wrong_intrinsics_give_a_poor_result_with_its_own_exit_code() {
    let f = files();
    // The second camera's focal length 1% long: a stale calibration.
    let cameras = edited_camchain(&f, "stale.yaml", |p| {
        p[4] *= 1.01;
        p[5] *= 1.01;
    });
    let out = f.dir.join("out");
    let o = calibrate(&f, &cameras, Some(&f.truth), &out, &[]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let table = stdout(&o);
    assert!(table.contains("status: poor"), "{table}");
    assert!(
        table.contains("warning: intrinsics of `left` do not fit"),
        "{table}"
    );
    assert!(
        table.contains(&format!("wrote {}", out.display())),
        "{table}"
    );
    assert!(stderr(&o).contains("status `poor`"), "{}", stderr(&o));
    // The result is still written, marked poor.
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["status"], "poor");
    assert_eq!(report["warnings"][0]["camera"], "left");
    assert_eq!(report["warnings"][0]["kind"], "systematic_residuals");
    assert!(entries(&out.join("camodocal")).contains(&"left_calib.yaml".to_owned()));
    // The true intrinsics pass.
    let good = f.dir.join("good");
    let o = calibrate(&f, &f.cameras, Some(&f.truth), &good, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("status: ok"));
}

#[test]
fn the_hand_eye_method_can_be_chosen() {
    let f = files();
    let out = f.dir.join("out");
    let o = calibrate(
        &f,
        &f.cameras,
        None,
        &out,
        &["--json", "--hand-eye", "none"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(report["hand_eye"].is_null());
    // Daniilidis on planar wheel odometry: refused, with the way out.
    let o = calibrate(
        &f,
        &f.cameras,
        None,
        &out,
        &["--json", "--hand-eye", "six-dof"],
    );
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let error = report["hand_eye"]["error"].as_str().unwrap();
    assert!(
        error.contains("planar") && error.contains("--hand-eye planar"),
        "{error}"
    );
    assert!(!error.contains(" rad"), "angles in degrees: {error}");
    let o = ibc(&["demo", "--hand-eye", "sideways"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn a_camchain_imucam_keeps_its_imu_transforms() {
    let f = files();
    let mut rig = Rig::read_kalibr(&f.cameras).unwrap();
    // An IMU 10 cm behind camera 0, axes aligned with it; each camera's T_cam_imu from the
    // file's extrinsics, and a time shift.
    let cam0_from_imu = nalgebra::Isometry3::translation(0.0, 0.0, -0.1);
    let first = rig.cameras[0].rig_from_camera;
    for c in &mut rig.cameras {
        c.camera_from_imu = Some(c.rig_from_camera.inverse() * first * cam0_from_imu);
        c.timeshift_cam_imu_s = Some(0.0025);
    }
    let imucam = f.dir.join("camchain-imucam.yaml");
    std::fs::write(&imucam, rig.to_kalibr_string()).unwrap();
    let out = f.dir.join("out");
    let o = calibrate(&f, &imucam, None, &out, &["--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let notes = report["notes"].to_string();
    assert!(
        notes.contains("T_cam_imu is written for every camera through `front`"),
        "{notes}"
    );
    let calibrated = Rig::read_kalibr(out.join("camchain-calibrated.yaml")).unwrap();
    for (c, prior) in calibrated.cameras.iter().zip(&rig.cameras) {
        assert_eq!(c.timeshift_cam_imu_s, Some(0.0025));
        // The IMU stays where it was relative to camera 0, through the calibrated extrinsics.
        let imu_in_rig = c.rig_from_camera * c.camera_from_imu.unwrap();
        let expected = calibrated.cameras[0].rig_from_camera * cam0_from_imu;
        assert!((imu_in_rig.translation.vector - expected.translation.vector).norm() < 1e-9);
        // And close to the file's, since nothing moved.
        let before = prior.camera_from_imu.unwrap().translation.vector;
        assert!((c.camera_from_imu.unwrap().translation.vector - before).norm() < 0.005);
    }
}

#[test]
fn messages_name_the_file_once() {
    let f = files();
    let out = f.dir.join("out");
    // A vocabulary that is not one: named.
    let o = calibrate(&f, &f.cameras, None, &out, &["--vocabulary", s(&f.map)]);
    check_failure(
        &o,
        &["vocabulary", "map.ibcmap", "not an ibc vocabulary file"],
    );
    // A malformed camera file inside a CamOdoCal folder: that file, once.
    let rig = Rig::read_kalibr(&f.cameras).unwrap();
    let folder = f.dir.join("rig");
    rig.write_camodocal_dir(&folder).unwrap();
    let yaml = folder.join("cam2_calib.yaml");
    let text = std::fs::read_to_string(&yaml)
        .unwrap()
        .replace("   mu:", "   mu_typo:");
    std::fs::write(&yaml, text).unwrap();
    let o = calibrate(&f, &folder, None, &out, &[]);
    check_failure(&o, &["cam2_calib.yaml", "mu"]);
    assert_eq!(
        stderr(&o).matches("cam2_calib.yaml").count(),
        1,
        "{}",
        stderr(&o)
    );
    // A missing camera file: its path once.
    let missing = f.dir.join("nowhere.yaml");
    let o = calibrate(&f, &missing, None, &out, &[]);
    check_failure(&o, &["nowhere.yaml"]);
    assert_eq!(
        stderr(&o).matches("nowhere.yaml").count(),
        1,
        "{}",
        stderr(&o)
    );
}
