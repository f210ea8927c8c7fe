//! The pinhole camera with radial-tangential distortion.
//!
//! D. C. Brown, "Decentering distortion of lenses", Photogrammetric Engineering 32(3), 1966;
//! the form of OpenCV, Kalibr (`pinhole` + `radtan`) and CamOdoCal (`PINHOLE`).

use nalgebra::{Matrix2x3, Matrix3, Unit, Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError, UnprojectionError};
use crate::model::{CameraModel, ParamJacobian, ProjectionJacobians, UnprojectionJacobians};
use crate::radtan::{self, Radtan};
use crate::validate;

/// Pinhole projection followed by radial-tangential distortion (8 parameters).
///
/// For a point `P = (x, y, z)` of the camera frame with `z > 0`:
///
/// ```text
/// (mx, my) = (x / z, y / z),   r^2 = mx^2 + my^2,   a = 1 + k1 r^2 + k2 r^4
/// xd = a mx + 2 p1 mx my + p2 (r^2 + 2 mx^2)
/// yd = a my + p1 (r^2 + 2 my^2) + 2 p2 mx my
/// u = fx xd + cx,   v = fy yd + cy
/// ```
///
/// Parameters, in CamOdoCal order: `[k1, k2, p1, p2, fx, fy, cx, cy]` (Kalibr's `intrinsics`
/// are `[fx, fy, cx, cy]` and its `radtan` `distortion_coeffs` `[k1, k2, p1, p2]`, OpenCV's
/// first four coefficients).
///
/// **Valid domain.** Points with `z > 0` whose normalized radius `r = |(mx, my)|` is below the
/// distortion's injective radius: the largest radius of a disc around the axis on which the
/// Jacobian determinant of the distortion stays positive (computed when the parameters are
/// set, [`injective_radius`](Self::injective_radius); infinite when the determinant never
/// vanishes, as for most real lenses). Beyond it the distortion folds back and pixels have
/// several rays.
///
/// **Unprojection** inverts the distortion by Newton's method with the analytic 2x2 Jacobian,
/// started at the distorted point, with step halving and a residual test at 4 eps; the ray is
/// `(mx, my, 1)` normalized. Non-convergence is an error, never a silently wrong point.
#[derive(Clone, Debug, PartialEq)]
pub struct PinholeRadtan {
    width: u32,
    height: u32,
    params: [f64; 8],
    injective_radius: f64,
}

impl PinholeRadtan {
    /// Number of parameters.
    pub const NUM_PARAMS: usize = 8;
    /// Parameter names, CamOdoCal order.
    pub const PARAM_NAMES: [&'static str; 8] = ["k1", "k2", "p1", "p2", "fx", "fy", "cx", "cy"];
    /// The model's name.
    pub const MODEL_NAME: &'static str = "pinhole_radtan";

    /// A camera of `width x height` pixels with parameters `[k1, k2, p1, p2, fx, fy, cx, cy]`.
    ///
    /// # Errors
    /// [`ParameterError`] if a parameter is not finite, `fx` or `fy` is not positive, or the
    /// image is empty.
    pub fn new(width: u32, height: u32, params: [f64; 8]) -> Result<Self, ParameterError> {
        validate::image_size(width, height)?;
        let mut cam = Self {
            width,
            height,
            params: [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
            injective_radius: f64::INFINITY,
        };
        cam.set_params(&params)?;
        Ok(cam)
    }

    /// The parameters `[k1, k2, p1, p2, fx, fy, cx, cy]`.
    pub fn params_array(&self) -> [f64; 8] {
        self.params
    }

    /// The distortion coefficients `[k1, k2, p1, p2]`.
    pub fn distortion(&self) -> [f64; 4] {
        [
            self.params[0],
            self.params[1],
            self.params[2],
            self.params[3],
        ]
    }

    /// Focal length, horizontal (pixels).
    pub fn fx(&self) -> f64 {
        self.params[4]
    }

    /// Focal length, vertical (pixels).
    pub fn fy(&self) -> f64 {
        self.params[5]
    }

    /// Principal point, horizontal (pixels).
    pub fn cx(&self) -> f64 {
        self.params[6]
    }

    /// Principal point, vertical (pixels).
    pub fn cy(&self) -> f64 {
        self.params[7]
    }

    /// The distortion's injective radius in normalized (z = 1) units; infinite if the
    /// distortion never folds.
    pub fn injective_radius(&self) -> f64 {
        self.injective_radius
    }

    #[inline]
    fn radtan(&self) -> Radtan {
        Radtan::from_slice(&self.params[0..4])
    }

    /// The normalized point (x / z, y / z) of a point in front of the camera.
    #[inline]
    fn normalized(&self, p: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError> {
        validate::finite_nonzero_point(p)?;
        if p.z <= 0.0 {
            return Err(ProjectionError::BehindCamera { z: p.z });
        }
        let m = Vector2::new(p.x / p.z, p.y / p.z);
        if let Err(radius) = validate::within_radius(&m, self.injective_radius) {
            return Err(ProjectionError::BeyondInjectiveRadius {
                radius,
                injective_radius: self.injective_radius,
            });
        }
        Ok(m)
    }

    /// Undistorted normalized point of a pixel, with the distorted one and dD/dm there.
    #[inline]
    fn undistorted(&self, pixel: &Vector2<f64>) -> Result<Undistorted, UnprojectionError> {
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            return Err(UnprojectionError::NonFinitePixel);
        }
        let md = Vector2::new(
            (pixel.x - self.cx()) / self.fx(),
            (pixel.y - self.cy()) / self.fy(),
        );
        let (m, j) = self.radtan().undistort(&md, self.injective_radius)?;
        if let Err(radius) = validate::within_radius(&m, self.injective_radius) {
            return Err(UnprojectionError::BeyondInjectiveRadius {
                radius,
                injective_radius: self.injective_radius,
            });
        }
        Ok((m, md, j))
    }
}

/// Undistorted point, distorted point, and dD/dm at the undistorted point.
type Undistorted = (Vector2<f64>, Vector2<f64>, nalgebra::Matrix2<f64>);

impl CameraModel for PinholeRadtan {
    crate::model::common_accessors!();

    fn principal_point(&self) -> Vector2<f64> {
        Vector2::new(self.cx(), self.cy())
    }

    fn set_params(&mut self, params: &[f64]) -> Result<(), ParameterError> {
        let p: [f64; 8] = validate::params(Self::MODEL_NAME, &Self::PARAM_NAMES, params)?;
        validate::positive("fx", p[4])?;
        validate::positive("fy", p[5])?;
        self.injective_radius = Radtan::from_slice(&p[0..4]).injective_radius();
        self.params = p;
        Ok(())
    }

    #[inline]
    fn project(&self, p_cam: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError> {
        let md = self.radtan().distort(&self.normalized(p_cam)?);
        Ok(Vector2::new(
            self.fx() * md.x + self.cx(),
            self.fy() * md.y + self.cy(),
        ))
    }

    #[inline]
    fn project_with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<ProjectionJacobians, ProjectionError> {
        let m = self.normalized(p_cam)?;
        let (md, j_d) = self.radtan().distort_with_jacobian(&m);
        // diag(fx, fy) J_D dm/dp with dm/dp = (1 / z) [[1, 0, -mx], [0, 1, -my]], written out.
        let iz = 1.0 / p_cam.z;
        let (s0, s1) = (self.fx() * iz, self.fy() * iz);
        let (j00, j01, j10, j11) = (j_d[(0, 0)], j_d[(0, 1)], j_d[(1, 0)], j_d[(1, 1)]);
        let d_pixel_d_point = Matrix2x3::new(
            s0 * j00,
            s0 * j01,
            -s0 * (j00 * m.x + j01 * m.y),
            s1 * j10,
            s1 * j11,
            -s1 * (j10 * m.x + j11 * m.y),
        );
        let jp = radtan::projection_param_jacobian((0, 4), (self.fx(), self.fy()), &m, &md);
        Ok(ProjectionJacobians {
            pixel: Vector2::new(self.fx() * md.x + self.cx(), self.fy() * md.y + self.cy()),
            d_pixel_d_point,
            d_pixel_d_params: jp,
        })
    }

    #[inline]
    fn unproject(&self, pixel: &Vector2<f64>) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        let (m, _, _) = self.undistorted(pixel)?;
        Ok(Unit::new_normalize(Vector3::new(m.x, m.y, 1.0)))
    }

    fn unproject_with_jacobians(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<UnprojectionJacobians, UnprojectionError> {
        let (m, md, j_d) = self.undistorted(pixel)?;
        let w = Vector3::new(m.x, m.y, 1.0);
        let n = w.norm();
        let ray = Unit::new_unchecked(w / n);
        // d (w / |w|) / d w = (I - ray ray^T) / |w|; w depends on m through its first two rows.
        let d_ray_d_w = (Matrix3::identity() - ray.as_ref() * ray.transpose()) / n;
        let l = d_ray_d_w.fixed_columns::<2>(0).into_owned();
        let mut jp = ParamJacobian::<3>::zeros();
        let d_ray_d_pixel =
            radtan::chain_unprojection((0, 4), (self.fx(), self.fy()), &m, &md, &j_d, &l, &mut jp)?;
        Ok(UnprojectionJacobians {
            ray,
            d_ray_d_pixel,
            d_ray_d_params: jp,
        })
    }

    fn radians_per_pixel_at_center(&self) -> f64 {
        1.0 / self.fx().min(self.fy())
    }
}
