//! The features really are projections of the truth within the noise; the noise, the
//! spurious features, the map-point error and the odometry have the sizes asked for.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use ibc_camera_models::CameraModel;
use ibc_pipeline::data::OdometryKind;
use ibc_pipeline::sim::{SimulatedWorld, scenario_list};
use nalgebra::{Isometry3, Vector3};
use sim_common::small;

/// Residuals (keypoint minus the projection of the true map point) of every log feature on a
/// map point, per axis.
fn log_residuals(w: &SimulatedWorld) -> Vec<f64> {
    let mut r = Vec::new();
    for (f, frame) in w.log.frames.iter().enumerate() {
        for (c, image) in frame.images.iter().enumerate() {
            let cam = &w.rig.cameras[c];
            let camera_from_world = (w.truth.world_from_rig[f] * cam.rig_from_camera).inverse();
            for (k, id) in w.log_point_ids[f][c].iter().enumerate() {
                let Some(id) = id else { continue };
                let x = camera_from_world * w.true_map_points[*id as usize];
                let predicted = cam.camera.project(&x.coords).unwrap();
                let kp = image.keypoints[k];
                assert!(cam.camera.in_image(&kp));
                r.push(kp.x - predicted.x);
                r.push(kp.y - predicted.y);
            }
        }
    }
    r
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn log_features_are_noisy_projections_of_the_true_map_points() {
    let w = SimulatedWorld::simulate(&small("garage").with_seed(21)).unwrap();
    let r = log_residuals(&w);
    assert!(r.len() > 50_000, "only {} residuals", r.len());
    // sigma 0.5 px per axis: the RMS of ~10^5 samples is within 2% (standard error 0.2%).
    let rms = rms(&r);
    assert!((rms - 0.5).abs() < 0.01, "rms residual {rms} px");
    let max = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(max < 3.0, "largest residual {max} px is past 6 sigma");
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    assert!(mean.abs() < 0.01, "mean residual {mean} px");

    let mut exact = small("garage").with_seed(21);
    exact.noise.pixel_sigma_px = 0.0;
    let w = SimulatedWorld::simulate(&exact).unwrap();
    let max = log_residuals(&w).iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(max < 1e-9, "noiseless residual {max} px");
}

#[test]
fn map_images_observe_their_points_from_their_poses() {
    let w = SimulatedWorld::simulate(&small("street").with_seed(2)).unwrap();
    let n_cams = w.map_rig.cameras.len();
    let mut r = Vec::new();
    for (i, image) in w.map.images.iter().enumerate() {
        let cam = &w.map_rig.cameras[i % n_cams];
        let pose = image.camera_from_world.unwrap();
        let expected = (w.survey_world_from_rig[i / n_cams] * cam.rig_from_camera).inverse();
        assert!(
            (pose.to_homogeneous() - expected.to_homogeneous())
                .abs()
                .max()
                < 1e-12
        );
        for (k, id) in image.point_ids.iter().enumerate() {
            let Some(id) = id else { continue };
            let p = cam
                .camera
                .project(&(pose * w.map.points[*id as usize]).coords)
                .unwrap();
            r.push((image.features.keypoints[k] - p).norm());
        }
    }
    // Each map point is seen in at least two map images.
    let mut seen = vec![0; w.map.points.len()];
    for image in &w.map.images {
        for id in image.point_ids.iter().flatten() {
            seen[*id as usize] += 1;
        }
    }
    assert!(seen.iter().all(|s| *s >= 2));
    // |residual| of a 2D Gaussian with sigma 0.5 has RMS sigma sqrt(2).
    let rms = rms(&r);
    assert!((rms - 0.5 * 2f64.sqrt()).abs() < 0.015, "rms {rms}");
}

#[test]
fn descriptors_differ_by_the_bit_flip_noise() {
    let w = SimulatedWorld::simulate(&small("garage").with_seed(8)).unwrap();
    // One map descriptor per point.
    let mut by_point = vec![None; w.map.points.len()];
    for image in &w.map.images {
        for (k, id) in image.point_ids.iter().enumerate() {
            if let Some(id) = id {
                by_point[*id as usize].get_or_insert(image.features.descriptors[k]);
            }
        }
    }
    let hamming = |a: &[u64; 4], b: &[u64; 4]| -> u32 {
        a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
    };
    let (mut same, mut n_same, mut other, mut n_other) = (0u64, 0u64, 0u64, 0u64);
    for (f, frame) in w.log.frames.iter().enumerate() {
        for (c, image) in frame.images.iter().enumerate() {
            for (k, id) in w.log_point_ids[f][c].iter().enumerate() {
                let Some(id) = id else { continue };
                let d = &image.descriptors[k];
                same += u64::from(hamming(d, &by_point[*id as usize].unwrap()));
                n_same += 1;
                let unrelated = by_point[(*id as usize + 7919) % by_point.len()].unwrap();
                other += u64::from(hamming(d, &unrelated));
                n_other += 1;
            }
        }
    }
    // Two views with bits flipped independently with p = 0.05 differ in 256 * 2p(1-p) = 24.3
    // bits on average; unrelated descriptors in 128.
    let same = same as f64 / n_same as f64;
    let other = other as f64 / n_other as f64;
    assert!(
        (same - 24.32).abs() < 0.5,
        "mean distance between views {same}"
    );
    assert!(
        (other - 128.0).abs() < 1.0,
        "mean distance to other points {other}"
    );
}

#[test]
fn spurious_features_make_up_the_requested_fraction() {
    for (name, fraction) in [("garage", 0.1), ("garage-spurious-30", 0.3)] {
        let w = SimulatedWorld::simulate(&small(name).with_seed(4)).unwrap();
        let total: usize = w.log_point_ids.iter().flatten().map(Vec::len).sum();
        let off_map = w
            .log_point_ids
            .iter()
            .flatten()
            .flatten()
            .filter(|id| id.is_none())
            .count();
        let share = off_map as f64 / total as f64;
        // Spurious features are `fraction` of each image; landmarks missing from the map add
        // a little more.
        assert!(
            share >= fraction - 0.005 && share < fraction + 0.05,
            "{name}: {share}"
        );
        let s = w.stats();
        assert!((s.on_map_points - (1.0 - share)).abs() < 1e-12);
        assert!(
            s.features_per_image > 500.0 && s.features_per_image < 2000.0,
            "{s:?}"
        );
        assert!(s.median_range_m > 5.0 && s.p90_range_m < 30.0, "{s:?}");
    }
}

#[test]
fn map_point_error_has_the_requested_size() {
    let w = SimulatedWorld::simulate(&small("garage-map-error").with_seed(6)).unwrap();
    let d: Vec<f64> = w
        .map
        .points
        .iter()
        .zip(&w.true_map_points)
        .flat_map(|(a, b)| (a - b).iter().copied().collect::<Vec<_>>())
        .collect();
    let rms = rms(&d);
    assert!((rms - 0.02).abs() < 0.001, "rms map error {rms} m");
    let exact = SimulatedWorld::simulate(&small("garage").with_seed(6)).unwrap();
    assert_eq!(exact.map.points, exact.true_map_points);
}

fn planar(p: &Isometry3<f64>) -> bool {
    let z = p.rotation * Vector3::z();
    p.translation.vector.z.abs() < 1e-12 && (z - Vector3::z()).norm() < 1e-12
}

#[test]
fn odometry_follows_the_true_motion_within_its_noise() {
    for name in ["garage", "handheld-6dof"] {
        // 60 to 100 steps: the RMS of the noise is measured to within about 10%.
        let w = SimulatedWorld::simulate(&small(name).with_seed(12).with_scale(0.2)).unwrap();
        let mount = w.truth.rig_from_odometry.unwrap();
        let odo: Vec<Isometry3<f64>> = w
            .log
            .frames
            .iter()
            .map(|f| f.world_from_odometry.unwrap())
            .collect();
        assert_eq!(
            odo[0],
            Isometry3::identity(),
            "{name}: odometry starts at its own origin"
        );
        let mut rot = Vec::new();
        let mut trans = Vec::new();
        for i in 1..odo.len() {
            let truth = (w.truth.world_from_rig[i - 1] * mount).inverse()
                * w.truth.world_from_rig[i]
                * mount;
            let measured = odo[i - 1].inverse() * odo[i];
            let d = truth.translation.vector.norm();
            let e = truth.inverse() * measured;
            rot.push(e.rotation.angle() / d);
            trans.push(e.translation.vector.norm() / d);
            if w.log.odometry == OdometryKind::Planar {
                assert!(
                    planar(&measured) && planar(&truth),
                    "{name}: frame {i} is not planar"
                );
            }
        }
        // 0.0005 rad per metre per axis; 0.5% of the step per axis (1 axis of yaw and 2 of
        // translation when planar, 3 and 3 in 6-DoF).
        let axes = if w.log.odometry == OdometryKind::Planar {
            (1.0, 2.0)
        } else {
            (3.0, 3.0)
        };
        let (r, t) = (rms(&rot), rms(&trans));
        let (er, et) = (0.0005 * f64::sqrt(axes.0), 0.005 * f64::sqrt(axes.1));
        assert!(
            (r / er - 1.0).abs() < 0.35,
            "{name}: rotation noise {r} rad/m, expected {er}"
        );
        assert!(
            (t / et - 1.0).abs() < 0.35,
            "{name}: translation noise {t}, expected {et}"
        );
    }
}

#[test]
fn every_builtin_scenario_simulates_at_a_small_scale() {
    let list = scenario_list();
    for (name, description) in ibc_pipeline::sim::builtin_scenarios() {
        assert!(list.contains(name) && list.contains(description));
        let w = SimulatedWorld::simulate(&small(name).with_seed(1)).unwrap();
        let n = w.log.camera_names.len();
        assert_eq!(w.truth.rig_from_camera.len(), n, "{name}");
        assert_eq!(w.truth.world_from_rig.len(), w.log.frames.len(), "{name}");
        assert_eq!(w.truth.scenario, name);
        assert!(w.log.frames.iter().all(|f| f.images.len() == n));
        let s = w.stats();
        assert!(
            s.features_per_image > 100.0 && s.map_points > 500,
            "{name}: {s:?}"
        );
        let drive = w.scenario.trajectory.motion == ibc_pipeline::sim::Motion::Drive;
        assert_eq!(w.truth.world_from_rig.iter().all(planar), drive, "{name}");
        // The loop turns: the heading covers a full circle over a closed loop.
        let headings: Vec<f64> = w
            .truth
            .world_from_rig
            .iter()
            .map(|p| {
                let x = p.rotation * Vector3::x();
                x.y.atan2(x.x)
            })
            .collect();
        let turned: f64 = headings
            .windows(2)
            .map(|h| {
                (h[1] - h[0] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI
            })
            .sum();
        assert!(
            turned.abs() > 4.0,
            "{name}: the loop turns by only {turned} rad"
        );
    }
}
