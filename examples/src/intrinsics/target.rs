//! The planar calibration target: a chessboard (or any grid of corners) of `rows x cols` inner
//! corners spaced `square` metres apart, or the corners of a Kalibr AprilGrid (pairs of corners
//! a tag's size apart, the pairs a spacing apart; see [`PlanarTarget::spacing`]).

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use super::error::IntrinsicsError;

/// A planar grid of `rows x cols` corners (a chessboard's inner corners), `square` metres apart.
///
/// **Board frame** (as OpenCV's `calibrateCamera` object points): corner `(row, col)` is at
/// `(col * square, row * square, 0)`. x runs along a row (increasing column), y down the
/// columns (increasing row), and z = x × y points into the board, away from a viewer who sees
/// the rows going down. Indices start at 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanarTarget {
    /// Rows of corners (at least 2).
    pub rows: u32,
    /// Corners per row (at least 2).
    pub cols: u32,
    /// Distance between neighbouring corners, metres (finite, positive). For an AprilGrid, the
    /// tag size (the side of a tag's black square).
    pub square: f64,
    /// For an AprilGrid: the gap between neighbouring tags, metres (finite, positive); the
    /// corners then come in pairs, the two sides of one tag `square` apart, and neighbouring
    /// pairs `spacing` apart (Kalibr's `tagSize * tagSpacing`). `None` (a chessboard): every
    /// step is `square`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing: Option<f64>,
}

impl PlanarTarget {
    /// A target of `rows x cols` corners, `square` metres apart.
    ///
    /// # Errors
    /// [`IntrinsicsError::InvalidTarget`] for fewer than 2 rows or columns, or a square size
    /// that is not finite and positive.
    pub fn new(rows: u32, cols: u32, square: f64) -> Result<Self, IntrinsicsError> {
        let target = Self {
            rows,
            cols,
            square,
            spacing: None,
        };
        target.validate()?;
        Ok(target)
    }

    /// A Kalibr AprilGrid's corners, `2 * tag_rows x 2 * tag_cols` of them: tags of side
    /// `tag_size` metres, `spacing` metres apart.
    ///
    /// # Errors
    /// [`IntrinsicsError::InvalidTarget`] for fewer than one tag row or column, or sizes that
    /// are not finite and positive.
    pub fn april_grid(
        tag_rows: u32,
        tag_cols: u32,
        tag_size: f64,
        spacing: f64,
    ) -> Result<Self, IntrinsicsError> {
        let target = Self {
            rows: tag_rows.saturating_mul(2),
            cols: tag_cols.saturating_mul(2),
            square: tag_size,
            spacing: Some(spacing),
        };
        target.validate()?;
        Ok(target)
    }

    /// Checks the target (useful after deserializing one).
    ///
    /// # Errors
    /// As [`new`](Self::new).
    pub fn validate(&self) -> Result<(), IntrinsicsError> {
        if self.rows < 2 || self.cols < 2 {
            return Err(IntrinsicsError::InvalidTarget(format!(
                "a board needs at least 2 x 2 corners, got {} x {}",
                self.rows, self.cols
            )));
        }
        if !(self.square.is_finite() && self.square > 0.0) {
            return Err(IntrinsicsError::InvalidTarget(format!(
                "the square size must be finite and positive (metres), got {}",
                self.square
            )));
        }
        if let Some(spacing) = self.spacing {
            if !(spacing.is_finite() && spacing > 0.0) {
                return Err(IntrinsicsError::InvalidTarget(format!(
                    "the tag spacing must be finite and positive (metres), got {spacing}"
                )));
            }
            if self.rows % 2 == 1 || self.cols % 2 == 1 {
                return Err(IntrinsicsError::InvalidTarget(format!(
                    "an AprilGrid has an even number of corner rows and columns (two per tag), \
                     got {} x {}",
                    self.rows, self.cols
                )));
            }
        }
        Ok(())
    }

    /// Parses `ROWSxCOLS` (for instance `6x9`) with the square size in metres.
    ///
    /// # Errors
    /// [`IntrinsicsError::InvalidTarget`] for text that is not two positive integers joined by
    /// `x`, or an invalid target.
    pub fn parse(board: &str, square: f64) -> Result<Self, IntrinsicsError> {
        let bad = || {
            IntrinsicsError::InvalidTarget(format!(
                "board `{board}` is not ROWSxCOLS (for instance 6x9: rows and columns of inner corners)"
            ))
        };
        let (r, c) = board.trim().split_once(['x', 'X']).ok_or_else(bad)?;
        let rows = r.trim().parse::<u32>().map_err(|_| bad())?;
        let cols = c.trim().parse::<u32>().map_err(|_| bad())?;
        Self::new(rows, cols, square)
    }

    /// Number of corners, `rows * cols`.
    pub fn num_corners(&self) -> usize {
        self.rows as usize * self.cols as usize
    }

    /// Whether `(row, col)` is a corner of the board.
    pub fn contains(&self, row: u32, col: u32) -> bool {
        row < self.rows && col < self.cols
    }

    /// The distance of the `index`-th corner line from the first, metres: `index * square`
    /// on a chessboard; on an AprilGrid `ceil(index / 2) * square + floor(index / 2) * spacing`.
    pub fn coordinate(&self, index: u32) -> f64 {
        match self.spacing {
            None => f64::from(index) * self.square,
            Some(spacing) => {
                f64::from(index.div_ceil(2)) * self.square + f64::from(index / 2) * spacing
            }
        }
    }

    /// The board-frame position of corner `(row, col)`: `(x(col), y(row), 0)` with
    /// [`coordinate`](Self::coordinate), `(col * square, row * square, 0)` on a chessboard.
    /// Indices beyond the board give points beyond it (check with [`contains`](Self::contains)).
    pub fn point(&self, row: u32, col: u32) -> Point3<f64> {
        Point3::new(self.coordinate(col), self.coordinate(row), 0.0)
    }

    /// The centre of the board in the board frame.
    pub fn center(&self) -> Point3<f64> {
        Point3::new(
            0.5 * self.coordinate(self.cols - 1),
            0.5 * self.coordinate(self.rows - 1),
            0.0,
        )
    }

    /// The board's diagonal from the first to the last corner, metres.
    pub fn diagonal(&self) -> f64 {
        let w = self.coordinate(self.cols - 1);
        let h = self.coordinate(self.rows - 1);
        w.hypot(h)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_rows_by_cols() {
        let t = PlanarTarget::parse("6x9", 0.04).unwrap();
        assert_eq!((t.rows, t.cols, t.num_corners()), (6, 9, 54));
        assert_eq!(t.point(1, 2), Point3::new(0.08, 0.04, 0.0));
        assert!(t.contains(5, 8) && !t.contains(6, 0) && !t.contains(0, 9));
        assert!((t.diagonal() - (0.32f64).hypot(0.2)).abs() < 1e-15);
    }

    #[test]
    fn april_grid_corners_pair_up() {
        // Kalibr's default grid: 6 x 6 tags of 88 mm, 0.3 of a tag apart.
        let t = PlanarTarget::april_grid(6, 6, 0.088, 0.0264).unwrap();
        assert_eq!((t.rows, t.cols), (12, 12));
        let xs: Vec<f64> = (0..4).map(|c| t.point(0, c).x).collect();
        let expected = [0.0, 0.088, 0.1144, 0.2024];
        for (x, e) in xs.iter().zip(expected) {
            assert!((x - e).abs() < 1e-12, "{xs:?}");
        }
        assert!((t.point(11, 11).y - (6.0 * 0.088 + 5.0 * 0.0264)).abs() < 1e-12);
    }

    #[test]
    fn refuses_bad_boards() {
        for (text, square) in [("6", 0.04), ("6x", 0.04), ("ax9", 0.04), ("1x9", 0.04)] {
            assert!(matches!(
                PlanarTarget::parse(text, square),
                Err(IntrinsicsError::InvalidTarget(_))
            ));
        }
        assert!(PlanarTarget::new(6, 9, 0.0).is_err());
        assert!(PlanarTarget::april_grid(6, 6, 0.088, 0.0).is_err());
        assert!(PlanarTarget::new(6, 9, f64::NAN).is_err());
    }
}
