//! Input checks shared by every solver, and the tolerances they use.
//!
//! All tolerances are relative, so they hold at any scale of the world coordinates.

use nalgebra::{Matrix3, Point3, Vector3};

use crate::error::{Degeneracy, PnpError, Result};
use crate::symmetric_eigen::smallest_eigenpairs;

/// A bearing is accepted as a unit vector when `| |f| - 1 | <= UNIT_NORM_TOLERANCE`. Loose
/// enough for bearings computed in `f32` and converted, tight enough to catch unnormalized
/// image points (`(x, y, 1)`).
pub const UNIT_NORM_TOLERANCE: f64 = 1e-6;

/// World points are coincident when their RMS spread is at most this fraction of the
/// centroid's distance from the origin (or exactly zero): below it the spread is round-off.
pub const COINCIDENT_TOLERANCE: f64 = 1e-12;

/// World points are collinear when the second principal standard deviation is at most this
/// fraction of the first. Above it the rotation about the line is determined, if poorly.
pub const COLLINEAR_TOLERANCE: f64 = 1e-9;

/// Two bearings are parallel when the sine of their angle is at most this (about 2e-5
/// arcseconds, far below any sensor's resolution).
pub const PARALLEL_TOLERANCE: f64 = 1e-10;

/// Checks counts, lengths, finiteness and unit norms of a correspondence set.
pub(crate) fn check_correspondences(
    solver: &'static str,
    needed: usize,
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
) -> Result<()> {
    if bearings.len() != points.len() {
        return Err(PnpError::LengthMismatch {
            bearings: bearings.len(),
            points: points.len(),
        });
    }
    if bearings.len() < needed {
        return Err(PnpError::NotEnoughPoints {
            solver,
            needed,
            got: bearings.len(),
        });
    }
    for (index, (f, x)) in bearings.iter().zip(points).enumerate() {
        // One branch per correspondence on the common path: `(x + y + z) * 0` is zero exactly
        // when the three are finite, and a squared norm inside `UNIT_SQUARED_BAND` means a
        // norm inside the tolerance. Anything else takes the exact, ordered checks below.
        let finite = (x.x + x.y + x.z) * 0.0 == 0.0;
        if !(finite && (f.norm_squared() - 1.0).abs() <= UNIT_SQUARED_BAND) {
            check_one(index, f, x)?;
        }
    }
    Ok(())
}

/// A squared norm within this of 1 puts the norm within [`UNIT_NORM_TOLERANCE`] of 1:
/// `(1 ± t)^2 = 1 ± 2t + t^2`, so `2t - t^2` less a margin for the rounding of the squared
/// norm. Bearings outside it are checked on their norm itself.
const UNIT_SQUARED_BAND: f64 = 2.0 * UNIT_NORM_TOLERANCE * (1.0 - UNIT_NORM_TOLERANCE) - 1e-15;

/// The checks of one correspondence, in the order they are reported.
#[cold]
fn check_one(index: usize, f: &Vector3<f64>, x: &Point3<f64>) -> Result<()> {
    if !f.iter().all(|v| v.is_finite()) {
        return Err(PnpError::NonFiniteBearing { index });
    }
    if !x.coords.iter().all(|v| v.is_finite()) {
        return Err(PnpError::NonFinitePoint { index });
    }
    let norm = f.norm();
    if (norm - 1.0).abs() > UNIT_NORM_TOLERANCE {
        return Err(PnpError::NonUnitBearing {
            index,
            norm,
            tolerance: UNIT_NORM_TOLERANCE,
        });
    }
    Ok(())
}

/// Refuses a bearing set whose rays are all one line through the centre.
pub(crate) fn check_bearings_spread(bearings: &[Vector3<f64>]) -> Result<()> {
    let Some(first) = bearings.first() else {
        return Ok(());
    };
    if bearings
        .iter()
        .all(|f| f.cross(first).norm() <= PARALLEL_TOLERANCE)
    {
        return Err(PnpError::Degenerate(Degeneracy::ParallelBearings));
    }
    Ok(())
}

/// Principal axes of a world point set: the frame EPnP puts its control points in.
#[derive(Debug, Clone)]
pub(crate) struct PointSpread {
    /// Centroid of the points.
    pub centroid: Point3<f64>,
    /// Principal directions as columns, by decreasing variance; a right-handed frame.
    pub axes: Matrix3<f64>,
    /// Standard deviation of the points along each axis (decreasing).
    pub std_devs: Vector3<f64>,
}

impl PointSpread {
    /// Third principal standard deviation over the first: 0 for a planar set.
    pub fn flatness(&self) -> f64 {
        self.std_devs[2] / self.std_devs[0]
    }
}

/// Principal axes of the points; refuses coincident and collinear sets.
pub(crate) fn point_spread(points: &[Point3<f64>]) -> Result<PointSpread> {
    let n = points.len() as f64;
    let centroid = Point3::from(
        points
            .iter()
            .fold(Vector3::zeros(), |acc, p| acc + p.coords)
            / n,
    );
    let mut scatter = Matrix3::zeros();
    for p in points {
        let d = p - centroid;
        scatter += d * d.transpose();
    }
    scatter /= n;
    let rows: [[f64; 3]; 3] = core::array::from_fn(|i| core::array::from_fn(|j| scatter[(i, j)]));
    // Ascending eigenvalues: the last two vectors are the first and second principal axes.
    let Some((_, vectors)) = smallest_eigenpairs::<3, 3>(rows) else {
        return Err(PnpError::Numerical(
            "the scatter of the world points is not finite (coordinates too large)",
        ));
    };
    let first = Vector3::from(vectors[2]);
    let second = Vector3::from(vectors[1]);
    // A right-handed frame: the third axis is the cross product of the first two.
    let axes = Matrix3::from_columns(&[first, second, first.cross(&second)]);
    // Spreads measured along the axes, not read from the eigenvalues: an eigenvalue carries
    // round-off of about eps times the largest, which would floor the spread ratio at
    // sqrt(eps) and hide exactly planar or collinear sets.
    let mut sums = Vector3::zeros();
    for p in points {
        let local = axes.tr_mul(&(p - centroid));
        sums += local.component_mul(&local);
    }
    let std_devs = (sums / n).map(f64::sqrt);
    let spread = std_devs[0];
    if spread == 0.0 || spread <= COINCIDENT_TOLERANCE * centroid.coords.norm() {
        return Err(PnpError::Degenerate(Degeneracy::CoincidentPoints));
    }
    if std_devs[1] <= COLLINEAR_TOLERANCE * spread {
        return Err(PnpError::Degenerate(Degeneracy::CollinearPoints));
    }
    Ok(PointSpread {
        centroid,
        axes,
        std_devs,
    })
}

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector3};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::{UNIT_NORM_TOLERANCE, check_correspondences, check_one};

    /// The one-branch screen of `check_correspondences` (a squared-norm band and a finiteness
    /// trick) decides exactly as the ordered checks of `check_one` do, around both edges of
    /// the unit-norm tolerance and for non-finite coordinates.
    #[test]
    fn fast_screen_agrees_with_the_exact_checks() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        let point = Point3::new(1.0, -2.0, 3.0);
        for _ in 0..20_000 {
            let direction = Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize();
            // Half the samples within 1e-12 of an edge of the tolerance, half anywhere in
            // twice its width.
            let offset = if rng.random::<bool>() {
                let edge = if rng.random::<bool>() { 1.0 } else { -1.0 };
                edge * (1.0 + rng.random_range(-1e-6..1e-6))
            } else {
                rng.random_range(-2.0..2.0)
            };
            let norm = 1.0 + offset * UNIT_NORM_TOLERANCE;
            let f = direction * norm;
            let screened = check_correspondences("test", 1, &[f], &[point]);
            assert_eq!(screened, check_one(0, &f, &point), "|f| = {}", f.norm());
        }
        let unit = Vector3::new(0.0, 0.6, 0.8);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e308] {
            let f = Vector3::new(bad, 0.6, 0.8);
            let x = Point3::new(bad, 1e308, 0.0);
            for (f, x) in [(f, point), (unit, x), (f, x)] {
                let screened = check_correspondences("test", 1, &[f], &[x]);
                assert_eq!(screened, check_one(0, &f, &x), "{f:?} {x:?}");
            }
        }
    }
}
