//! Image folders and the detection over them: one folder per camera (Kalibr's layout when its
//! bag is extracted: `DIR/cam0/1403715273262142976.png`, ...), images of different cameras
//! with the same file stem taken at the same time.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::aprilgrid::AprilGrid;
use super::detect::{detect_april_grid, read_gray_image};
use super::error::TargetError;
use crate::intrinsics::{CornerSet, ImageCorners};

/// File extensions read as images (case-insensitive).
pub const IMAGE_EXTENSIONS: [&str; 8] = ["png", "jpg", "jpeg", "pgm", "ppm", "bmp", "tif", "tiff"];
/// The most images read from one folder.
pub const MAX_IMAGES_PER_CAMERA: usize = 100_000;
/// The most camera folders.
pub const MAX_CAMERAS: usize = 64;

/// One camera's image files, by time (file stem), sorted.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraFolder {
    /// The camera's name (the folder's name).
    pub name: String,
    /// `(time, path)` of every image, sorted by time.
    pub images: Vec<(String, PathBuf)>,
}

/// The image files of `dir`, regular files with an [`IMAGE_EXTENSIONS`] extension, sorted.
fn image_files(dir: &Path) -> Result<Vec<(String, PathBuf)>, TargetError> {
    let bad = |reason: String| TargetError::Image {
        path: dir.to_owned(),
        reason,
    };
    let mut images = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| bad(e.to_string()))?;
    for entry in entries {
        let entry = entry.map_err(|e| bad(e.to_string()))?;
        let path = entry.path();
        let is_image = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| IMAGE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()));
        // Only regular files: symlinks, FIFOs and devices are skipped (not followed).
        let regular = entry.file_type().map(|t| t.is_file()).unwrap_or(false);
        if !(is_image && regular) {
            continue;
        }
        let Some(stem) = path.file_stem().and_then(|s| s.to_str()) else {
            return Err(TargetError::Image {
                path: path.clone(),
                reason: "the file name is not UTF-8".into(),
            });
        };
        images.push((stem.to_owned(), path.clone()));
        if images.len() > MAX_IMAGES_PER_CAMERA {
            return Err(bad(format!(
                "more than {MAX_IMAGES_PER_CAMERA} images in one folder"
            )));
        }
    }
    images.sort();
    if let Some(w) = images.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(TargetError::Image {
            path: w[1].1.clone(),
            reason: format!(
                "two images of time `{}` in one folder ({})",
                w[0].0,
                w[0].1.display()
            ),
        });
    }
    Ok(images)
}

/// The camera folders of `dir`: its subfolders that hold images, sorted by name; or, when
/// `dir` itself holds images and no such subfolder, `dir` alone as camera `cam0`.
///
/// # Errors
/// [`TargetError::Image`] naming the folder: unreadable, without images, more than
/// [`MAX_CAMERAS`] cameras, or two images of one time in a folder.
pub fn list_camera_folders(dir: impl AsRef<Path>) -> Result<Vec<CameraFolder>, TargetError> {
    let dir = dir.as_ref();
    let bad = |reason: String| TargetError::Image {
        path: dir.to_owned(),
        reason,
    };
    let mut folders = Vec::new();
    let entries = std::fs::read_dir(dir).map_err(|e| bad(e.to_string()))?;
    for entry in entries {
        let entry = entry.map_err(|e| bad(e.to_string()))?;
        if !entry.file_type().map(|t| t.is_dir()).unwrap_or(false) {
            continue;
        }
        let path = entry.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        if name.starts_with('.') {
            continue;
        }
        let images = image_files(&path)?;
        if !images.is_empty() {
            folders.push(CameraFolder {
                name: name.to_owned(),
                images,
            });
        }
        if folders.len() > MAX_CAMERAS {
            return Err(bad(format!("more than {MAX_CAMERAS} camera folders")));
        }
    }
    if folders.is_empty() {
        let images = image_files(dir)?;
        if images.is_empty() {
            return Err(bad(format!(
                "no images ({}) in the folder or in its subfolders",
                IMAGE_EXTENSIONS.join(", ")
            )));
        }
        folders.push(CameraFolder {
            name: "cam0".into(),
            images,
        });
    }
    folders.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(folders)
}

/// What the detection found in one camera's images.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraDetections {
    /// The camera's name.
    pub name: String,
    /// Its corners (every image, those without a board with no corners).
    pub corners: CornerSet,
    /// Tags decoded that are not on the grid, summed over the images.
    pub foreign_tags: usize,
}

/// Detects `grid` in every image of `folder` (images in parallel); `progress` is called once
/// per image done.
///
/// # Errors
/// [`TargetError::Image`] for an unreadable image or images of different sizes;
/// [`TargetError::DetectorFailed`]; [`TargetError::NoTargetFound`] when no image shows the
/// grid, [`TargetError::TargetMismatch`] when the images show more tags that the grid does not
/// have than tags it has.
pub fn detect_camera_folder(
    folder: &CameraFolder,
    grid: &AprilGrid,
    progress: &(dyn Fn() + Sync),
) -> Result<CameraDetections, TargetError> {
    let found: Vec<(u32, u32, ImageCorners, usize)> = folder
        .images
        .par_iter()
        .map(|(time, path)| {
            let image = read_gray_image(path)?;
            let name = path.display().to_string();
            let detection = detect_april_grid(&image, grid, &name)?;
            progress();
            Ok((
                image.width(),
                image.height(),
                ImageCorners {
                    name: time.clone(),
                    corners: detection.corners,
                },
                detection.foreign_tags,
            ))
        })
        .collect::<Result<_, TargetError>>()?;
    let (width, height) = found.first().map_or((0, 0), |f| (f.0, f.1));
    if let Some(k) = found.iter().position(|f| (f.0, f.1) != (width, height)) {
        return Err(TargetError::Image {
            path: folder.images[k].1.clone(),
            reason: format!(
                "{} x {} pixels, but the camera's first image is {width} x {height}",
                found[k].0, found[k].1
            ),
        });
    }
    let foreign_tags = found.iter().map(|f| f.3).sum();
    let corners = found.iter().map(|f| f.2.corners.len()).sum::<usize>();
    // Four corners a tag: more foreign tags than the grid's own means the wrong grid.
    if corners == 0 || foreign_tags > corners / 4 {
        return Err(if foreign_tags > 0 {
            TargetError::TargetMismatch {
                camera: folder.name.clone(),
                foreign_tags,
                grid: format!("{} x {}", grid.tag_rows, grid.tag_cols),
            }
        } else {
            TargetError::NoTargetFound {
                camera: folder.name.clone(),
                images: folder.images.len(),
            }
        });
    }
    Ok(CameraDetections {
        name: folder.name.clone(),
        corners: CornerSet {
            width,
            height,
            board: Some(grid.planar_target()),
            images: found.into_iter().map(|f| f.2).collect(),
        },
        foreign_tags,
    })
}
