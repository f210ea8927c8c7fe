//! The rig-log file (`.ibclog`): encoding and validated decoding. The layout is documented in
//! the [`io`](super) module.

use rayon::prelude::*;

use super::bytes::{
    CHECKSUM_LEN, COMMON_HEADER_LEN, Cursor, FileKind, POSE_LEN, buffer_len, check_envelope,
    check_pose, count_u32, finish, layout_len, put_f64, put_pose, put_u32, put_u64, start,
};
use super::error::{FormatError, invalid};
use super::features::{decode_features, put_feature_sections, starts};
use super::map_format::check_features;
use crate::data::{Frame, ImageFeatures, OdometryKind, RigLog};
use ibc_vocab_tree::Descriptor;

/// Bytes of the log header (common header, counts, odometry kind).
pub(crate) const LOG_HEADER_LEN: usize = COMMON_HEADER_LEN + 24;
/// Bytes of one frame record.
const FRAME_RECORD_LEN: usize = 16 + POSE_LEN;
/// The longest camera name, in bytes of UTF-8.
pub const MAX_CAMERA_NAME_BYTES: usize = 1024;

fn odometry_code(kind: OdometryKind) -> u8 {
    match kind {
        OdometryKind::None => 0,
        OdometryKind::Planar => 1,
        OdometryKind::SixDof => 2,
    }
}

fn odometry_from_code(code: u8) -> Option<OdometryKind> {
    match code {
        0 => Some(OdometryKind::None),
        1 => Some(OdometryKind::Planar),
        2 => Some(OdometryKind::SixDof),
        _ => None,
    }
}

/// The file's length past the camera names, or `None` on overflow.
fn log_len(names: u64, cameras: u64, frames: u64, features: u64, desc_bytes: u64) -> Option<u64> {
    layout_len(&[
        (1, (LOG_HEADER_LEN + CHECKSUM_LEN) as u64),
        (1, names),
        (frames, FRAME_RECORD_LEN as u64),
        (frames.checked_mul(cameras)?, 4),
        (features, 16 + desc_bytes),
    ])
}

/// Why a camera name is not acceptable, if it is not.
fn check_name(name: &str, names_before: &[String]) -> Option<String> {
    if name.trim().is_empty() || name.contains(['\n', '\r', '\0']) {
        Some(format!(
            "camera name {name:?} is empty or has a line break or NUL"
        ))
    } else if name.len() > MAX_CAMERA_NAME_BYTES {
        Some(format!(
            "a camera name has {} bytes, more than {MAX_CAMERA_NAME_BYTES}",
            name.len()
        ))
    } else if names_before.iter().any(|n| n == name) {
        Some(format!("camera name {name:?} appears twice"))
    } else {
        None
    }
}

/// Checks a log before writing it, so that every file written reads back.
fn check_log<D: Descriptor>(log: &RigLog<D>) -> Result<(), FormatError> {
    let cameras = log.camera_names.len();
    if cameras == 0 {
        return Err(invalid("a rig log needs at least one camera name"));
    }
    count_u32(cameras, "cameras")?;
    count_u32(log.frames.len(), "frames")?;
    for (i, name) in log.camera_names.iter().enumerate() {
        if let Some(why) = check_name(name, &log.camera_names[..i]) {
            return Err(invalid(why));
        }
    }
    let mut last = f64::NEG_INFINITY;
    for (i, frame) in log.frames.iter().enumerate() {
        if frame.images.len() != cameras {
            return Err(invalid(format!(
                "frame {i} has {} images but the log names {cameras} cameras",
                frame.images.len()
            )));
        }
        check_timestamp(frame.timestamp, last, i)?;
        last = frame.timestamp;
        match (&frame.world_from_odometry, log.odometry) {
            (Some(_), OdometryKind::None) => {
                return Err(invalid(format!(
                    "frame {i} has an odometry pose but the log's odometry kind is none"
                )));
            }
            (Some(pose), _) => check_pose(pose, &|| format!("frame {i} odometry"))?,
            (None, _) => {}
        }
        for (c, image) in frame.images.iter().enumerate() {
            if image.descriptors.len() != image.keypoints.len() {
                return Err(invalid(format!(
                    "frame {i} camera {c} has {} keypoints and {} descriptors",
                    image.keypoints.len(),
                    image.descriptors.len()
                )));
            }
            count_u32(image.len(), "features in one image")?;
            check_features(image, &|| format!("frame {i} camera {c}"))?;
        }
    }
    Ok(())
}

/// Time stamps are finite and do not decrease.
fn check_timestamp(t: f64, last: f64, i: usize) -> Result<(), FormatError> {
    if !t.is_finite() {
        return Err(invalid(format!("frame {i} has a non-finite time stamp")));
    }
    if t < last {
        return Err(invalid(format!(
            "frame {i} has time stamp {t} s, before the previous frame's {last} s: frames must \
             be in time order"
        )));
    }
    Ok(())
}

/// Encodes a rig log (see the [`io`](super) module for the layout).
///
/// # Errors
/// [`FormatError::Invalid`] for a log that would not read back: no camera, bad or duplicate
/// camera names, a frame with another number of images than cameras, time stamps out of
/// order, odometry poses in a log whose odometry kind is none, non-finite values, a count
/// past `u32`.
pub fn log_to_bytes<D: Descriptor>(log: &RigLog<D>) -> Result<Vec<u8>, FormatError> {
    check_log(log)?;
    let features: usize = log
        .frames
        .iter()
        .flat_map(|f| f.images.iter().map(ImageFeatures::len))
        .sum();
    let names_len: usize = log.camera_names.iter().map(|n| 4 + n.len()).sum();
    let len = buffer_len(
        log_len(
            names_len as u64,
            log.camera_names.len() as u64,
            log.frames.len() as u64,
            features as u64,
            D::BYTES as u64,
        ),
        "log",
    )?;
    let mut out = start::<D>(FileKind::Log, len);
    // Counts checked by `check_log`.
    put_u32(&mut out, log.camera_names.len() as u32);
    put_u32(&mut out, log.frames.len() as u32);
    out.push(odometry_code(log.odometry));
    out.extend_from_slice(&[0; 7]);
    put_u64(&mut out, features as u64);
    for name in &log.camera_names {
        put_u32(&mut out, name.len() as u32);
        out.extend_from_slice(name.as_bytes());
    }
    for frame in &log.frames {
        put_f64(&mut out, frame.timestamp);
        out.push(u8::from(frame.world_from_odometry.is_some()));
        out.extend_from_slice(&[0; 7]);
        put_pose(&mut out, frame.world_from_odometry.as_ref());
    }
    for frame in &log.frames {
        for image in &frame.images {
            put_u32(&mut out, image.len() as u32);
        }
    }
    put_feature_sections(&mut out, log.frames.iter().flat_map(|f| &f.images));
    Ok(finish(out))
}

/// Reads the camera names that follow the header, checking each length against the bytes
/// left before trusting it.
fn read_names(bytes: &[u8], cameras: u32) -> Result<(Vec<String>, usize), FormatError> {
    let end = bytes.len() - CHECKSUM_LEN;
    let mut at = LOG_HEADER_LEN;
    if u64::from(cameras) * 4 > (end - at) as u64 {
        return Err(invalid(format!(
            "the file is too short for {cameras} camera names"
        )));
    }
    let mut names: Vec<String> = Vec::new();
    for c in 0..cameras {
        if end - at < 4 {
            return Err(invalid(format!(
                "the file ends inside the name of camera {c} of {cameras}"
            )));
        }
        let len = Cursor::new(&bytes[at..at + 4]).u32() as usize;
        at += 4;
        if len > MAX_CAMERA_NAME_BYTES || len > end - at {
            return Err(invalid(format!(
                "camera {c}'s name has {len} bytes: more than {MAX_CAMERA_NAME_BYTES} or past \
                 the end of the file"
            )));
        }
        let name = std::str::from_utf8(&bytes[at..at + len])
            .map_err(|_| invalid(format!("camera {c}'s name is not UTF-8")))?
            .to_owned();
        at += len;
        if let Some(why) = check_name(&name, &names) {
            return Err(invalid(why));
        }
        names.push(name);
    }
    Ok((names, at))
}

/// Decodes and validates a rig log (see the [`io`](super) module for the checks).
///
/// # Errors
/// [`FormatError`] naming the first problem found.
pub fn log_from_bytes<D: Descriptor>(bytes: &[u8]) -> Result<RigLog<D>, FormatError> {
    check_envelope::<D>(bytes, FileKind::Log, LOG_HEADER_LEN + CHECKSUM_LEN)?;
    let mut header = Cursor::new(&bytes[COMMON_HEADER_LEN..LOG_HEADER_LEN]);
    let n_cameras = header.u32();
    let n_frames = header.u32();
    let code = header.u8();
    let reserved = header.bytes(7);
    let n_features = header.u64();
    let odometry = odometry_from_code(code).ok_or_else(|| {
        invalid(format!(
            "odometry kind code {code} is not 0 (none), 1 (planar) or 2 (6-DoF)"
        ))
    })?;
    if reserved.iter().any(|b| *b != 0) {
        return Err(invalid("reserved header bytes 41..48 must be zero"));
    }
    if n_cameras == 0 {
        return Err(invalid("the log names no camera"));
    }
    let (camera_names, names_end) = read_names(bytes, n_cameras)?;
    let actual = bytes.len() as u64;
    let needed = log_len(
        (names_end - LOG_HEADER_LEN) as u64,
        u64::from(n_cameras),
        u64::from(n_frames),
        n_features,
        D::BYTES as u64,
    );
    if needed != Some(actual) {
        return Err(FormatError::LayoutMismatch {
            counts: format!("{n_cameras} cameras, {n_frames} frames, {n_features} features"),
            needed: needed.unwrap_or(u64::MAX),
            actual,
        });
    }
    // From here on every section fits in the file, so counts bound every allocation.
    let mut at = names_end;
    let section = |at: &mut usize, len: usize| {
        let s = &bytes[*at..*at + len];
        *at += len;
        s
    };
    let cameras = n_cameras as usize;
    let records = section(&mut at, n_frames as usize * FRAME_RECORD_LEN);
    let mut frames: Vec<Frame<D>> = Vec::with_capacity(n_frames as usize);
    let mut last = f64::NEG_INFINITY;
    for (i, c) in records.chunks_exact(FRAME_RECORD_LEN).enumerate() {
        let mut r = Cursor::new(c);
        let timestamp = r.f64();
        check_timestamp(timestamp, last, i)?;
        last = timestamp;
        let flag = r.u8();
        if r.bytes(7).iter().any(|b| *b != 0) {
            return Err(invalid(format!("frame {i}: reserved bytes are not zero")));
        }
        let world_from_odometry = match (flag, odometry) {
            (0, _) => {
                if r.bytes(POSE_LEN).iter().any(|b| *b != 0) {
                    return Err(invalid(format!(
                        "frame {i} has no odometry pose but its pose bytes are not zero"
                    )));
                }
                None
            }
            (1, OdometryKind::None) => {
                return Err(invalid(format!(
                    "frame {i} has an odometry pose but the log's odometry kind is none"
                )));
            }
            (1, _) => Some(r.pose(&|| format!("frame {i} odometry"))?),
            (f, _) => {
                return Err(invalid(format!(
                    "frame {i}: odometry flag {f} is not 0 or 1"
                )));
            }
        };
        frames.push(Frame {
            timestamp,
            images: Vec::with_capacity(cameras),
            world_from_odometry,
        });
    }
    let counts_bytes = section(&mut at, n_frames as usize * cameras * 4);
    let counts: Vec<usize> = counts_bytes
        .chunks_exact(4)
        .map(|c| Cursor::new(c).u32() as usize)
        .collect();
    let total: u64 = counts.iter().map(|c| *c as u64).sum();
    if total != n_features {
        return Err(invalid(format!(
            "the images hold {total} features but the header says {n_features}"
        )));
    }
    let f = n_features as usize;
    let keypoints = section(&mut at, f * 16);
    let descriptors = section(&mut at, f * D::BYTES);
    let first = starts(&counts);
    let decoded: Vec<Result<ImageFeatures<D>, FormatError>> = counts
        .par_iter()
        .zip(first.par_iter())
        .enumerate()
        .map(|(n, (&count, &s))| {
            decode_features::<D>(
                &keypoints[16 * s..16 * (s + count)],
                &descriptors[D::BYTES * s..D::BYTES * (s + count)],
                &|| format!("frame {} camera {}", n / cameras, n % cameras),
            )
        })
        .collect();
    let mut decoded = decoded.into_iter();
    for frame in &mut frames {
        for _ in 0..cameras {
            if let Some(image) = decoded.next() {
                frame.images.push(image?);
            }
        }
    }
    Ok(RigLog {
        camera_names,
        odometry,
        frames,
    })
}
