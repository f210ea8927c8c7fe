//! Scenario files: round trips, the example files, and every kind of bad file.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use std::path::{Path, PathBuf};

use ibc_pipeline::data::OdometryKind;
use ibc_pipeline::sim::{
    BuiltinRig, EnvironmentKind, Motion, RigSource, Scenario, SimError, SimulatedWorld,
    builtin_scenarios, simulate_to_dir,
};

fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

#[test]
fn every_builtin_scenario_round_trips_through_yaml() {
    for (name, _) in builtin_scenarios() {
        let s = Scenario::builtin(name)
            .unwrap()
            .with_seed(u64::MAX - 3)
            .with_scale(0.1 + 1e-9);
        let text = s.to_yaml_string();
        let back = Scenario::from_yaml_str(&text, Path::new(".")).unwrap();
        assert_eq!(back, s, "{name}:\n{text}");
    }
}

#[test]
fn the_example_scenario_files_load_simulate_and_round_trip() {
    let mut n = 0;
    for entry in std::fs::read_dir(scenarios_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "yaml") {
            continue;
        }
        n += 1;
        let s = Scenario::from_yaml_file(&path).unwrap();
        let back = Scenario::from_yaml_str(&s.to_yaml_string(), Path::new("/elsewhere")).unwrap();
        assert_eq!(back, s, "{}", path.display());
        let w = SimulatedWorld::simulate(&s.clone().with_scale(sim_common::SMALL)).unwrap();
        assert!(
            w.stats().features_per_image > 100.0,
            "{}: {:?}",
            path.display(),
            w.stats()
        );
    }
    assert!(n >= 3);
    // The written-out default is the built-in default but for its description.
    let mut garage = Scenario::from_yaml_file(scenarios_dir().join("garage.yaml")).unwrap();
    garage.description = Scenario::builtin("garage").unwrap().description;
    assert_eq!(garage, Scenario::builtin("garage").unwrap());
}

#[test]
fn a_kalibr_rig_is_mounted_and_changed_as_the_file_says() {
    let s = Scenario::from_yaml_file(scenarios_dir().join("kalibr-stereo-car.yaml")).unwrap();
    assert_eq!(s.environment, EnvironmentKind::Street);
    assert!(matches!(s.rig, RigSource::File { .. }));
    let map_rig = s.map_rig().unwrap();
    let names: Vec<&str> = map_rig
        .rig
        .cameras
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    assert_eq!(names, ["cam0", "cam1", "cam2"]);
    // Camera 0 sits where the mount says, looking forward.
    let cam0 = map_rig.rig.cameras[0].rig_from_camera;
    assert!((cam0.translation.vector - nalgebra::Vector3::new(1.9, 0.055, 1.35)).norm() < 1e-12);
    assert!((cam0.rotation * nalgebra::Vector3::z() - nalgebra::Vector3::x()).norm() < 1e-12);
    // The rear camera looks backward; the change turns it 2 degrees about its y-axis.
    let truth = s.true_rig().unwrap();
    let rear = &truth.rig.cameras[2].rig_from_camera;
    let turned = map_rig.rig.cameras[2]
        .rig_from_camera
        .rotation
        .angle_to(&rear.rotation);
    assert!((turned.to_degrees() - 2.0).abs() < 1e-9);
    assert!((rear.rotation * nalgebra::Vector3::z()).x < -0.99);
}

#[test]
fn simulate_to_dir_writes_the_four_files() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("small.yaml");
    std::fs::write(&path, "version: 1\nbase: garden-pentagon\nscale: 0.05\n").unwrap();
    let out = dir.path().join("out");
    let (world, files) = simulate_to_dir(path.to_str().unwrap(), Some(99), &out).unwrap();
    assert_eq!(world.truth.seed, 99);
    assert_eq!(world.scenario.rig, RigSource::Builtin(BuiltinRig::Pentagon));
    for f in [&files.map, &files.log, &files.cameras, &files.truth] {
        assert!(f.starts_with(&out) && f.is_file(), "{}", f.display());
    }
    let err = simulate_to_dir("no-such-scenario", None, &out).unwrap_err();
    assert!(matches!(err, SimError::UnknownScenario { .. }));
    assert!(
        err.to_string().contains("garage-left-roll-30"),
        "the error lists the names: {err}"
    );
}

/// Parses `body` (after `version: 1`) and expects an error whose message has `words`.
fn rejects(body: &str, words: &str) {
    let text = format!("version: 1\n{body}");
    let err =
        Scenario::from_yaml_str(&text, &scenarios_dir()).expect_err(&format!("accepted:\n{text}"));
    assert!(
        err.to_string().contains(words),
        "`{err}` does not say `{words}`"
    );
}

#[test]
fn bad_scenario_files_are_errors_that_name_the_key() {
    let e = Scenario::from_yaml_str("seed: 1\n", Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("missing key `version`"), "{e}");
    let e = Scenario::from_yaml_str("version: 2\n", Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("scenario version 1"), "{e}");
    let e = Scenario::from_yaml_str("", Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("empty"), "{e}");
    let e = Scenario::from_yaml_str("version: 1\nrig: [unclosed\n", Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("not valid YAML"), "{e}");
    let e = Scenario::from_yaml_str("- a list\n", Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("mapping"), "{e}");

    rejects("noize: {pixel_sigma_px: 1}\n", "unknown key `noize`");
    rejects(
        "noise: {pixel_sigma: 1}\n",
        "unknown key `pixel_sigma` in `noise`",
    );
    rejects("noise: {pixel_sigma_px: -1}\n", "noise.pixel_sigma_px = -1");
    rejects(
        "noise: {pixel_sigma_px: high}\n",
        "`noise.pixel_sigma_px` must be a finite number",
    );
    rejects(
        "noise: {spurious_fraction: 0.99}\n",
        "noise.spurious_fraction",
    );
    rejects("detection: {full_range_m: 40}\n", "detection.max_range_m");
    rejects("scale: 0\n", "scale = 0");
    rejects("scale: 1.5\n", "scale = 1.5");
    rejects("seed: -4\n", "`seed`");
    rejects("base: parking\n", "unknown scenario `parking`");
    rejects("environment: moon\n", "`environment` is `moon`");
    rejects(
        "trajectory: {motion: fly}\n",
        "`trajectory.motion` is `fly`",
    );
    rejects("trajectory: {frames: 1}\n", "trajectory.frames = 1");
    rejects(
        "trajectory: {frames: 2.5}\n",
        "`trajectory.frames` must be a non-negative integer",
    );
    rejects(
        "trajectory: {motion: handheld}\n",
        "planar (wheel) odometry needs planar motion",
    );
    rejects("odometry: gps\n", "`odometry` is `gps`");
    rejects("rig: {builtin: bus}\n", "`rig.builtin` is `bus`");
    rejects(
        "rig: {}\n",
        "exactly one of `builtin`, `kalibr`, `camodocal` (found none)",
    );
    rejects(
        "rig: {builtin: pentagon, kalibr: x.yaml}\n",
        "found builtin, kalibr",
    );
    rejects(
        "rig: {builtin: pentagon, mount: {translation: [0, 0, 1]}}\n",
        "`rig.mount` is only for rigs from files",
    );
    rejects("rig: {kalibr: rigs/missing.yaml}\n", "missing.yaml");
    rejects("rig: {camodocal: rigs}\n", "extrinsic.txt");
    rejects(
        "rig: {kalibr: rigs/stereo-rear-camchain.yaml, mount: {rotation_wxyz: [1, 1, 0, 0]}}\n",
        "`rig.mount.rotation_wxyz` must be a unit quaternion",
    );
    rejects(
        "rig: {kalibr: rigs/stereo-rear-camchain.yaml, mount: {translation: [0, 1]}}\n",
        "`rig.mount.translation` must be a list of 3 numbers",
    );
    rejects(
        "rig: {kalibr: rigs/stereo-rear-camchain.yaml, field_of_view_deg: 0}\n",
        "rig.field_of_view_deg",
    );
    rejects(
        "changes: [{camera: roof}]\n",
        "`changes[0].camera` is `roof`, not a camera of the rig",
    );
    rejects(
        "changes: [{camera: 4}]\n",
        "`changes[0].camera` is 4 but the rig has 4 cameras",
    );
    rejects(
        "changes: [{translation_m: [0, 0, 0]}]\n",
        "missing key `changes[0].camera`",
    );
    rejects(
        "changes: [{camera: left, turn: [0, 0, 1]}]\n",
        "unknown key `turn` in `changes[0]`",
    );
    rejects("changes: {camera: left}\n", "`changes` must be a list");
    // A base's changes must name cameras of the rig that replaces the base's.
    rejects(
        "base: garage-moved-cameras\nrig: {kalibr: rigs/stereo-rear-camchain.yaml}\n",
        "`left`",
    );

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.yaml");
    std::fs::write(&path, "version: 1\nnoize: 1\n").unwrap();
    let e = Scenario::from_yaml_file(&path).unwrap_err();
    assert!(
        e.to_string().contains("bad.yaml") && e.to_string().contains("noize"),
        "{e}"
    );
    let e = Scenario::from_yaml_file(dir.path().join("none.yaml")).unwrap_err();
    assert!(matches!(e, SimError::Io(_)), "{e}");
}

#[test]
fn defaults_fill_what_a_file_leaves_out() {
    let s = Scenario::from_yaml_str(
        "version: 1\nbase: handheld-6dof\nseed: 5\nnoise: {pixel_sigma_px: 1.5}\n",
        Path::new("."),
    )
    .unwrap();
    let mut expected = Scenario::builtin("handheld-6dof").unwrap().with_seed(5);
    expected.noise.pixel_sigma_px = 1.5;
    assert_eq!(s, expected);
    assert_eq!(s.trajectory.motion, Motion::Handheld);
    assert_eq!(s.odometry, OdometryKind::SixDof);
}

#[test]
fn lens_changes_reach_the_log_not_the_camera_file_and_round_trip() {
    let text = "version: 1\nscale: 0.05\nchanges:\n  - camera: left\n    focal_change: -0.01\n    \
                principal_point_change_px: [2, -1]\n";
    let s = Scenario::from_yaml_str(text, Path::new(".")).unwrap();
    let back = Scenario::from_yaml_str(&s.to_yaml_string(), Path::new(".")).unwrap();
    assert_eq!(back, s);
    let world = SimulatedWorld::simulate(&s).unwrap();
    // The camera file (the map-building rig) keeps the old lens; the truth holds the new one.
    let old = ibc_camera_models::CameraModel::params(&world.map_rig.cameras[1].camera).to_vec();
    let new = &world.truth.intrinsics[1];
    assert!((new[4] / old[4] - 0.99).abs() < 1e-12 && (new[5] / old[5] - 0.99).abs() < 1e-12);
    assert!((new[6] - old[6] - 2.0).abs() < 1e-12 && (new[7] - old[7] + 1.0).abs() < 1e-12);
    assert_eq!(
        world.truth.intrinsics[0],
        ibc_camera_models::CameraModel::params(&world.map_rig.cameras[0].camera)
    );
    rejects(
        "changes:\n  - camera: left\n    focal_change: 0.7\n",
        "focal_change = 0.7, not in (-0.5, 0.5)",
    );
    rejects(
        "changes:\n  - camera: left\n    principal_point_change_px: [1]\n",
        "principal_point_change_px` must be a list of 2 numbers",
    );
}
