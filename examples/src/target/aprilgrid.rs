//! Kalibr's AprilGrid target: its definition file, the board-frame position of every corner,
//! and the printed pattern (for rendering).
//!
//! References: E. Olson, "AprilTag: a robust and flexible visual fiducial system", ICRA 2011,
//! and J. Wang, E. Olson, "AprilTag 2", IROS 2016 (the tag36h11 family and its bit order: row
//! by row from the tag's top left, most significant bit first); Kalibr's
//! `GridCalibrationTargetAprilgrid` (the grid's layout, corner order and target file). The
//! codes themselves come from the `aprilgrid` crate's table.
//!
//! # Layout (Kalibr's `GridCalibrationTargetAprilgrid`)
//! `tag_rows x tag_cols` AprilTags of the 36h11 family with a 2-bit black border (a tag is
//! 10 x 10 cells: 6 x 6 data bits inside the border), each `tag_size` metres wide, separated
//! by `tag_spacing * tag_size` metres. Tag `k` sits in tag row `k / tag_cols` and tag column
//! `k % tag_cols`; its lower-left corner (in the board frame) is at
//! `(col * (s + g), row * (s + g), 0)` with `s = tag_size`, `g = tag_spacing * tag_size`.
//! A small black square of side `g` fills every gap crossing (and the gaps at the border), so
//! that each tag corner is a saddle point between two black squares, which is what the
//! detector finds and refines.
//!
//! Corners: tag `k`'s four corners, in the detector's order `j = 0..4` (lower-left,
//! lower-right, upper-right, upper-left), are the [`PlanarTarget`] corners
//! `(2 * row + [0, 0, 1, 1][j], 2 * col + [0, 1, 1, 0][j])`: the AprilGrid is a grid of
//! `2 tag_rows x 2 tag_cols` corners whose steps alternate between `s` and `g`
//! ([`PlanarTarget::spacing`]). Kalibr numbers the same corners `4 k + j`.
//!
//! # Definition file (Kalibr's target YAML)
//! ```yaml
//! target_type: 'aprilgrid'
//! tagCols: 6
//! tagRows: 6
//! tagSize: 0.088     # metres
//! tagSpacing: 0.3    # a fraction of tagSize
//! ```
//! Other target types (`checkerboard`, `circlegrid`) are refused with a message: no
//! maintained Rust detector for them was found, and `ibc intrinsics --corners` takes their
//! corners from any other detector.

use std::path::Path;

use yaml_rust2::{Yaml, YamlLoader};

use super::error::TargetError;
use crate::intrinsics::PlanarTarget;

/// Bits per side of a tag's data (36h11: 6 x 6).
pub const DATA_BITS: u32 = 6;
/// Black border width in bits (Kalibr's targets have 2).
pub const BORDER_BITS: u32 = 2;
/// Cells per side of a tag: data and border on both sides.
pub const TAG_CELLS: u32 = DATA_BITS + 2 * BORDER_BITS;
/// The largest target definition read, in bytes (a real one is about 100 bytes).
pub const MAX_TARGET_FILE_BYTES: u64 = 64 * 1024;
/// Kalibr's AprilGrids use tag36h11, which has this many tags.
pub const TAG_FAMILY_SIZE: u32 = 587;

/// A Kalibr AprilGrid (see the module docs for the layout).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AprilGrid {
    /// Rows of tags.
    pub tag_rows: u32,
    /// Columns of tags.
    pub tag_cols: u32,
    /// Side of a tag's black square, metres.
    pub tag_size: f64,
    /// Gap between tags as a fraction of `tag_size` (Kalibr's `tagSpacing`; its printed
    /// targets use 0.3).
    pub tag_spacing: f64,
}

impl AprilGrid {
    /// A grid of `tag_rows x tag_cols` tags of side `tag_size` metres, `tag_spacing` of a tag
    /// apart.
    ///
    /// # Errors
    /// [`TargetError::InvalidTarget`] for no tags, more tags than tag36h11 has, or sizes that
    /// are not finite and positive.
    pub fn new(
        tag_rows: u32,
        tag_cols: u32,
        tag_size: f64,
        tag_spacing: f64,
    ) -> Result<Self, TargetError> {
        let grid = Self {
            tag_rows,
            tag_cols,
            tag_size,
            tag_spacing,
        };
        grid.validate()?;
        Ok(grid)
    }

    fn validate(&self) -> Result<(), TargetError> {
        let bad = |m: String| Err(TargetError::InvalidTarget(m));
        if self.tag_rows == 0 || self.tag_cols == 0 {
            return bad(format!(
                "an AprilGrid needs at least one tag row and column, got {} x {}",
                self.tag_rows, self.tag_cols
            ));
        }
        if u64::from(self.tag_rows) * u64::from(self.tag_cols) > u64::from(TAG_FAMILY_SIZE) {
            return bad(format!(
                "{} x {} tags, but tag36h11 has only {TAG_FAMILY_SIZE}",
                self.tag_rows, self.tag_cols
            ));
        }
        if !(self.tag_size.is_finite() && self.tag_size > 0.0) {
            return bad(format!(
                "tagSize must be finite and positive (metres), got {}",
                self.tag_size
            ));
        }
        if !(self.tag_spacing.is_finite() && self.tag_spacing > 0.0 && self.tag_spacing <= 2.0) {
            return bad(format!(
                "tagSpacing is a fraction of tagSize in (0, 2], got {}",
                self.tag_spacing
            ));
        }
        Ok(())
    }

    /// Parses a Kalibr target definition (see the module docs).
    ///
    /// # Errors
    /// [`TargetError::InvalidTarget`] naming the key that is missing or malformed, a target
    /// type other than `aprilgrid`, or YAML that is not a mapping.
    pub fn from_kalibr_str(text: &str) -> Result<Self, TargetError> {
        let bad = |m: String| TargetError::InvalidTarget(m);
        ibc_camera_models::check_yaml_input(text).map_err(|e| bad(e.to_string()))?;
        let docs = YamlLoader::load_from_str(text).map_err(|e| bad(format!("YAML: {e}")))?;
        let doc = docs
            .into_iter()
            .next()
            .ok_or_else(|| bad("the file is empty".into()))?;
        if doc.as_hash().is_none() {
            return Err(bad(
                "a target definition is a mapping (target_type, tagCols, ...)".into(),
            ));
        }
        match doc["target_type"].as_str() {
            Some("aprilgrid") => {}
            Some(other) => {
                return Err(bad(format!(
                    "target_type `{other}`: only `aprilgrid` targets are detected in images \
                     (for a chessboard, detect its corners with another tool and run \
                     `ibc intrinsics --corners`)"
                )));
            }
            None => return Err(bad("`target_type` is missing (expected 'aprilgrid')".into())),
        }
        let count = |key: &str| -> Result<u32, TargetError> {
            match &doc[key] {
                Yaml::Integer(n) => u32::try_from(*n)
                    .map_err(|_| bad(format!("`{key}` must be a positive integer, got {n}"))),
                Yaml::BadValue => Err(bad(format!("`{key}` is missing"))),
                other => Err(bad(format!("`{key}` must be an integer, got {other:?}"))),
            }
        };
        let real = |key: &str| -> Result<f64, TargetError> {
            match &doc[key] {
                Yaml::Integer(n) => Ok(*n as f64),
                Yaml::Real(_) => doc[key]
                    .as_f64()
                    .ok_or_else(|| bad(format!("`{key}` is not a number"))),
                Yaml::BadValue => Err(bad(format!("`{key}` is missing"))),
                other => Err(bad(format!("`{key}` must be a number, got {other:?}"))),
            }
        };
        Self::new(
            count("tagRows")?,
            count("tagCols")?,
            real("tagSize")?,
            real("tagSpacing")?,
        )
    }

    /// Reads a Kalibr target definition: a regular file of at most
    /// [`MAX_TARGET_FILE_BYTES`].
    ///
    /// # Errors
    /// [`TargetError::TargetFile`] naming the file, with the reason.
    pub fn read_kalibr(path: impl AsRef<Path>) -> Result<Self, TargetError> {
        let path = path.as_ref();
        let in_file = |reason: String| TargetError::TargetFile {
            path: path.to_owned(),
            reason,
        };
        let text = ibc_camera_models::io::read_text(path, MAX_TARGET_FILE_BYTES)
            .map_err(|e| in_file(e.to_string()))?;
        Self::from_kalibr_str(&text).map_err(|e| in_file(e.to_string()))
    }

    /// Kalibr's target YAML for this grid.
    pub fn to_kalibr_string(&self) -> String {
        format!(
            "target_type: 'aprilgrid'\ntagCols: {}\ntagRows: {}\ntagSize: {:?}\ntagSpacing: {:?}\n",
            self.tag_cols, self.tag_rows, self.tag_size, self.tag_spacing
        )
    }

    /// Number of tags.
    pub fn num_tags(&self) -> u32 {
        self.tag_rows * self.tag_cols
    }

    /// The gap between tags, metres.
    pub fn gap(&self) -> f64 {
        self.tag_spacing * self.tag_size
    }

    /// The grid's corners as a [`PlanarTarget`] of `2 tag_rows x 2 tag_cols` corners.
    pub fn planar_target(&self) -> PlanarTarget {
        PlanarTarget {
            rows: 2 * self.tag_rows,
            cols: 2 * self.tag_cols,
            square: self.tag_size,
            spacing: Some(self.gap()),
        }
    }

    /// The [`PlanarTarget`] corner `(row, col)` of corner `j` (0..4, the detector's order) of
    /// tag `id`; `None` for a tag that is not on this grid or `j >= 4`.
    pub fn corner_index(&self, id: u32, j: usize) -> Option<(u32, u32)> {
        if id >= self.num_tags() || j >= 4 {
            return None;
        }
        let (row, col) = (id / self.tag_cols, id % self.tag_cols);
        Some((2 * row + [0, 0, 1, 1][j], 2 * col + [0, 1, 1, 0][j]))
    }

    /// Whether the printed target is black at board point `(x, y)` (metres, board frame);
    /// `None` outside the printed area (the grid and a white margin of one tag around it).
    pub fn is_black(&self, x: f64, y: f64) -> Option<bool> {
        let (s, g) = (self.tag_size, self.gap());
        let pitch = s + g;
        let width = f64::from(self.tag_cols) * pitch - g;
        let height = f64::from(self.tag_rows) * pitch - g;
        if x < -s || y < -s || x > width + s || y > height + s {
            return None;
        }
        // Position within the pitch: [0, s) a tag column, [s, pitch) a gap.
        let (cx, cy) = ((x + g) / pitch, (y + g) / pitch);
        let (ix, iy) = (cx.floor(), cy.floor());
        // In gap coordinates: the gap before tag column `ix` spans [ix * pitch - g, ix * pitch).
        let in_gap_x = x - (ix * pitch - g) < g;
        let in_gap_y = y - (iy * pitch - g) < g;
        let (col, row) = (ix as i64, iy as i64);
        let inside_x = (0..=i64::from(self.tag_cols)).contains(&col);
        let inside_y = (0..=i64::from(self.tag_rows)).contains(&row);
        if !(inside_x && inside_y) {
            return Some(false);
        }
        match (in_gap_x, in_gap_y) {
            // A gap crossing: the small black square.
            (true, true) => Some(true),
            (true, false) | (false, true) => Some(false),
            (false, false) => {
                if col >= i64::from(self.tag_cols) || row >= i64::from(self.tag_rows) {
                    return Some(false);
                }
                let id = row as u32 * self.tag_cols + col as u32;
                let u = (x - (ix * pitch)) / s * f64::from(TAG_CELLS);
                let v = (y - (iy * pitch)) / s * f64::from(TAG_CELLS);
                Some(tag_cell_is_black(id, u as u32, v as u32))
            }
        }
    }
}

/// Whether cell `(u, v)` of tag `id` is black: `u` counts cells along the board's x axis and
/// `v` along its y axis from the tag's lower-left corner, both in `0..TAG_CELLS`.
fn tag_cell_is_black(id: u32, u: u32, v: u32) -> bool {
    let data = BORDER_BITS..BORDER_BITS + DATA_BITS;
    if !(data.contains(&u) && data.contains(&v)) {
        return true;
    }
    let code = aprilgrid::tag_families::T36H11[id as usize];
    let (i, j) = (u - BORDER_BITS, v - BORDER_BITS);
    let (r, c) = cell_to_bit(i, j);
    let bit = (DATA_BITS * DATA_BITS - 1) - (r * DATA_BITS + c);
    (code >> bit) & 1 == 0
}

/// The (row, column) of a data bit in the tag's code (row-major, most significant bit first)
/// for data cell `(i, j)` counted along the board's x and y axes.
fn cell_to_bit(i: u32, j: u32) -> (u32, u32) {
    // Row 0 is the tag's top (largest y: the board's y axis points up on the print, as in
    // Kalibr), column 0 its left: the AprilTag convention, which the detector reads.
    (DATA_BITS - 1 - j, i)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_kalibrs_definition() {
        let text =
            "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 5\ntagSize: 0.088\ntagSpacing: 0.3\n";
        let g = AprilGrid::from_kalibr_str(text).unwrap();
        assert_eq!((g.tag_rows, g.tag_cols), (5, 6));
        assert!((g.gap() - 0.0264).abs() < 1e-15);
        assert_eq!(
            AprilGrid::from_kalibr_str(&g.to_kalibr_string()).unwrap(),
            g
        );
        let t = g.planar_target();
        assert_eq!((t.rows, t.cols), (10, 12));
        assert_eq!(g.corner_index(7, 2), Some((3, 3)));
        assert_eq!(g.corner_index(8, 1), Some((2, 5)));
        assert_eq!(g.corner_index(30, 0), None);
    }

    #[test]
    fn refuses_other_targets_and_bad_keys() {
        for (text, needle) in [
            (
                "target_type: 'checkerboard'\ntargetCols: 6\n",
                "checkerboard",
            ),
            ("tagCols: 6\n", "target_type"),
            (
                "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.1\n",
                "tagSpacing",
            ),
            (
                "target_type: 'aprilgrid'\ntagCols: -1\ntagRows: 6\ntagSize: 0.1\ntagSpacing: 0.3\n",
                "tagCols",
            ),
            (
                "target_type: 'aprilgrid'\ntagCols: 30\ntagRows: 30\ntagSize: 0.1\ntagSpacing: 0.3\n",
                "587",
            ),
            ("- a\n- b\n", "mapping"),
        ] {
            let e = AprilGrid::from_kalibr_str(text).unwrap_err().to_string();
            assert!(e.contains(needle), "{text}: {e}");
        }
    }

    #[test]
    fn the_pattern_has_black_borders_and_gap_squares() {
        let g = AprilGrid::new(2, 3, 0.1, 0.3).unwrap();
        // A tag's border cell, a gap crossing, a gap between two tags, the white margin.
        assert_eq!(g.is_black(0.005, 0.005), Some(true));
        assert_eq!(g.is_black(0.115, 0.115), Some(true));
        assert_eq!(g.is_black(0.115, 0.05), Some(false));
        assert_eq!(g.is_black(-0.05, 0.05), Some(false));
        assert_eq!(g.is_black(-0.2, 0.05), None);
    }
}
