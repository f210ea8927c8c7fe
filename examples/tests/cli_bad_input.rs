#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! Bad input through the `ibc` binary: each case gives a one-line error naming the problem
//! and a likely cause, a non-zero exit, and no output files.

mod cli_common;

use std::path::Path;

use cli_common::{check_failure, entries, files, ibc};
use ibc_camera_models::Rig;
use ibc_pipeline::data::BinaryDescriptor;
use ibc_pipeline::data::io::{read_log, write_log};

/// Runs `ibc calibrate` and checks the failure: exit code 1, one line on stderr containing
/// every one of `expected`, nothing written to the output folder.
fn fails(map: &Path, log: &Path, cameras: &Path, expected: &[&str]) {
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("result");
    let s = |p: &Path| p.to_str().unwrap().to_owned();
    let o = ibc(&[
        "calibrate",
        "--map",
        &s(map),
        "--log",
        &s(log),
        "--cameras",
        &s(cameras),
        "--out",
        &s(&target),
    ]);
    check_failure(&o, expected);
    assert!(
        entries(&target).is_empty(),
        "partial output: {:?}",
        entries(&target)
    );
    assert!(entries(out.path()).is_empty(), "{:?}", entries(out.path()));
}

#[test]
fn missing_files_are_named() {
    let f = files();
    let missing = f.dir.join("nowhere.ibcmap");
    fails(
        &missing,
        &f.log,
        &f.cameras,
        &["map:", "nowhere.ibcmap", "is the path right?"],
    );
    let missing = f.dir.join("nowhere.ibclog");
    fails(
        &f.map,
        &missing,
        &f.cameras,
        &["rig log:", "nowhere.ibclog"],
    );
    let missing = f.dir.join("nowhere.yaml");
    fails(
        &f.map,
        &f.log,
        &missing,
        &["camera file", "nowhere.yaml", "Kalibr camchain"],
    );
}

#[test]
fn malformed_files_are_refused() {
    let f = files();
    // A flipped byte in the map: the checksum catches it.
    let mut bytes = std::fs::read(&f.map).unwrap();
    bytes[100] ^= 0x40;
    let corrupt = f.dir.join("corrupt.ibcmap");
    std::fs::write(&corrupt, &bytes).unwrap();
    fails(
        &corrupt,
        &f.log,
        &f.cameras,
        &["checksum mismatch", "corrupt"],
    );
    // A truncated log.
    let bytes = std::fs::read(&f.log).unwrap();
    let truncated = f.dir.join("truncated.ibclog");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    fails(&f.map, &truncated, &f.cameras, &["truncated"]);
    // The map and the log swapped.
    fails(&f.log, &f.map, &f.cameras, &["were the arguments swapped?"]);
    // A camera file that is not a camchain.
    let bad = f.dir.join("bad.yaml");
    std::fs::write(&bad, "cam0:\n  camera_model: pinhole\n").unwrap();
    fails(
        &f.map,
        &f.log,
        &bad,
        &["camera file", "bad.yaml", "missing key"],
    );
}

#[test]
fn camera_counts_that_disagree_are_refused() {
    let f = files();
    let mut rig = Rig::read_kalibr(&f.cameras).unwrap();
    rig.cameras.pop();
    let three = f.dir.join("three.yaml");
    rig.write_kalibr(&three).unwrap();
    fails(
        &f.map,
        &f.log,
        &three,
        &["3 camera(s)", "the rig log has 4", "different rigs"],
    );
}

#[test]
fn a_log_that_does_not_fit_the_map_is_refused() {
    let f = files();
    // Descriptors unrelated to the map's: nothing can be localized.
    let mut log = read_log::<BinaryDescriptor>(&f.log).unwrap();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    for frame in &mut log.frames {
        for image in &mut frame.images {
            for d in &mut image.descriptors {
                for w in d.iter_mut() {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    *w = state;
                }
            }
        }
    }
    let foreign = f.dir.join("foreign.ibclog");
    write_log(&foreign, &log).unwrap();
    fails(
        &f.map,
        &foreign,
        &f.cameras,
        &["no image was localized", "mapped area"],
    );
}

#[test]
fn a_log_without_complete_frame_sets_is_refused() {
    let f = files();
    // Camera 2 saw nothing: the error names it and says why its images failed.
    let mut log = read_log::<BinaryDescriptor>(&f.log).unwrap();
    for frame in &mut log.frames {
        frame.images[2].keypoints.clear();
        frame.images[2].descriptors.clear();
    }
    let blind = f.dir.join("blind.ibclog");
    write_log(&blind, &log).unwrap();
    fails(
        &f.map,
        &blind,
        &f.cameras,
        &[
            "camera `rear` was localized in none of its",
            "the image has no feature",
        ],
    );
    // Cameras 2 and 3 saw nothing in turns: each is localized, never all four together.
    let mut log = read_log::<BinaryDescriptor>(&f.log).unwrap();
    for (i, frame) in log.frames.iter_mut().enumerate() {
        let c = 2 + i % 2;
        frame.images[c].keypoints.clear();
        frame.images[c].descriptors.clear();
    }
    let alternating = f.dir.join("alternating.ibclog");
    write_log(&alternating, &log).unwrap();
    fails(
        &f.map,
        &alternating,
        &f.cameras,
        &["no complete frame set", "every camera"],
    );
}

#[test]
fn unknown_scenarios_are_named() {
    let out = tempfile::tempdir().unwrap();
    let target = out.path().join("world");
    let o = ibc(&[
        "simulate",
        "--scenario",
        "no-such-world",
        "--out",
        target.to_str().unwrap(),
    ]);
    check_failure(&o, &["unknown scenario `no-such-world`", "garage"]);
    assert!(!target.exists());
    let o = ibc(&["--scenario", "no-such-world"]);
    check_failure(&o, &["unknown scenario"]);
}
