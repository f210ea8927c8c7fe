//! The experiment presets change exactly what they say, relative to the configuration that
//! built the map, which is what the written camera file holds.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use approx::assert_abs_diff_eq;
use ibc_camera_models::Rig;
use ibc_pipeline::sim::{CameraChange, Scenario, SimulatedWorld};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use sim_common::small;

/// `map_rig_camera^-1 * true_camera` is `Translation(t_rig) * map * Rotation(r)`: returns the
/// translation of the camera centre in the rig frame and the rotation in the camera frame.
fn change(map: &Isometry3<f64>, truth: &Isometry3<f64>) -> (Vector3<f64>, UnitQuaternion<f64>) {
    let in_camera = map.rotation.inverse() * truth.rotation;
    (truth.translation.vector - map.translation.vector, in_camera)
}

fn check(name: &str, expected: &[(&str, Vector3<f64>, UnitQuaternion<f64>)]) {
    let w = SimulatedWorld::simulate(&small(name).with_seed(3)).unwrap();
    let reference = SimulatedWorld::simulate(&small("garage").with_seed(3)).unwrap();
    // The map is the same: the map-building rig did not change.
    assert!(
        w.map == reference.map,
        "{name}: the map differs from the default scenario's"
    );
    assert_eq!(w.map_rig, reference.map_rig);
    for (i, cam) in w.map_rig.cameras.iter().enumerate() {
        let truth = w.truth.rig_from_camera[i];
        assert_eq!(truth, w.rig.cameras[i].rig_from_camera);
        let (t, r) = change(&cam.rig_from_camera, &truth);
        let (et, er) = expected.iter().find(|(n, _, _)| *n == cam.name).map_or(
            (Vector3::zeros(), UnitQuaternion::identity()),
            |(_, t, r)| (*t, *r),
        );
        assert_abs_diff_eq!(t, et, epsilon = 1e-12);
        assert!(
            r.angle_to(&er) < 1e-12,
            "{name}: camera {} turned by {r:?}",
            cam.name
        );
    }
    // The camera file written holds the map-building configuration, never the truth.
    let dir = tempfile::tempdir().unwrap();
    let files = w.write(dir.path()).unwrap();
    let written = Rig::read_kalibr(&files.cameras).unwrap();
    let rel = |a: &Isometry3<f64>, b: &Isometry3<f64>| a.inverse() * b;
    for i in 1..written.cameras.len() {
        let from_file = rel(
            &written.cameras[0].rig_from_camera,
            &written.cameras[i].rig_from_camera,
        );
        let map = rel(
            &w.map_rig.cameras[0].rig_from_camera,
            &w.map_rig.cameras[i].rig_from_camera,
        );
        assert!(
            (from_file.to_homogeneous() - map.to_homogeneous())
                .abs()
                .max()
                < 1e-12
        );
    }
}

#[test]
fn the_default_scenario_calibrates_the_rig_that_built_the_map() {
    check("garage", &[]);
}

#[test]
fn moved_cameras_are_moved_forward_by_9_7_and_10_cm() {
    let id = UnitQuaternion::identity();
    check(
        "garage-moved-cameras",
        &[
            ("left", Vector3::new(0.097, 0.0, 0.0), id),
            ("right", Vector3::new(0.100, 0.0, 0.0), id),
        ],
    );
}

#[test]
fn the_left_camera_is_turned_30_degrees_about_its_x_axis() {
    let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 30f64.to_radians());
    check("garage-left-roll-30", &[("left", Vector3::zeros(), r)]);
}

#[test]
fn the_left_camera_is_turned_15_degrees_about_its_z_axis() {
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 15f64.to_radians());
    check("garage-left-yaw-15", &[("left", Vector3::zeros(), r)]);
}

#[test]
fn a_change_naming_no_camera_is_an_error() {
    let mut s = Scenario::builtin("garage").unwrap();
    s.changes.push(CameraChange::moved("roof", Vector3::x()));
    let err = SimulatedWorld::simulate(&s).unwrap_err();
    assert!(err.to_string().contains("`roof`"), "{err}");
}
