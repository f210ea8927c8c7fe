#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! The `ibc` commands through the binary: `scenarios`, `demo`, and `simulate` then `calibrate`
//! giving the same result as `demo`.

mod cli_common;

use cli_common::{entries, ibc, json_close, scenario_file, stderr, stdout};
use ibc_pipeline::report::output_names;

#[test]
fn scenarios_lists_the_built_in_worlds() {
    let o = ibc(&["scenarios"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    for name in [
        "garage",
        "street",
        "garage-moved-cameras",
        "garden-pentagon",
        "handheld-6dof",
    ] {
        assert!(
            text.lines().any(|l| l.starts_with(name)),
            "{name} missing from\n{text}"
        );
    }
    assert!(text.contains("(default)"));
}

#[test]
fn simulate_then_calibrate_gives_the_demo_result() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = scenario_file(dir.path(), "garage", 0.1);
    // The demo, with its JSON report on stdout and every output file in `demo`.
    let demo_dir = dir.path().join("demo");
    let o = ibc(&[
        "demo",
        "--scenario",
        &scenario,
        "--seed",
        "3",
        "--json",
        "--quiet",
        "--out",
        demo_dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).is_empty(),
        "stderr is not a terminal: no progress output"
    );
    let mut demo: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // The same world written to files, then calibrated from them.
    let world = dir.path().join("world");
    let o = ibc(&[
        "simulate",
        "--scenario",
        &scenario,
        "--seed",
        "3",
        "--out",
        world.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut listed = entries(&world);
    listed.sort();
    assert_eq!(
        listed,
        ["camchain.yaml", "log.ibclog", "map.ibcmap", "truth.json"]
    );
    let out = dir.path().join("out");
    let path = |name: &str| world.join(name).to_str().unwrap().to_owned();
    let o = ibc(&[
        "calibrate",
        "--map",
        &path("map.ibcmap"),
        "--log",
        &path("log.ibclog"),
        "--cameras",
        &path("camchain.yaml"),
        "--truth",
        &path("truth.json"),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Where the files went, on standard error since standard output holds the JSON.
    assert!(
        stderr(&o).contains("wrote ") && stderr(&o).contains("report.json"),
        "{}",
        stderr(&o)
    );
    let mut calibrated: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for report in [&mut demo, &mut calibrated] {
        report.as_object_mut().unwrap().remove("timing_s").unwrap();
    }
    // A Kalibr camchain names no cameras: matched by order, and the report says so.
    let notes = calibrated.as_object_mut().unwrap().remove("notes").unwrap();
    assert!(
        notes[0]
            .as_str()
            .unwrap()
            .contains("matched to the log by order (cam0 = front"),
        "{notes}"
    );
    assert!(
        demo.get("notes").is_none(),
        "the demo's names match: no note"
    );
    // Equal but for the last bits of the prior extrinsics, which went through the camchain's
    // chained T_cn_cnm1.
    json_close(&demo, &calibrated, "report").unwrap();
    assert_eq!(demo["scenario"], "garage");
    assert_eq!(demo["seed"], 3);
    // Every output file, in both folders.
    for folder in [&demo_dir, &out] {
        for name in [
            output_names::REPORT_JSON,
            output_names::REPORT_TEXT,
            output_names::CAMCHAIN,
            output_names::TOP_VIEW,
            output_names::ERRORS,
        ] {
            assert!(
                folder.join(name).is_file(),
                "{name} missing in {}",
                folder.display()
            );
        }
        let camodocal = entries(&folder.join(output_names::CAMODOCAL_DIR));
        assert_eq!(camodocal.len(), 5, "{camodocal:?}");
        assert!(camodocal.contains(&"extrinsic.txt".to_owned()));
    }
    // The written camchain reads back with the estimated extrinsics.
    let rig = ibc_camera_models::Rig::read_kalibr(out.join(output_names::CAMCHAIN)).unwrap();
    let left = &calibrated["cameras"][1]["rig_from_camera"]["translation"];
    let t = rig.cameras[1].rig_from_camera.translation.vector;
    assert!((t.x - left[0].as_f64().unwrap()).abs() < 1e-12);
    // The plots have axes with units, round ticks and legends.
    let top = std::fs::read_to_string(out.join(output_names::TOP_VIEW)).unwrap();
    for label in [
        ">x [m] (map frame)<",
        ">y [m] (map frame)<",
        "camera `left` centres",
        "rig trajectory",
        "ahead of camera 0 [m]",
    ] {
        assert!(top.contains(label), "top view: {label}");
    }
    let histogram = std::fs::read_to_string(out.join(output_names::ERRORS)).unwrap();
    for label in [
        ">reprojection error [px]<",
        "correspondences per bin of",
        "before refinement (mean",
        ">0.2<",
    ] {
        assert!(histogram.contains(label), "histogram: {label}");
    }
    // The text table of `calibrate` without --json.
    let table = std::fs::read_to_string(out.join(output_names::REPORT_TEXT)).unwrap();
    assert!(table.contains("frame sets") && table.contains("hand-eye (guo-planar"));
}

#[test]
fn the_json_report_has_the_keys_the_issue_lists() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = scenario_file(dir.path(), "handheld-6dof", 0.1);
    let o = ibc(&["--scenario", &scenario, "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for key in [
        "scenario",
        "cameras",
        "frame_sets_used",
        "mean_poses_per_set",
        "correspondences",
        "reprojection_error_px",
        "hand_eye",
        "timing_s",
    ] {
        assert!(r.get(key).is_some(), "{key}");
    }
    for key in [
        "name",
        "rig_from_camera",
        "rig_from_camera_std",
        "rotation_error_deg",
        "translation_error_deg",
        "translation_error_m",
    ] {
        assert!(r["cameras"][1].get(key).is_some(), "cameras[1].{key}");
    }
    assert_eq!(
        r["cameras"][1]["rig_from_camera"]["rotation_wxyz"]
            .as_array()
            .unwrap()
            .len(),
        4
    );
    assert!(r["reprojection_error_px"]["initial"].is_number());
    assert!(r["reprojection_error_px"]["final"].is_number());
    assert_eq!(r["hand_eye"]["method"], "daniilidis");
    assert!(r["hand_eye"]["rig_from_odometry"]["translation"].is_array());
    assert!(r["hand_eye"]["rotation_error_deg"].is_number());
    for key in [
        "localization",
        "initialization",
        "refinement",
        "hand_eye",
        "total",
    ] {
        assert!(r["timing_s"][key].is_number(), "timing_s.{key}");
    }
}

/// `ibc calibrate --quiet` on the simulated world in `world` (its map, log, camchain and
/// truth), the outputs in `world/out`, with the `extra` arguments.
fn calibrate_world(world: &std::path::Path, out: &str, extra: &[&str]) -> std::process::Output {
    let path = |name: &str| world.join(name).to_str().unwrap().to_owned();
    let mut args = vec![
        "calibrate".to_owned(),
        "--quiet".to_owned(),
        "--map".to_owned(),
        path("map.ibcmap"),
        "--log".to_owned(),
        path("log.ibclog"),
        "--cameras".to_owned(),
        path("camchain.yaml"),
        "--truth".to_owned(),
        path("truth.json"),
        "--out".to_owned(),
        path(out),
    ];
    args.extend(extra.iter().map(|a| (*a).to_owned()));
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    ibc(&args)
}

/// The garage at half size simulated by `ibc simulate` into `dir/world` from a scenario file
/// whose `changes` give each of its cameras the lens change `change` (YAML keys of a camera
/// change); returns the world's folder.
fn changed_lenses_world(dir: &std::path::Path, change: &str) -> std::path::PathBuf {
    let mut yaml = String::from("version: 1\nbase: garage\nscale: 0.5\nchanges:\n");
    for name in ["front", "left", "rear", "right"] {
        yaml.push_str(&format!("  - camera: {name}\n    {change}\n"));
    }
    let scenario = dir.join("lenses.yaml");
    std::fs::write(&scenario, yaml).unwrap();
    let world = dir.join("world");
    let o = ibc(&[
        "simulate",
        "--quiet",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        world.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    world
}

#[test]
fn refine_intrinsics_corrects_a_stale_camera_file_and_writes_the_refined_ones() {
    // Every lens changed since the map and the camera file were made (a scenario file's
    // `changes`): the camera file's focal lengths are 1 % long, its principal points 3 px off.
    let dir = tempfile::tempdir().unwrap();
    let change = format!(
        "focal_change: {}\n    principal_point_change_px: [-3, -3]",
        1.0 / 1.01 - 1.0
    );
    let world = changed_lenses_world(dir.path(), &change);
    let calibrate = |out: &str, set: &str| {
        calibrate_world(&world, out, &["--json", "--refine-intrinsics", set])
    };
    let truth = world.join("truth.json");
    // Held: the gates flag the calibration (exit 3).
    let o = calibrate("held", "none");
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    // Refined: focal lengths within 0.05 px, principal points within 0.2 px, exit 0, and the
    // refined intrinsics in the report and in the written camchain.
    let o = calibrate("refined", "focal+center");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
    let written =
        ibc_camera_models::Rig::read_kalibr(world.join("refined").join(output_names::CAMCHAIN))
            .unwrap();
    for (c, camera) in report["cameras"].as_array().unwrap().iter().enumerate() {
        let refined = camera["intrinsics_refinement"]["refined"]
            .as_array()
            .unwrap();
        assert_eq!(refined.len(), 4);
        for p in refined {
            let name = p["name"].as_str().unwrap();
            let bar = if name.starts_with('m') { 0.05 } else { 0.2 };
            let error = p["error"].as_f64().unwrap();
            assert!(error.abs() <= bar, "camera {c} {name}: {error} px");
        }
        let params = ibc_camera_models::CameraModel::params(&written.cameras[c].camera);
        for (k, v) in params.iter().enumerate() {
            let t = truth["intrinsics"][c][k].as_f64().unwrap();
            assert!((v - t).abs() <= 0.2, "camera {c} parameter {k}: {v} vs {t}");
        }
    }
    let kinds: Vec<&str> = report["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, vec!["intrinsics_changed"; 8], "{kinds:?}");
    // A set that is not one is a usage error naming the choices.
    let o = calibrate("bad", "focal+skew");
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("focal+center"), "{}", stderr(&o));
}

#[test]
fn online_replays_the_log_and_follows_a_drifting_focal_length() {
    // Every focal length drifts +0.5 % over the drive (a scenario file's `focal_drift`).
    let dir = tempfile::tempdir().unwrap();
    let world = changed_lenses_world(dir.path(), "focal_drift: 0.005");
    let o = calibrate_world(&world, "out", &["--online"]);
    let out = stdout(&o);
    let (mut updates, mut skips, mut checks, mut within) = (0, 0, 0, 0);
    let mut worst = 0.0f64;
    for line in out.lines().filter(|l| l.starts_with("online, frame set")) {
        if line.contains("skipped: the rig turned") {
            skips += 1;
            continue;
        }
        assert!(line.contains("updated: "), "{line}");
        updates += 1;
        // `mu 396.606 (std 0.016, error +0.048)` per focal length.
        for part in line.split("(std ").skip(1) {
            let (std, rest) = part.split_once(", error ").unwrap();
            let error = rest.split(')').next().unwrap();
            let k = error.parse::<f64>().unwrap().abs() / std.parse::<f64>().unwrap();
            worst = worst.max(k);
            checks += 1;
            within += usize::from(k <= 3.0);
        }
    }
    // The drive starts straight: the first due updates are skipped, and say why.
    assert!(skips >= 1 && updates >= 10, "{out}");
    assert_eq!(checks, updates * 8);
    assert!(
        within as f64 >= 0.95 * checks as f64,
        "{within} of {checks}\n{out}"
    );
    assert!(worst <= 4.0, "{worst}\n{out}");
}
