//! A uniform 2D grid over the landmarks' x-y positions, for spatial culling: a camera only
//! tests the landmarks of the cells within its range, in a fixed order (cell by cell, then
//! landmark by landmark), so the result does not depend on threads.

use nalgebra::{Point2, Point3};

/// Landmark indices bucketed by grid cell, stored compactly (cell starts and one index list).
#[derive(Clone, Debug, Default)]
pub(crate) struct Grid {
    origin: Point2<f64>,
    cell: f64,
    nx: usize,
    ny: usize,
    /// `starts[c]..starts[c + 1]` indexes `items` for cell `c = iy * nx + ix`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    /// Buckets `points` (their x and y) into square cells of `cell` metres.
    pub(crate) fn new(points: &[Point3<f64>], cell: f64) -> Self {
        if points.is_empty() {
            return Self {
                cell,
                ..Self::default()
            };
        }
        let (mut lo, mut hi) = (
            Point2::new(f64::MAX, f64::MAX),
            Point2::new(f64::MIN, f64::MIN),
        );
        for p in points {
            lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
            hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
        }
        let nx = ((hi.x - lo.x) / cell).floor() as usize + 1;
        let ny = ((hi.y - lo.y) / cell).floor() as usize + 1;
        let mut grid = Self {
            origin: lo,
            cell,
            nx,
            ny,
            starts: vec![0; nx * ny + 1],
            items: vec![0; points.len()],
        };
        let cells: Vec<usize> = points.iter().map(|p| grid.cell_of(p)).collect();
        for &c in &cells {
            grid.starts[c + 1] += 1;
        }
        for c in 0..nx * ny {
            grid.starts[c + 1] += grid.starts[c];
        }
        let mut fill = grid.starts.clone();
        for (i, &c) in cells.iter().enumerate() {
            grid.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    fn cell_of(&self, p: &Point3<f64>) -> usize {
        let ix = (((p.x - self.origin.x) / self.cell).floor().max(0.0) as usize).min(self.nx - 1);
        let iy = (((p.y - self.origin.y) / self.cell).floor().max(0.0) as usize).min(self.ny - 1);
        iy * self.nx + ix
    }

    /// Calls `f` with the index of every landmark in the cells that come within `radius` of
    /// `(x, y)` (a superset of the landmarks within `radius`), cell by cell.
    pub(crate) fn for_each_near(&self, x: f64, y: f64, radius: f64, mut f: impl FnMut(u32)) {
        if self.items.is_empty() {
            return;
        }
        let c = self.cell;
        let span = |v: f64, o: f64, n: usize| {
            let lo = ((v - radius - o) / c).floor();
            let hi = ((v + radius - o) / c).floor();
            let clamp = |t: f64| (t.max(0.0) as usize).min(n - 1);
            (lo <= (n - 1) as f64 && hi >= 0.0).then(|| (clamp(lo), clamp(hi)))
        };
        let (Some((x0, x1)), Some((y0, y1))) = (
            span(x, self.origin.x, self.nx),
            span(y, self.origin.y, self.ny),
        ) else {
            return;
        };
        let r2 = radius * radius;
        for iy in y0..=y1 {
            let cy0 = self.origin.y + iy as f64 * c;
            let dy = (cy0 - y).max(0.0).max(y - (cy0 + c));
            for ix in x0..=x1 {
                let cx0 = self.origin.x + ix as f64 * c;
                let dx = (cx0 - x).max(0.0).max(x - (cx0 + c));
                if dx * dx + dy * dy > r2 {
                    continue;
                }
                let k = iy * self.nx + ix;
                for &i in &self.items[self.starts[k] as usize..self.starts[k + 1] as usize] {
                    f(i);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::random::{Purpose, stream};
    use rand::RngExt;

    #[test]
    fn queries_return_every_point_within_the_radius() {
        let mut rng = stream(5, Purpose::World, 0, 0);
        let points: Vec<Point3<f64>> = (0..3000)
            .map(|_| {
                Point3::new(
                    rng.random_range(-50.0..80.0),
                    rng.random_range(0.0..40.0),
                    rng.random_range(0.0..3.0),
                )
            })
            .collect();
        let grid = Grid::new(&points, 4.0);
        for &(x, y, r) in &[
            (0.0, 0.0, 10.0),
            (75.0, 38.0, 30.0),
            (-70.0, 20.0, 25.0),
            (10.0, 5.0, 0.5),
        ] {
            let mut found = Vec::new();
            grid.for_each_near(x, y, r, |i| found.push(i));
            found.sort_unstable();
            let n = found.len();
            found.dedup();
            assert_eq!(found.len(), n, "an index was reported twice");
            for (i, p) in points.iter().enumerate() {
                if (p.x - x).hypot(p.y - y) <= r {
                    assert!(found.binary_search(&(i as u32)).is_ok(), "point {i} missed");
                }
            }
        }
    }
}
