//! AprilGrid detection in images, with the `aprilgrid` crate's detector (saddle points refined
//! to sub-pixel, quads grown into a board, tags decoded against tag36h11).
//!
//! The crate's steps are composed here rather than called through its `TagDetector::detect`,
//! which picks the saddle orientation to start from by iterating a hash map: where two
//! orientations hold equally many saddles the board it grows, and so the corners found,
//! changed from run to run on the same image (seen on rendered fisheye images: 24 or 72
//! corners of one view). Here the orientation buckets are ordered, ties go to the larger
//! angle, the quads are decoded in index order and a tag id found twice keeps its first
//! quad, so the same image gives the same corners every time. The board is grown with the
//! grid's own spacing ratio (the crate's search assumes Kalibr's default 0.3), and a start
//! saddle that already lies on the best board found is not grown again (the same board would
//! come back): on 752 x 480 views that took the search from 2-23 ms an image to 1.5-15 ms.
//!
//! The detector's tag corners become [`Corner`]s of the grid's [`PlanarTarget`](crate::intrinsics::PlanarTarget)
//! ([`AprilGrid::corner_index`]); tags whose id is not on the grid (another target in view)
//! are dropped and counted. Pixel coordinates have pixel centres at integer coordinates, as
//! everywhere in ibc.
//!
//! The detection crate may panic on images it does not expect; such a panic is caught and
//! returned as [`TargetError::DetectorFailed`] naming the image, never passed on to the
//! caller.

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use aprilgrid::TagFamily;
use aprilgrid::board::Board;
use aprilgrid::detector::{TagDetector, best_tag, bit_code, decode_positions, init_quads};
use aprilgrid::saddle::Saddle;
use aprilgrid::tag_families::T36H11;
use image::{DynamicImage, GrayImage, ImageReader};
use kdtree::KdTree;

use super::aprilgrid::AprilGrid;
use super::error::TargetError;
use crate::intrinsics::Corner;

/// The largest image file read, in bytes: 256 MiB.
pub const MAX_IMAGE_FILE_BYTES: u64 = 256 << 20;
/// The largest image side decoded, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// What the detector found in one image.
#[derive(Clone, Debug, PartialEq)]
pub struct Detection {
    /// The grid corners found, each at most once, ordered by (row, column).
    pub corners: Vec<Corner>,
    /// Tags decoded whose id is not on the grid (another target, or a wrong target file).
    pub foreign_tags: usize,
}

/// Detects `grid` in a grey image named `name` (the name is used in errors).
///
/// # Errors
/// [`TargetError::DetectorFailed`] if the detection crate panicked on the image.
pub fn detect_april_grid(
    image: &GrayImage,
    grid: &AprilGrid,
    name: &str,
) -> Result<Detection, TargetError> {
    let tags = catch_unwind(AssertUnwindSafe(|| grid_tags(image, grid))).map_err(|panic| {
        let reason = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic without a message".into());
        TargetError::DetectorFailed {
            image: name.to_owned(),
            reason,
        }
    })?;
    let mut corners = Vec::with_capacity(tags.len() * 4);
    let mut foreign_tags = 0;
    for (id, points) in &tags {
        if *id >= grid.num_tags() {
            foreign_tags += 1;
            continue;
        }
        for (j, (u, v)) in points.iter().enumerate() {
            if let Some((row, col)) = grid.corner_index(*id, j)
                && u.is_finite()
                && v.is_finite()
            {
                corners.push(Corner {
                    row,
                    col,
                    u: f64::from(*u),
                    v: f64::from(*v),
                });
            }
        }
    }
    corners.sort_by_key(|c| (c.row, c.col));
    corners.dedup_by_key(|c| (c.row, c.col));
    Ok(Detection {
        corners,
        foreign_tags,
    })
}

/// Tag36h11's data bits per side, its black border in bits, and the Hamming distance up to
/// which a code is accepted (the detection crate's values for the family).
const TAG36H11_EDGE_BITS: u8 = 6;
const TAG36H11_BORDER_BITS: u8 = 2;
const TAG36H11_MAX_HAMMING: u8 = 3;

/// Start saddles tried when growing the board (the detection crate's bound).
const MAX_BOARD_STARTS: usize = 30;

/// Boards grown per image: the second search, over the saddles the first board's tags did not
/// use, finds the part of a grid that the first could not reach (a board whose growth stopped
/// at a strongly distorted or partly hidden row). The detection crate's bound.
const MAX_BOARDS: usize = 2;

/// The tags of the grid in an image, by id: each tag's four corners as the detection crate
/// orders them (see [`AprilGrid::corner_index`]).
fn grid_tags(image: &GrayImage, grid: &AprilGrid) -> BTreeMap<u32, [(f32, f32); 4]> {
    let mut tags = BTreeMap::new();
    let detector = TagDetector::new(&TagFamily::T36H11, None);
    let mut saddles = detector.refined_saddle_points(&DynamicImage::ImageLuma8(image.clone()));
    for _ in 0..MAX_BOARDS {
        let mut used = vec![false; saddles.len()];
        for quad in best_board(&saddles, grid) {
            let corners = quad.map(|i| saddles[i].p);
            if let Some((id, ordered)) = decode_tag(image, corners) {
                tags.entry(id).or_insert(ordered);
                for i in quad {
                    used[i] = true;
                }
            }
        }
        // Nothing decoded, or every tag found: another search can add nothing.
        if !used.contains(&true) || tags.len() >= grid.num_tags() as usize {
            break;
        }
        let mut keep = used.iter().map(|u| !u);
        saddles.retain(|_| keep.next().unwrap_or(false));
    }
    tags
}

/// The quads (saddle indices) of the largest board grown from the saddles, in index order.
fn best_board(saddles: &[Saddle], grid: &AprilGrid) -> Vec<[usize; 4]> {
    let mut tree = KdTree::new(2);
    for (i, saddle) in saddles.iter().enumerate() {
        if tree.add(saddle.arr(), i).is_err() {
            return Vec::new();
        }
    }
    // The grid's saddles share one orientation: start from the most numerous (whole degrees).
    let mut by_angle: BTreeMap<i32, Vec<usize>> = BTreeMap::new();
    for (i, saddle) in saddles.iter().enumerate() {
        by_angle
            .entry(saddle.theta.round() as i32)
            .or_default()
            .push(i);
    }
    let Some(starts) = by_angle.values().max_by_key(|v| v.len()) else {
        return Vec::new();
    };
    let active = vec![true; saddles.len()];
    let spacing = grid.tag_spacing as f32;
    let mut best: Option<Board<'_, '_>> = None;
    // Saddles of the best board so far: a start among them grows that board again.
    let mut on_best = vec![false; saddles.len()];
    for &start in starts.iter().rev().take(MAX_BOARD_STARTS) {
        if on_best[start] {
            continue;
        }
        for quad in init_quads(saddles, start, &tree) {
            let board = Board::new(saddles, &active, &quad, spacing, &tree);
            if best.as_ref().is_none_or(|b| board.score > b.score) {
                on_best.fill(false);
                for i in board.all_tag_indexes().into_iter().flatten() {
                    on_best[i] = true;
                }
                best = Some(board);
            }
        }
        if best.as_ref().is_some_and(|b| b.score >= grid.num_tags()) {
            break;
        }
    }
    let Some(mut board) = best else {
        return Vec::new();
    };
    board.try_fix_missing();
    let mut quads = board.all_tag_indexes();
    quads.sort_unstable();
    quads
}

/// The tag36h11 id of a quad and its corners in the detection crate's order, if it decodes.
fn decode_tag(image: &GrayImage, corners: [(f32, f32); 4]) -> Option<(u32, [(f32, f32); 4])> {
    let samples = decode_positions(
        image.width(),
        image.height(),
        &corners,
        TAG36H11_BORDER_BITS,
        TAG36H11_EDGE_BITS,
        0.5,
    )?;
    let bits = bit_code(image, &samples, 10, 3)?;
    let (id, rotation) = best_tag(bits, TAG36H11_MAX_HAMMING, &T36H11, TAG36H11_EDGE_BITS)?;
    // The crate's corner order for a decoded tag: rotated to the code's orientation, then
    // reversed.
    let mut ordered = corners;
    ordered.rotate_left(rotation);
    ordered.reverse();
    Some((u32::try_from(id).ok()?, ordered))
}

/// Reads an image file as 8-bit grey: a regular file of at most [`MAX_IMAGE_FILE_BYTES`], in
/// any format the `image` crate decodes (PNG, JPEG, ...), at most [`MAX_IMAGE_SIDE`] pixels a
/// side.
///
/// # Errors
/// [`TargetError::Image`] naming the file: unreadable, not a regular file, too large, or not an
/// image.
pub fn read_gray_image(path: impl AsRef<Path>) -> Result<GrayImage, TargetError> {
    let path = path.as_ref();
    let bad = |reason: String| TargetError::Image {
        path: path.to_owned(),
        reason,
    };
    let bytes = ibc_camera_models::io::read_bytes(path, MAX_IMAGE_FILE_BYTES)
        .map_err(|e| bad(e.to_string()))?;
    let mut reader = ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| bad(format!("cannot tell the image format: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_IMAGE_SIDE);
    limits.max_image_height = Some(MAX_IMAGE_SIDE);
    reader.limits(limits);
    let image = reader
        .decode()
        .map_err(|e| bad(format!("not a readable image: {e}")))?;
    Ok(image.into_luma8())
}
