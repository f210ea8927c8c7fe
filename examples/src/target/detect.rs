//! AprilGrid detection in images, with the `aprilgrid` crate's detector (saddle points refined
//! to sub-pixel, quads grown into a board, tags decoded against tag36h11).
//!
//! The detector's tag corners become [`Corner`]s of the grid's [`PlanarTarget`](crate::intrinsics::PlanarTarget)
//! ([`AprilGrid::corner_index`]); tags whose id is not on the grid (another target in view)
//! are dropped and counted. Pixel coordinates have pixel centres at integer coordinates, as
//! everywhere in ibc.
//!
//! The detection crate may panic on images it does not expect; such a panic is caught and
//! returned as [`TargetError::DetectorFailed`] naming the image, never passed on to the
//! caller.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use aprilgrid::TagFamily;
use aprilgrid::detector::TagDetector;
use image::{DynamicImage, GrayImage, ImageReader};

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
    let detector = TagDetector::new(&TagFamily::T36H11, None);
    let dynamic = DynamicImage::ImageLuma8(image.clone());
    let tags = catch_unwind(AssertUnwindSafe(|| detector.detect(&dynamic))).map_err(|panic| {
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
