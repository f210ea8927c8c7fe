//! File round trips (map, log, ground truth, cameras), descriptor kinds, write errors and
//! atomic writes.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use ibc_camera_models::{CameraModel, Rig};
use ibc_pipeline::data::io::{
    DataFileError, FormatError, read_descriptor_layout, read_log, read_map, read_truth,
    truth_from_json, truth_to_json, write_log, write_map, write_truth,
};
use ibc_pipeline::data::{
    BinaryDescriptor, FloatDescriptor, Frame, ImageFeatures, Map, MapImage, OdometryKind, RigLog,
};
use ibc_vocab_tree::DescriptorKind;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn dir_entries(dir: &std::path::Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_simulated_world_reads_back_exactly() {
    let world = sim_common::world("garage-map-error", 3);
    let dir = tempfile::tempdir().unwrap();
    let files = world.write(dir.path()).unwrap();
    assert_eq!(
        dir_entries(dir.path()),
        ["camchain.yaml", "log.ibclog", "map.ibcmap", "truth.json"],
        "no temporary files are left"
    );
    assert!(read_map::<BinaryDescriptor>(&files.map).unwrap() == world.map);
    assert!(read_log::<BinaryDescriptor>(&files.log).unwrap() == world.log);
    assert_eq!(read_truth(&files.truth).unwrap(), world.truth);
    let layout = read_descriptor_layout(&files.log).unwrap();
    assert_eq!((layout.kind, layout.width), (DescriptorKind::Binary, 4));

    // The camchain holds the map-building rig: the same intrinsics, and the same poses
    // relative to camera 0 (Kalibr stores poses relative to the previous camera).
    let rig = Rig::read_kalibr(&files.cameras).unwrap();
    assert_eq!(rig.cameras.len(), world.map_rig.cameras.len());
    let base = world.map_rig.cameras[0].rig_from_camera.inverse();
    for (read, sim) in rig.cameras.iter().zip(&world.map_rig.cameras) {
        assert_eq!(read.camera.params(), sim.camera.params());
        assert_eq!(read.topic, sim.topic, "names survive as topics");
        let expected = base * sim.rig_from_camera;
        let err = (read.rig_from_camera.inverse() * expected).to_homogeneous()
            - nalgebra::Matrix4::identity();
        assert!(err.abs().max() < 1e-12, "{}: {err}", sim.name);
    }
}

#[test]
fn writing_again_replaces_the_files() {
    let dir = tempfile::tempdir().unwrap();
    let a = sim_common::world("garage", 1);
    let b = sim_common::world("garage", 2);
    let files = a.write(dir.path()).unwrap();
    b.write(dir.path()).unwrap();
    assert!(read_map::<BinaryDescriptor>(&files.map).unwrap() == b.map);
    assert_eq!(dir_entries(dir.path()).len(), 4);
}

fn random_pose(rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    let axis = Vector3::new(rng.random(), rng.random(), rng.random::<f64>()) - Vector3::repeat(0.5);
    Isometry3::from_parts(
        Translation3::new(rng.random(), rng.random(), rng.random()),
        UnitQuaternion::from_scaled_axis(axis * 3.0),
    )
}

/// A map with `D` descriptors drawn by `desc`, with the edge cases: an image with no
/// features, images with and without poses, features with and without points.
fn handmade_map<D>(rng: &mut ChaCha8Rng, desc: impl Fn(&mut ChaCha8Rng) -> D) -> Map<D> {
    let points = (0..50)
        .map(|_| Point3::new(rng.random(), rng.random(), rng.random::<f64>() * 10.0))
        .collect();
    let mut images = vec![MapImage {
        camera_from_world: None,
        features: ImageFeatures {
            keypoints: vec![],
            descriptors: vec![],
        },
        point_ids: vec![],
    }];
    for i in 0..5 {
        let n = 7 * i + 1;
        images.push(MapImage {
            camera_from_world: (i % 2 == 0).then(|| random_pose(rng)),
            features: ImageFeatures {
                keypoints: (0..n)
                    .map(|_| {
                        Vector2::new(rng.random::<f64>() * 1280.0, rng.random::<f64>() * 960.0)
                    })
                    .collect(),
                descriptors: (0..n).map(|_| desc(rng)).collect(),
            },
            point_ids: (0..n)
                .map(|k| (k % 3 != 0).then(|| rng.random_range(0..50u32)))
                .collect(),
        });
    }
    Map { points, images }
}

fn handmade_log<D>(
    rng: &mut ChaCha8Rng,
    desc: impl Fn(&mut ChaCha8Rng) -> D,
    kind: OdometryKind,
) -> RigLog<D> {
    let frames = (0..6)
        .map(|i| Frame {
            timestamp: 0.1 * f64::from(i),
            images: (0..3)
                .map(|c| {
                    let n = (i * 3 + c) as usize % 5;
                    ImageFeatures {
                        keypoints: (0..n)
                            .map(|_| Vector2::new(rng.random(), rng.random()))
                            .collect(),
                        descriptors: (0..n).map(|_| desc(rng)).collect(),
                    }
                })
                .collect(),
            world_from_odometry: (kind != OdometryKind::None && i != 2).then(|| random_pose(rng)),
        })
        .collect();
    RigLog {
        camera_names: vec!["front".into(), "left camera".into(), "ü".into()],
        odometry: kind,
        frames,
    }
}

fn surf(rng: &mut ChaCha8Rng) -> FloatDescriptor {
    std::array::from_fn(|_| rng.random::<f32>() - 0.5)
}

fn orb(rng: &mut ChaCha8Rng) -> BinaryDescriptor {
    std::array::from_fn(|_| rng.random())
}

#[test]
fn binary_and_surf_descriptors_round_trip() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let dir = tempfile::tempdir().unwrap();
    let (mp, lp) = (dir.path().join("m.ibcmap"), dir.path().join("l.ibclog"));

    let map = handmade_map(&mut rng, surf);
    write_map(&mp, &map).unwrap();
    assert_eq!(read_map::<FloatDescriptor>(&mp).unwrap(), map);
    let layout = read_descriptor_layout(&mp).unwrap();
    assert_eq!((layout.kind, layout.width), (DescriptorKind::Float, 64));
    let err = read_map::<BinaryDescriptor>(&mp).unwrap_err();
    assert!(
        matches!(
            &err,
            DataFileError::Format {
                source: FormatError::DescriptorMismatch { .. },
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("float (64 f32 values)"), "{err}");

    for kind in [
        OdometryKind::None,
        OdometryKind::Planar,
        OdometryKind::SixDof,
    ] {
        let log = handmade_log(&mut rng, surf, kind);
        write_log(&lp, &log).unwrap();
        assert_eq!(read_log::<FloatDescriptor>(&lp).unwrap(), log);
        let log = handmade_log(&mut rng, orb, kind);
        write_log(&lp, &log).unwrap();
        assert_eq!(read_log::<BinaryDescriptor>(&lp).unwrap(), log);
    }
    // Wider binary descriptors (512 bits) are a different layout.
    let map = handmade_map(&mut rng, |r: &mut ChaCha8Rng| -> [u64; 8] {
        std::array::from_fn(|_| r.random())
    });
    write_map(&mp, &map).unwrap();
    assert_eq!(read_map::<[u64; 8]>(&mp).unwrap(), map);
    assert!(read_map::<BinaryDescriptor>(&mp).is_err());

    let empty: Map<BinaryDescriptor> = Map::default();
    write_map(&mp, &empty).unwrap();
    assert_eq!(read_map::<BinaryDescriptor>(&mp).unwrap(), empty);
}

#[test]
fn invalid_data_is_refused_before_anything_is_written() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let dir = tempfile::tempdir().unwrap();
    let mp = dir.path().join("m.ibcmap");
    let lp = dir.path().join("l.ibclog");
    let good = handmade_map(&mut rng, orb);

    let mut bad = good.clone();
    bad.images[1].point_ids[0] = Some(50);
    let mut bad_len = good.clone();
    bad_len.images[2].features.descriptors.pop();
    let mut bad_kp = good.clone();
    bad_kp.images[3].features.keypoints[0].x = f64::NAN;
    let mut bad_point = good.clone();
    bad_point.points[4].y = f64::INFINITY;
    for (what, map) in [
        ("point id", bad),
        ("lengths", bad_len),
        ("keypoint", bad_kp),
        ("point", bad_point),
    ] {
        let err = write_map(&mp, &map).unwrap_err();
        assert!(
            matches!(
                err,
                DataFileError::Format {
                    source: FormatError::Invalid { .. },
                    ..
                }
            ),
            "{what}: {err}"
        );
        assert!(
            err.to_string().contains("m.ibcmap"),
            "the error names the file: {err}"
        );
    }

    let log = handmade_log(&mut rng, orb, OdometryKind::Planar);
    let mut no_odometry_kind = log.clone();
    no_odometry_kind.odometry = OdometryKind::None;
    let mut out_of_order = log.clone();
    out_of_order.frames[3].timestamp = -1.0;
    let mut missing_camera = log.clone();
    missing_camera.frames[1].images.pop();
    let mut duplicate = log.clone();
    duplicate.camera_names[2] = "front".into();
    let mut no_cameras = log.clone();
    no_cameras.camera_names.clear();
    for (what, log) in [
        ("odometry without a kind", no_odometry_kind),
        ("time order", out_of_order),
        ("image count", missing_camera),
        ("duplicate name", duplicate),
        ("no camera", no_cameras),
    ] {
        let err = write_log(&lp, &log).unwrap_err();
        assert!(
            matches!(
                err,
                DataFileError::Format {
                    source: FormatError::Invalid { .. },
                    ..
                }
            ),
            "{what}: {err}"
        );
    }
    assert!(
        dir_entries(dir.path()).is_empty(),
        "nothing was written: {:?}",
        dir_entries(dir.path())
    );

    let missing = dir.path().join("no/such/folder/m.ibcmap");
    let err = write_map(&missing, &good).unwrap_err();
    assert!(matches!(err, DataFileError::Io { .. }), "{err}");
    assert_eq!(err.path(), missing);
    let err = read_map::<BinaryDescriptor>(&missing).unwrap_err();
    assert!(err.to_string().contains("no/such/folder"), "{err}");
}

#[test]
fn ground_truth_json_round_trips_and_is_validated() {
    let world = sim_common::world("handheld-6dof", 4);
    let text = truth_to_json(&world.truth).unwrap();
    assert_eq!(truth_from_json(&text).unwrap(), world.truth);
    assert!(text.contains("\"rotation_wxyz\""));
    let dir = tempfile::tempdir().unwrap();
    write_truth(dir.path().join("t.json"), &world.truth).unwrap();
    assert_eq!(read_truth(dir.path().join("t.json")).unwrap(), world.truth);

    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let q = &value["rig_from_camera"][0]["rotation_wxyz"];
    let norm: f64 = q
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((norm - 1.0).abs() < 1e-12);

    let mutate = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = value.clone();
        f(&mut v);
        truth_from_json(&v.to_string())
    };
    type Edit<'a> = &'a dyn Fn(&mut serde_json::Value);
    let bad: [(&str, Edit); 5] = [
        ("non-unit quaternion", &|v| {
            v["world_from_rig"][3]["rotation_wxyz"][0] = 2.0.into()
        }),
        ("unknown field", &|v| v["extra"] = 1.into()),
        ("missing field", &|v| {
            v.as_object_mut().unwrap().remove("seed");
        }),
        ("wrong format", &|v| v["format"] = "camchain".into()),
        ("future version", &|v| v["version"] = 2.into()),
    ];
    for (what, f) in bad {
        assert!(mutate(f).is_err(), "{what} was accepted");
    }
    assert!(truth_from_json("{").is_err());
}
