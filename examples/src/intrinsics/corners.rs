//! Detected board corners, per image, and their file format (JSON, described in the module
//! docs of [`crate::intrinsics`]).

use std::collections::HashSet;
use std::path::Path;

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::error::IntrinsicsError;
use super::target::PlanarTarget;

/// The `format` value of a corner file.
pub const CORNER_FORMAT: &str = "ibc-corners";

/// The version of the corner file format this crate writes and reads.
pub const CORNER_FORMAT_VERSION: u32 = 1;

/// One detected corner: its board index and its pixel (pixel centres at integer coordinates,
/// as OpenCV's `findChessboardCorners` / `cornerSubPix` report them).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Corner {
    /// Board row (0-based).
    pub row: u32,
    /// Board column (0-based).
    pub col: u32,
    /// Horizontal pixel coordinate.
    pub u: f64,
    /// Vertical pixel coordinate.
    pub v: f64,
}

impl Corner {
    /// The pixel `(u, v)`.
    pub fn pixel(&self) -> Vector2<f64> {
        Vector2::new(self.u, self.v)
    }
}

/// The corners detected in one image. Corners the detector missed are simply absent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageCorners {
    /// The image's name (a file name, a timestamp): used in messages and reports.
    pub name: String,
    /// Its corners, in any order, each board index at most once.
    pub corners: Vec<Corner>,
}

/// The corners of every image of one camera, with the image size.
#[derive(Clone, Debug, PartialEq)]
pub struct CornerSet {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The board the corners belong to, when the file says (the simulator writes it).
    pub board: Option<PlanarTarget>,
    /// One entry per image.
    pub images: Vec<ImageCorners>,
}

/// The JSON form of a corner file.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CornerFile {
    format: String,
    version: u32,
    image_width: u32,
    image_height: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    board: Option<PlanarTarget>,
    images: Vec<ImageCorners>,
}

impl CornerSet {
    /// Parses a corner file's JSON text.
    ///
    /// # Errors
    /// [`IntrinsicsError::CornerJson`] for malformed JSON (with line and column) or a missing,
    /// unknown or mistyped field; [`IntrinsicsError::CornerFile`] for another `format` or
    /// `version`, or an invalid `board`.
    pub fn from_json_str(text: &str) -> Result<Self, IntrinsicsError> {
        let file: CornerFile = serde_json::from_str(text)
            .map_err(|source| IntrinsicsError::CornerJson { path: None, source })?;
        if file.format != CORNER_FORMAT {
            return Err(corner_file_error(format!(
                "`format` is `{}`, expected `{CORNER_FORMAT}`",
                file.format
            )));
        }
        if file.version != CORNER_FORMAT_VERSION {
            return Err(corner_file_error(format!(
                "`version` is {}, this build reads version {CORNER_FORMAT_VERSION}",
                file.version
            )));
        }
        if let Some(board) = &file.board {
            board
                .validate()
                .map_err(|e| corner_file_error(format!("`board`: {e}")))?;
        }
        Ok(Self {
            width: file.image_width,
            height: file.image_height,
            board: file.board,
            images: file.images,
        })
    }

    /// The corner file's JSON text (pretty-printed, one corner a line).
    pub fn to_json_string(&self) -> String {
        let mut s = String::new();
        s.push_str("{\n");
        s.push_str(&format!("  \"format\": \"{CORNER_FORMAT}\",\n"));
        s.push_str(&format!("  \"version\": {CORNER_FORMAT_VERSION},\n"));
        s.push_str(&format!("  \"image_width\": {},\n", self.width));
        s.push_str(&format!("  \"image_height\": {},\n", self.height));
        if let Some(b) = &self.board {
            let spacing = b
                .spacing
                .map(|g| format!(", \"spacing\": {}", json_number(g)))
                .unwrap_or_default();
            s.push_str(&format!(
                "  \"board\": {{\"rows\": {}, \"cols\": {}, \"square\": {}{spacing}}},\n",
                b.rows,
                b.cols,
                json_number(b.square)
            ));
        }
        s.push_str("  \"images\": [");
        for (i, image) in self.images.iter().enumerate() {
            s.push_str(if i == 0 { "\n" } else { ",\n" });
            s.push_str(&format!(
                "    {{\"name\": {}, \"corners\": [",
                serde_json::Value::String(image.name.clone())
            ));
            for (k, c) in image.corners.iter().enumerate() {
                s.push_str(if k == 0 { "\n" } else { ",\n" });
                s.push_str(&format!(
                    "      {{\"row\": {}, \"col\": {}, \"u\": {}, \"v\": {}}}",
                    c.row,
                    c.col,
                    json_number(c.u),
                    json_number(c.v)
                ));
            }
            s.push_str(if image.corners.is_empty() {
                "]}"
            } else {
                "\n    ]}"
            });
        }
        s.push_str(if self.images.is_empty() {
            "]\n}\n"
        } else {
            "\n  ]\n}\n"
        });
        s
    }

    /// Reads a corner file.
    ///
    /// # Errors
    /// [`IntrinsicsError::Io`] if it cannot be read, otherwise as
    /// [`from_json_str`](Self::from_json_str), naming the file.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, IntrinsicsError> {
        let path = path.as_ref();
        let text = ibc_camera_models::io::read_text(path, crate::data::io::MAX_TEXT_INPUT_BYTES)?;
        Self::from_json_str(&text).map_err(|e| match e {
            IntrinsicsError::CornerFile { message, .. } => IntrinsicsError::CornerFile {
                path: Some(path.to_owned()),
                message,
            },
            IntrinsicsError::CornerJson { source, .. } => IntrinsicsError::CornerJson {
                path: Some(path.to_owned()),
                source,
            },
            other => other,
        })
    }

    /// Writes the corner file atomically (temporary file in the same folder, then a rename).
    ///
    /// # Errors
    /// [`IntrinsicsError::Output`] if the folder is missing or not writable.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), IntrinsicsError> {
        ibc_camera_models::io::write_atomically(path.as_ref(), self.to_json_string().as_bytes())?;
        Ok(())
    }

    /// Total number of corners over all images.
    pub fn num_corners(&self) -> usize {
        self.images.iter().map(|i| i.corners.len()).sum()
    }

    /// Checks the corners against a target and the image: a non-empty image, every index on
    /// the board and listed once per image, every pixel finite and inside
    /// `[-0.5, width - 0.5] x [-0.5, height - 0.5]`, at least `min_corners` per image and
    /// `min_images` images.
    ///
    /// # Errors
    /// [`IntrinsicsError::InvalidInput`] for an empty image size,
    /// [`IntrinsicsError::CornerNotOnBoard`], [`IntrinsicsError::DuplicateCorner`],
    /// [`IntrinsicsError::CornerOutsideImage`], [`IntrinsicsError::TooFewCorners`],
    /// [`IntrinsicsError::TooFewImages`], in that order of checking.
    pub fn validate(
        &self,
        target: &PlanarTarget,
        min_corners: usize,
        min_images: usize,
    ) -> Result<(), IntrinsicsError> {
        if self.width == 0 || self.height == 0 {
            return Err(IntrinsicsError::InvalidInput(format!(
                "the image size {}x{} is empty",
                self.width, self.height
            )));
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        for image in &self.images {
            let mut seen = HashSet::with_capacity(image.corners.len());
            for c in &image.corners {
                if !target.contains(c.row, c.col) {
                    return Err(IntrinsicsError::CornerNotOnBoard {
                        image: image.name.clone(),
                        row: c.row,
                        col: c.col,
                        rows: target.rows,
                        cols: target.cols,
                    });
                }
                if !seen.insert((c.row, c.col)) {
                    return Err(IntrinsicsError::DuplicateCorner {
                        image: image.name.clone(),
                        row: c.row,
                        col: c.col,
                    });
                }
                let inside = c.u >= -0.5 && c.u <= w - 0.5 && c.v >= -0.5 && c.v <= h - 0.5;
                if !inside {
                    return Err(IntrinsicsError::CornerOutsideImage {
                        image: image.name.clone(),
                        row: c.row,
                        col: c.col,
                        u: c.u,
                        v: c.v,
                        width: self.width,
                        height: self.height,
                    });
                }
            }
            if image.corners.len() < min_corners {
                return Err(IntrinsicsError::TooFewCorners {
                    image: image.name.clone(),
                    got: image.corners.len(),
                    needed: min_corners,
                });
            }
        }
        if self.images.len() < min_images {
            return Err(IntrinsicsError::TooFewImages {
                got: self.images.len(),
                needed: min_images,
            });
        }
        Ok(())
    }
}

fn corner_file_error(message: String) -> IntrinsicsError {
    IntrinsicsError::CornerFile {
        path: None,
        message,
    }
}

/// A float as JSON: the shortest text that reads back to the same value (Rust's `Display`
/// round-trips), never `NaN` or `inf` (written as `null`, which the reader then refuses).
fn json_number(x: f64) -> String {
    if x.is_finite() {
        format!("{x:?}")
    } else {
        "null".to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corner(row: u32, col: u32, u: f64, v: f64) -> Corner {
        Corner { row, col, u, v }
    }

    fn sample() -> CornerSet {
        CornerSet {
            width: 640,
            height: 480,
            board: Some(PlanarTarget::new(2, 3, 0.05).unwrap()),
            images: vec![
                ImageCorners {
                    name: "a \"quoted\" name.png".into(),
                    corners: vec![corner(0, 0, 10.25, 20.0), corner(1, 2, 0.1 + 0.2, 479.5)],
                },
                ImageCorners {
                    name: "empty".into(),
                    corners: vec![],
                },
            ],
        }
    }

    #[test]
    fn json_round_trip_is_exact() {
        let set = sample();
        let back = CornerSet::from_json_str(&set.to_json_string()).unwrap();
        assert_eq!(back, set);
    }

    #[test]
    fn refuses_unknown_fields_and_versions() {
        let text = sample().to_json_string();
        let err = CornerSet::from_json_str(&text.replace("\"version\": 1", "\"version\": 2"))
            .unwrap_err();
        assert!(err.to_string().contains("version"), "{err}");
        let err = CornerSet::from_json_str(&text.replace("\"u\":", "\"x\":")).unwrap_err();
        assert!(err.to_string().contains("unknown field"), "{err}");
        let err = CornerSet::from_json_str(&text.replace("ibc-corners", "opencv")).unwrap_err();
        assert!(err.to_string().contains("format"), "{err}");
    }

    #[test]
    fn validation_names_the_corner() {
        let target = PlanarTarget::new(2, 3, 0.05).unwrap();
        let mut set = sample();
        set.images[1].corners.push(corner(0, 1, 1.0, 1.0));
        assert!(set.validate(&target, 1, 2).is_ok());
        assert!(matches!(
            set.validate(&target, 2, 2),
            Err(IntrinsicsError::TooFewCorners {
                got: 1,
                needed: 2,
                ..
            })
        ));
        assert!(matches!(
            set.validate(&target, 1, 3),
            Err(IntrinsicsError::TooFewImages { got: 2, needed: 3 })
        ));
        set.images[1].corners[0].u = 640.0;
        assert!(matches!(
            set.validate(&target, 1, 2),
            Err(IntrinsicsError::CornerOutsideImage { row: 0, col: 1, .. })
        ));
        set.images[1].corners[0] = corner(2, 0, 1.0, 1.0);
        assert!(matches!(
            set.validate(&target, 1, 2),
            Err(IntrinsicsError::CornerNotOnBoard { row: 2, .. })
        ));
        set.images[1].corners[0] = corner(0, 0, 1.0, 1.0);
        set.images[1].corners.push(corner(0, 0, 2.0, 1.0));
        assert!(matches!(
            set.validate(&target, 1, 2),
            Err(IntrinsicsError::DuplicateCorner { row: 0, col: 0, .. })
        ));
    }
}
