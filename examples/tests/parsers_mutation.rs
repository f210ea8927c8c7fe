//! A mutation test of every parser a user's file reaches (issue 14): camera YAML, Kalibr
//! camchain, CamOdoCal `extrinsic.txt`, map, rig log, vocabulary (binary and DBoW2 text),
//! ground truth, corner file and scenario file. Each valid document is damaged by seeded
//! random bit flips, truncations, insertions, deletions and (for text) numbers replaced by
//! extreme ones; binary files are also resealed (length and checksum rewritten) so that the
//! content checks behind the checksum are reached. Every damaged input must give a typed
//! error or a valid value, never a panic, and never make the parser allocate beyond a cap
//! (measured by a counting allocator, per thread).
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
// The counting allocator is the one place the tests need `unsafe`: `GlobalAlloc` is an unsafe
// trait. It forwards every call to the system allocator unchanged.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

use ibc_camera_models::Rig;
use ibc_camera_models::camodocal::{
    format_camera, format_extrinsics, parse_camera, parse_extrinsics,
};
use ibc_pipeline::data::io::{
    log_from_bytes, log_to_bytes, map_from_bytes, map_to_bytes, truth_from_json, truth_to_json,
    xxh64,
};
use ibc_pipeline::data::{BinaryDescriptor, Map, MapImage, RigLog};
use ibc_pipeline::intrinsics::CornerSet;
use ibc_pipeline::intrinsics::simulate::{BoardSimulationOptions, preset_camera, simulate_boards};
use ibc_pipeline::intrinsics::{IntrinsicModel, PlanarTarget};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};
use ibc_vocab_tree::{TrainingOptions, Vocabulary};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Counts the bytes each thread holds, and their peak.
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn track(delta: isize) {
    // `try_with`: a thread being torn down has no counters any more.
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

// SAFETY: every method forwards to `System` with the caller's arguments unchanged; the
// counters are plain thread-local cells without destructors.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            track(layout.size() as isize);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) };
        track(-(layout.size() as isize));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            track(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result with the most bytes it held at once on this thread.
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    let peak = PEAK.with(Cell::get) - base;
    (out, peak.max(0) as usize)
}

/// Damaged versions per document.
const MUTATIONS: usize = 1000;

/// Numbers that break naive parsers.
const EXTREMES: [&str; 14] = [
    "0",
    "-0",
    "1e308",
    "-1e308",
    "1e-320",
    "nan",
    "inf",
    "-inf",
    "4294967296",
    "18446744073709551616",
    "-1",
    "99999999999999999999999",
    "0x10",
    "1e999",
];

/// One random damage of `doc`.
fn mutate(doc: &[u8], rng: &mut ChaCha8Rng, text: bool) -> Vec<u8> {
    let mut b = doc.to_vec();
    let kind = rng.random_range(0..if text { 6 } else { 5 });
    let at = |rng: &mut ChaCha8Rng, len: usize| rng.random_range(0..len.max(1));
    match kind {
        0 => {
            for _ in 0..rng.random_range(1..4) {
                if !b.is_empty() {
                    let i = at(rng, b.len());
                    b[i] ^= 1 << rng.random_range(0..8);
                }
            }
        }
        1 => b.truncate(at(rng, b.len())),
        2 => {
            let i = at(rng, b.len());
            let n = rng.random_range(1..16);
            let extra: Vec<u8> = (0..n).map(|_| rng.random()).collect();
            b.splice(i..i, extra);
        }
        3 => {
            // Duplicate a slice: repeated keys, rows, records.
            let i = at(rng, b.len());
            let j = (i + rng.random_range(1..64)).min(b.len());
            let copy = b[i..j].to_vec();
            b.splice(j..j, copy);
        }
        4 => {
            let i = at(rng, b.len());
            let j = (i + rng.random_range(1..32)).min(b.len());
            b.drain(i..j);
        }
        _ => {
            // Replace a number with an extreme one.
            let s = String::from_utf8_lossy(&b).into_owned();
            let starts: Vec<usize> = s
                .char_indices()
                .filter(|(i, c)| {
                    c.is_ascii_digit() && (*i == 0 || !s.as_bytes()[i - 1].is_ascii_alphanumeric())
                })
                .map(|(i, _)| i)
                .collect();
            if let Some(&start) = starts.get(at(rng, starts.len())) {
                let end = s[start..]
                    .find(|c: char| {
                        !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '+')
                    })
                    .map_or(s.len(), |k| start + k);
                let with = EXTREMES[at(rng, EXTREMES.len())];
                b = format!("{}{with}{}", &s[..start], &s[end..]).into_bytes();
            }
        }
    }
    b
}

/// How a damaged binary file is resealed so that its content checks are reached.
#[derive(Clone, Copy, PartialEq)]
enum Seal {
    /// Not resealed (text).
    None,
    /// The trailing XXH64 rewritten (vocabulary files).
    Checksum,
    /// The length field (bytes 24..32) and the checksum rewritten (maps and logs).
    LengthAndChecksum,
}

/// Rewrites the seal of a damaged binary file.
fn reseal(b: &mut [u8], seal: Seal) {
    if b.len() < 40 || seal == Seal::None {
        return;
    }
    if seal == Seal::LengthAndChecksum {
        let n = b.len() as u64;
        b[24..32].copy_from_slice(&n.to_le_bytes());
    }
    let end = b.len() - 8;
    let sum = xxh64(&b[..end]);
    b[end..].copy_from_slice(&sum.to_le_bytes());
}

/// Feeds `MUTATIONS` damaged versions of `doc` to `parse`, which returns `Ok(())` for a valid
/// value and `Err(message)` for its typed error; fails on a panic or on an allocation peak
/// above `cap` bytes. Returns (accepted, refused).
fn campaign(
    name: &str,
    doc: &[u8],
    seed: u64,
    text: bool,
    seal: Seal,
    cap: usize,
    parse: &dyn Fn(&[u8]) -> Result<(), String>,
) -> (usize, usize) {
    // The undamaged document is valid, and the counter sees what the parser allocates.
    let (result, peak) = peak_of(|| parse(doc));
    assert_eq!(result, Ok(()), "{name}: the seed document does not parse");
    assert!(peak > 0, "{name}: the allocation counter saw nothing");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut accepted, mut refused) = (0, 0);
    for k in 0..MUTATIONS {
        let mut input = mutate(doc, &mut rng, text);
        if k % 2 == 1 {
            reseal(&mut input, seal);
        }
        let (result, peak) =
            peak_of(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| parse(&input))));
        let Ok(outcome) = result else {
            panic!(
                "{name}: panic on mutation {k} (seed {seed}): {:?}",
                String::from_utf8_lossy(&input)
            );
        };
        assert!(
            peak <= cap,
            "{name}: mutation {k} allocated {peak} bytes (cap {cap})"
        );
        match outcome {
            Ok(()) => accepted += 1,
            Err(message) => {
                assert!(!message.is_empty(), "{name}: an empty error message");
                refused += 1;
            }
        }
    }
    println!("{name}: {accepted} accepted, {refused} refused");
    (accepted, refused)
}

/// Text of bytes, or the error a reader gives for bytes that are not UTF-8.
fn text(b: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(b).map_err(|e| format!("not UTF-8: {e}"))
}

/// A tiny world: 10 frames of the garage, its map cut to 3 images.
fn tiny() -> (
    SimulatedWorld,
    Map<BinaryDescriptor>,
    RigLog<BinaryDescriptor>,
) {
    let scenario = Scenario::builtin("garage").unwrap().with_scale(0.02);
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    // The first 3 map images, 40 features each, their points renumbered.
    let mut points = Vec::new();
    let images: Vec<MapImage<BinaryDescriptor>> = world.map.images[..3]
        .iter()
        .map(|image| {
            let n = image.features.len().min(40);
            let point_ids = image.point_ids[..n]
                .iter()
                .map(|id| {
                    id.map(|p| {
                        points.push(world.map.points[p as usize]);
                        (points.len() - 1) as u32
                    })
                })
                .collect();
            MapImage {
                camera_from_world: image.camera_from_world,
                features: ibc_pipeline::data::ImageFeatures {
                    keypoints: image.features.keypoints[..n].to_vec(),
                    descriptors: image.features.descriptors[..n].to_vec(),
                },
                point_ids,
            }
        })
        .collect();
    let map = Map { points, images };
    let mut log = world.log.clone();
    log.frames.truncate(3);
    for frame in &mut log.frames {
        for image in &mut frame.images {
            image.keypoints.truncate(20);
            image.descriptors.truncate(20);
        }
    }
    (world, map, log)
}

const MIB: usize = 1 << 20;

#[test]
fn the_allocation_counter_sees_an_allocation() {
    let (v, peak) = peak_of(|| vec![1u8; 10 * MIB]);
    assert!(peak >= 10 * MIB && v.len() == 10 * MIB);
}

#[test]
fn camera_files_survive_mutation() {
    let kb = preset_camera(IntrinsicModel::KannalaBrandt).unwrap();
    let parse = |b: &[u8]| -> Result<(), String> {
        let named = parse_camera(text(b)?).map_err(|e| e.to_string())?;
        // What the reader accepts is a plausible camera.
        assert!(
            named.camera.check_plausible().is_ok(),
            "accepted an implausible camera"
        );
        Ok(())
    };
    campaign(
        "camera YAML",
        format_camera("left", &kb).as_bytes(),
        1,
        true,
        Seal::None,
        MIB,
        &parse,
    );
    let rig = Rig::read_kalibr(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../camera-models/tests/data/trimbot-camchain.yaml"
    ))
    .unwrap();
    let parse_chain = |b: &[u8]| -> Result<(), String> {
        let rig = Rig::from_kalibr_str(text(b)?).map_err(|e| e.to_string())?;
        for c in &rig.cameras {
            assert!(
                c.camera.check_plausible().is_ok(),
                "accepted an implausible camera"
            );
        }
        Ok(())
    };
    campaign(
        "Kalibr camchain",
        rig.to_kalibr_string().as_bytes(),
        2,
        true,
        Seal::None,
        MIB,
        &parse_chain,
    );
    let extrinsics = format_extrinsics(
        rig.cameras
            .iter()
            .map(|c| (c.name.as_str(), &c.rig_from_camera)),
    );
    let parse_ext = |b: &[u8]| -> Result<(), String> {
        parse_extrinsics(text(b)?)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    campaign(
        "extrinsic.txt",
        extrinsics.as_bytes(),
        3,
        true,
        Seal::None,
        MIB,
        &parse_ext,
    );
}

#[test]
fn maps_and_logs_survive_mutation() {
    let (_, map, log) = tiny();
    let map_bytes = map_to_bytes(&map).unwrap();
    let log_bytes = log_to_bytes(&log).unwrap();
    // What a reader accepts, the writer writes back (its checks are the same).
    let parse_map = |b: &[u8]| -> Result<(), String> {
        let m = map_from_bytes::<BinaryDescriptor>(b).map_err(|e| e.to_string())?;
        assert!(
            map_to_bytes(&m).is_ok(),
            "accepted a map that cannot be written"
        );
        Ok(())
    };
    let cap = 16 * map_bytes.len().max(log_bytes.len()) + MIB;
    campaign(
        "map",
        &map_bytes,
        4,
        false,
        Seal::LengthAndChecksum,
        cap,
        &parse_map,
    );
    let parse_log = |b: &[u8]| -> Result<(), String> {
        let l = log_from_bytes::<BinaryDescriptor>(b).map_err(|e| e.to_string())?;
        assert!(
            log_to_bytes(&l).is_ok(),
            "accepted a log that cannot be written"
        );
        Ok(())
    };
    campaign(
        "rig log",
        &log_bytes,
        5,
        false,
        Seal::LengthAndChecksum,
        cap,
        &parse_log,
    );
}

#[test]
fn vocabularies_survive_mutation() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let images: Vec<Vec<BinaryDescriptor>> = (0..8)
        .map(|_| {
            (0..30)
                .map(|_| [rng.random(), rng.random(), rng.random(), rng.random()])
                .collect()
        })
        .collect();
    let vocabulary =
        Vocabulary::train(&images, &TrainingOptions::default().with_shape(3, 2)).unwrap();
    let bytes = vocabulary.to_bytes();
    let parse = |b: &[u8]| -> Result<(), String> {
        Vocabulary::<BinaryDescriptor>::from_bytes(b)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    campaign(
        "vocabulary",
        &bytes,
        6,
        false,
        Seal::Checksum,
        16 * bytes.len() + MIB,
        &parse,
    );
    // A DBoW2 text vocabulary: branching 2, depth 1, two binary words.
    let word = |v: u8| vec![v.to_string(); 32].join(" ");
    let dbow2 = format!("2 1 0 0\n0 1 {} 0.5\n0 1 {} 0.25\n", word(7), word(200));
    let parse_text = |b: &[u8]| -> Result<(), String> {
        Vocabulary::<BinaryDescriptor>::from_dbow2_text(b)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    campaign(
        "DBoW2 text vocabulary",
        dbow2.as_bytes(),
        7,
        true,
        Seal::None,
        MIB,
        &parse_text,
    );
}

#[test]
fn truth_corner_and_scenario_files_survive_mutation() {
    let (world, _, _) = tiny();
    let truth = truth_to_json(&world.truth).unwrap();
    let parse_truth = |b: &[u8]| -> Result<(), String> {
        let t = truth_from_json(text(b)?).map_err(|e| e.to_string())?;
        assert!(truth_to_json(&t).is_ok());
        Ok(())
    };
    campaign(
        "ground truth",
        truth.as_bytes(),
        8,
        true,
        Seal::None,
        16 * truth.len() + MIB,
        &parse_truth,
    );
    let camera = preset_camera(IntrinsicModel::PinholeRadtan).unwrap();
    let target = PlanarTarget::new(4, 5, 0.04).unwrap();
    let options = BoardSimulationOptions {
        views: 3,
        ..BoardSimulationOptions::for_model(IntrinsicModel::PinholeRadtan)
    };
    let corners = simulate_boards(&camera, &target, &options)
        .unwrap()
        .corners
        .to_json_string();
    let parse_corners = |b: &[u8]| -> Result<(), String> {
        CornerSet::from_json_str(text(b)?)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    campaign(
        "corner file",
        corners.as_bytes(),
        9,
        true,
        Seal::None,
        16 * corners.len() + MIB,
        &parse_corners,
    );
    let scenario = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenarios/garage.yaml"
    ))
    .unwrap();
    let base = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios"));
    let parse_scenario = |b: &[u8]| -> Result<(), String> {
        Scenario::from_yaml_str(text(b)?, base)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    campaign(
        "scenario",
        scenario.as_bytes(),
        10,
        true,
        Seal::None,
        4 * MIB,
        &parse_scenario,
    );
}
