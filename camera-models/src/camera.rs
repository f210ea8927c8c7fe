//! The [`Camera`] enum: a model chosen at run time (from a file, say).

use nalgebra::{Matrix2x3, Matrix3x2, Unit, Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError, UnprojectionError};
use crate::model::{CameraModel, ProjectionJacobians, UnprojectionJacobians};
use crate::{KannalaBrandt, PinholeRadtan, Unified};

/// Any of the three models. It implements [`CameraModel`] by delegating, so code written for
/// `C: CameraModel` works with it too, and every operation of the models is available without
/// knowing which one was loaded.
///
/// With the `serde` feature it is internally tagged by `model`:
/// `{"model": "kannala_brandt", "width": 1280, "height": 800, "k1": ..., "v0": ...}`.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(tag = "model", rename_all = "snake_case")
)]
#[non_exhaustive]
pub enum Camera {
    /// [`KannalaBrandt`] (CamOdoCal `KANNALA_BRANDT`, Kalibr `pinhole` + `equidistant`).
    KannalaBrandt(KannalaBrandt),
    /// [`PinholeRadtan`] (CamOdoCal `PINHOLE`, Kalibr `pinhole` + `radtan`).
    PinholeRadtan(PinholeRadtan),
    /// [`Unified`] (CamOdoCal `MEI`, Kalibr `omni` + `radtan`).
    Unified(Unified),
}

impl From<KannalaBrandt> for Camera {
    fn from(c: KannalaBrandt) -> Self {
        Self::KannalaBrandt(c)
    }
}

impl From<PinholeRadtan> for Camera {
    fn from(c: PinholeRadtan) -> Self {
        Self::PinholeRadtan(c)
    }
}

impl From<Unified> for Camera {
    fn from(c: Unified) -> Self {
        Self::Unified(c)
    }
}

/// Calls `$body` with `$c` bound to the inner model.
macro_rules! each {
    ($self:expr, $c:ident => $body:expr) => {
        match $self {
            Camera::KannalaBrandt($c) => $body,
            Camera::PinholeRadtan($c) => $body,
            Camera::Unified($c) => $body,
        }
    };
}

impl Camera {
    /// The inner Kannala-Brandt model, if it is one.
    pub fn as_kannala_brandt(&self) -> Option<&KannalaBrandt> {
        match self {
            Self::KannalaBrandt(c) => Some(c),
            _ => None,
        }
    }

    /// The inner pinhole model, if it is one.
    pub fn as_pinhole_radtan(&self) -> Option<&PinholeRadtan> {
        match self {
            Self::PinholeRadtan(c) => Some(c),
            _ => None,
        }
    }

    /// The inner unified model, if it is one.
    pub fn as_unified(&self) -> Option<&Unified> {
        match self {
            Self::Unified(c) => Some(c),
            _ => None,
        }
    }
}

impl CameraModel for Camera {
    fn model_name(&self) -> &'static str {
        each!(self, c => c.model_name())
    }

    fn width(&self) -> u32 {
        each!(self, c => c.width())
    }

    fn height(&self) -> u32 {
        each!(self, c => c.height())
    }

    fn principal_point(&self) -> Vector2<f64> {
        each!(self, c => c.principal_point())
    }

    fn num_params(&self) -> usize {
        each!(self, c => c.num_params())
    }

    fn param_names(&self) -> &'static [&'static str] {
        each!(self, c => c.param_names())
    }

    fn params(&self) -> &[f64] {
        each!(self, c => c.params())
    }

    fn set_params(&mut self, params: &[f64]) -> Result<(), ParameterError> {
        each!(self, c => c.set_params(params))
    }

    #[inline]
    fn project(&self, p_cam: &Vector3<f64>) -> Result<Vector2<f64>, ProjectionError> {
        each!(self, c => c.project(p_cam))
    }

    #[inline]
    fn project_with_point_jacobian(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<(Vector2<f64>, Matrix2x3<f64>), ProjectionError> {
        each!(self, c => c.project_with_point_jacobian(p_cam))
    }

    #[inline]
    fn project_with_jacobians(
        &self,
        p_cam: &Vector3<f64>,
    ) -> Result<ProjectionJacobians, ProjectionError> {
        each!(self, c => c.project_with_jacobians(p_cam))
    }

    #[inline]
    fn unproject(&self, pixel: &Vector2<f64>) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        each!(self, c => c.unproject(pixel))
    }

    #[inline]
    fn unproject_fast(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<Unit<Vector3<f64>>, UnprojectionError> {
        each!(self, c => c.unproject_fast(pixel))
    }

    fn unproject_with_pixel_jacobian(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<(Unit<Vector3<f64>>, Matrix3x2<f64>), UnprojectionError> {
        each!(self, c => c.unproject_with_pixel_jacobian(pixel))
    }

    fn unproject_with_jacobians(
        &self,
        pixel: &Vector2<f64>,
    ) -> Result<UnprojectionJacobians, UnprojectionError> {
        each!(self, c => c.unproject_with_jacobians(pixel))
    }

    fn radians_per_pixel(&self, pixel: &Vector2<f64>) -> Result<f64, UnprojectionError> {
        each!(self, c => c.radians_per_pixel(pixel))
    }

    fn radians_per_pixel_at_center(&self) -> f64 {
        each!(self, c => c.radians_per_pixel_at_center())
    }
}
