//! The planar calibration target: a chessboard (or any grid of corners) of `rows x cols` inner
//! corners spaced `square` metres apart.

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
    /// Distance between neighbouring corners, metres (finite, positive).
    pub square: f64,
}

impl PlanarTarget {
    /// A target of `rows x cols` corners, `square` metres apart.
    ///
    /// # Errors
    /// [`IntrinsicsError::InvalidTarget`] for fewer than 2 rows or columns, or a square size
    /// that is not finite and positive.
    pub fn new(rows: u32, cols: u32, square: f64) -> Result<Self, IntrinsicsError> {
        let target = Self { rows, cols, square };
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

    /// The board-frame position of corner `(row, col)`: `(col * square, row * square, 0)`.
    /// Indices beyond the board give points beyond it (check with [`contains`](Self::contains)).
    pub fn point(&self, row: u32, col: u32) -> Point3<f64> {
        Point3::new(
            f64::from(col) * self.square,
            f64::from(row) * self.square,
            0.0,
        )
    }

    /// The centre of the board in the board frame.
    pub fn center(&self) -> Point3<f64> {
        Point3::new(
            0.5 * f64::from(self.cols - 1) * self.square,
            0.5 * f64::from(self.rows - 1) * self.square,
            0.0,
        )
    }

    /// The board's diagonal from the first to the last corner, metres.
    pub fn diagonal(&self) -> f64 {
        let w = f64::from(self.cols - 1) * self.square;
        let h = f64::from(self.rows - 1) * self.square;
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
    fn refuses_bad_boards() {
        for (text, square) in [("6", 0.04), ("6x", 0.04), ("ax9", 0.04), ("1x9", 0.04)] {
            assert!(matches!(
                PlanarTarget::parse(text, square),
                Err(IntrinsicsError::InvalidTarget(_))
            ));
        }
        assert!(PlanarTarget::new(6, 9, 0.0).is_err());
        assert!(PlanarTarget::new(6, 9, f64::NAN).is_err());
    }
}
