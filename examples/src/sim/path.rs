//! Planar paths: polylines whose corners are rounded by circular arcs (fillets), sampled by
//! arc length. The simulator drives every trajectory along one.
//!
//! A corner between the directions `d_in` and `d_out`, turning by the signed angle `phi`, is
//! replaced by an arc of radius `R` tangent to both legs: it starts `R tan(|phi| / 2)` before
//! the corner and ends as far after it, so the heading is continuous and the curvature is
//! `0` or `±1/R`.

use nalgebra::Vector2;

/// One piece of a [`Path2`].
#[derive(Clone, Debug, PartialEq)]
enum Segment {
    /// From `start` along the unit direction `dir` for `len` metres.
    Line {
        start: Vector2<f64>,
        dir: Vector2<f64>,
        len: f64,
    },
    /// Around `center` with `radius`, from the angle `start_angle` through the signed
    /// `sweep` (positive turns left).
    Arc {
        center: Vector2<f64>,
        radius: f64,
        start_angle: f64,
        sweep: f64,
    },
}

impl Segment {
    fn len(&self) -> f64 {
        match self {
            Self::Line { len, .. } => *len,
            Self::Arc { radius, sweep, .. } => radius * sweep.abs(),
        }
    }

    /// Position and heading (radians, of the direction of travel) at `s` metres in.
    fn at(&self, s: f64) -> (Vector2<f64>, f64) {
        match self {
            Self::Line { start, dir, .. } => (start + dir * s, dir.y.atan2(dir.x)),
            Self::Arc {
                center,
                radius,
                start_angle,
                sweep,
            } => {
                let a = start_angle + sweep.signum() * s / radius;
                let p = center + Vector2::new(a.cos(), a.sin()) * *radius;
                (p, a + sweep.signum() * std::f64::consts::FRAC_PI_2)
            }
        }
    }
}

/// A planar path: lines joined by tangent arcs, open or closed.
#[derive(Clone, Debug, PartialEq)]
pub struct Path2 {
    segments: Vec<Segment>,
    /// Arc length at the start of each segment.
    starts: Vec<f64>,
    length: f64,
    closed: bool,
}

impl Path2 {
    /// The path through `waypoints` with every corner rounded by an arc of `radius` metres.
    /// A closed path also joins the last waypoint to the first and rounds those corners.
    ///
    /// # Errors
    /// A message when there are fewer than two waypoints (three for a closed path), two
    /// consecutive waypoints coincide, or a leg is too short for the arcs at its ends.
    pub fn rounded(waypoints: &[Vector2<f64>], radius: f64, closed: bool) -> Result<Self, String> {
        let n = waypoints.len();
        if n < 2 || (closed && n < 3) {
            return Err(format!("a path needs more waypoints than {n}"));
        }
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(format!(
                "corner radius {radius} must be finite and non-negative"
            ));
        }
        let legs = if closed { n } else { n - 1 };
        let mut dirs = Vec::with_capacity(legs);
        let mut lens = Vec::with_capacity(legs);
        for i in 0..legs {
            let d = waypoints[(i + 1) % n] - waypoints[i];
            let len = d.norm();
            if len.is_nan() || len <= 1e-9 {
                return Err(format!("waypoints {i} and {} coincide", (i + 1) % n));
            }
            dirs.push(d / len);
            lens.push(len);
        }
        // Corner k sits at waypoint k, between leg k - 1 and leg k.
        let corner = |k: usize| -> Option<(f64, f64)> {
            if !closed && (k == 0 || k == n - 1) {
                return None;
            }
            let d_in = dirs[(k + legs - 1) % legs];
            let d_out = dirs[k % legs];
            let phi = (d_in.x * d_out.y - d_in.y * d_out.x).atan2(d_in.dot(&d_out));
            Some((phi, radius * (phi.abs() / 2.0).tan()))
        };
        let corners: Vec<Option<(f64, f64)>> = (0..n).map(corner).collect();
        let cut = |k: usize| corners[k % n].map_or(0.0, |(_, t)| t);
        let mut segments = Vec::new();
        for i in 0..legs {
            let (a, b) = (cut(i), cut(i + 1));
            if a + b > lens[i] + 1e-9 {
                return Err(format!(
                    "leg {i} is {:.2} m long, too short for corner arcs of radius {radius} m",
                    lens[i]
                ));
            }
            let start = waypoints[i] + dirs[i] * a;
            let len = (lens[i] - a - b).max(0.0);
            if len > 0.0 {
                segments.push(Segment::Line {
                    start,
                    dir: dirs[i],
                    len,
                });
            }
            if let Some((phi, t)) = corners[(i + 1) % n]
                && phi.abs() > 1e-12
                && radius > 0.0
            {
                let d = dirs[i];
                let arc_start = waypoints[(i + 1) % n] - d * t;
                let left = Vector2::new(-d.y, d.x);
                let center = arc_start + left * (radius * phi.signum());
                let r = arc_start - center;
                segments.push(Segment::Arc {
                    center,
                    radius,
                    start_angle: r.y.atan2(r.x),
                    sweep: phi,
                });
            }
        }
        let mut starts = Vec::with_capacity(segments.len());
        let mut length = 0.0;
        for s in &segments {
            starts.push(length);
            length += s.len();
        }
        Ok(Self {
            segments,
            starts,
            length,
            closed,
        })
    }

    /// Total length in metres.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Whether the path ends where it starts.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Position and heading (radians from the x-axis, of the direction of travel) at arc
    /// length `s`, clamped to `[0, length]` (wrapped for a closed path).
    pub fn at(&self, s: f64) -> (Vector2<f64>, f64) {
        let s = if self.closed && self.length > 0.0 {
            s.rem_euclid(self.length)
        } else {
            s.clamp(0.0, self.length)
        };
        let k = self.starts.partition_point(|&a| a <= s).saturating_sub(1);
        match self.segments.get(k) {
            Some(seg) => seg.at(s - self.starts[k]),
            None => (Vector2::zeros(), 0.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use std::f64::consts::{FRAC_PI_2, PI};

    #[test]
    fn rounded_rectangle_has_the_expected_length_and_is_continuous() {
        let w = [
            Vector2::new(0.0, 0.0),
            Vector2::new(20.0, 0.0),
            Vector2::new(20.0, 10.0),
            Vector2::new(0.0, 10.0),
        ];
        let r = 3.0;
        let p = Path2::rounded(&w, r, true).unwrap();
        // Each of the four corners replaces 2r of straight legs by a quarter circle.
        assert_abs_diff_eq!(
            p.length(),
            60.0 - 4.0 * (2.0 * r - FRAC_PI_2 * r),
            epsilon = 1e-9
        );
        let n = 2000;
        let step = p.length() / f64::from(n);
        for i in 0..n {
            let (a, ha) = p.at(f64::from(i) * step);
            let (b, _) = p.at(f64::from(i + 1) * step);
            // Consecutive samples are one step apart (to the chord of a 3 m arc).
            assert!(((b - a).norm() - step).abs() < 1e-3, "jump at sample {i}");
            // The heading points along the path.
            let dir = (b - a).normalize();
            let dh = (dir.y.atan2(dir.x) - ha + PI).rem_euclid(2.0 * PI) - PI;
            assert!(dh.abs() < 0.02, "heading off by {dh} at sample {i}");
        }
        let (start, h) = p.at(0.0);
        assert_abs_diff_eq!(start, Vector2::new(r, 0.0), epsilon = 1e-12);
        assert_abs_diff_eq!(h, 0.0, epsilon = 1e-12);
    }

    #[test]
    fn short_legs_and_repeated_points_are_refused() {
        let w = [
            Vector2::new(0.0, 0.0),
            Vector2::new(2.0, 0.0),
            Vector2::new(2.0, 2.0),
        ];
        assert!(Path2::rounded(&w, 3.0, false).is_err());
        let w = [Vector2::new(0.0, 0.0), Vector2::new(0.0, 0.0)];
        assert!(Path2::rounded(&w, 1.0, false).is_err());
    }
}
