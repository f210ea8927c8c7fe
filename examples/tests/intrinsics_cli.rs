//! `ibc intrinsics` through the binary: the simulated mode writes the CamOdoCal YAML, the
//! Kalibr camchain, the JSON report and the residual SVG; a corner file calibrates the same;
//! bad input gives one line on standard error, exit code 1 and no output files.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, Output};

use ibc_camera_models::{CameraModel, camodocal};

fn ibc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ibc"))
        .arg("intrinsics")
        .args(args)
        .output()
        .unwrap()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The report's parameter `name`: (value, truth) when the report has the truth.
fn parameter(report: &serde_json::Value, name: &str) -> (f64, Option<f64>) {
    let p = report["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == name)
        .unwrap();
    (p["value"].as_f64().unwrap(), p["truth"].as_f64())
}

#[test]
fn simulated_mode_writes_every_output_and_its_corners_calibrate_again() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sim");
    let run = ibc(&[
        "--simulate",
        "--model",
        "kb",
        "--missing",
        "0.05",
        "--out",
        path(&out),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let summary = String::from_utf8(run.stdout).unwrap();
    assert!(
        summary.contains("initialization: vanishing points"),
        "{summary}"
    );
    for file in [
        "cam0_camera_calib.yaml",
        "camchain.yaml",
        "intrinsics_report.json",
        "residuals.svg",
        "corners.json",
        "truth_camera_calib.yaml",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    // The report agrees with the CamOdoCal file, and with the truth to a few standard
    // deviations of the 9x6 board (about 0.1 px).
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("intrinsics_report.json")).unwrap())
            .unwrap();
    let camera = camodocal::read_camera(out.join("cam0_camera_calib.yaml")).unwrap();
    let truth = camodocal::read_camera(out.join("truth_camera_calib.yaml")).unwrap();
    for (i, name) in ["mu", "mv", "u0", "v0"].iter().enumerate() {
        let (value, t) = parameter(&report, name);
        assert_eq!(value, camera.camera.params()[4 + i]);
        assert_eq!(t.unwrap(), truth.camera.params()[4 + i]);
        assert!((value - t.unwrap()).abs() < 0.4, "{name}: {value} vs {t:?}");
    }
    let rms = report["rms_px"].as_f64().unwrap();
    assert!((rms / 0.2 - 1.0).abs() < 0.1, "rms {rms}");
    let camchain = std::fs::read_to_string(out.join("camchain.yaml")).unwrap();
    assert!(
        camchain.contains("cam0") && camchain.contains("intrinsics"),
        "{camchain}"
    );
    let svg = std::fs::read_to_string(out.join("residuals.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert!(svg.matches("<circle").count() > 500);

    // The simulated corners as an input file, with the JSON report on standard output.
    let again = dir.path().join("again");
    let run = ibc(&[
        "--corners",
        path(&out.join("corners.json")),
        "--model",
        "kb",
        "--json",
        "--out",
        path(&again),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let printed: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(printed["format"], "ibc-intrinsics-report");
    assert_eq!(parameter(&printed, "mu").0, parameter(&report, "mu").0);
    assert!(again.join("cam0_camera_calib.yaml").is_file());
    assert!(!again.join("corners.json").exists());
}

/// Runs `ibc intrinsics` on a corner file with `text` and checks it fails cleanly.
fn assert_fails_cleanly(text: &str, expected: &str) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("corners.json");
    std::fs::write(&file, text).unwrap();
    let out = dir.path().join("out");
    let run = ibc(&[
        "--corners",
        path(&file),
        "--board",
        "6x9",
        "--square",
        "0.04",
        "--out",
        path(&out),
    ]);
    assert_eq!(run.status.code(), Some(1));
    let stderr = String::from_utf8(run.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains(expected),
        "{stderr}"
    );
    assert!(run.stdout.is_empty());
    assert!(!out.exists(), "an output folder was left behind");
}

#[test]
fn malformed_corner_files_fail_with_one_line_and_no_output() {
    assert_fails_cleanly(
        "{\"format\": \"ibc-corners\", \"version\": 1,",
        "corners.json",
    );
    assert_fails_cleanly("[1, 2, 3]", "corners.json");
    let outside = r#"{"format": "ibc-corners", "version": 1, "image_width": 640, "image_height": 480,
        "images": [{"name": "a", "corners": [{"row": 0, "col": 0, "u": 700.0, "v": 10.0}]}]}"#;
    assert_fails_cleanly(outside, "outside the 640x480 image");
    let few = r#"{"format": "ibc-corners", "version": 1, "image_width": 640, "image_height": 480,
        "images": []}"#;
    assert_fails_cleanly(few, "0 images");
}

#[test]
fn usage_errors_exit_with_code_2() {
    let run = ibc(&["--simulate", "--model", "fisheye", "--out", "x"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("unknown model `fisheye`"));
    let run = ibc(&["--out", "x"]);
    assert_eq!(run.status.code(), Some(2));
}
