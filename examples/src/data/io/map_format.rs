//! The map file (`.ibcmap`): encoding and validated decoding. The layout is documented in the
//! [`io`](super) module.

use nalgebra::Point3;
use rayon::prelude::*;

use super::bytes::{
    CHECKSUM_LEN, COMMON_HEADER_LEN, Cursor, FileKind, POSE_LEN, buffer_len, check_envelope,
    check_pose, count_u32, finish, layout_len, put_f64, put_pose, put_u32, put_u64, start,
};
use super::error::{FormatError, invalid};
use super::features::{decode_features, put_feature_sections, starts};
use crate::data::{ImageFeatures, Map, MapImage};
use ibc_vocab_tree::Descriptor;

/// Bytes of the map header (common header and counts).
pub(crate) const MAP_HEADER_LEN: usize = COMMON_HEADER_LEN + 16;
/// Bytes of one image record.
const IMAGE_RECORD_LEN: usize = 8 + POSE_LEN;
/// The point id that marks a feature with no map point.
pub const NO_POINT: u32 = u32::MAX;

/// The file's length for these counts, or `None` on overflow.
fn map_len(points: u64, images: u64, features: u64, desc_bytes: u64) -> Option<u64> {
    layout_len(&[
        (1, (MAP_HEADER_LEN + CHECKSUM_LEN) as u64),
        (points, 24),
        (images, IMAGE_RECORD_LEN as u64),
        (features, 16 + desc_bytes + 4),
    ])
}

/// Checks a map before writing it, so that every file written reads back.
fn check_map<D: Descriptor>(map: &Map<D>) -> Result<(), FormatError> {
    let n_points = count_u32(map.points.len(), "map points")?;
    if n_points == NO_POINT {
        return Err(invalid("a map holds at most 2^32 - 2 points"));
    }
    count_u32(map.images.len(), "map images")?;
    if let Some(i) = map
        .points
        .iter()
        .position(|p| !p.coords.iter().all(|v| v.is_finite()))
    {
        return Err(invalid(format!(
            "map point {i} has a non-finite coordinate"
        )));
    }
    for (i, image) in map.images.iter().enumerate() {
        let f = &image.features;
        let n = f.keypoints.len();
        if f.descriptors.len() != n || image.point_ids.len() != n {
            return Err(invalid(format!(
                "map image {i} has {n} keypoints, {} descriptors and {} point ids",
                f.descriptors.len(),
                image.point_ids.len()
            )));
        }
        count_u32(n, "features in one image")?;
        if let Some(pose) = &image.camera_from_world {
            check_pose(pose, &|| format!("map image {i}"))?;
        }
        check_features(f, &|| format!("map image {i}"))?;
        if let Some((k, id)) = image
            .point_ids
            .iter()
            .enumerate()
            .find_map(|(k, id)| id.filter(|id| *id >= n_points).map(|id| (k, id)))
        {
            return Err(invalid(format!(
                "map image {i} feature {k} observes point {id} but the map has {n_points} points"
            )));
        }
    }
    Ok(())
}

/// Checks keypoints and descriptors of one image before writing: finite values.
pub(crate) fn check_features<D: Descriptor>(
    f: &ImageFeatures<D>,
    what: &dyn Fn() -> String,
) -> Result<(), FormatError> {
    if let Some(k) = f
        .keypoints
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(invalid(format!("{} keypoint {k} is not finite", what())));
    }
    if let Some(k) = f.descriptors.iter().position(|d| !d.is_finite()) {
        return Err(invalid(format!(
            "{} descriptor {k} has a non-finite value",
            what()
        )));
    }
    Ok(())
}

/// Encodes a map (see the [`io`](super) module for the layout).
///
/// # Errors
/// [`FormatError::Invalid`] for a map that would not read back: lengths that disagree within
/// an image, a point id past the points, a non-finite value, a count past `u32`.
pub fn map_to_bytes<D: Descriptor>(map: &Map<D>) -> Result<Vec<u8>, FormatError> {
    check_map(map)?;
    let features: usize = map.images.iter().map(|i| i.features.len()).sum();
    let len = buffer_len(
        map_len(
            map.points.len() as u64,
            map.images.len() as u64,
            features as u64,
            D::BYTES as u64,
        ),
        "map",
    )?;
    let mut out = start::<D>(FileKind::Map, len);
    // Counts checked by `check_map`.
    put_u32(&mut out, map.points.len() as u32);
    put_u32(&mut out, map.images.len() as u32);
    put_u64(&mut out, features as u64);
    for p in &map.points {
        p.coords.iter().for_each(|v| put_f64(&mut out, *v));
    }
    for image in &map.images {
        put_u32(&mut out, image.features.len() as u32);
        out.push(u8::from(image.camera_from_world.is_some()));
        out.extend_from_slice(&[0; 3]);
        put_pose(&mut out, image.camera_from_world.as_ref());
    }
    put_feature_sections(&mut out, map.images.iter().map(|i| &i.features));
    for image in &map.images {
        for id in &image.point_ids {
            put_u32(&mut out, id.unwrap_or(NO_POINT));
        }
    }
    Ok(finish(out))
}

/// Decodes and validates a map (see the [`io`](super) module for the checks).
///
/// # Errors
/// [`FormatError`] naming the first problem found.
pub fn map_from_bytes<D: Descriptor>(bytes: &[u8]) -> Result<Map<D>, FormatError> {
    check_envelope::<D>(bytes, FileKind::Map, MAP_HEADER_LEN + CHECKSUM_LEN)?;
    let mut header = Cursor::new(&bytes[COMMON_HEADER_LEN..MAP_HEADER_LEN]);
    let n_points = header.u32();
    let n_images = header.u32();
    let n_features = header.u64();
    let actual = bytes.len() as u64;
    let needed = map_len(
        u64::from(n_points),
        u64::from(n_images),
        n_features,
        D::BYTES as u64,
    );
    if needed != Some(actual) {
        return Err(FormatError::LayoutMismatch {
            counts: format!("{n_points} points, {n_images} images, {n_features} features"),
            needed: needed.unwrap_or(u64::MAX),
            actual,
        });
    }
    if n_points == NO_POINT {
        return Err(invalid("the point count 2^32 - 1 is reserved"));
    }
    // From here on every section fits in the file, so counts bound every allocation.
    let mut at = MAP_HEADER_LEN;
    let section = |at: &mut usize, len: usize| {
        let s = &bytes[*at..*at + len];
        *at += len;
        s
    };
    let points_bytes = section(&mut at, n_points as usize * 24);
    let mut points = Vec::with_capacity(n_points as usize);
    for (i, c) in points_bytes.chunks_exact(24).enumerate() {
        let mut r = Cursor::new(c);
        let p = Point3::new(r.f64(), r.f64(), r.f64());
        if !p.coords.iter().all(|v| v.is_finite()) {
            return Err(invalid(format!(
                "map point {i} has a non-finite coordinate"
            )));
        }
        points.push(p);
    }
    let records = section(&mut at, n_images as usize * IMAGE_RECORD_LEN);
    let mut counts = Vec::with_capacity(n_images as usize);
    let mut poses = Vec::with_capacity(n_images as usize);
    let mut total = 0u64;
    for (i, c) in records.chunks_exact(IMAGE_RECORD_LEN).enumerate() {
        let mut r = Cursor::new(c);
        let count = r.u32();
        let flag = r.u8();
        let reserved = r.bytes(3);
        if reserved.iter().any(|b| *b != 0) {
            return Err(invalid(format!(
                "map image {i}: reserved bytes are not zero"
            )));
        }
        let pose = match flag {
            0 => {
                if r.bytes(POSE_LEN).iter().any(|b| *b != 0) {
                    return Err(invalid(format!(
                        "map image {i} has no pose but its pose bytes are not zero"
                    )));
                }
                None
            }
            1 => Some(r.pose(&|| format!("map image {i}"))?),
            f => {
                return Err(invalid(format!(
                    "map image {i}: pose flag {f} is not 0 or 1"
                )));
            }
        };
        total += u64::from(count);
        counts.push(count as usize);
        poses.push(pose);
    }
    if total != n_features {
        return Err(invalid(format!(
            "the images hold {total} features but the header says {n_features}"
        )));
    }
    let f = n_features as usize;
    let keypoints = section(&mut at, f * 16);
    let descriptors = section(&mut at, f * D::BYTES);
    let ids = section(&mut at, f * 4);
    let first = starts(&counts);
    let decoded: Vec<Result<MapImage<D>, FormatError>> = counts
        .par_iter()
        .zip(first.par_iter())
        .zip(poses.into_par_iter())
        .enumerate()
        .map(|(i, ((&n, &s), camera_from_world))| {
            let what = || format!("map image {i}");
            let features = decode_features::<D>(
                &keypoints[16 * s..16 * (s + n)],
                &descriptors[D::BYTES * s..D::BYTES * (s + n)],
                &what,
            )?;
            let mut point_ids = Vec::with_capacity(n);
            for (k, c) in ids[4 * s..4 * (s + n)].chunks_exact(4).enumerate() {
                let id = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                point_ids.push(match id {
                    NO_POINT => None,
                    id if id < n_points => Some(id),
                    id => {
                        return Err(invalid(format!(
                            "map image {i} feature {k} observes point {id} but the map has \
                             {n_points} points"
                        )));
                    }
                });
            }
            Ok(MapImage {
                camera_from_world,
                features,
                point_ids,
            })
        })
        .collect();
    let images = decoded.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(Map { points, images })
}
