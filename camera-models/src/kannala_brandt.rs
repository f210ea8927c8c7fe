//! The Kannala-Brandt generic camera model, reduced to 8 parameters.
//!
//! J. Kannala and S. S. Brandt, "A generic camera model and calibration method for
//! conventional, wide-angle, and fish-eye lenses", IEEE TPAMI 28(8), 2006, section 3.1 (the
//! radially symmetric model with 5 terms of which the first is fixed to 1). CamOdoCal calls it
//! `KANNALA_BRANDT` (`EquidistantCamera`); Kalibr calls it `pinhole` + `equidistant`.

use nalgebra::{Matrix2x3, Matrix3x2, Unit, Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError, UnprojectionError};
use crate::model::{CameraModel, ParamJacobian, ProjectionJacobians, UnprojectionJacobians};
use crate::polynomial;
use crate::series::{sin_minus_x_cos_over_cube, sinc_with, x_minus_sin_over_cube};
use crate::validate;

/// Iteration bound of the safeguarded Newton-bisection (bisection alone reaches full f64
/// precision on `[0, pi]` in about 60 steps; Newton needs about 3).
pub const MAX_FAST_ITERATIONS: usize = 100;

/// The Newton-bisection tests its quadratic-convergence stop only for steps below this
/// fraction of theta: a larger step could pass it only where |r'' / r'| < 1e-4 (a lens that is
/// equidistant to within 1e-4, which then takes one step more), and skipping the test saves
/// evaluating r'' in the early steps.
const QUADRATIC_TEST_BELOW: f64 = 1e-6;

/// Eigenvalues whose imaginary part is within this fraction of `1 + |re|` are taken as real
/// roots: near the fold the two real roots that meet there come out of the eigenvalue
/// iteration as a complex pair with an imaginary part of order sqrt(eps).
const NEAR_REAL: f64 = 1e-6;

/// A normalized radius up to this fraction beyond r(theta_max) is taken as r(theta_max): 8 ulps,
/// the rounding of a pixel projected exactly at theta_max and normalized again.
pub const FOLD_SLACK: f64 = 8.0 * f64::EPSILON;

/// The reduced Kannala-Brandt model (8 parameters): an equidistant fisheye polynomial.
///
/// For a point `P = (x, y, z)` of the camera frame:
///
/// ```text
/// theta = atan2(sqrt(x^2 + y^2), z)                  angle of incidence, in [0, pi]
/// phi   = atan2(y, x)
/// r(theta) = theta + k1 theta^3 + k2 theta^5 + k3 theta^7 + k4 theta^9
/// u = mu r(theta) cos(phi) + u0
/// v = mv r(theta) sin(phi) + v0
/// ```
///
/// Parameters, in CamOdoCal order: `[k1, k2, k3, k4, mu, mv, u0, v0]` (CamOdoCal's YAML calls
/// k1..k4 `k2..k5`; Kalibr's `equidistant` `distortion_coeffs` are k1..k4 and its `pinhole`
/// `intrinsics` are `[mu, mv, u0, v0]`).
///
/// **Valid domain.** Because theta comes from `atan2`, points past 90 and past 180 degrees of
/// field of view are handled (there is no division by z). The model is valid for
/// `theta <= theta_max`, where `theta_max = min(pi, first positive root of r'(theta))`: past the
/// first root of r' (the fold) r decreases and two angles share a pixel. `theta_max` and
/// `r(theta_max)` are computed when the parameters are set. The negative optical axis itself
/// (theta = pi exactly) images to a circle and is refused. A pixel is unprojectable when its
/// normalized radius `d = |((u - u0)/mu, (v - v0)/mv)|` is at most `r(theta_max)`.
///
/// **Unprojection** solves `r(theta) = d` on `[0, theta_max]`, where r is increasing so the
/// root is unique. [`CameraModel::unproject`] does it as the paper does, through the
/// eigenvalues of the companion matrix, done exactly: the degree is that of the highest
/// non-zero coefficient, the matrix is a fixed-size stack array, the QR iteration is bounded,
/// the smallest real root in `[0, theta_max]` is taken and polished by safeguarded Newton
/// (that root is the only one there, so the iteration stops as soon as it has found it).
/// [`CameraModel::unproject_fast`] runs the safeguarded Newton-bisection alone (started at
/// `theta = d (1 - k1 d^2)`), for hot loops; both agree to 1e-12 rad. The paper's `theta = d` fallback for
/// pixels with no root is only offered through
/// [`backproject_with_fallback`](Self::backproject_with_fallback), which flags it.
#[derive(Clone, Debug, PartialEq)]
pub struct KannalaBrandt {
    width: u32,
    height: u32,
    params: [f64; 8],
    theta_max: f64,
    max_radius: f64,
}

/// The result of [`KannalaBrandt::backproject_with_fallback`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KbBackprojection {
    /// The unit ray.
    pub ray: Unit<Vector3<f64>>,
    /// The angle of incidence used (radians).
    pub theta: f64,
    /// True when no root of r(theta) = d exists in `[0, theta_max]` and the paper's (and
    /// CamOdoCal's) `theta = d` fallback was used: the ray is then not the pixel's ray.
    pub fallback: bool,
}

impl KannalaBrandt {
    /// Number of parameters.
    pub const NUM_PARAMS: usize = 8;
    /// Parameter names, CamOdoCal order.
    pub const PARAM_NAMES: [&'static str; 8] = ["k1", "k2", "k3", "k4", "mu", "mv", "u0", "v0"];
    /// The model's name.
    pub const MODEL_NAME: &'static str = "kannala_brandt";

    /// A camera of `width x height` pixels with parameters `[k1, k2, k3, k4, mu, mv, u0, v0]`.
    ///
    /// # Errors
    /// [`ParameterError`] if a parameter is not finite, `mu` or `mv` is not positive, or the
    /// image is empty.
    pub fn new(width: u32, height: u32, params: [f64; 8]) -> Result<Self, ParameterError> {
        validate::image_size(width, height)?;
        let mut cam = Self {
            width,
            height,
            params: [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
            theta_max: std::f64::consts::PI,
            max_radius: std::f64::consts::PI,
        };
        cam.set_params(&params)?;
        Ok(cam)
    }

    /// The parameters `[k1, k2, k3, k4, mu, mv, u0, v0]`.
    pub fn params_array(&self) -> [f64; 8] {
        self.params
    }

    /// The distortion coefficients `[k1, k2, k3, k4]`.
    pub fn k(&self) -> [f64; 4] {
        [
            self.params[0],
            self.params[1],
            self.params[2],
            self.params[3],
        ]
    }

    /// Horizontal scale (pixels per unit of r).
    pub fn mu(&self) -> f64 {
        self.params[4]
    }

    /// Vertical scale (pixels per unit of r).
    pub fn mv(&self) -> f64 {
        self.params[5]
    }

    /// Principal point, horizontal (pixels).
    pub fn u0(&self) -> f64 {
        self.params[6]
    }

    /// Principal point, vertical (pixels).
    pub fn v0(&self) -> f64 {
        self.params[7]
    }

    /// The largest valid angle of incidence: `min(pi, first positive root of r'(theta))`.
    pub fn theta_max(&self) -> f64 {
        self.theta_max
    }

    /// `r(theta_max)`: the largest normalized radius that has a ray.
    pub fn max_radius(&self) -> f64 {
        self.max_radius
    }

    /// Whether `theta_max` is a fold of r (r' vanishes there) rather than pi.
    pub fn has_fold(&self) -> bool {
        self.theta_max < std::f64::consts::PI
    }

    /// `r(theta) = theta + k1 theta^3 + k2 theta^5 + k3 theta^7 + k4 theta^9`.
    #[inline]
    pub fn radius(&self, theta: f64) -> f64 {
        theta * self.radius_over_theta(theta)
    }

    /// `r'(theta) = 1 + 3 k1 theta^2 + 5 k2 theta^4 + 7 k3 theta^6 + 9 k4 theta^8`.
    #[inline]
    pub fn radius_derivative(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.k();
        let t2 = theta * theta;
        1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
    }

    /// `r''(theta) = 6 k1 theta + 20 k2 theta^3 + 42 k3 theta^5 + 72 k4 theta^7`.
    #[inline]
    fn radius_second_derivative(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.k();
        let t2 = theta * theta;
        theta * (6.0 * k1 + t2 * (20.0 * k2 + t2 * (42.0 * k3 + t2 * 72.0 * k4)))
    }

    /// `r(theta) / theta = 1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8`.
    #[inline]
    fn radius_over_theta(&self, theta: f64) -> f64 {
        let [k1, k2, k3, k4] = self.k();
        let t2 = theta * theta;
        1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))
    }

    /// The angle of incidence theta in `[0, theta_max]` with `r(theta) = d`, through the
    /// eigenvalues of the companion matrix of `k4 t^9 + k3 t^7 + k2 t^5 + k1 t^3 + t - d`
    /// (degree from the highest non-zero coefficient), the smallest real root in
    /// `[0, theta_max]`, polished by safeguarded Newton. No heap allocation.
    ///
    /// # Errors
    /// [`UnprojectionError::BeyondFold`] if `d > r(theta_max)` or `d` is negative or not
    /// finite; [`UnprojectionError::EigenvalueIterationLimit`] or
    /// [`UnprojectionError::NoRealRoot`] if the eigenvalue iteration fails.
    pub fn theta_from_radius(&self, d: f64) -> Result<f64, UnprojectionError> {
        let d = self.check_radius(d)?;
        if d == 0.0 {
            return Ok(0.0);
        }
        if d == self.max_radius {
            return Ok(self.theta_max);
        }
        let [k1, k2, k3, k4] = self.k();
        let coeffs = [-d, 1.0, 0.0, k1, 0.0, k2, 0.0, k3, 0.0, k4];
        // r is increasing on [0, theta_max] and r(0) = 0 <= d <= r(theta_max), so exactly one
        // root lies there: the first real eigenvalue found in the window is the smallest real
        // root in it, and the iteration stops there.
        let slack = NEAR_REAL * (1.0 + self.theta_max);
        let in_window = |re: f64, im: f64| {
            im.abs() <= NEAR_REAL * (1.0 + re.abs()) && re >= -slack && re <= self.theta_max + slack
        };
        let root = polynomial::first_root_where(&coeffs, in_window).map_err(|e| {
            UnprojectionError::EigenvalueIterationLimit {
                iterations: e.iterations,
            }
        })?;
        let Some((best, _)) = root else {
            return Err(UnprojectionError::NoRealRoot);
        };
        self.newton_bisection(d, best.clamp(0.0, self.theta_max))
    }

    /// The same angle as [`theta_from_radius`](Self::theta_from_radius) by safeguarded
    /// Newton-bisection on `[0, theta_max]`, started at `theta = d (1 - k1 d^2)`: the fast path.
    ///
    /// # Errors
    /// As [`theta_from_radius`](Self::theta_from_radius), or
    /// [`UnprojectionError::NotConverged`] after [`MAX_FAST_ITERATIONS`] (which bisection
    /// alone cannot reach).
    #[inline]
    pub fn theta_from_radius_fast(&self, d: f64) -> Result<f64, UnprojectionError> {
        let d = self.check_radius(d)?;
        if d == 0.0 {
            return Ok(0.0);
        }
        if d == self.max_radius {
            return Ok(self.theta_max);
        }
        // First-order inverse of r(theta) = theta (1 + k1 theta^2 + ...): theta ~ d (1 - k1 d^2).
        let guess = d * (1.0 - self.params[0] * d * d);
        self.newton_bisection(d, guess.clamp(0.0, self.theta_max))
    }

    /// Check d against [0, r(theta_max)] and return it, clamped to r(theta_max) when it exceeds
    /// it by no more than [`FOLD_SLACK`] relative (the rounding of a pixel projected exactly at
    /// theta_max).
    #[inline]
    fn check_radius(&self, d: f64) -> Result<f64, UnprojectionError> {
        if !d.is_finite() {
            return Err(UnprojectionError::NonFinitePixel);
        }
        if d >= 0.0 && d <= self.max_radius {
            return Ok(d);
        }
        if d > self.max_radius && d <= self.max_radius * (1.0 + FOLD_SLACK) {
            return Ok(self.max_radius);
        }
        Err(UnprojectionError::BeyondFold {
            radius: d,
            max_radius: self.max_radius,
        })
    }

    /// Solve r(theta) = d on the bracket [0, theta_max] (where r(0) - d < 0 <= r(theta_max) - d)
    /// from `theta`: Newton steps, replaced by bisection whenever they leave the bracket. It
    /// stops when a step is below 2 ulps, or after a Newton step whose remaining error, by
    /// Newton's quadratic convergence about |r'' / (2 r')| step^2, is below half an ulp: that
    /// saves the last step that would only confirm convergence, and the many steps that rounding
    /// noise in r would otherwise cost where r' is small (near pi on wide lenses, near the
    /// fold), where steps of a few ulps keep bouncing around the root.
    #[inline]
    fn newton_bisection(&self, d: f64, mut theta: f64) -> Result<f64, UnprojectionError> {
        let (mut lo, mut hi) = (0.0, self.theta_max);
        let mut f = 0.0;
        for _ in 0..MAX_FAST_ITERATIONS {
            f = self.radius(theta) - d;
            if f == 0.0 {
                return Ok(theta);
            }
            if f < 0.0 {
                lo = theta;
            } else {
                hi = theta;
            }
            let derivative = self.radius_derivative(theta);
            let step = f / derivative;
            let mut next = theta - step;
            let newton = next > lo && next < hi;
            if !newton {
                next = 0.5 * (lo + hi);
            }
            if (next - theta).abs() <= 2.0 * f64::EPSILON * next || next == theta {
                return Ok(next);
            }
            // (r'' is only evaluated once the step is small.)
            if newton
                && step.abs() <= QUADRATIC_TEST_BELOW * next
                && (self.radius_second_derivative(theta) * step * step).abs()
                    <= 0.5 * f64::EPSILON * next * derivative.abs()
            {
                return Ok(next);
            }
            theta = next;
        }
        Err(UnprojectionError::NotConverged {
            iterations: MAX_FAST_ITERATIONS,
            residual: f.abs(),
        })
    }

    /// The paper's backprojection with its fallback made visible: the companion-matrix root
    /// when there is one, otherwise `theta = d` with `fallback = true` (what CamOdoCal does
    /// silently, for example on its own test camera's image corners beyond the fold).
    ///
    /// # Errors
    /// [`UnprojectionError::NonFinitePixel`] for a non-finite pixel. A missing root is not an
    /// error here: it is the flagged fallback.
    pub fn backproject_with_fallback(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<KbBackprojection, UnprojectionError> {
        let m = self.normalized(pixel)?;
        let d = m.norm();
        let (theta, fallback) = match self.theta_from_radius(d) {
            Ok(t) => (t, false),
            Err(UnprojectionError::NonFinitePixel) => {
                return Err(UnprojectionError::NonFinitePixel);
            }
            Err(_) => (d, true),
        };
        let ray = if fallback {
            // theta is not the root of r(theta) = d: only the direct form is right.
            let s = theta.sin() / d;
            Unit::new_normalize(Vector3::new(m.x * s, m.y * s, theta.cos()))
        } else {
            self.ray_from_theta(&m, theta)
        };
        Ok(KbBackprojection {
            ray,
            theta,
            fallback,
        })
    }

    /// ((u - u0) / mu, (v - v0) / mv).
    #[inline]
    fn normalized(&self, pixel: &Vector2<f64>) -> Result<Vector2<f64>, UnprojectionError> {
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            return Err(UnprojectionError::NonFinitePixel);
        }
        Ok(Vector2::new(
            (pixel.x - self.u0()) / self.mu(),
            (pixel.y - self.v0()) / self.mv(),
        ))
    }

    /// The unit ray at the root theta of r(theta) = d, in the direction of m:
    /// (sin(theta) m / d, cos(theta)), with sin(theta) / d written as
    /// sinc(theta) / (r(theta) / theta) so it is exact at d = 0.
    #[inline]
    fn ray_from_theta(&self, m: &Vector2<f64>, theta: f64) -> Unit<Vector3<f64>> {
        self.ray_from_sin_cos(m, theta, theta.sin_cos())
    }

    /// [`ray_from_theta`](Self::ray_from_theta) with `(sin(theta), cos(theta))` given.
    #[inline]
    fn ray_from_sin_cos(
        &self,
        m: &Vector2<f64>,
        theta: f64,
        (sin, cos): (f64, f64),
    ) -> Unit<Vector3<f64>> {
        let s = sinc_with(theta, sin) / self.radius_over_theta(theta);
        Unit::new_normalize(Vector3::new(m.x * s, m.y * s, cos))
    }

    /// The theta_max and r(theta_max) of a parameter set.
    fn limits(k: [f64; 4]) -> (f64, f64) {
        let pi = std::f64::consts::PI;
        let [k1, k2, k3, k4] = k;
        let rp = |t: f64| {
            let t2 = t * t;
            1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)))
        };
        let r = |t: f64| {
            let t2 = t * t;
            t * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
        };
        // r'(theta) is a quartic in s = theta^2: 1 + 3 k1 s + 5 k2 s^2 + 7 k3 s^3 + 9 k4 s^4.
        let quartic = [1.0, 3.0 * k1, 5.0 * k2, 7.0 * k3, 9.0 * k4];
        let mut first = pi;
        match polynomial::roots(&quartic) {
            Ok(roots) => {
                for i in 0..roots.len {
                    let (re, im) = (roots.re[i], roots.im[i]);
                    if re > 0.0 && im.abs() <= NEAR_REAL * (1.0 + re) && re.sqrt() < first {
                        first = re.sqrt();
                    }
                }
            }
            Err(_) => {
                // The bounded iteration gave up: scan instead (4096 samples on [0, pi]).
                for i in 1..=4096 {
                    let t = pi * f64::from(i) / 4096.0;
                    if rp(t) <= 0.0 {
                        first = t;
                        break;
                    }
                }
            }
        }
        // Refine the fold to the last theta where r' > 0 (bisection on the sign of r').
        if first < pi {
            let (mut lo, mut hi) = (first * (1.0 - 1e-3), (first * (1.0 + 1e-3)).min(pi));
            if rp(lo) > 0.0 && rp(hi) <= 0.0 {
                for _ in 0..200 {
                    let mid = 0.5 * (lo + hi);
                    if mid <= lo || mid >= hi {
                        break;
                    }
                    if rp(mid) > 0.0 {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                first = lo;
            }
        }
        let theta_max = first.min(pi);
        (theta_max, r(theta_max))
    }

    /// Shared projection core: the pixel and the quantities the Jacobians reuse.
    #[inline]
    fn project_core(&self, p: &Vector3<f64>) -> Result<ProjectionCore, ProjectionError> {
        validate::finite_nonzero_point(p)?;
        let rho = fast_hypot(p.x, p.y);
        let theta = incidence_angle(rho, p.z);
        if theta > self.theta_max {
            return Err(ProjectionError::BeyondFold {
                theta,
                theta_max: self.theta_max,
            });
        }
        // theta / rho, with its limit 1/z on the positive axis.
        let theta_over_rho = if rho > 0.0 {
            theta / rho
        } else if p.z > 0.0 {
            1.0 / p.z
        } else {
            return Err(ProjectionError::OnNegativeAxis);
        };
        // g = r(theta) / rho.
        let g = self.radius_over_theta(theta) * theta_over_rho;
        let pixel = Vector2::new(
            self.mu() * p.x * g + self.u0(),
            self.mv() * p.y * g + self.v0(),
        );
        Ok(ProjectionCore {
            pixel,
            rho,
            theta,
            theta_over_rho,
            g,
        })
    }

    /// d pixel / d point from the projection core.
    #[inline]
    fn point_jacobian(&self, p: &Vector3<f64>, c: &ProjectionCore) -> Matrix2x3<f64> {
        let [k1, k2, k3, k4] = self.k();
        let t = c.theta;
        let t2 = t * t;
        // q = (d g / d rho) / rho = N(theta) / rho^3 with N = r' sin cos - r, written as
        // (N / theta^3) (theta / rho)^3 and N / theta^3 expanded so nothing cancels at theta = 0.
        // sin(2 theta) = 2 rho z / |P|^2: no trigonometric call.
        let a_over_t2 = 3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4));
        let b_over_t3 = k1 + t2 * (k2 + t2 * (k3 + t2 * k4));
        let n2 = p.norm_squared();
        let sin_2t = 2.0 * c.rho * p.z / n2;
        let n_over_t3 = a_over_t2 * sinc_with(2.0 * t, sin_2t)
            - b_over_t3
            - 4.0 * x_minus_sin_over_cube(2.0 * t, sin_2t);
        let tr = c.theta_over_rho;
        let q = n_over_t3 * tr * tr * tr;
        let g_z = -self.radius_derivative(t) / n2;
        let (x, y) = (p.x, p.y);
        let (mu, mv) = (self.mu(), self.mv());
        Matrix2x3::new(
            mu * (c.g + x * x * q),
            mu * x * y * q,
            mu * x * g_z,
            mv * x * y * q,
            mv * (c.g + y * y * q),
            mv * y * g_z,
        )
    }
}

/// sqrt(x^2 + y^2), falling back to the slower overflow-safe `hypot` only when the squares
/// overflow or underflow.
#[inline]
fn fast_hypot(x: f64, y: f64) -> f64 {
    let s = x * x + y * y;
    if s.is_finite() && s > f64::MIN_POSITIVE {
        s.sqrt()
    } else {
        x.hypot(y)
    }
}

/// `atan2(rho, z)` for `rho >= 0`, in `[0, pi]`, through `atan` of a ratio in `[-1, 1]` (half
/// the instructions of glibc's `atan2`; within one ulp of it). Exactly 0 and pi on the axis.
#[inline]
fn incidence_angle(rho: f64, z: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    if rho == 0.0 {
        return if z >= 0.0 { 0.0 } else { PI };
    }
    if z >= rho {
        (rho / z).atan()
    } else if -z >= rho {
        PI - (rho / -z).atan()
    } else {
        FRAC_PI_2 - (z / rho).atan()
    }
}

/// What projection computes once and the Jacobians reuse.
struct ProjectionCore {
    pixel: Vector2<f64>,
    /// sqrt(x^2 + y^2).
    rho: f64,
    theta: f64,
    theta_over_rho: f64,
    g: f64,
}

impl CameraModel for KannalaBrandt {
    crate::model::common_accessors!();

    fn principal_point(&self) -> Vector2<f64> {
        Vector2::new(self.u0(), self.v0())
    }

    fn set_params(&mut self, params: &[f64]) -> Result<(), ParameterError> {
        let p: [f64; 8] = validate::params(Self::MODEL_NAME, &Self::PARAM_NAMES, params)?;
        validate::positive("mu", p[4])?;
        validate::positive("mv", p[5])?;
        let (theta_max, max_radius) = Self::limits([p[0], p[1], p[2], p[3]]);
        self.params = p;
        self.theta_max = theta_max;
        self.max_radius = max_radius;
        Ok(())
    }

    #[inline]
    fn project(&self, p_cam: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError> {
        Ok(self.project_core(p_cam)?.pixel)
    }

    #[inline]
    fn project_with_point_jacobian(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<(Vector2<f64>, Matrix2x3<f64>), ProjectionError> {
        let c = self.project_core(p_cam)?;
        Ok((c.pixel, self.point_jacobian(p_cam, &c)))
    }

    #[inline]
    fn project_with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<ProjectionJacobians, ProjectionError> {
        let c = self.project_core(p_cam)?;
        let d_pixel_d_point = self.point_jacobian(p_cam, &c);
        let (x, y) = (p_cam.x, p_cam.y);
        let (mu, mv) = (self.mu(), self.mv());
        let mut jp = ParamJacobian::<2>::zeros();
        // d/dk_i of mu x r(theta) / rho = mu x theta^(2i+1) / rho = mu x theta^(2i) (theta/rho).
        let t2 = c.theta * c.theta;
        let mut pow = t2 * c.theta_over_rho;
        for i in 0..4 {
            jp[(0, i)] = mu * x * pow;
            jp[(1, i)] = mv * y * pow;
            pow *= t2;
        }
        jp[(0, 4)] = x * c.g;
        jp[(1, 5)] = y * c.g;
        jp[(0, 6)] = 1.0;
        jp[(1, 7)] = 1.0;
        Ok(ProjectionJacobians {
            pixel: c.pixel,
            d_pixel_d_point,
            d_pixel_d_params: jp,
        })
    }

    fn unproject(&self, pixel: &Vector2<f64>) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        let m = self.normalized(pixel)?;
        let d = fast_hypot(m.x, m.y);
        let theta = self.theta_from_radius(d)?;
        Ok(self.ray_from_theta(&m, theta))
    }

    #[inline]
    fn unproject_fast(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        let m = self.normalized(pixel)?;
        let d = fast_hypot(m.x, m.y);
        let theta = self.theta_from_radius_fast(d)?;
        Ok(self.ray_from_theta(&m, theta))
    }

    fn unproject_with_jacobians(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<UnprojectionJacobians, UnprojectionError> {
        let m = self.normalized(pixel)?;
        let d = m.norm();
        let t = self.theta_from_radius(d)?;
        let (sin_t, cos_t) = t.sin_cos();
        let ray = self.ray_from_sin_cos(&m, t, (sin_t, cos_t));
        let [k1, k2, k3, k4] = self.k();
        let t2 = t * t;
        let big_r = self.radius_over_theta(t);
        let rp = self.radius_derivative(t);
        let sc = sinc_with(t, sin_t);
        let s = sc / big_r;
        // S = sinc / R; S'/theta = ((sinc'/theta) R - sinc (R'/theta)) / R^2, all even series.
        let dsinc_over_t = -sin_minus_x_cos_over_cube(t, (sin_t, cos_t));
        let dr_over_t = 2.0 * k1 + t2 * (4.0 * k2 + t2 * (6.0 * k3 + t2 * 8.0 * k4));
        let ds_over_t = (dsinc_over_t * big_r - sc * dr_over_t) / (big_r * big_r);
        // Q = S'(theta) / (d r'(theta)) = (S'/theta) (theta / d) / r' with theta / d = 1 / R.
        let q = ds_over_t / (big_r * rp);
        let (mx, my) = (m.x, m.y);
        let d_ray_d_m = Matrix3x2::new(
            s + mx * mx * q,
            mx * my * q,
            mx * my * q,
            s + my * my * q,
            -s * mx / rp,
            -s * my / rp,
        );
        let (mu, mv) = (self.mu(), self.mv());
        let col_u = d_ray_d_m.column(0) / mu;
        let col_v = d_ray_d_m.column(1) / mv;
        let d_ray_d_pixel = Matrix3x2::from_columns(&[col_u, col_v]);
        let mut jp = ParamJacobian::<3>::zeros();
        // k_i: theta moves by -theta^(2i+1) / r', and S also depends on k_i through R.
        let mut pow = t2; // theta^(2i)
        for i in 0..4 {
            let dtheta = -pow * t / rp;
            let ds = t * ds_over_t * dtheta - sc * pow / (big_r * big_r);
            jp[(0, i)] = mx * ds;
            jp[(1, i)] = my * ds;
            jp[(2, i)] = -sin_t * dtheta;
            pow *= t2;
        }
        jp.set_column(4, &(col_u * (-mx)));
        jp.set_column(5, &(col_v * (-my)));
        jp.set_column(6, &(-col_u));
        jp.set_column(7, &(-col_v));
        Ok(UnprojectionJacobians {
            ray,
            d_ray_d_pixel,
            d_ray_d_params: jp,
        })
    }

    fn radians_per_pixel_at_center(&self) -> f64 {
        1.0 / self.mu().min(self.mv())
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use proptest::prelude::*;

    use super::incidence_angle;

    #[test]
    fn incidence_angle_is_exact_on_the_axis() {
        assert_eq!(incidence_angle(0.0, 2.0), 0.0);
        assert_eq!(incidence_angle(0.0, -2.0), PI);
        // The branch boundaries |z| = rho.
        assert_eq!(incidence_angle(1.0, 1.0), 1.0_f64.atan2(1.0));
        assert_eq!(incidence_angle(1.0, -1.0), 1.0_f64.atan2(-1.0));
    }

    proptest! {
        /// The `atan`-based incidence angle (the speed path of `project`) agrees with `atan2`
        /// to a few ulps over the whole sphere, all three branches and both signs of z.
        #[test]
        fn incidence_angle_matches_atan2(theta in 0.0..PI, scale in 1e-3..1e3f64) {
            let (rho, z) = (scale * theta.sin(), scale * theta.cos());
            let want = rho.atan2(z);
            let got = incidence_angle(rho, z);
            prop_assert!((got - want).abs() <= 4.0 * f64::EPSILON * want, "{got} vs {want}");
        }
    }
}
