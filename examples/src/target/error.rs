//! The target module's error type: unreadable images, target files that are not AprilGrids,
//! and a detector that failed.

use std::path::PathBuf;

/// Why a target file, an image or a detection could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TargetError {
    /// The target definition is invalid (sizes, counts), with the reason.
    #[error("invalid target: {0}")]
    InvalidTarget(String),
    /// A target file could not be read or is not a Kalibr target definition.
    #[error("{}: {reason}", path.display())]
    TargetFile {
        /// The file.
        path: PathBuf,
        /// What was wrong with it.
        reason: String,
    },
    /// An image file could not be read or decoded.
    #[error("{}: {reason}", path.display())]
    Image {
        /// The image file.
        path: PathBuf,
        /// What was wrong with it.
        reason: String,
    },
    /// An option of the renderer or detector is outside its valid range.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The detector failed on an image (it panicked inside the detection crate; the image is
    /// named so that it can be looked at).
    #[error("{image}: the AprilGrid detector failed on this image ({reason})")]
    DetectorFailed {
        /// The image's name.
        image: String,
        /// The detector's message.
        reason: String,
    },
    /// A camera's own calibration failed (its intrinsics), with the reason.
    #[error("camera `{camera}`: {reason}")]
    Camera {
        /// The camera's name.
        camera: String,
        /// What failed.
        reason: String,
    },
    /// A camera never sees the target at the same time as a camera linked to the reference.
    #[error(
        "camera `{camera}` never sees the target at the same time as `{reference}` or a camera \
         linked to it: one board seen at different times does not determine its extrinsic \
         (hold the board where `{camera}` and another camera both see it)"
    )]
    NotConnected {
        /// The camera that is not linked.
        camera: String,
        /// The reference camera.
        reference: String,
    },
    /// The joint refinement failed.
    #[error("the joint refinement of intrinsics and extrinsics failed: {0}")]
    Refinement(String),
    /// No image of a camera shows the target.
    #[error("camera `{camera}`: no AprilGrid found in any of its {images} images")]
    NoTargetFound {
        /// The camera (its folder's name).
        camera: String,
        /// Images searched.
        images: usize,
    },
    /// The images show more tags that the target file's grid does not have than tags it has.
    #[error(
        "camera `{camera}`: the images show {foreign_tags} tags that a {grid} grid does not have, \
         more than its own: the target file disagrees with the images (tagRows, tagCols?)"
    )]
    TargetMismatch {
        /// The camera (its folder's name).
        camera: String,
        /// Tags decoded that are not on the grid.
        foreign_tags: usize,
        /// The grid's tag rows x columns.
        grid: String,
    },
}
