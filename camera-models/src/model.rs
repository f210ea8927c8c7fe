//! The [`CameraModel`] trait shared by every model and by the [`Camera`](crate::Camera) enum.

use nalgebra::{Matrix2x3, Matrix3x2, SMatrix, Unit, Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError, UnprojectionError};

/// The largest parameter count of any model (the unified model has 9).
pub const MAX_PARAMS: usize = 9;

/// A Jacobian with respect to the parameters: `R` rows, [`MAX_PARAMS`] columns, on the stack.
///
/// Column `j < num_params()` is the derivative with respect to parameter `j` in the model's
/// CamOdoCal order; columns from `num_params()` on are zero. Generic code takes the first
/// columns with `jac.columns(0, camera.num_params())` (a view, no copy), concrete code with
/// `jac.fixed_columns::<8>(0)`.
pub type ParamJacobian<const R: usize> = SMatrix<f64, R, MAX_PARAMS>;

/// A pixel with its derivatives, from [`CameraModel::project_with_jacobians`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProjectionJacobians {
    /// The pixel `(u, v)`.
    pub pixel: Vector2<f64>,
    /// d pixel / d point (2x3), the point in the camera frame.
    pub d_pixel_d_point: Matrix2x3<f64>,
    /// d pixel / d params (2 x [`MAX_PARAMS`], zero beyond `num_params()`).
    pub d_pixel_d_params: ParamJacobian<2>,
}

/// A unit ray with its derivatives, from [`CameraModel::unproject_with_jacobians`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnprojectionJacobians {
    /// The unit ray in the camera frame.
    pub ray: Unit<Vector3<f64>>,
    /// d ray / d pixel (3x2).
    pub d_ray_d_pixel: Matrix3x2<f64>,
    /// d ray / d params (3 x [`MAX_PARAMS`], zero beyond `num_params()`).
    pub d_ray_d_params: ParamJacobian<3>,
}

/// A calibrated central camera: the map between points in its frame and pixels.
///
/// Conventions, for every model:
/// - The camera frame has z along the optical axis, x to the right and y down the image.
///   Points are given in that frame (`camera_from_world * X_world`).
/// - Pixel centres are at integer coordinates: pixel `(0, 0)` covers `[-0.5, 0.5]^2`, and the
///   image covers `[-0.5, width - 0.5] x [-0.5, height - 0.5]` (OpenCV, Kalibr, CamOdoCal).
/// - Projection works on directions: `project(s * p) == project(p)` for `s > 0`. Whether the
///   pixel falls inside the image is a separate question ([`in_image`](Self::in_image)).
/// - Unprojection returns a unit ray, never a z = 1 point, so rays beyond 90 degrees of
///   incidence are represented.
/// - Parameters are in CamOdoCal order (see each model) and are validated when set; the derived
///   limits (Kannala-Brandt fold, radial-tangential injective radius) are recomputed then, not
///   per point.
/// - Nothing allocates on the heap: Jacobians are fixed-size stack matrices.
pub trait CameraModel {
    /// The model's name (`"kannala_brandt"`, `"pinhole_radtan"` or `"unified"`).
    fn model_name(&self) -> &'static str;

    /// Image width in pixels.
    fn width(&self) -> u32;

    /// Image height in pixels.
    fn height(&self) -> u32;

    /// Whether a pixel lies in the image, `[-0.5, width - 0.5] x [-0.5, height - 0.5]`
    /// (pixel centres at integers). False for non-finite pixels.
    fn in_image(&self, pixel: &Vector2<f64>) -> bool {
        let w = f64::from(self.width());
        let h = f64::from(self.height());
        pixel.x >= -0.5 && pixel.x <= w - 0.5 && pixel.y >= -0.5 && pixel.y <= h - 0.5
    }

    /// The principal point (the image of the optical axis) in pixels.
    fn principal_point(&self) -> Vector2<f64>;

    /// Number of parameters `N` (8 or 9).
    fn num_params(&self) -> usize;

    /// Parameter names in order (CamOdoCal order).
    fn param_names(&self) -> &'static [&'static str];

    /// The parameter vector, CamOdoCal order, length [`num_params`](Self::num_params).
    fn params(&self) -> &[f64];

    /// Indices (CamOdoCal order) of the two focal-length parameters, horizontal then
    /// vertical: every model's parameter vector ends with them and the principal point
    /// (Kannala-Brandt `mu, mv`, pinhole `fx, fy`, unified `gamma1, gamma2`).
    fn focal_length_indices(&self) -> [usize; 2] {
        let n = self.num_params();
        [n - 4, n - 3]
    }

    /// Indices (CamOdoCal order) of the principal point's two coordinates (`u0, v0` or
    /// `cx, cy`), the last two parameters of every model.
    fn principal_point_indices(&self) -> [usize; 2] {
        let n = self.num_params();
        [n - 2, n - 1]
    }

    /// Replace the parameter vector (CamOdoCal order) after validating it, and recompute the
    /// derived limits. On error the camera is unchanged.
    ///
    /// # Errors
    /// [`ParameterError`] if the length is wrong, a value is not finite, a focal length is not
    /// positive, or xi is negative.
    fn set_params(&mut self, params: &[f64]) -> Result<(), ParameterError>;

    /// Project a point of the camera frame to a pixel.
    ///
    /// # Errors
    /// [`ProjectionError`] when the point is outside the model's valid domain (see the model's
    /// documentation), is zero or is not finite.
    fn project(&self, p_cam: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError>;

    /// Project and return d pixel / d point (2x3), for refinements that keep the intrinsics
    /// fixed.
    ///
    /// # Errors
    /// As [`project`](Self::project).
    fn project_with_point_jacobian(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<(Vector2<f64>, Matrix2x3<f64>), ProjectionError> {
        let j = self.project_with_jacobians(p_cam)?;
        Ok((j.pixel, j.d_pixel_d_point))
    }

    /// Project and return d pixel / d point (2x3) and d pixel / d params (2xN).
    ///
    /// # Errors
    /// As [`project`](Self::project).
    fn project_with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<ProjectionJacobians, ProjectionError>;

    /// The unit ray of a pixel.
    ///
    /// # Errors
    /// [`UnprojectionError`] when no ray of the valid domain maps to the pixel, when an
    /// iteration does not converge, or when the pixel is not finite.
    fn unproject(&self, pixel: &Vector2<f64>) -> Result<Unit<Vector3<f64>>, UnprojectionError>;

    /// The unit ray of a pixel by the model's fastest exact method, for look-up tables and hot
    /// loops. It agrees with [`unproject`](Self::unproject) to 1e-12 rad; only Kannala-Brandt
    /// differs in method (safeguarded Newton-bisection instead of the companion matrix).
    ///
    /// # Errors
    /// As [`unproject`](Self::unproject).
    fn unproject_fast(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        self.unproject(pixel)
    }

    /// Unproject and return d ray / d pixel (3x2).
    ///
    /// # Errors
    /// As [`unproject`](Self::unproject).
    fn unproject_with_pixel_jacobian(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<(Unit<Vector3<f64>>, Matrix3x2<f64>), UnprojectionError> {
        let j = self.unproject_with_jacobians(pixel)?;
        Ok((j.ray, j.d_ray_d_pixel))
    }

    /// Unproject and return d ray / d pixel (3x2) and d ray / d params (3xN).
    ///
    /// # Errors
    /// As [`unproject`](Self::unproject).
    fn unproject_with_jacobians(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<UnprojectionJacobians, UnprojectionError>;

    /// The angle (radians) that one pixel spans at `pixel`, in the direction where it spans
    /// the most: the largest singular value of d ray / d pixel. Multiply a pixel threshold by
    /// it to get an angular threshold for bearing-vector solvers.
    ///
    /// # Errors
    /// As [`unproject`](Self::unproject).
    fn radians_per_pixel(&self, pixel: &Vector2<f64>) -> Result<f64, UnprojectionError> {
        let (_, j) = self.unproject_with_pixel_jacobian(pixel)?;
        Ok(largest_singular_value(&j))
    }

    /// [`radians_per_pixel`](Self::radians_per_pixel) at the principal point: `1 / f` for the
    /// smaller focal length `f` of the model there (`mu`, `fx`, `gamma / (1 + xi)`, ...). A
    /// camera-wide conversion of pixel thresholds into angles that never fails.
    fn radians_per_pixel_at_center(&self) -> f64;
}

/// The [`CameraModel`] accessors every model implements the same way (from its `width`,
/// `height` and `params` fields and its `MODEL_NAME`, `NUM_PARAMS`, `PARAM_NAMES` constants).
macro_rules! common_accessors {
    () => {
        fn model_name(&self) -> &'static str {
            Self::MODEL_NAME
        }

        fn width(&self) -> u32 {
            self.width
        }

        fn height(&self) -> u32 {
            self.height
        }

        fn num_params(&self) -> usize {
            Self::NUM_PARAMS
        }

        fn param_names(&self) -> &'static [&'static str] {
            &Self::PARAM_NAMES
        }

        fn params(&self) -> &[f64] {
            &self.params
        }
    };
}
pub(crate) use common_accessors;

/// Largest singular value of a 3x2 matrix: the square root of the largest eigenvalue of the
/// 2x2 Gram matrix `J^T J`, in closed form.
pub(crate) fn largest_singular_value(j: &Matrix3x2<f64>) -> f64 {
    let g = j.transpose() * j;
    let (a, b, d) = (g[(0, 0)], g[(0, 1)], g[(1, 1)]);
    let half_trace = 0.5 * (a + d);
    let disc = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    (half_trace + disc).max(0.0).sqrt()
}
