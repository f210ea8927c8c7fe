//! The unified (Mei) omnidirectional camera model with radial-tangential distortion.
//!
//! C. Mei and P. Rives, "Single view point omnidirectional camera calibration from planar
//! grids", ICRA 2007 (after C. Geyer and K. Daniilidis, "A unifying theory for central
//! panoramic systems", ECCV 2000). CamOdoCal calls it `MEI` (`CataCamera`); Kalibr calls it
//! `omni` + `radtan` (or `omni` + `none`).

use nalgebra::{Matrix2x3, Matrix3x2, Unit, Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError, UnprojectionError};
use crate::model::{CameraModel, ParamJacobian, ProjectionJacobians, UnprojectionJacobians};
use crate::radtan::{self, Radtan};
use crate::validate;

/// The unified projection model with radial-tangential distortion (9 parameters).
///
/// For a point `P = (x, y, z)` of the camera frame, projected on the unit sphere and then
/// from a centre `xi` above the sphere's centre:
///
/// ```text
/// (mx, my) = (x, y) / (z + xi |P|)
/// (xd, yd) = D(mx, my)            radial-tangential distortion [k1, k2, p1, p2]
/// u = gamma1 xd + u0,   v = gamma2 yd + v0
/// ```
///
/// Parameters, in CamOdoCal order: `[xi, k1, k2, p1, p2, gamma1, gamma2, u0, v0]` (Kalibr's
/// `omni` `intrinsics` are `[xi, gamma1, gamma2, u0, v0]`).
///
/// **Valid domain.** Points with `z > -w |P|`, where `w = xi` for `xi <= 1` and `w = 1 / xi`
/// for `xi > 1`: for `xi <= 1` the denominator `z + xi |P|` must be positive; for `xi > 1` it
/// always is, but the map from the sphere to the plane folds at `z = -|P| / xi`, so two points
/// would share a pixel past it. `xi = 0` is the pinhole (`z > 0`). In addition, the undistorted
/// point must lie within the distortion's injective radius (see
/// [`PinholeRadtan`](crate::PinholeRadtan)). Unprojection needs `r^2 = mx^2 + my^2 <=
/// 1 / (xi^2 - 1)` when `xi > 1` (the image of the fold), and lifts the undistorted point
/// to the sphere in closed form:
///
/// ```text
/// f = (xi + sqrt(1 + (1 - xi^2) r^2)) / (1 + r^2)
/// ray = (f mx, f my, f - xi)     a unit vector; f - xi is computed as
///                                (sqrt(1 + (1 - xi^2) r^2) - xi r^2) / (1 + r^2)
/// ```
///
/// The distortion is inverted by Newton's method with the analytic 2x2 Jacobian and a
/// convergence test (as for [`PinholeRadtan`](crate::PinholeRadtan)).
#[derive(Clone, Debug, PartialEq)]
pub struct Unified {
    width: u32,
    height: u32,
    params: [f64; 9],
    injective_radius: f64,
}

impl Unified {
    /// Number of parameters.
    pub const NUM_PARAMS: usize = 9;
    /// Parameter names, CamOdoCal order.
    pub const PARAM_NAMES: [&'static str; 9] =
        ["xi", "k1", "k2", "p1", "p2", "gamma1", "gamma2", "u0", "v0"];
    /// The model's name.
    pub const MODEL_NAME: &'static str = "unified";

    /// A camera of `width x height` pixels with parameters
    /// `[xi, k1, k2, p1, p2, gamma1, gamma2, u0, v0]`.
    ///
    /// # Errors
    /// [`ParameterError`] if a parameter is not finite, `xi` is negative, `gamma1` or `gamma2`
    /// is not positive, or the image is empty.
    pub fn new(width: u32, height: u32, params: [f64; 9]) -> Result<Self, ParameterError> {
        validate::image_size(width, height)?;
        let mut cam = Self {
            width,
            height,
            params: [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
            injective_radius: f64::INFINITY,
        };
        cam.set_params(&params)?;
        Ok(cam)
    }

    /// The parameters `[xi, k1, k2, p1, p2, gamma1, gamma2, u0, v0]`.
    pub fn params_array(&self) -> [f64; 9] {
        self.params
    }

    /// The mirror parameter xi.
    pub fn xi(&self) -> f64 {
        self.params[0]
    }

    /// The distortion coefficients `[k1, k2, p1, p2]`.
    pub fn distortion(&self) -> [f64; 4] {
        [
            self.params[1],
            self.params[2],
            self.params[3],
            self.params[4],
        ]
    }

    /// Generalized focal length, horizontal (pixels).
    pub fn gamma1(&self) -> f64 {
        self.params[5]
    }

    /// Generalized focal length, vertical (pixels).
    pub fn gamma2(&self) -> f64 {
        self.params[6]
    }

    /// Principal point, horizontal (pixels).
    pub fn u0(&self) -> f64 {
        self.params[7]
    }

    /// Principal point, vertical (pixels).
    pub fn v0(&self) -> f64 {
        self.params[8]
    }

    /// The bound `-w` that `z / |P|` must exceed: `-xi` for `xi <= 1`, `-1 / xi` for `xi > 1`.
    pub fn cos_theta_limit(&self) -> f64 {
        let xi = self.xi();
        if xi <= 1.0 { -xi } else { -1.0 / xi }
    }

    /// The distortion's injective radius in normalized units (infinite if it never folds).
    pub fn injective_radius(&self) -> f64 {
        self.injective_radius
    }

    #[inline]
    fn radtan(&self) -> Radtan {
        Radtan::from_slice(&self.params[1..5])
    }

    /// The undistorted normalized point of a point in the domain, with `|P|` and the
    /// denominator `z + xi |P|`.
    #[inline]
    fn normalized(&self, p: &Vector3<f64>) -> Result<(Vector2<f64>, f64, f64), ProjectionError> {
        validate::finite_nonzero_point(p)?;
        let n = p.norm();
        let cos_theta = p.z / n;
        let limit = self.cos_theta_limit();
        if cos_theta <= limit {
            return Err(ProjectionError::OutsideMeiDomain { cos_theta, limit });
        }
        let den = p.z + self.xi() * n;
        if den <= 0.0 {
            return Err(ProjectionError::OutsideMeiDomain { cos_theta, limit });
        }
        let m = Vector2::new(p.x / den, p.y / den);
        if let Err(radius) = validate::within_radius(&m, self.injective_radius) {
            return Err(ProjectionError::BeyondInjectiveRadius {
                radius,
                injective_radius: self.injective_radius,
            });
        }
        Ok((m, n, den))
    }

    /// The undistorted point of a pixel with the distorted one, dD/dm, r^2 and the root
    /// `sqrt(1 + (1 - xi^2) r^2)`.
    #[inline]
    fn undistorted(&self, pixel: &Vector2<f64>) -> Result<Undistorted, UnprojectionError> {
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            return Err(UnprojectionError::NonFinitePixel);
        }
        let md = Vector2::new(
            (pixel.x - self.u0()) / self.gamma1(),
            (pixel.y - self.v0()) / self.gamma2(),
        );
        let (m, j_d) = self.radtan().undistort(&md, self.injective_radius)?;
        if let Err(radius) = validate::within_radius(&m, self.injective_radius) {
            return Err(UnprojectionError::BeyondInjectiveRadius {
                radius,
                injective_radius: self.injective_radius,
            });
        }
        let r2 = m.norm_squared();
        let xi = self.xi();
        let q = 1.0 + (1.0 - xi * xi) * r2;
        if q < 0.0 {
            return Err(UnprojectionError::OutsideMeiDomain {
                r2,
                max_r2: 1.0 / (xi * xi - 1.0),
            });
        }
        Ok(Undistorted {
            m,
            md,
            j_d,
            r2,
            sq: q.sqrt(),
        })
    }

    /// The unit ray of an undistorted point (the lift to the sphere).
    #[inline]
    fn lift(&self, u: &Undistorted) -> Unit<Vector3<f64>> {
        let xi = self.xi();
        let inv = 1.0 / (1.0 + u.r2);
        let f = (xi + u.sq) * inv;
        let z = (u.sq - xi * u.r2) * inv;
        Unit::new_normalize(Vector3::new(f * u.m.x, f * u.m.y, z))
    }
}

/// The undistortion result that the lift and its Jacobians share.
struct Undistorted {
    m: Vector2<f64>,
    md: Vector2<f64>,
    j_d: nalgebra::Matrix2<f64>,
    r2: f64,
    sq: f64,
}

impl CameraModel for Unified {
    crate::model::common_accessors!();

    fn principal_point(&self) -> Vector2<f64> {
        Vector2::new(self.u0(), self.v0())
    }

    fn set_params(&mut self, params: &[f64]) -> Result<(), ParameterError> {
        let p: [f64; 9] = validate::params(Self::MODEL_NAME, &Self::PARAM_NAMES, params)?;
        validate::non_negative("xi", p[0])?;
        validate::positive("gamma1", p[5])?;
        validate::positive("gamma2", p[6])?;
        self.injective_radius = Radtan::from_slice(&p[1..5]).injective_radius();
        self.params = p;
        Ok(())
    }

    #[inline]
    fn project(&self, p_cam: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError> {
        let (m, _, _) = self.normalized(p_cam)?;
        let md = self.radtan().distort(&m);
        Ok(Vector2::new(
            self.gamma1() * md.x + self.u0(),
            self.gamma2() * md.y + self.v0(),
        ))
    }

    #[inline]
    fn project_with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<ProjectionJacobians, ProjectionError> {
        let (m, n, den) = self.normalized(p_cam)?;
        let (md, j_d) = self.radtan().distort_with_jacobian(&m);
        let xi = self.xi();
        let (x, y, z) = (p_cam.x, p_cam.y, p_cam.z);
        // m = (x, y) / den with den = z + xi |P|; d den / dP = (xi x/n, xi y/n, 1 + xi z/n).
        // (Two divisions, 1/n and 1/den; the divider is what limits this function's speed.)
        let xi_over_n = xi / n;
        let dden = Vector3::new(xi_over_n * x, xi_over_n * y, 1.0 + xi_over_n * z);
        let iden = 1.0 / den;
        let (mx, my) = (m.x * iden, m.y * iden);
        let dm_dp = Matrix2x3::new(
            iden - mx * dden.x,
            -mx * dden.y,
            -mx * dden.z,
            -my * dden.x,
            iden - my * dden.y,
            -my * dden.z,
        );
        let (g1, g2) = (self.gamma1(), self.gamma2());
        let mut jp = radtan::projection_param_jacobian((1, 5), (g1, g2), &m, &md);
        let d_pixel_d_point = radtan::scale_rows(j_d * dm_dp, (g1, g2));
        // d m / d xi = -m |P| / den.
        let dm_dxi = -m * (n * iden);
        let d_xi = j_d * dm_dxi;
        jp[(0, 0)] = g1 * d_xi.x;
        jp[(1, 0)] = g2 * d_xi.y;
        Ok(ProjectionJacobians {
            pixel: Vector2::new(g1 * md.x + self.u0(), g2 * md.y + self.v0()),
            d_pixel_d_point,
            d_pixel_d_params: jp,
        })
    }

    #[inline]
    fn unproject(&self, pixel: &Vector2<f64>) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        let u = self.undistorted(pixel)?;
        Ok(self.lift(&u))
    }

    fn unproject_with_jacobians(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<UnprojectionJacobians, UnprojectionError> {
        let u = self.undistorted(pixel)?;
        let ray = self.lift(&u);
        let xi = self.xi();
        let (mx, my) = (u.m.x, u.m.y);
        let inv = 1.0 / (1.0 + u.r2);
        let f = (xi + u.sq) * inv;
        // df/dr2 = ((1 - xi^2) / (2 sq) (1 + r2) - (xi + sq)) / (1 + r2)^2.
        let df_dr2 = ((1.0 - xi * xi) / (2.0 * u.sq) - f) * inv;
        let (dfx, dfy) = (2.0 * mx * df_dr2, 2.0 * my * df_dr2);
        let l = Matrix3x2::new(f + mx * dfx, mx * dfy, my * dfx, f + my * dfy, dfx, dfy);
        let mut jp = ParamJacobian::<3>::zeros();
        let d_ray_d_pixel = radtan::chain_unprojection(
            (1, 5),
            (self.gamma1(), self.gamma2()),
            &u.m,
            &u.md,
            &u.j_d,
            &l,
            &mut jp,
        )?;
        // df/dxi = (1 - xi r2 / sq) / (1 + r2); ray = (f mx, f my, f - xi).
        let df_dxi = (1.0 - xi * u.r2 / u.sq) * inv;
        jp.set_column(0, &Vector3::new(mx * df_dxi, my * df_dxi, df_dxi - 1.0));
        Ok(UnprojectionJacobians {
            ray,
            d_ray_d_pixel,
            d_ray_d_params: jp,
        })
    }

    fn radians_per_pixel_at_center(&self) -> f64 {
        (1.0 + self.xi()) / self.gamma1().min(self.gamma2())
    }
}
