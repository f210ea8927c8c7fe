//! COLMAP data in and out (issue 19): fixtures written by COLMAP itself (pycolmap 4.2.1, by
//! `tests/data/colmap/make_fixtures.py`, which also dumps every value into `expected.json`)
//! read exactly; a simulated world written as COLMAP data and read back; bad input refused
//! with typed errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use approx::assert_relative_eq;
use ibc_pipeline::colmap::{
    ColmapDatabase, ColmapError, ColmapLogOptions, ColmapModel, NO_POINT3D, SensorKind,
    ibc_cameras, log_from_database, map_from_colmap, read_colmap_log, read_colmap_map, read_model,
    survey_image_sources, write_colmap, write_colmap_log,
};
use ibc_pipeline::ibc_camera_models::{Camera, CameraModel, RigCamera, Unified};
use ibc_pipeline::ibc_vocab_tree::DescriptorKind;
use ibc_pipeline::nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};
use serde_json::Value;

type Sift = [f32; 128];

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/colmap")
}

fn expected() -> Value {
    let text = std::fs::read_to_string(fixtures().join("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap()
}

fn u(v: &Value) -> u64 {
    v.as_u64().unwrap()
}

fn pose(v: &Value) -> Isometry3<f64> {
    let q: Vec<f64> = v["rotation_wxyz"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .collect();
    let t: Vec<f64> = v["translation"].as_array().unwrap().iter().map(f).collect();
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::new_unchecked(Quaternion::new(q[0], q[1], q[2], q[3])),
    )
}

/// Poses agree to a few ulps (COLMAP's quaternions are normalized again on reading).
fn assert_pose(a: &Isometry3<f64>, b: &Isometry3<f64>) {
    assert_relative_eq!(a.translation.vector, b.translation.vector, epsilon = 1e-15);
    assert_relative_eq!(
        a.rotation.quaternion().coords,
        b.rotation.quaternion().coords,
        epsilon = 1e-15
    );
}

/// Compares a model with everything `expected.json` says COLMAP wrote.
fn check_model(model: &ColmapModel, e: &Value) {
    let cameras = e["cameras"].as_array().unwrap();
    assert_eq!(model.cameras.len(), cameras.len());
    for (c, ec) in model.cameras.iter().zip(cameras) {
        assert_eq!(u64::from(c.camera_id), u(&ec["camera_id"]));
        assert_eq!(c.model.name(), ec["model"].as_str().unwrap());
        assert_eq!(c.width, u(&ec["width"]));
        assert_eq!(c.height, u(&ec["height"]));
        let params: Vec<f64> = ec["params"].as_array().unwrap().iter().map(f).collect();
        assert_eq!(c.params, params, "camera {}", c.camera_id);
    }
    let rigs = e["rigs"].as_array().unwrap();
    assert_eq!(model.rigs.len(), rigs.len());
    for (r, er) in model.rigs.iter().zip(rigs) {
        assert_eq!(u64::from(r.rig_id), u(&er["rig_id"]));
        assert_eq!(r.ref_sensor.kind, SensorKind::Camera);
        assert_eq!(u64::from(r.ref_sensor.id), u(&er["ref_camera_id"]));
        let sensors = er["sensors"].as_array().unwrap();
        assert_eq!(r.sensors.len(), sensors.len());
        for ((s, p), es) in r.sensors.iter().zip(sensors) {
            assert_eq!(u64::from(s.id), u(&es["camera_id"]));
            assert_pose(p.as_ref().unwrap(), &pose(es));
        }
    }
    let frames = e["frames"].as_array().unwrap();
    assert_eq!(model.frames.len(), frames.len());
    for (fr, ef) in model.frames.iter().zip(frames) {
        assert_eq!(u64::from(fr.frame_id), u(&ef["frame_id"]));
        assert_eq!(u64::from(fr.rig_id), u(&ef["rig_id"]));
        assert_pose(&fr.rig_from_world, &pose(&ef["rig_from_world"]));
        let mut ids: Vec<u64> = fr.data.iter().map(|d| d.1).collect();
        ids.sort_unstable();
        let eids: Vec<u64> = ef["image_ids"].as_array().unwrap().iter().map(u).collect();
        assert_eq!(ids, eids);
    }
    let images = e["images"].as_array().unwrap();
    assert_eq!(model.images.len(), images.len());
    let mut observations = 0;
    for (i, ei) in model.images.iter().zip(images) {
        assert_eq!(u64::from(i.image_id), u(&ei["image_id"]));
        assert_eq!(i.name, ei["name"].as_str().unwrap());
        assert_eq!(u64::from(i.camera_id), u(&ei["camera_id"]));
        assert_pose(&i.cam_from_world, &pose(&ei["cam_from_world"]));
        let points = ei["points2D"].as_array().unwrap();
        assert_eq!(i.points2d.len(), points.len());
        for (p, ep) in i.points2d.iter().zip(points) {
            assert_eq!(p.xy.x, f(&ep[0]));
            assert_eq!(p.xy.y, f(&ep[1]));
            match ep[2].as_i64().unwrap() {
                -1 => assert_eq!(p.point3d_id, NO_POINT3D),
                id => {
                    assert_eq!(p.point3d_id, id as u64);
                    observations += 1;
                }
            }
        }
    }
    assert_eq!(
        observations, 238,
        "the fixture's observations (pycolmap's summary)"
    );
    let points = e["points3D"].as_array().unwrap();
    assert_eq!(model.points3d.len(), points.len());
    for (p, ep) in model.points3d.iter().zip(points) {
        assert_eq!(p.point3d_id, u(&ep["point3D_id"]));
        let xyz: Vec<f64> = ep["xyz"].as_array().unwrap().iter().map(f).collect();
        assert_eq!([p.xyz.x, p.xyz.y, p.xyz.z], [xyz[0], xyz[1], xyz[2]]);
        let color: Vec<u64> = ep["color"].as_array().unwrap().iter().map(u).collect();
        assert_eq!(p.color.map(u64::from).to_vec(), color);
        assert_eq!(p.error, f(&ep["error"]));
        let track: Vec<(u32, u32)> = ep["track"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| (u(&t[0]) as u32, u(&t[1]) as u32))
            .collect();
        assert_eq!(p.track, track);
    }
}

#[test]
fn colmap_text_and_binary_models_read_exactly() {
    let e = expected();
    let text = read_model(fixtures().join("text")).unwrap();
    let binary = read_model(fixtures().join("binary")).unwrap();
    check_model(&text, &e);
    check_model(&binary, &e);
    // COLMAP writes text with 17 significant digits: the two are the same numbers.
    assert_eq!(text, binary);
}

#[test]
fn colmap_cameras_convert_to_ibc_and_project_as_colmap_does() {
    let e = expected();
    let model = read_model(fixtures().join("binary")).unwrap();
    let cameras = ibc_cameras(&model).unwrap();
    assert!(matches!(cameras[&1], Camera::KannalaBrandt(_)));
    for id in [2, 3, 4] {
        assert!(
            matches!(cameras[&id], Camera::PinholeRadtan(_)),
            "camera {id}"
        );
    }
    // Every observation, projected by ibc's converted camera, lands where COLMAP's own
    // camera model puts it, 0.5 px apart (the pixel conventions).
    let mut checked = 0;
    for (image, ei) in model.images.iter().zip(e["images"].as_array().unwrap()) {
        let camera = &cameras[&image.camera_id];
        for pr in ei["projections"].as_array().unwrap() {
            let point = model
                .points3d
                .iter()
                .find(|p| p.point3d_id == u(&pr[0]))
                .unwrap();
            let uv = camera
                .project(&(image.cam_from_world * point.xyz).coords)
                .unwrap();
            assert!(
                (uv.x + 0.5 - f(&pr[1])).abs() < 1e-9 && (uv.y + 0.5 - f(&pr[2])).abs() < 1e-9,
                "image {}: ibc {uv:?} + 0.5 vs COLMAP ({}, {})",
                image.name,
                pr[1],
                pr[2]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 238);
    // And back: ibc's cameras as COLMAP cameras give the same projection (OPENCV for the
    // pinhole models, OPENCV_FISHEYE for Kannala-Brandt).
    for c in &model.cameras {
        let back =
            ibc_pipeline::colmap::ColmapCamera::from_ibc(c.camera_id, "c", &cameras[&c.camera_id])
                .unwrap();
        assert_eq!(back.to_ibc().unwrap(), cameras[&c.camera_id]);
        if matches!(c.model.name(), "OPENCV" | "OPENCV_FISHEYE") {
            assert_eq!(
                back, *c,
                "an OPENCV / OPENCV_FISHEYE camera writes back the same"
            );
        }
    }
}

#[test]
fn colmap_database_reads_exactly() {
    let e = expected();
    let db = ColmapDatabase::open(fixtures().join("database.db")).unwrap();
    let model = read_model(fixtures().join("text")).unwrap();
    assert_eq!(db.cameras().unwrap(), model.cameras);
    let db_rigs = db.rigs().unwrap();
    assert_eq!(db_rigs, model.rigs);
    let frames = db.frames().unwrap();
    assert_eq!(frames.len(), model.frames.len());
    for (a, b) in frames.iter().zip(&model.frames) {
        assert_eq!(
            (a.frame_id, a.rig_id, &a.data),
            (b.frame_id, b.rig_id, &b.data)
        );
    }
    let images = db.images().unwrap();
    let expected_images = e["database_images"].as_array().unwrap();
    assert_eq!(images.len(), expected_images.len());
    let mut features = 0;
    for (image, ei) in images.iter().zip(expected_images) {
        assert_eq!(u64::from(image.image_id), u(&ei["image_id"]));
        assert_eq!(image.name, ei["name"].as_str().unwrap());
        assert_eq!(u64::from(image.camera_id), u(&ei["camera_id"]));
        let got = db.features::<Sift>(image).unwrap();
        let keypoints = ei["keypoints"].as_array().unwrap();
        let descriptors = ei["descriptors"].as_array().unwrap();
        assert_eq!(got.keypoints.len(), keypoints.len());
        for (k, ek) in got.keypoints.iter().zip(keypoints) {
            // f32 in the database; ibc's pixel centres.
            assert_eq!(k.x, f(&ek[0]) - 0.5);
            assert_eq!(k.y, f(&ek[1]) - 0.5);
        }
        for (d, ed) in got.descriptors.iter().zip(descriptors) {
            let hex = ed.as_str().unwrap();
            let bytes: Vec<f32> = (0..128)
                .map(|i| f32::from(u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap()))
                .collect();
            assert_eq!(d.as_slice(), bytes.as_slice());
        }
        features += got.len();
    }
    assert_eq!(features, 8 * 35 - 2 + 4, "the fixture's keypoints");
    assert_eq!(db.descriptor_layout().unwrap().kind, DescriptorKind::Float);
    // The fixture is in SQLite's rollback-journal mode: reading it writes nothing next to it
    // (a write-ahead-log database would get -wal and -shm files).
    drop(db);
    for side in ["database.db-wal", "database.db-shm"] {
        assert!(
            !fixtures().join(side).exists(),
            "{side} next to the fixture"
        );
    }
}

#[test]
fn colmap_model_and_database_make_an_ibc_map() {
    let e = expected();
    let colmap =
        read_colmap_map::<Sift>(fixtures().join("binary"), fixtures().join("database.db")).unwrap();
    let model = read_model(fixtures().join("binary")).unwrap();
    let map = &colmap.map;
    assert_eq!(map.points.len(), 30);
    assert_eq!(map.images.len(), 8);
    assert_eq!(colmap.image_names[1], "left/000001.png");
    let db_images = e["database_images"].as_array().unwrap();
    for (i, image) in map.images.iter().enumerate() {
        let m = &model.images[i];
        assert_eq!(image.camera_from_world, Some(m.cam_from_world));
        assert_eq!(image.features.len(), m.points2d.len());
        let ed = db_images
            .iter()
            .find(|d| d["name"] == m.name.as_str())
            .unwrap();
        for (k, (kp, p)) in image.features.keypoints.iter().zip(&m.points2d).enumerate() {
            assert_eq!(*kp, p.xy.add_scalar(-0.5));
            let hex = ed["descriptors"][k].as_str().unwrap();
            assert_eq!(
                image.features.descriptors[k][0],
                f32::from(u8::from_str_radix(&hex[..2], 16).unwrap())
            );
            match image.point_ids[k] {
                None => assert_eq!(p.point3d_id, NO_POINT3D),
                Some(id) => {
                    assert_eq!(colmap.point3d_ids[id as usize], p.point3d_id);
                    assert_eq!(map.points[id as usize], model.points3d[id as usize].xyz);
                }
            }
        }
    }
    // The text model gives the same map.
    let from_text =
        read_colmap_map::<Sift>(fixtures().join("text"), fixtures().join("database.db")).unwrap();
    assert_eq!(from_text, colmap);
}

#[test]
fn colmap_database_makes_a_rig_log_from_its_frames() {
    let log = read_colmap_log::<Sift>(fixtures().join("database.db"), &ColmapLogOptions::default())
        .unwrap();
    // Rig 1 (front + left) is the only rig of two cameras; its three frames.
    assert_eq!(log.camera_names, ["front", "left"]);
    assert_eq!(log.frames.len(), 3);
    let db = ColmapDatabase::open(fixtures().join("database.db")).unwrap();
    let images = db.images().unwrap();
    for (k, frame) in log.frames.iter().enumerate() {
        assert_eq!(frame.timestamp, (k + 1) as f64, "000001.png is 1 s");
        for (c, name) in ["front", "left"].iter().enumerate() {
            let image = images
                .iter()
                .find(|i| i.name == format!("{name}/{:06}.png", k + 1))
                .unwrap();
            assert_eq!(frame.images[c], db.features::<Sift>(image).unwrap());
        }
    }
}

#[test]
fn colmap_database_without_frames_groups_images_by_name() {
    // A database of a rig's images without a frame table (as COLMAP's feature extraction
    // writes before `rig_configurator`): same file name in the camera folders = one frame.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("log.db");
    std::fs::copy(fixtures().join("database.db"), &path).unwrap();
    {
        let c = rusqlite::Connection::open(&path).unwrap();
        c.execute_batch(
            "DROP TABLE frame_data; DROP TABLE frames; \
             DELETE FROM images WHERE name LIKE 'survey/%'; \
             DELETE FROM images WHERE name = 'left/000002.png';",
        )
        .unwrap();
    }
    let log = read_colmap_log::<Sift>(&path, &ColmapLogOptions::default()).unwrap();
    assert_eq!(log.camera_names, ["front", "left"]);
    let times: Vec<f64> = log.frames.iter().map(|f| f.timestamp).collect();
    assert_eq!(times, [1.0, 2.0, 3.0, 4.0]);
    // left/000002.png was removed, front/000004.png has no left image.
    assert!(log.frames[1].images[1].is_empty() && !log.frames[1].images[0].is_empty());
    assert!(log.frames[3].images[1].is_empty());
    assert_eq!(log.frames[3].images[0].len(), 4);
}

/// A small simulated garage (the tests' usual scale).
fn small_world() -> SimulatedWorld {
    SimulatedWorld::simulate(
        &Scenario::builtin("garage")
            .unwrap()
            .with_scale(0.05)
            .with_seed(19),
    )
    .unwrap()
}

#[test]
fn simulated_world_round_trips_through_colmap() {
    let world = small_world();
    let dir = tempfile::tempdir().unwrap();
    let sources = survey_image_sources(world.map.images.len(), world.map_rig.cameras.len());
    let written = write_colmap(dir.path(), &world.map_rig, &world.map, &sources).unwrap();
    assert_eq!(
        written.len(),
        7,
        "5 model files, the database, the rig config"
    );
    let read =
        read_colmap_map::<[u64; 4]>(dir.path().join("sparse"), dir.path().join("database.db"))
            .unwrap();
    let map = &read.map;
    // Points: text with the shortest round-trip digits, read back bit for bit.
    assert_eq!(map.points, world.map.points);
    assert_eq!(map.images.len(), world.map.images.len());
    let mut worst_keypoint = 0.0f64;
    for (a, b) in map.images.iter().zip(&world.map.images) {
        let (pa, pb) = (a.camera_from_world.unwrap(), b.camera_from_world.unwrap());
        assert_relative_eq!(
            pa.translation.vector,
            pb.translation.vector,
            epsilon = 1e-12
        );
        assert!(pa.rotation.angle_to(&pb.rotation) < 1e-12);
        assert_eq!(a.point_ids, b.point_ids);
        assert_eq!(a.features.descriptors, b.features.descriptors);
        for (ka, kb) in a.features.keypoints.iter().zip(&b.features.keypoints) {
            worst_keypoint = worst_keypoint.max((ka - kb).abs().max());
        }
    }
    // x + 0.5 - 0.5 in f64: a few ulps of a pixel coordinate.
    assert!(
        worst_keypoint < 1e-12,
        "keypoints moved by {worst_keypoint:e} px"
    );
    // The cameras and rig read back as COLMAP holds them.
    let model = read_model(dir.path().join("sparse")).unwrap();
    let cameras = ibc_cameras(&model).unwrap();
    for (i, c) in world.map_rig.cameras.iter().enumerate() {
        let back = &cameras[&(i as u32 + 1)];
        for (x, y) in back.params().iter().zip(c.camera.params()) {
            assert!(
                (x - y).abs() <= 1e-12 * y.abs().max(1.0),
                "camera {}",
                c.name
            );
        }
        if i > 0 {
            let (sensor, pose) = &model.rigs[0].sensors[i - 1];
            assert_eq!(sensor.id, i as u32 + 1);
            let expected = c.rig_from_camera.inverse() * world.map_rig.cameras[0].rig_from_camera;
            assert_relative_eq!(
                pose.unwrap().to_homogeneous(),
                expected.to_homogeneous(),
                epsilon = 1e-12
            );
        }
    }
    // Every frame's pose, through the rig, gives its images' poses.
    for frame in &model.frames {
        for (sensor, image_id) in &frame.data {
            let image = model.image(*image_id as u32).unwrap();
            let camera_from_rig = match sensor.id {
                1 => Isometry3::identity(),
                id => model.rigs[0].sensors[id as usize - 2].1.unwrap(),
            };
            let composed = camera_from_rig * frame.rig_from_world;
            assert_relative_eq!(
                composed.to_homogeneous(),
                image.cam_from_world.to_homogeneous(),
                epsilon = 1e-9
            );
        }
    }
}

#[test]
fn simulated_world_calibrates_the_same_from_colmap_files() {
    use ibc_pipeline::calib::{CalibrationOptions, calibrate};
    let world = small_world();
    let dir = tempfile::tempdir().unwrap();
    let sources = survey_image_sources(world.map.images.len(), world.map_rig.cameras.len());
    write_colmap(dir.path().join("map"), &world.map_rig, &world.map, &sources).unwrap();
    let log_path = dir.path().join("log.db");
    write_colmap_log(&log_path, &world.map_rig, &world.log).unwrap();
    let map = read_colmap_map::<[u64; 4]>(
        dir.path().join("map/sparse"),
        dir.path().join("map/database.db"),
    )
    .unwrap()
    .map;
    let log = read_colmap_log::<[u64; 4]>(
        &log_path,
        &ColmapLogOptions {
            seconds_per_unit: 1e-9,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(log.camera_names, world.log.camera_names);
    assert_eq!(log.frames.len(), world.log.frames.len());
    let mut worst_keypoint = 0.0f64;
    for (a, b) in log.frames.iter().zip(&world.log.frames) {
        assert!((a.timestamp - b.timestamp).abs() < 1e-9);
        for (ia, ib) in a.images.iter().zip(&b.images) {
            assert_eq!(ia.descriptors, ib.descriptors);
            for (ka, kb) in ia.keypoints.iter().zip(&ib.keypoints) {
                worst_keypoint = worst_keypoint.max((ka - kb).abs().max());
            }
        }
    }
    // The database stores keypoints as f32: 2^-24 of ~1000 px.
    assert!(
        worst_keypoint < 1e-4,
        "log keypoints moved by {worst_keypoint:e} px"
    );
    let options = CalibrationOptions::default();
    let native = calibrate(&world.map, &world.log, &world.map_rig, &options).unwrap();
    let colmap = calibrate(&map, &log, &world.map_rig, &options).unwrap();
    assert_eq!(native.frame_sets.len(), colmap.frame_sets.len());
    let mut worst = (0.0f64, 0.0f64);
    for (a, b) in native.rig_from_camera.iter().zip(&colmap.rig_from_camera) {
        worst.0 = worst.0.max(a.rotation.angle_to(&b.rotation));
        worst.1 = worst
            .1
            .max((a.translation.vector - b.translation.vector).norm());
    }
    println!(
        "native vs COLMAP files: {:.2e} rad, {:.2e} m",
        worst.0, worst.1
    );
    // The f32 keypoints of the log move the estimate by far less than its uncertainty.
    assert!(worst.0 < 1e-6 && worst.1 < 1e-6, "{worst:?}");
}

// ---- bad input ----

fn copy_fixture(sub: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(fixtures().join(sub)).unwrap() {
        let entry = entry.unwrap();
        std::fs::copy(entry.path(), dir.path().join(entry.file_name())).unwrap();
    }
    dir
}

#[test]
fn truncated_binary_models_are_typed_errors() {
    let dir = copy_fixture("binary");
    for name in [
        "cameras.bin",
        "images.bin",
        "points3D.bin",
        "rigs.bin",
        "frames.bin",
    ] {
        let path = dir.path().join(name);
        let bytes = std::fs::read(&path).unwrap();
        // Every truncation: a typed error naming the file, never a panic or a model.
        for len in 0..bytes.len() {
            std::fs::write(&path, &bytes[..len]).unwrap();
            let err = read_model(dir.path()).unwrap_err();
            assert!(
                matches!(
                    err,
                    ColmapError::Truncated { .. } | ColmapError::BadCount { .. }
                ),
                "{name} cut at {len}: {err}"
            );
            assert!(err.to_string().contains(name), "{err}");
        }
        // One byte more is as wrong.
        let mut longer = bytes.clone();
        longer.push(0);
        std::fs::write(&path, &longer).unwrap();
        assert!(matches!(
            read_model(dir.path()).unwrap_err(),
            ColmapError::TrailingBytes { extra: 1, .. }
        ));
        std::fs::write(&path, &bytes).unwrap();
    }
    read_model(dir.path()).unwrap();
}

#[test]
fn corrupted_counts_are_refused_before_allocating() {
    let dir = copy_fixture("binary");
    let path = dir.path().join("points3D.bin");
    let bytes = std::fs::read(&path).unwrap();
    let mut bad = bytes.clone();
    bad[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&path, &bad).unwrap();
    let err = read_model(dir.path()).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::BadCount {
                count: u64::MAX,
                offset: 0,
                ..
            }
        ),
        "{err}"
    );
    std::fs::write(&path, &bytes).unwrap();
    // The 2D point count of the first image (after its id, pose, camera and name).
    let path = dir.path().join("images.bin");
    let bytes = std::fs::read(&path).unwrap();
    let at = 8 + 4 + 56 + 4 + "front/000001.png".len() + 1;
    let mut bad = bytes.clone();
    bad[at..at + 8].copy_from_slice(&(1u64 << 60).to_le_bytes());
    std::fs::write(&path, &bad).unwrap();
    let err = read_model(dir.path()).unwrap_err();
    assert!(
        matches!(err, ColmapError::BadCount { count, .. } if count == 1 << 60),
        "{err}"
    );
    std::fs::write(&path, &bytes).unwrap();
    // A 2D point of a 3D point that does not exist.
    let mut bad = bytes.clone();
    let first_point = at + 8 + 16;
    bad[first_point..first_point + 8].copy_from_slice(&999u64.to_le_bytes());
    std::fs::write(&path, &bad).unwrap();
    let err = read_model(dir.path()).unwrap_err();
    assert!(
        matches!(err, ColmapError::Invalid { .. }) && err.to_string().contains("999"),
        "{err}"
    );
}

#[test]
fn unknown_and_unsupported_camera_models_are_named() {
    let dir = copy_fixture("binary");
    let path = dir.path().join("cameras.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[12..16].copy_from_slice(&99i32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let err = read_model(dir.path()).unwrap_err();
    assert!(
        matches!(err, ColmapError::UnknownCameraModel { camera_id: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().contains("id 99"), "{err}");

    let dir = copy_fixture("text");
    let path = dir.path().join("cameras.txt");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("PINHOLE 320", "FANCY_LENS 320");
    std::fs::write(&path, text).unwrap();
    let err = read_model(dir.path()).unwrap_err();
    assert!(err.to_string().contains("FANCY_LENS"), "{err}");

    // A model COLMAP knows but ibc cannot represent exactly.
    let text = std::fs::read_to_string(fixtures().join("text/cameras.txt"))
        .unwrap()
        .replace(
            "4 PINHOLE 320 240 250 251 160 120",
            "4 FOV 320 240 250 251 160 120 0.9",
        );
    std::fs::write(&path, text).unwrap();
    let model = read_model(dir.path()).unwrap();
    let err = ibc_cameras(&model).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::UnsupportedCameraModel {
                camera_id: 4,
                model: "FOV"
            }
        ),
        "{err}"
    );
    // The map does not need the cameras: it still reads.
    read_colmap_map::<Sift>(dir.path(), fixtures().join("database.db")).unwrap();
}

fn edited_database(sql: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("database.db");
    std::fs::copy(fixtures().join("database.db"), &path).unwrap();
    rusqlite::Connection::open(&path)
        .unwrap()
        .execute_batch(sql)
        .unwrap();
    (dir, path)
}

#[test]
fn databases_without_descriptors_or_images_are_typed_errors() {
    let model = read_model(fixtures().join("text")).unwrap();
    let (_dir, path) = edited_database("DELETE FROM descriptors;");
    let db = ColmapDatabase::open(&path).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::MissingFeatures {
                what: "descriptors",
                ..
            }
        ),
        "{err}"
    );
    assert!(log_from_database::<Sift>(&db, &ColmapLogOptions::default()).is_err());

    let (_dir, path) = edited_database("DROP TABLE descriptors;");
    let db = ColmapDatabase::open(&path).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::MissingFeatures {
                what: "descriptors",
                ..
            }
        ),
        "{err}"
    );

    let (_dir, path) = edited_database("DELETE FROM images WHERE name = 'left/000002.png';");
    let db = ColmapDatabase::open(&path).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(
        matches!(&err, ColmapError::ImageNotInDatabase { image, .. } if image == "left/000002.png"),
        "{err}"
    );

    // Keypoints of another image count than the model's 2D points.
    let (_dir, path) = edited_database(
        "UPDATE keypoints SET rows = 34, data = substr(data, 1, 34 * 24) WHERE image_id = 3;",
    );
    let db = ColmapDatabase::open(&path).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(matches!(err, ColmapError::BadFeatures { .. }), "{err}");

    // A blob shorter than its rows and columns.
    let (_dir, path) =
        edited_database("UPDATE descriptors SET data = substr(data, 1, 100) WHERE image_id = 2;");
    let db = ColmapDatabase::open(&path).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(matches!(err, ColmapError::BadFeatures { .. }), "{err}");

    // SIFT asked for as binary descriptors.
    let db = ColmapDatabase::open(fixtures().join("database.db")).unwrap();
    let err = map_from_colmap::<[u64; 4]>(&model, &db).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::DescriptorMismatch {
                kind: 0,
                cols: 128,
                ..
            }
        ),
        "{err}"
    );

    // Not a database at all.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("database.db");
    std::fs::write(&path, b"this is not SQLite").unwrap();
    assert!(matches!(
        ColmapDatabase::open(&path).unwrap_err(),
        ColmapError::Database { .. }
    ));
    assert!(matches!(
        ColmapDatabase::open(dir.path()).unwrap_err(),
        ColmapError::Io(_)
    ));
    assert!(matches!(
        read_model(dir.path()).unwrap_err(),
        ColmapError::NotAModel { .. }
    ));
}

#[test]
fn a_rig_colmap_cannot_hold_writes_nothing() {
    let world = small_world();
    let mut rig = world.map_rig.clone();
    let unified = Unified::new(
        640,
        480,
        [1.0, 0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0],
    )
    .unwrap();
    rig.cameras[1] = RigCamera::new(
        rig.cameras[1].name.clone(),
        unified.into(),
        rig.cameras[1].rig_from_camera,
    );
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let sources = survey_image_sources(world.map.images.len(), rig.cameras.len());
    let err = write_colmap(&out, &rig, &world.map, &sources).unwrap_err();
    assert!(
        matches!(
            err,
            ColmapError::UnsupportedIbcModel {
                model: "unified",
                ..
            }
        ),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // Sources that do not cover the map.
    let err = write_colmap(&out, &world.map_rig, &world.map, &sources[1..]).unwrap_err();
    assert!(matches!(err, ColmapError::Invalid { .. }), "{err}");
    assert!(!out.exists(), "nothing written");
}

// ---- the command line ----

fn ibc(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_ibc"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn ibc_calibrate_takes_colmap_maps_and_logs() {
    let dir = tempfile::tempdir().unwrap();
    let d = |p: &str| dir.path().join(p).to_str().unwrap().to_owned();
    std::fs::write(
        dir.path().join("small.yaml"),
        "version: 1\nbase: garage\nscale: 0.05\n",
    )
    .unwrap();
    let o = ibc(&[
        "simulate",
        "--scenario",
        &d("small.yaml"),
        "--out",
        &d("world"),
        "--colmap",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut names: Vec<String> = std::fs::read_dir(dir.path().join("world/colmap"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["database.db", "log.db", "rig_config.json", "sparse"]
    );
    let cameras = d("world/camchain.yaml");
    let calibrate = |map: &[&str], log: &str, out: &str| {
        let out = d(out);
        let mut args = vec![
            "calibrate",
            "--log",
            log,
            "--cameras",
            &cameras,
            "--out",
            &out,
        ];
        args.extend_from_slice(map);
        args.extend_from_slice(&["--json", "--quiet", "--colmap-seconds-per-unit", "1e-9"]);
        ibc(&args)
    };
    let native = calibrate(
        &["--map", &d("world/map.ibcmap")],
        &d("world/log.ibclog"),
        "native",
    );
    let colmap = calibrate(
        &[
            "--map",
            &d("world/colmap/sparse"),
            "--database",
            &d("world/colmap/database.db"),
        ],
        &d("world/colmap/log.db"),
        "colmap",
    );
    // A COLMAP map with an ibc log, too.
    let mixed = calibrate(
        &[
            "--map",
            &d("world/colmap/sparse"),
            "--database",
            &d("world/colmap/database.db"),
        ],
        &d("world/log.ibclog"),
        "mixed",
    );
    for o in [&native, &colmap, &mixed] {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let report = |o: &std::process::Output| -> Value { serde_json::from_slice(&o.stdout).unwrap() };
    let (a, b, m) = (report(&native), report(&colmap), report(&mixed));
    for (ca, (cb, cm)) in a["cameras"].as_array().unwrap().iter().zip(
        b["cameras"]
            .as_array()
            .unwrap()
            .iter()
            .zip(m["cameras"].as_array().unwrap()),
    ) {
        let t = |c: &Value| -> Vec<f64> {
            c["rig_from_camera"]["translation"]
                .as_array()
                .unwrap()
                .iter()
                .map(f)
                .collect()
        };
        let std = c_std(ca);
        for (x, y) in t(ca).iter().zip(t(cb)) {
            // The log's f32 keypoints move the extrinsics by a small part of their uncertainty.
            assert!(
                (x - y).abs() < 0.05 * std.max(1e-6),
                "{} vs {} (sd {std})",
                x,
                y
            );
        }
        for (x, y) in t(ca).iter().zip(t(cm)) {
            // The map alone goes through f64 text: the same to ~1e-12.
            assert!((x - y).abs() < 1e-9, "{} vs {}", x, y);
        }
    }

    // The calibration as COLMAP's rig config: camera 0 the reference, the others'
    // cam_from_rig the inverse of the report's rig_from_camera.
    let config: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("colmap/rig_config.json")).unwrap(),
    )
    .unwrap();
    let cameras = config[0]["cameras"].as_array().unwrap();
    assert_eq!(cameras.len(), 4);
    assert_eq!(cameras[0]["ref_sensor"], true);
    for (c, rc) in cameras.iter().zip(b["cameras"].as_array().unwrap()).skip(1) {
        let t: Vec<f64> = c["cam_from_rig_translation"]
            .as_array()
            .unwrap()
            .iter()
            .map(f)
            .collect();
        let rig_from_camera = pose(&rc["rig_from_camera"]);
        let expected = rig_from_camera.inverse().translation.vector;
        for k in 0..3 {
            assert!((t[k] - expected[k]).abs() < 1e-9, "{t:?} vs {expected:?}");
        }
    }

    // A COLMAP model without its database: a usage error, nothing written.
    let o = ibc(&[
        "calibrate",
        "--map",
        &d("world/colmap/sparse"),
        "--log",
        &d("world/colmap/log.db"),
        "--cameras",
        &d("world/camchain.yaml"),
        "--out",
        &d("bad"),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--database"));
    assert!(!dir.path().join("bad").exists());
    // A database whose descriptors were dropped: a typed error naming it, nothing written.
    let broken = dir.path().join("broken.db");
    std::fs::copy(dir.path().join("world/colmap/database.db"), &broken).unwrap();
    rusqlite::Connection::open(&broken)
        .unwrap()
        .execute_batch("DROP TABLE descriptors;")
        .unwrap();
    let o = ibc(&[
        "calibrate",
        "--map",
        &d("world/colmap/sparse"),
        "--database",
        broken.to_str().unwrap(),
        "--log",
        &d("world/colmap/log.db"),
        "--cameras",
        &d("world/camchain.yaml"),
        "--out",
        &d("bad"),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("broken.db") && err.contains("descriptors"),
        "{err}"
    );
    assert!(!dir.path().join("bad").exists());
}

/// The largest translation standard deviation of a report camera, metres.
fn c_std(c: &Value) -> f64 {
    c["rig_from_camera_std"]["translation_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(f)
        .fold(0.0, f64::max)
}

#[test]
fn ibc_writes_colmap_binary_models_byte_for_byte() {
    // The fixture read and written again is the file COLMAP wrote, byte for byte.
    let model = read_model(fixtures().join("binary")).unwrap();
    for (name, bytes) in ibc_pipeline::colmap::model_to_binary(&model) {
        let colmap = std::fs::read(fixtures().join("binary").join(name)).unwrap();
        assert!(bytes == colmap, "{name} differs from COLMAP's");
    }
    // And the text writer's model reads back the same.
    let dir = tempfile::tempdir().unwrap();
    ibc_pipeline::colmap::write_model(dir.path(), &model, ibc_pipeline::colmap::ModelFormat::Text)
        .unwrap();
    assert_eq!(read_model(dir.path()).unwrap(), model);
}

#[test]
fn mutated_models_and_databases_never_panic() {
    use rand::{RngExt, SeedableRng};
    // Seeded byte flips, insertions and cuts of every fixture file: each read returns a model
    // or a typed error, never a panic (a fuzz-like campaign, as parsers_mutation runs for
    // ibc's own files).
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(19);
    let mut errors = 0;
    for sub in ["binary", "text"] {
        let dir = copy_fixture(sub);
        let names: Vec<PathBuf> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        for _ in 0..300 {
            let path = &names[rng.random_range(0..names.len())];
            let original = std::fs::read(path).unwrap();
            let mut bytes = original.clone();
            for _ in 0..rng.random_range(1..4) {
                let at = rng.random_range(0..bytes.len());
                match rng.random_range(0..3) {
                    0 => bytes[at] ^= 1 << rng.random_range(0..8),
                    1 => bytes.insert(at, rng.random()),
                    _ => bytes.truncate(at.max(1)),
                }
            }
            std::fs::write(path, &bytes).unwrap();
            if read_model(dir.path()).is_err() {
                errors += 1;
            }
            std::fs::write(path, &original).unwrap();
        }
    }
    let (_dir, path) = edited_database("");
    let original = std::fs::read(&path).unwrap();
    let model = read_model(fixtures().join("binary")).unwrap();
    let mut db_errors = 0;
    for _ in 0..100 {
        std::fs::write(&path, &original).unwrap();
        let table = ["keypoints", "descriptors", "cameras", "rig_sensors"][rng.random_range(0..4)];
        let (column, rows) = match table {
            "cameras" => ("params", 4),
            "rig_sensors" => ("sensor_from_rig", 1),
            // Image 9 is in neither the model nor a frame: nothing reads it.
            _ => ("data", 8),
        };
        // Cut the first bytes of one row's blob.
        rusqlite::Connection::open(&path)
            .unwrap()
            .execute(
                &format!("UPDATE {table} SET {column} = substr({column}, 1 + ?1) WHERE rowid = ?2"),
                rusqlite::params![rng.random_range(1..64), rng.random_range(1..=rows)],
            )
            .unwrap();
        let db = ColmapDatabase::open(&path).unwrap();
        let map = map_from_colmap::<Sift>(&model, &db);
        let log = log_from_database::<Sift>(&db, &ColmapLogOptions::default());
        let cameras = db.cameras();
        let rigs = db.rigs();
        if map.is_err() || log.is_err() || cameras.is_err() || rigs.is_err() {
            db_errors += 1;
        }
    }
    println!("{errors} of 600 mutated models and {db_errors} of 100 databases refused");
    assert!(db_errors == 100, "every cut blob is caught ({db_errors})");
    assert!(errors > 400, "most mutated files are refused ({errors})");
}

#[test]
fn descriptors_other_than_sift_or_binary_are_named() {
    // COLMAP 4's learned descriptors (ALIKED is type 1 or 2) are not SIFT.
    let (_dir, path) = edited_database("UPDATE descriptors SET type = 2;");
    let db = ColmapDatabase::open(&path).unwrap();
    let err = db.descriptor_layout().unwrap_err();
    assert!(err.to_string().contains("type 2"), "{err}");
    let model = read_model(fixtures().join("binary")).unwrap();
    let err = map_from_colmap::<Sift>(&model, &db).unwrap_err();
    assert!(
        matches!(err, ColmapError::DescriptorMismatch { kind: 2, .. }),
        "{err}"
    );
}
