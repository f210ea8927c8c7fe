#!/usr/bin/env python3
"""COLMAP fixtures of ibc's COLMAP tests (`examples/tests/colmap.rs`), written by COLMAP itself.

    python3 -m venv venv && venv/bin/pip install pycolmap numpy   # pycolmap 4.2.1 made them
    venv/bin/python make_fixtures.py                # rewrites the fixtures next to this script
    venv/bin/python make_fixtures.py verify DIR     # checks a model + database ibc wrote

`make` builds a tiny reconstruction with pycolmap (COLMAP's own Python bindings): four cameras
of four models (OPENCV_FISHEYE, OPENCV, SIMPLE_RADIAL, PINHOLE), a two-camera rig with three
frames plus two single-camera images, 3D points with tracks, and a database with the same
cameras, rigs, frames and images, 6-column SIFT keypoints and 128-byte SIFT descriptors (one
database image is not in the model). COLMAP writes the model as text (`text/`) and binary
(`binary/`) and the database (`database.db`); `expected.json` holds every value, so the Rust
test compares what ibc reads against what COLMAP wrote, without Python.

`verify DIR` loads what ibc wrote into DIR (`sparse/` text model, `database.db`,
`rig_config.json`) with pycolmap and checks that COLMAP reads the same numbers: the
observations reproject (with COLMAP's camera models and pixel convention) onto their keypoints
with zero mean residual (the keypoints carry the simulator's noise), the database's keypoints
and descriptors are the model's 2D points', the rig config's cameras and `cam_from_rig` agree
with the model's rigs.
"""

import json
import pathlib
import sys

import numpy as np
import pycolmap

HERE = pathlib.Path(__file__).resolve().parent


def rigid(rotvec, t):
    """A Rigid3d from a rotation vector (radians) and a translation."""
    angle = float(np.linalg.norm(rotvec))
    axis = np.asarray(rotvec) / angle if angle > 0 else np.array([1.0, 0.0, 0.0])
    h = angle / 2
    xyzw = np.concatenate([axis * np.sin(h), [np.cos(h)]])
    return pycolmap.Rigid3d(pycolmap.Rotation3d(xyzw), np.asarray(t, dtype=float))


def wxyz(r):
    x, y, z, w = r.rotation.quat
    return [float(w), float(x), float(y), float(z)]


def make():
    rng = np.random.default_rng(19)
    rec = pycolmap.Reconstruction()
    cams = [
        (1, "OPENCV_FISHEYE", 640, 480, [300.0, 302.0, 320.5, 240.5, 0.01, -0.005, 0.001, -0.0002]),
        (2, "OPENCV", 640, 480, [500.0, 505.0, 319.5, 239.5, -0.1, 0.02, 0.001, -0.002]),
        (3, "SIMPLE_RADIAL", 800, 600, [600.0, 400.0, 300.0, -0.05]),
        (4, "PINHOLE", 320, 240, [250.0, 251.0, 160.0, 120.0]),
    ]
    cameras = {}
    for cid, model, w, h, params in cams:
        cam = pycolmap.Camera.create_from_model_name(cid, model, 1.0, w, h)
        cam.params = params
        cameras[cid] = cam
        rec.add_camera(cam)

    # Rig 1: camera 1 is the reference sensor, camera 2 is 20 cm to its left, turned 10 degrees.
    rig = pycolmap.Rig(rig_id=1)
    rig.add_ref_sensor(cameras[1].sensor_id)
    rig.add_sensor(cameras[2].sensor_id, rigid([0.0, 0.17, 0.02], [-0.2, 0.01, 0.03]))
    rec.add_rig(rig)
    for cid in (3, 4):
        r = pycolmap.Rig(rig_id=cid)
        r.add_ref_sensor(cameras[cid].sensor_id)
        rec.add_rig(r)

    points = rng.uniform([-3, -2, 5], [3, 2, 9], size=(30, 3))

    # (image_id, name, camera_id, frame_id, cam_from_world or None for a rig image)
    images = []
    frames = []
    image_id = 1
    for k in range(3):
        rig_from_world = rigid(rng.normal(0, 0.05, 3), rng.normal(0, 0.3, 3))
        frame = pycolmap.Frame(frame_id=k + 1, rig_id=1)
        frame.rig_from_world = rig_from_world
        members = []
        for cid, folder in ((1, "front"), (2, "left")):
            members.append((image_id, cid))
            images.append((image_id, f"{folder}/{k + 1:06d}.png", cid, k + 1))
            frame.add_data_id(pycolmap.data_t(cameras[cid].sensor_id, image_id))
            image_id += 1
        frames.append((frame, members))
    for cid, name in ((3, "survey/a.png"), (4, "survey/b.png")):
        frame = pycolmap.Frame(frame_id=image_id, rig_id=cid)
        frame.rig_from_world = rigid(rng.normal(0, 0.05, 3), rng.normal(0, 0.3, 3))
        frame.add_data_id(pycolmap.data_t(cameras[cid].sensor_id, image_id))
        images.append((image_id, name, cid, image_id))
        frames.append((frame, [(image_id, cid)]))
        image_id += 1

    for frame, _ in frames:
        rec.add_frame(frame)

    keypoints = {}
    descriptors = {}
    observations = {}
    for iid, name, cid, fid in images:
        cam = cameras[cid]
        frame = rec.frame(fid)
        sensor_from_rig = rec.rig(frame.rig_id).sensor_from_rig(cam.sensor_id) \
            if not rec.rig(frame.rig_id).is_ref_sensor(cam.sensor_id) else pycolmap.Rigid3d()
        cam_from_world = sensor_from_rig * frame.rig_from_world
        rows = []
        obs = []
        for pid, xyz in enumerate(points):
            pc = cam_from_world * xyz
            if pc[2] <= 0.5:
                continue
            uv = cam.img_from_cam(pc)
            if uv is None or not (0 <= uv[0] < cam.width and 0 <= uv[1] < cam.height):
                continue
            uv = uv + rng.normal(0, 0.3, 2)
            rows.append(uv)
            obs.append(pid)
        for _ in range(5):
            rows.append(rng.uniform([0, 0], [cam.width, cam.height]))
            obs.append(-1)
        order = rng.permutation(len(rows))
        xy = np.array(rows)[order]
        obs = [obs[i] for i in order]
        shape = rng.normal(0, 2, (len(xy), 4))
        kp = np.hstack([xy, shape]).astype(np.float32)
        keypoints[iid] = kp
        descriptors[iid] = rng.integers(0, 256, (len(xy), 128), dtype=np.uint8)
        observations[iid] = obs
        image = pycolmap.Image(name=name, keypoints=kp[:, :2].astype(np.float64),
                               camera_id=cid, image_id=iid)
        image.frame_id = fid
        rec.add_image(image)

    # Points: tracks of the observations; ids are COLMAP's (from 1).
    for pid, xyz in enumerate(points):
        track = pycolmap.Track()
        for iid, obs in observations.items():
            for idx, p in enumerate(obs):
                if p == pid:
                    track.add_element(iid, idx)
        if track.length() < 2:
            continue
        point3D_id = rec.add_point3D(xyz + rng.normal(0, 0.01, 3), track,
                                     rng.integers(0, 256, 3).astype(np.uint8))
        rec.point3D(point3D_id).error = float(rng.uniform(0.1, 1.0))
    for fid in [f.frame_id for f, _ in frames]:
        rec.register_frame(fid)

    for sub in ("text", "binary"):
        (HERE / sub).mkdir(exist_ok=True)
    rec.write_text(HERE / "text")
    rec.write_binary(HERE / "binary")

    db_path = HERE / "database.db"
    db_path.unlink(missing_ok=True)
    db = pycolmap.Database.open(db_path)
    for cam in cameras.values():
        db.write_camera(cam, use_camera_id=True)
    for r in rec.rigs.values():
        db.write_rig(r, use_rig_id=True)
    all_images = list(images)
    # An image of the rig's log that the model does not hold (not registered).
    extra = (image_id, "front/000004.png", 1, None)
    all_images.append(extra)
    keypoints[image_id] = np.hstack([rng.uniform(0, 480, (4, 2)), rng.normal(0, 2, (4, 4))]).astype(np.float32)
    descriptors[image_id] = rng.integers(0, 256, (4, 128), dtype=np.uint8)
    for iid, name, cid, fid in all_images:
        db.write_image(pycolmap.Image(name=name, camera_id=cid, image_id=iid), use_image_id=True)
        db.write_keypoints(iid, keypoints[iid])
        db.write_descriptors(iid, pycolmap.FeatureDescriptors(pycolmap.FeatureExtractorType.SIFT,
                                                              descriptors[iid]))
    for frame, _ in frames:
        f = pycolmap.Frame(frame_id=frame.frame_id, rig_id=frame.rig_id)
        for d in frame.data_ids:
            f.add_data_id(d)
        db.write_frame(f, use_frame_id=True)
    db.close()
    # COLMAP keeps its databases in write-ahead-log mode, in which even a read-only reader
    # creates database.db-wal and database.db-shm next to the file; the fixture is switched to
    # SQLite's rollback journal, so that the tests read it without writing into the repository.
    # The tables and their bytes are the same.
    import sqlite3
    with sqlite3.connect(db_path) as connection:
        connection.execute("PRAGMA journal_mode=DELETE")
    connection.close()

    rec = pycolmap.Reconstruction(HERE / "binary")
    expected = {
        "source": f"written by pycolmap {pycolmap.__version__} (make_fixtures.py)",
        "cameras": [
            {"camera_id": c.camera_id, "model": c.model.name, "width": c.width,
             "height": c.height, "params": [float(p) for p in c.params]}
            for c in sorted(rec.cameras.values(), key=lambda c: c.camera_id)
        ],
        "rigs": [
            {"rig_id": r.rig_id, "ref_camera_id": r.ref_sensor_id.id,
             "sensors": [{"camera_id": s.id,
                          "rotation_wxyz": wxyz(r.sensor_from_rig(s)),
                          "translation": [float(v) for v in r.sensor_from_rig(s).translation]}
                         for s in r.non_ref_sensors]}
            for r in sorted(rec.rigs.values(), key=lambda r: r.rig_id)
        ],
        "frames": [
            {"frame_id": f.frame_id, "rig_id": f.rig_id,
             "rig_from_world": {"rotation_wxyz": wxyz(f.rig_from_world),
                                "translation": [float(v) for v in f.rig_from_world.translation]},
             "image_ids": sorted(int(d.id) for d in f.data_ids)}
            for f in sorted(rec.frames.values(), key=lambda f: f.frame_id)
        ],
        "images": [
            {"image_id": i.image_id, "name": i.name, "camera_id": i.camera_id,
             "frame_id": i.frame_id,
             "cam_from_world": {"rotation_wxyz": wxyz(i.cam_from_world()),
                                "translation": [float(v) for v in i.cam_from_world().translation]},
             "points2D": [[float(p.xy[0]), float(p.xy[1]),
                           int(p.point3D_id) if p.has_point3D() else -1] for p in i.points2D],
             # COLMAP's own projection of every 3D point the image observes (its camera
             # model, its pixel convention): what ibc's converted camera must reproduce.
             "projections": [
                 [int(p.point3D_id)] + [float(v) for v in rec.cameras[i.camera_id].img_from_cam(
                     i.cam_from_world() * rec.point3D(p.point3D_id).xyz)]
                 for p in i.points2D if p.has_point3D()]}
            for i in sorted(rec.images.values(), key=lambda i: i.image_id)
        ],
        "points3D": [
            {"point3D_id": pid, "xyz": [float(v) for v in p.xyz],
             "color": [int(v) for v in p.color], "error": float(p.error),
             "track": [[int(e.image_id), int(e.point2D_idx)] for e in p.track.elements]}
            for pid, p in sorted(rec.points3D.items())
        ],
        "database_images": [
            {"image_id": iid, "name": name, "camera_id": cid,
             "keypoints": [[float(v) for v in row] for row in keypoints[iid]],
             "descriptors": [bytes(row).hex() for row in descriptors[iid]]}
            for iid, name, cid, _ in all_images
        ],
    }
    (HERE / "expected.json").write_text(json.dumps(expected, indent=1) + "\n")
    print(rec.summary())


def verify(folder):
    folder = pathlib.Path(folder)
    rec = pycolmap.Reconstruction(folder / "sparse")
    print(rec.summary())
    db = pycolmap.Database.open(folder / "database.db")
    residuals = []
    behind = 0
    for image in rec.images.values():
        cam = rec.camera(image.camera_id)
        kp = db.read_keypoints(image.image_id)
        assert len(kp) == len(image.points2D), image.name
        db_image = db.read_image_with_name(image.name)
        assert db_image.image_id == image.image_id, image.name
        for idx, p2 in enumerate(image.points2D):
            assert np.allclose(kp[idx, :2], p2.xy, atol=1e-3), (image.name, idx)
            if p2.has_point3D():
                uv = cam.img_from_cam(image.cam_from_world() * rec.point3D(p2.point3D_id).xyz)
                if uv is None:  # beyond 90 degrees: ibc's fisheyes see there, COLMAP's do not
                    behind += 1
                    continue
                residuals.append(p2.xy - uv)
        desc = db.read_descriptors(image.image_id)
        assert desc.data.shape[0] == len(image.points2D), image.name
    residuals = np.array(residuals)
    mean = residuals.mean(axis=0)
    rms = float(np.sqrt((residuals ** 2).sum(axis=1).mean()))
    # Keypoints are noisy (the simulator's pixel noise), so each residual is noise; their mean
    # is zero to within noise / sqrt(n) when COLMAP and ibc agree on the camera models and
    # the pixel convention (a half-pixel slip would show as a mean of 0.5 px).
    print(f"{len(residuals)} observations ({behind} beyond 90 degrees skipped): mean residual "
          f"({mean[0]:+.4f}, {mean[1]:+.4f}) px, RMS {rms:.3f} px")
    ok = bool(np.abs(mean).max() < 0.02 and rms < 3.0)
    configs = pycolmap.read_rig_config(folder / "rig_config.json")
    for config in configs:
        rig = None
        for cam_config in config.cameras:
            prefix = cam_config.image_prefix
            images = [i for i in rec.images.values() if i.name.startswith(prefix)]
            assert images, prefix
            ids = {i.camera_id for i in images}
            assert len(ids) == 1, prefix
            rig = rec.rig(rec.frame(images[0].frame_id).rig_id)
            sensor = rec.camera(ids.pop()).sensor_id
            if cam_config.ref_sensor:
                assert rig.is_ref_sensor(sensor), prefix
            else:
                a = rig.sensor_from_rig(sensor)
                b = cam_config.cam_from_rig
                assert np.allclose(a.translation, b.translation, atol=1e-9), prefix
                assert np.allclose(a.rotation.matrix(), b.rotation.matrix(), atol=1e-9), prefix
        print(f"rig config of {len(config.cameras)} cameras agrees with rig {rig.rig_id}")
    db.close()
    print("pycolmap reads what ibc wrote: OK" if ok else "REPROJECTION MISMATCH")
    return 0 if ok else 1


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "verify":
        sys.exit(verify(sys.argv[2]))
    make()
