//! Every kind of corrupt, truncated or mismatched map and log file is a typed error naming the
//! problem, never a panic and never an allocation sized by an unchecked count.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod sim_common;

use ibc_pipeline::data::io::{
    DataFileError, FormatError, log_from_bytes, log_to_bytes, map_from_bytes, map_to_bytes,
    read_map,
};
use ibc_pipeline::data::{
    BinaryDescriptor, FloatDescriptor, Frame, ImageFeatures, Map, MapImage, OdometryKind, RigLog,
};
use nalgebra::{Isometry3, Point3, Vector2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim_common::{reseal, reseal_with_length};

/// 3 points, 2 images (3 features with a pose, 2 without): 516 bytes.
///
/// Offsets: header 0..48, points 48..120, image records 120..248 (image 0: count 120, flag
/// 124, reserved 125..128, pose 128..184), keypoints 248..328, descriptors 328..488, point
/// ids 488..508, checksum 508..516.
fn map() -> Map<BinaryDescriptor> {
    let kp = |x: f64| Vector2::new(x, x + 0.5);
    Map {
        points: vec![
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(4.0, 5.0, 6.0),
            Point3::new(7.0, 8.0, 9.0),
        ],
        images: vec![
            MapImage {
                camera_from_world: Some(Isometry3::translation(1.0, 0.0, 0.0)),
                features: ImageFeatures {
                    keypoints: vec![kp(1.0), kp(2.0), kp(3.0)],
                    descriptors: vec![[1; 4], [2; 4], [3; 4]],
                },
                point_ids: vec![Some(0), None, Some(2)],
            },
            MapImage {
                camera_from_world: None,
                features: ImageFeatures {
                    keypoints: vec![kp(4.0), kp(5.0)],
                    descriptors: vec![[4; 4], [5; 4]],
                },
                point_ids: vec![Some(1), Some(0)],
            },
        ],
    }
}

/// Cameras `x1`, `x2`; planar odometry; 3 frames (odometry at frames 0 and 2) with
/// [2, 1], [0, 3], [1, 1] features: 700 bytes.
///
/// Offsets: header 0..56 (camera count 32, frame count 36, odometry kind 40, features 48),
/// names 56..68 (length 56, "x1" 60..62, length 62, "x2" 66..68), frame records 68..284
/// (frame 0: time 68, flag 76, pose 84..140; frame 1 at 140), counts 284..308, keypoints
/// 308..436, descriptors 436..692, checksum 692..700.
fn log() -> RigLog<BinaryDescriptor> {
    let image = |n: usize| ImageFeatures {
        keypoints: (0..n).map(|i| Vector2::new(i as f64, 2.0)).collect(),
        descriptors: (0..n).map(|i| [i as u64; 4]).collect(),
    };
    let counts = [[2, 1], [0, 3], [1, 1]];
    RigLog {
        camera_names: vec!["x1".into(), "x2".into()],
        odometry: OdometryKind::Planar,
        frames: counts
            .iter()
            .enumerate()
            .map(|(i, c)| Frame {
                timestamp: 0.1 * i as f64,
                images: c.iter().map(|n| image(*n)).collect(),
                world_from_odometry: (i != 1).then(|| Isometry3::translation(i as f64, 0.0, 0.0)),
            })
            .collect(),
    }
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn put_f64(b: &mut [u8], at: usize, v: f64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn map_err(bytes: &[u8]) -> FormatError {
    map_from_bytes::<BinaryDescriptor>(bytes).expect_err("the corrupt map was accepted")
}

fn log_err(bytes: &[u8]) -> FormatError {
    log_from_bytes::<BinaryDescriptor>(bytes).expect_err("the corrupt log was accepted")
}

fn says(err: &FormatError, words: &str) {
    assert!(
        err.to_string().contains(words),
        "`{err}` does not say `{words}`"
    );
}

#[test]
fn the_layouts_are_as_documented() {
    let m = map_to_bytes(&map()).unwrap();
    assert_eq!(m.len(), 516);
    assert_eq!(&m[..8], b"IBCMAP\0\0");
    assert_eq!(map_from_bytes::<BinaryDescriptor>(&m).unwrap(), map());
    let l = log_to_bytes(&log()).unwrap();
    assert_eq!(l.len(), 700);
    assert_eq!(&l[..8], b"IBCLOG\0\0");
    assert_eq!(&l[60..62], b"x1");
    assert_eq!(log_from_bytes::<BinaryDescriptor>(&l).unwrap(), log());
}

#[test]
fn damaged_envelopes_are_named() {
    let good = map_to_bytes(&map()).unwrap();
    assert!(matches!(map_err(&[]), FormatError::TooShort { len: 0, .. }));
    assert!(matches!(
        map_err(&good[..10]),
        FormatError::TooShort { len: 10, .. }
    ));
    let e = map_err(&good[..good.len() - 100]);
    assert!(
        matches!(
            e,
            FormatError::LengthMismatch {
                declared: 516,
                actual: 416
            }
        ),
        "{e}"
    );
    says(&e, "truncated");
    let mut longer = good.clone();
    longer.push(0);
    assert!(matches!(
        map_err(&longer),
        FormatError::LengthMismatch { .. }
    ));
    let mut flipped = good.clone();
    flipped[300] ^= 0x10;
    says(&map_err(&flipped), "checksum mismatch");
    let mut checksum = good.clone();
    checksum[515] ^= 1;
    assert!(matches!(
        map_err(&checksum),
        FormatError::ChecksumMismatch { .. }
    ));
    let png = b"\x89PNG\r\n\x1a\n0000000000000000000000000000000000000000000000000000000";
    assert!(matches!(map_err(png), FormatError::BadMagic { .. }));
    let e = map_err(&log_to_bytes(&log()).unwrap());
    assert!(
        matches!(
            e,
            FormatError::WrongFileKind {
                expected: "map",
                found: "rig log"
            }
        ),
        "{e}"
    );
    let e = log_err(&good);
    assert!(
        matches!(
            e,
            FormatError::WrongFileKind {
                expected: "rig log",
                found: "map"
            }
        ),
        "{e}"
    );
    let mut version = good.clone();
    put_u32(&mut version, 8, 2);
    let e = map_err(&version);
    assert!(
        matches!(
            e,
            FormatError::UnsupportedVersion {
                found: 2,
                supported: 1
            }
        ),
        "{e}"
    );
    let mut kind = good.clone();
    kind[12] = 9;
    assert!(matches!(
        map_err(&kind),
        FormatError::UnknownDescriptorKind { code: 9 }
    ));
    let e = map_from_bytes::<FloatDescriptor>(&good).unwrap_err();
    assert!(matches!(e, FormatError::DescriptorMismatch { .. }), "{e}");
    says(&e, "binary 256-bit");
    assert!(matches!(
        map_from_bytes::<[u64; 8]>(&good).unwrap_err(),
        FormatError::DescriptorMismatch { .. }
    ));
}

#[test]
fn corrupt_map_content_is_named_even_with_a_valid_checksum() {
    let good = map_to_bytes(&map()).unwrap();
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        reseal(&mut b);
        map_err(&b)
    };
    // Huge counts: the length check rejects them before anything is allocated.
    let e = edit(&|b| put_u32(b, 32, u32::MAX - 1));
    assert!(matches!(e, FormatError::LayoutMismatch { .. }), "{e}");
    let e = edit(&|b| put_u64(b, 40, u64::MAX));
    assert!(
        matches!(
            e,
            FormatError::LayoutMismatch {
                needed: u64::MAX,
                ..
            }
        ),
        "{e}"
    );
    let e = edit(&|b| put_u32(b, 36, 1_000_000));
    assert!(matches!(e, FormatError::LayoutMismatch { .. }), "{e}");
    says(
        &edit(&|b| put_u32(b, 488, 3)),
        "observes point 3 but the map has 3 points",
    );
    says(
        &edit(&|b| put_u32(b, 120, 4)),
        "hold 6 features but the header says 5",
    );
    says(&edit(&|b| put_f64(b, 128 + 24, 2.0)), "norm");
    says(&edit(&|b| put_f64(b, 48 + 8, f64::NAN)), "map point 0");
    says(
        &edit(&|b| put_f64(b, 248 + 16, f64::INFINITY)),
        "map image 0 keypoint 1",
    );
    says(&edit(&|b| b[124] = 7), "pose flag 7");
    says(
        &edit(&|b| b[124] = 0),
        "no pose but its pose bytes are not zero",
    );
    says(&edit(&|b| b[126] = 1), "reserved");
    says(&edit(&|b| b[13] = 1), "reserved");
    says(&edit(&|b| b[20] = 1), "reserved");
}

#[test]
fn corrupt_float_descriptors_are_named() {
    let m: Map<FloatDescriptor> = Map {
        points: vec![Point3::origin()],
        images: vec![MapImage {
            camera_from_world: None,
            features: ImageFeatures {
                keypoints: vec![Vector2::new(1.0, 1.0)],
                descriptors: vec![[0.25; 64]],
            },
            point_ids: vec![Some(0)],
        }],
    };
    let mut b = map_to_bytes(&m).unwrap();
    // Descriptors start after the header (48), 1 point (24), 1 record (64), 1 keypoint (16).
    b[152..156].copy_from_slice(&f32::NAN.to_le_bytes());
    reseal(&mut b);
    let e = map_from_bytes::<FloatDescriptor>(&b).unwrap_err();
    says(&e, "descriptor 0 has a non-finite value");
}

#[test]
fn corrupt_log_content_is_named_even_with_a_valid_checksum() {
    let good = log_to_bytes(&log()).unwrap();
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        reseal(&mut b);
        log_err(&b)
    };
    says(&edit(&|b| put_u32(b, 32, 0)), "names no camera");
    says(
        &edit(&|b| put_u32(b, 56, 60_000)),
        "camera 0's name has 60000 bytes",
    );
    says(
        &edit(&|b| put_u32(b, 32, u32::MAX)),
        "too short for 4294967295 camera names",
    );
    says(&edit(&|b| b[67] = b'1'), "appears twice");
    says(&edit(&|b| b[60] = 0xFF), "not UTF-8");
    says(&edit(&|b| b[61] = b'\n'), "line break");
    says(&edit(&|b| b[40] = 5), "odometry kind code 5");
    says(&edit(&|b| b[40] = 0), "odometry kind is none");
    says(&edit(&|b| b[44] = 1), "reserved");
    says(&edit(&|b| put_f64(b, 140, -1.0)), "time order");
    says(
        &edit(&|b| put_f64(b, 68, f64::NAN)),
        "non-finite time stamp",
    );
    says(&edit(&|b| b[76] = 2), "odometry flag 2");
    says(&edit(&|b| put_f64(b, 84 + 24, 0.5)), "frame 0 odometry");
    says(
        &edit(&|b| put_u32(b, 284, 3)),
        "hold 9 features but the header says 8",
    );
    says(
        &edit(&|b| put_f64(b, 308, f64::NAN)),
        "frame 0 camera 0 keypoint 0",
    );
    let e = edit(&|b| put_u32(b, 36, 4_000_000_000));
    assert!(matches!(e, FormatError::LayoutMismatch { .. }), "{e}");
    let e = edit(&|b| put_u64(b, 48, 1 << 60));
    assert!(matches!(e, FormatError::LayoutMismatch { .. }), "{e}");
}

#[test]
fn random_damage_never_panics_and_what_is_accepted_is_canonical() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let files = [map_to_bytes(&map()).unwrap(), log_to_bytes(&log()).unwrap()];
    let mut rejected = 0;
    let trials = 3000;
    for t in 0..trials {
        let mut b = files[t % 2].clone();
        match rng.random_range(0..4) {
            0 => {
                let i = rng.random_range(0..b.len());
                b[i] = rng.random();
            }
            1 => b.truncate(rng.random_range(0..b.len())),
            2 => {
                let i = rng.random_range(0..b.len());
                b.insert(i, rng.random());
            }
            _ => {
                // Damage the content, then make the envelope consistent again, so that the
                // content checks are what must catch it.
                for _ in 0..rng.random_range(1..4) {
                    let i = rng.random_range(32..b.len() - 8);
                    b[i] = rng.random();
                }
                reseal_with_length(&mut b);
            }
        }
        let ok = if t % 2 == 0 {
            map_from_bytes::<BinaryDescriptor>(&b)
                .map(|m| {
                    assert_eq!(
                        map_from_bytes::<BinaryDescriptor>(&map_to_bytes(&m).unwrap()).unwrap(),
                        m
                    )
                })
                .is_ok()
        } else {
            log_from_bytes::<BinaryDescriptor>(&b)
                .map(|l| {
                    assert_eq!(
                        log_from_bytes::<BinaryDescriptor>(&log_to_bytes(&l).unwrap()).unwrap(),
                        l
                    )
                })
                .is_ok()
        };
        rejected += usize::from(!ok);
    }
    // Only content damage to keypoints, descriptors, timestamps or poses can survive.
    assert!(
        rejected > trials * 3 / 4,
        "only {rejected} of {trials} rejected"
    );
}

#[test]
fn errors_from_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.ibcmap");
    let mut b = map_to_bytes(&map()).unwrap();
    b[300] ^= 1;
    std::fs::write(&path, &b).unwrap();
    let e = read_map::<BinaryDescriptor>(&path).unwrap_err();
    assert!(matches!(
        e,
        DataFileError::Format {
            source: FormatError::ChecksumMismatch { .. },
            ..
        }
    ));
    assert!(e.to_string().contains("broken.ibcmap"), "{e}");
    assert_eq!(e.path(), path);
}
