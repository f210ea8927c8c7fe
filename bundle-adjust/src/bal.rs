//! Bundle Adjustment in the Large (Agarwal, Snavely, Seitz, Szeliski, ECCV 2010): the file
//! format, its camera model with analytic Jacobians, and a ready-made problem.
//!
//! Camera model: P = R(ω) X + t with R(ω) the rotation by the angle-axis vector ω
//! (Rodrigues), p = −P / P_z, pixel = f (1 + k₁|p|² + k₂|p|⁴) p. A camera block is
//! `[ωx, ωy, ωz, tx, ty, tz, f, k1, k2]`, a point block `[X, Y, Z]`; the residual is the
//! predicted minus the observed pixel. The file lists `num_cameras num_points
//! num_observations`, then one `camera point x y` line per observation, then the camera
//! blocks and the points, one value per line.

use std::path::Path;

use nalgebra::{Matrix2x3, Matrix3, Vector3};

use crate::RobustLoss;
use crate::corrector::validate_loss;
use crate::cost::{CostFunction, Jacobians};
use crate::error::{BalFileError, BalSyntaxError, BundleAdjustError, Result};
use crate::manifold::skew;
use crate::options::SolverOptions;
use crate::problem::{ParameterBlockId, Problem};
use crate::summary::Summary;

/// Largest BAL file [`BalProblem::from_file`] reads: 16 GiB, several times the largest
/// problem of the BAL collection (a bound so that a wrong path, such as a device, cannot
/// exhaust memory).
pub const BAL_MAX_FILE_BYTES: u64 = 16 << 30;

/// One observation of a BAL file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BalObservation {
    /// Camera index.
    pub camera: usize,
    /// Point index.
    pub point: usize,
    /// Observed pixel (BAL's image coordinates, origin at the image centre).
    pub pixel: [f64; 2],
}

/// A BAL problem: cameras, points and observations.
#[derive(Debug, Clone, PartialEq)]
pub struct BalProblem {
    /// Camera blocks `[ωx, ωy, ωz, tx, ty, tz, f, k1, k2]`.
    pub cameras: Vec<[f64; 9]>,
    /// Points `[X, Y, Z]`.
    pub points: Vec<[f64; 3]>,
    /// Observations.
    pub observations: Vec<BalObservation>,
}

/// The ids of a BAL problem's blocks inside a [`Problem`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BalBlocks {
    /// One id per camera.
    pub cameras: Vec<ParameterBlockId>,
    /// One id per point.
    pub points: Vec<ParameterBlockId>,
}

/// Splits a text into whitespace-separated tokens with their one-based line numbers.
struct Tokens<'a> {
    lines: core::iter::Enumerate<core::str::Lines<'a>>,
    current: Option<(usize, core::str::SplitWhitespace<'a>)>,
    /// One-based number of the last line read (at the end of the text, its last line).
    last_line: usize,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            lines: text.lines().enumerate(),
            current: None,
            last_line: 0,
        }
    }

    /// The line to report for a value missing at the end of the text: its last line (1 for
    /// an empty text).
    fn end_line(&self) -> usize {
        self.last_line.max(1)
    }

    fn next_token(&mut self) -> Option<(usize, &'a str)> {
        loop {
            if let Some((line, words)) = &mut self.current
                && let Some(w) = words.next()
            {
                return Some((*line, w));
            }
            let (i, l) = self.lines.next()?;
            self.last_line = i + 1;
            self.current = Some((i + 1, l.split_whitespace()));
        }
    }

    fn parse<T: core::str::FromStr>(&mut self, expected: &'static str) -> Result<(usize, T)> {
        let Some((line, token)) = self.next_token() else {
            return Err(BundleAdjustError::BalParse {
                line: self.end_line(),
                source: BalSyntaxError::UnexpectedEnd { expected },
            });
        };
        token
            .parse()
            .map(|v| (line, v))
            .map_err(|_| BundleAdjustError::BalParse {
                line,
                source: BalSyntaxError::Malformed {
                    expected,
                    token: token.to_owned(),
                },
            })
    }

    fn finite(&mut self, expected: &'static str) -> Result<f64> {
        let (line, v): (usize, f64) = self.parse(expected)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(BundleAdjustError::BalParse {
                line,
                source: BalSyntaxError::NonFinite { expected },
            })
        }
    }
}

impl BalProblem {
    /// Reads a BAL file (a regular file of at most [`BAL_MAX_FILE_BYTES`]).
    ///
    /// # Errors
    /// [`BalFileError::Io`] naming the file if it cannot be read,
    /// [`BalFileError::Parse`] naming it and carrying [`BalProblem::parse`]'s error otherwise.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, BalFileError> {
        let path = path.as_ref();
        let text = ibc_camera_models::io::read_text(path, BAL_MAX_FILE_BYTES)?;
        Self::parse(&text).map_err(|source| BalFileError::Parse {
            path: path.to_owned(),
            source,
        })
    }

    /// Parses the text of a BAL file.
    ///
    /// # Errors
    /// [`BundleAdjustError::BalParse`] with the line of the first malformed, non-finite or
    /// out-of-range value, a missing value or trailing data.
    pub fn parse(text: &str) -> Result<Self> {
        let mut t = Tokens::new(text);
        let (_, num_cameras): (_, usize) = t.parse("the number of cameras")?;
        let (_, num_points): (_, usize) = t.parse("the number of points")?;
        let (_, num_observations): (_, usize) = t.parse("the number of observations")?;
        let mut observations = Vec::with_capacity(num_observations.min(1 << 24));
        for _ in 0..num_observations {
            let (line, camera): (_, usize) = t.parse("an observation's camera index")?;
            let (_, point): (_, usize) = t.parse("an observation's point index")?;
            if camera >= num_cameras || point >= num_points {
                return Err(BundleAdjustError::BalParse {
                    line,
                    source: BalSyntaxError::ObservationOutOfRange {
                        camera,
                        point,
                        cameras: num_cameras,
                        points: num_points,
                    },
                });
            }
            let x = t.finite("an observed x")?;
            let y = t.finite("an observed y")?;
            observations.push(BalObservation {
                camera,
                point,
                pixel: [x, y],
            });
        }
        let mut cameras = Vec::with_capacity(num_cameras.min(1 << 24));
        for _ in 0..num_cameras {
            let mut c = [0.0; 9];
            for v in &mut c {
                *v = t.finite("a camera parameter")?;
            }
            cameras.push(c);
        }
        let mut points = Vec::with_capacity(num_points.min(1 << 24));
        for _ in 0..num_points {
            let mut p = [0.0; 3];
            for v in &mut p {
                *v = t.finite("a point coordinate")?;
            }
            points.push(p);
        }
        if let Some((line, token)) = t.next_token() {
            return Err(BundleAdjustError::BalParse {
                line,
                source: BalSyntaxError::TrailingData {
                    token: token.to_owned(),
                },
            });
        }
        Ok(Self {
            cameras,
            points,
            observations,
        })
    }

    /// The residual (predicted minus observed pixel) of observation `index`, or `None` for an
    /// index out of range or an observation of a camera or point that does not exist.
    #[must_use]
    pub fn residual(&self, index: usize) -> Option<[f64; 2]> {
        let o = self.observations.get(index)?;
        let camera = self.cameras.get(o.camera)?;
        let point = self.points.get(o.point)?;
        let cost = BalReprojection::new(o.pixel);
        let mut r = [0.0; 2];
        cost.evaluate(&[camera, point], &mut r, None).then_some(r)
    }

    /// Cost ½ Σ ρ(|r|²) over all observations.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidLossScale`] for an invalid loss.
    pub fn cost(&self, loss: RobustLoss) -> Result<f64> {
        validate_loss(&loss)?;
        Ok((0..self.observations.len())
            .filter_map(|i| self.residual(i))
            .map(|r| 0.5 * loss.evaluate(r[0] * r[0] + r[1] * r[1])[0])
            .sum())
    }

    /// Recentres and rescales the reconstruction as Ceres's `bundle_adjuster` example does:
    /// points and camera centres move by the coordinate-wise median of the points and are
    /// scaled so the median L1 distance of the points to it is 100. Reprojections, hence
    /// costs, are unchanged; the parameter values (and so the solver's path) change.
    pub fn normalize(&mut self) {
        let n = self.points.len();
        if n == 0 {
            return;
        }
        let mut tmp = vec![0.0; n];
        let mut median = Vector3::zeros();
        for axis in 0..3 {
            for (t, p) in tmp.iter_mut().zip(&self.points) {
                *t = p[axis];
            }
            median[axis] = upper_median(&mut tmp);
        }
        for (t, p) in tmp.iter_mut().zip(&self.points) {
            *t = (Vector3::from(*p) - median).abs().sum();
        }
        let mad = upper_median(&mut tmp);
        if mad.is_nan() || mad <= 0.0 {
            return;
        }
        let scale = 100.0 / mad;
        for p in &mut self.points {
            let q = (Vector3::from(*p) - median) * scale;
            *p = [q.x, q.y, q.z];
        }
        for c in &mut self.cameras {
            let omega = Vector3::new(c[0], c[1], c[2]);
            let t = Vector3::new(c[3], c[4], c[5]);
            // centre = −Rᵀ t; t = −R centre.
            let center = -rotate(&-omega, &t);
            let center = (center - median) * scale;
            let t = -rotate(&omega, &center);
            c[3] = t.x;
            c[4] = t.y;
            c[5] = t.z;
        }
    }

    /// Builds a [`Problem`] with one block per camera and point, the points marked for
    /// elimination, and one [`BalReprojection`] residual per observation with `loss`.
    ///
    /// # Errors
    /// [`BundleAdjustError::InvalidLossScale`] for an invalid loss,
    /// [`BundleAdjustError::NonFiniteParameter`] for a non-finite value,
    /// [`BundleAdjustError::NonFiniteObservation`] for a non-finite pixel, or
    /// [`BundleAdjustError::IndexOutOfRange`] for an observation of a camera or point that
    /// does not exist.
    pub fn to_problem(&self, loss: RobustLoss) -> Result<(Problem, BalBlocks)> {
        let mut problem = Problem::new();
        let cameras = self
            .cameras
            .iter()
            .map(|c| problem.add_parameter_block(c))
            .collect::<Result<Vec<_>>>()?;
        let points = self
            .points
            .iter()
            .map(|p| problem.add_parameter_block(p))
            .collect::<Result<Vec<_>>>()?;
        for &p in &points {
            problem.set_eliminated(p, true)?;
        }
        for (i, o) in self.observations.iter().enumerate() {
            if !(o.pixel[0].is_finite() && o.pixel[1].is_finite()) {
                return Err(BundleAdjustError::NonFiniteObservation { index: i });
            }
            let out_of_range = |target, index, count| BundleAdjustError::IndexOutOfRange {
                what: "observation",
                position: i,
                target,
                index,
                count,
            };
            let c = *cameras
                .get(o.camera)
                .ok_or_else(|| out_of_range("camera", o.camera, cameras.len()))?;
            let p = *points
                .get(o.point)
                .ok_or_else(|| out_of_range("point", o.point, points.len()))?;
            problem.add_residual_block(BalReprojection::new(o.pixel), loss, &[c, p])?;
        }
        Ok((problem, BalBlocks { cameras, points }))
    }

    /// Copies the cameras and points back from a solved problem built by
    /// [`BalProblem::to_problem`].
    ///
    /// # Errors
    /// [`BundleAdjustError::UnknownParameterBlock`] if `blocks` belongs to another problem.
    pub fn read_back(&mut self, problem: &Problem, blocks: &BalBlocks) -> Result<()> {
        for (c, &id) in self.cameras.iter_mut().zip(&blocks.cameras) {
            c.copy_from_slice(problem.parameter_block(id)?);
        }
        for (p, &id) in self.points.iter_mut().zip(&blocks.points) {
            p.copy_from_slice(problem.parameter_block(id)?);
        }
        Ok(())
    }

    /// Bundle-adjusts cameras and points in place (points eliminated).
    ///
    /// # Errors
    /// As [`BalProblem::to_problem`] and [`Problem::solve`].
    pub fn solve(&mut self, loss: RobustLoss, options: &SolverOptions) -> Result<Summary> {
        let (mut problem, blocks) = self.to_problem(loss)?;
        let summary = problem.solve(options)?;
        self.read_back(&problem, &blocks)?;
        Ok(summary)
    }
}

/// Ceres's median: the element at position n/2 after sorting (the upper median).
fn upper_median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Coefficients of R(ω) = I + a [ω]× + b [ω]×² (Rodrigues) and of the left Jacobian
/// J_l(ω) = I + b [ω]× + c [ω]×², from one sine and cosine: a = sin θ/θ,
/// b = (1 − cos θ)/θ² = a²/(1 + cos θ), c = (θ − sin θ)/θ³ = (1 − a)/θ², with their
/// Taylor series for θ² below 1e-8.
#[inline]
fn rodrigues_coefficients(omega: &Vector3<f64>) -> (f64, f64, f64) {
    let theta2 = omega.norm_squared();
    if theta2 < 1e-8 {
        (
            1.0 - theta2 / 6.0,
            0.5 - theta2 / 24.0,
            1.0 / 6.0 - theta2 / 120.0,
        )
    } else {
        let theta = theta2.sqrt();
        let (sin, cos) = theta.sin_cos();
        let a = sin / theta;
        (a, a * a / (1.0 + cos), (1.0 - a) / theta2)
    }
}

/// R(ω) X.
#[inline]
fn rotate(omega: &Vector3<f64>, x: &Vector3<f64>) -> Vector3<f64> {
    let (a, b, _) = rodrigues_coefficients(omega);
    let wx = omega.cross(x);
    x + wx * a + omega.cross(&wx) * b
}

/// The BAL reprojection residual of one observation; arguments `[camera (9), point (3)]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BalReprojection {
    observed: [f64; 2],
}

impl BalReprojection {
    /// The residual for an observed pixel.
    #[must_use]
    pub fn new(observed: [f64; 2]) -> Self {
        Self { observed }
    }
}

impl CostFunction for BalReprojection {
    fn num_residuals(&self) -> usize {
        2
    }

    fn parameter_block_sizes(&self) -> &[usize] {
        &[9, 3]
    }

    #[inline]
    fn evaluate(
        &self,
        parameters: &[&[f64]],
        residuals: &mut [f64],
        jacobians: Option<&mut Jacobians<'_>>,
    ) -> bool {
        let (c, x) = (parameters[0], parameters[1]);
        let omega = Vector3::new(c[0], c[1], c[2]);
        let point = Vector3::new(x[0], x[1], x[2]);
        let (ca, cb, cc) = rodrigues_coefficients(&omega);
        let wx = omega.cross(&point);
        let rotated = point + wx * ca + omega.cross(&wx) * cb;
        let p = rotated + Vector3::new(c[3], c[4], c[5]);
        let (f, k1, k2) = (c[6], c[7], c[8]);
        let inv_z = -1.0 / p.z;
        let (u, v) = (p.x * inv_z, p.y * inv_z);
        let r2 = u * u + v * v;
        let d = 1.0 + r2 * (k1 + k2 * r2);
        residuals[0] = f * d * u - self.observed[0];
        residuals[1] = f * d * v - self.observed[1];
        let Some(jac) = jacobians else {
            return true;
        };
        // ∂pixel/∂P = ∂pixel/∂(u, v) · ∂(u, v)/∂P.
        let dd = 2.0 * (k1 + 2.0 * k2 * r2);
        let a = nalgebra::Matrix2::new(
            f * (d + dd * u * u),
            f * dd * u * v,
            f * dd * u * v,
            f * (d + dd * v * v),
        );
        let b = Matrix2x3::new(inv_z, 0.0, u * inv_z, 0.0, inv_z, v * inv_z);
        let m = a * b;
        let k = skew(&omega);
        let k2m = k * k;
        if let Some(jc) = jac.row_major_mut(0) {
            let jl = Matrix3::identity() + k * cb + k2m * cc;
            let d_omega = m * (-skew(&rotated) * jl);
            let extra = [
                d * u,
                f * r2 * u,
                f * r2 * r2 * u,
                d * v,
                f * r2 * v,
                f * r2 * r2 * v,
            ];
            for row in 0..2 {
                let out = &mut jc[row * 9..row * 9 + 9];
                for col in 0..3 {
                    out[col] = d_omega[(row, col)];
                    out[3 + col] = m[(row, col)];
                }
                out[6..9].copy_from_slice(&extra[row * 3..row * 3 + 3]);
            }
        }
        if let Some(jp) = jac.row_major_mut(1) {
            let rot = Matrix3::identity() + k * ca + k2m * cb;
            let dp = m * rot;
            for row in 0..2 {
                for col in 0..3 {
                    jp[row * 3 + col] = dp[(row, col)];
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn parse_errors_name_the_line() {
        let err = BalProblem::parse("1 1 1\n0 0 1.0 x\n").unwrap_err();
        assert!(matches!(err, BundleAdjustError::BalParse { line: 2, .. }));
        let err = BalProblem::parse("1 1 1\n0 3 1.0 2.0\n").unwrap_err();
        assert!(matches!(err, BundleAdjustError::BalParse { line: 2, .. }));
        let err = BalProblem::parse("1 1 1\n0 0 nan 2.0\n").unwrap_err();
        assert!(matches!(err, BundleAdjustError::BalParse { line: 2, .. }));
        let err = BalProblem::parse("1 1").unwrap_err();
        assert!(matches!(err, BundleAdjustError::BalParse { .. }));
        let text = "1 1 1\n0 0 1 2\n0 0 0 0 0 -5 100 0 0\n1 2 3\n4";
        assert!(matches!(
            BalProblem::parse(text),
            Err(BundleAdjustError::BalParse { line: 5, .. })
        ));
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let camera = [0.3, -0.2, 0.15, 0.5, -0.3, -4.0, 520.0, -0.05, 0.01];
        let point = [0.4, -0.7, 1.2];
        let cost = BalReprojection::new([10.0, -4.0]);
        let mut r = [0.0; 2];
        let mut data = vec![0.0; 24];
        let slots = [
            crate::cost::JacobianSlot {
                offset: 0,
                cols: 9,
                wanted: true,
            },
            crate::cost::JacobianSlot {
                offset: 18,
                cols: 3,
                wanted: true,
            },
        ];
        let mut jw = Jacobians::new(&mut data, &slots, 2);
        assert!(cost.evaluate(&[&camera, &point], &mut r, Some(&mut jw)));
        assert!(jw.shape_error().is_none());
        let eval = |c: &[f64], p: &[f64]| {
            let mut out = [0.0; 2];
            cost.evaluate(&[c, p], &mut out, None);
            out
        };
        for k in 0..12 {
            let h = 1e-6 * if k == 6 { 100.0 } else { 1.0 };
            let (mut cp, mut cm) = (camera, camera);
            let (mut pp, mut pm) = (point, point);
            if k < 9 {
                cp[k] += h;
                cm[k] -= h;
            } else {
                pp[k - 9] += h;
                pm[k - 9] -= h;
            }
            let (a, b) = (eval(&cp, &pp), eval(&cm, &pm));
            for row in 0..2 {
                let fd = (a[row] - b[row]) / (2.0 * h);
                let analytic = if k < 9 {
                    data[row * 9 + k]
                } else {
                    data[18 + row * 3 + k - 9]
                };
                assert_relative_eq!(analytic, fd, max_relative = 1e-6, epsilon = 1e-6);
            }
        }
    }

    #[test]
    fn rotation_series_matches_rodrigues() {
        let x = Vector3::new(1.0, 2.0, -0.5);
        let small = Vector3::new(3e-9, -2e-9, 1e-9);
        let r = rotate(&small, &x);
        let reference = nalgebra::Rotation3::new(small) * x;
        assert_relative_eq!(r, reference, epsilon = 1e-15);
        let big = Vector3::new(0.3, -1.2, 2.0);
        assert_relative_eq!(
            rotate(&big, &x),
            nalgebra::Rotation3::new(big) * x,
            epsilon = 1e-14
        );
    }

    #[test]
    fn normalization_preserves_residuals() {
        let text = "2 2 3\n0 0 10.0 5.0\n1 0 -3.0 2.0\n1 1 1.0 1.0\n\
                    0.1 0.2 0.3 1 2 -10 500 0.01 0.001\n\
                    -0.1 0.05 0.2 -1 0.5 -12 480 -0.02 0.002\n\
                    0.5 0.2 1.0\n-0.3 0.4 0.8\n";
        let mut bal = BalProblem::parse(text).unwrap();
        let before: Vec<_> = (0..3).map(|i| bal.residual(i).unwrap()).collect();
        bal.normalize();
        for (i, b) in before.iter().enumerate() {
            let after = bal.residual(i).unwrap();
            assert_relative_eq!(after[0], b[0], epsilon = 1e-9);
            assert_relative_eq!(after[1], b[1], epsilon = 1e-9);
        }
    }
}
