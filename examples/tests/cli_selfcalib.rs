#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! `ibc selfcalib` and `ibc map` through the binary (issue 17): the rig's extrinsics from its
//! own log, the outputs of `ibc calibrate` (JSON report with `scale_source`, table, Kalibr
//! camchain, CamOdoCal folder); a map built from the log that `ibc calibrate` then calibrates
//! against; bad input as one line, a non-zero exit and nothing written.

mod cli_common;

use cli_common::{entries, ibc, scenario_file, stderr, stdout};
use ibc_camera_models::Rig;

/// Simulates the garage at `scale` into `<dir>/world` and returns that folder.
fn simulated_garage(dir: &std::path::Path, scale: f64) -> std::path::PathBuf {
    let world = dir.join("world");
    let scenario = scenario_file(dir, "garage", scale);
    let o = ibc(&[
        "simulate",
        "--quiet",
        "--scenario",
        &scenario,
        "--out",
        world.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    world
}

#[test]
fn selfcalib_and_map_on_a_simulated_garage() {
    let dir = tempfile::tempdir().unwrap();
    let world = simulated_garage(dir.path(), 0.2);
    let out = dir.path().join("out");
    let path = |name: &str| world.join(name).to_str().unwrap().to_owned();
    let o = ibc(&[
        "selfcalib",
        "--quiet",
        "--json",
        "--log",
        &path("log.ibclog"),
        "--cameras",
        &path("camchain.yaml"),
        "--truth",
        &path("truth.json"),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(report["format"], "ibc-selfcalibration-report");
    assert_eq!(report["scale_source"], "odometry");
    assert_eq!(report["translation_unit"], "m");
    assert_eq!(report["status"], "ok");
    let cameras = report["cameras"].as_array().unwrap();
    assert_eq!(cameras.len(), 4);
    for c in cameras {
        // Rotations within the bar; translations in metres, the odometry's scale error
        // (0.04 % here) included: a few millimetres on baselines of metres.
        let rotation = c["rotation_error_deg"].as_f64().unwrap();
        let translation = c["translation_error_m"].as_f64().unwrap();
        assert!(rotation <= 0.003, "{c}");
        assert!(translation <= 0.004, "{c}");
    }
    assert!(
        cameras[1]["rig_from_camera_std"]["rotation_deg"][0]
            .as_f64()
            .unwrap()
            > 0.0
    );
    let mut files = entries(&out);
    files.sort();
    assert_eq!(
        files,
        [
            "camchain-calibrated.yaml",
            "camodocal",
            "colmap",
            "report.json",
            "report.txt",
            "rig_config.json",
            "top_view.svg"
        ]
    );
    // The calibration as a COLMAP model: the four cameras and one rig.
    let model = ibc_pipeline::colmap::read_model(out.join("colmap")).unwrap();
    assert_eq!((model.cameras.len(), model.rigs.len()), (4, 1));
    assert!(model.images.is_empty() && model.points3d.is_empty());
    assert_eq!(entries(&out.join("camodocal")).len(), 5);
    let svg = std::fs::read_to_string(out.join("top_view.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.matches("<circle").count() > 1000);
    assert!(
        svg.contains("reconstructed points") && svg.contains("rear"),
        "{}",
        svg.lines()
            .filter(|l| l.contains("<text"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    // The written camchain reads back with the estimated extrinsics.
    let rig = Rig::read_kalibr(out.join("camchain-calibrated.yaml")).unwrap();
    assert_eq!(rig.cameras.len(), 4);
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(written, report);

    // `ibc map` on the same log with the calibrated rig (its extrinsics refined: the camera
    // file is the truth, so they stay within a millimetre), then `ibc calibrate` against it.
    let built = dir.path().join("built.ibcmap");
    let o = ibc(&[
        "map",
        "--quiet",
        "--json",
        "--refine-extrinsics",
        "--colmap",
        dir.path().join("built-colmap").to_str().unwrap(),
        "--log",
        &path("log.ibclog"),
        "--cameras",
        &path("camchain.yaml"),
        "--out",
        built.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let summary: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(summary["points"].as_u64().unwrap() > 10_000, "{summary}");
    assert!(
        summary["reprojection_error_px"].as_f64().unwrap() < 1.0,
        "{summary}"
    );
    assert_eq!(summary["extrinsics"], "refined", "{summary}");
    // The log has wheel odometry: the averaging used its distances on the straights.
    assert!(
        summary["odometry_distances"].as_u64().unwrap() > 0,
        "{summary}"
    );
    assert!(summary["covariance_error"].is_null(), "{summary}");
    // The same map as COLMAP data reads back with every point.
    let colmap = dir.path().join("built-colmap");
    let read = ibc_pipeline::colmap::read_colmap_map::<[u64; 4]>(
        colmap.join("sparse"),
        colmap.join("database.db"),
    )
    .unwrap();
    assert_eq!(
        read.map.points.len() as u64,
        summary["points"].as_u64().unwrap()
    );
    assert!(colmap.join("rig_config.json").is_file());
    let cameras = summary["cameras"].as_array().unwrap();
    assert_eq!(cameras.len(), 4, "{summary}");
    for c in cameras {
        assert!(c["moved_mm"].as_f64().unwrap() < 1.0, "{c}");
        assert!(c["turned_deg"].as_f64().unwrap() < 0.01, "{c}");
    }
    let calibrated = dir.path().join("calibrated");
    let o = ibc(&[
        "calibrate",
        "--quiet",
        "--json",
        "--map",
        built.to_str().unwrap(),
        "--log",
        &path("log.ibclog"),
        "--cameras",
        &path("camchain.yaml"),
        "--truth",
        &path("truth.json"),
        "--out",
        calibrated.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    // Camera 0 defines the rig frame (its errors are null); the others within the bars.
    let scored: Vec<_> = report["cameras"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| !c["rotation_error_deg"].is_null())
        .collect();
    assert_eq!(scored.len(), 3, "{report}");
    for c in scored {
        assert!(c["rotation_error_deg"].as_f64().unwrap() <= 0.005, "{c}");
        assert!(c["translation_error_m"].as_f64().unwrap() <= 0.001, "{c}");
    }
}

#[test]
fn bad_input_is_one_line_a_non_zero_exit_and_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let world = simulated_garage(dir.path(), 0.05);
    let path = |name: &str| world.join(name).to_str().unwrap().to_owned();
    let out = dir.path().join("out");
    let cases: [(&[&str], &str); 4] = [
        (&["--baseline", "front:nope=2"], "no camera `nope`"),
        (&["--baseline", "front:rear=-1"], "finite positive"),
        (&["--baseline", "front-rear"], "CAM_A:CAM_B=METRES"),
        (&["--truth", "/nonexistent/truth.json"], "truth"),
    ];
    for (extra, expected) in cases {
        let mut args = vec!["selfcalib", "--quiet", "--log"];
        let log = path("log.ibclog");
        let cameras = path("camchain.yaml");
        args.push(&log);
        args.extend(["--cameras", &cameras, "--out", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let o = ibc(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{extra:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{extra:?}: {err}");
        assert!(err.contains(expected), "{extra:?}: {err}");
        assert!(
            entries(&out).is_empty(),
            "{extra:?} wrote {:?}",
            entries(&out)
        );
    }
    // A camera file of another rig: the count differs, named in one line.
    let o = ibc(&[
        "selfcalib",
        "--quiet",
        "--log",
        &path("map.ibcmap"),
        "--cameras",
        &path("camchain.yaml"),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1);
    assert!(entries(&out).is_empty());
}
