//! Interop with glam's f64 types (feature `glam`), for code written with glam (Bevy, ...).
//!
//! [`CameraModelGlam`] adds `project_glam` / `unproject_glam` to every [`CameraModel`]; the
//! free functions convert vectors and poses. glam's `DQuat` is stored `[x, y, z, w]`; the
//! conversions map components by name, so no order can be confused.

use glam::{DQuat, DVec2, DVec3};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector2, Vector3};

use crate::error::{ProjectionError, UnprojectionError};
use crate::model::CameraModel;

/// nalgebra 2-vector to glam.
pub fn vec2_to_glam(v: &Vector2<f64>) -> DVec2 {
    DVec2::new(v.x, v.y)
}

/// glam 2-vector to nalgebra.
pub fn vec2_from_glam(v: DVec2) -> Vector2<f64> {
    Vector2::new(v.x, v.y)
}

/// nalgebra 3-vector to glam.
pub fn vec3_to_glam(v: &Vector3<f64>) -> DVec3 {
    DVec3::new(v.x, v.y, v.z)
}

/// glam 3-vector to nalgebra.
pub fn vec3_from_glam(v: DVec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// A pose `a_from_b` as glam's rotation and translation (`p_a = rotation * p_b + translation`).
pub fn isometry_to_glam(pose: &Isometry3<f64>) -> (DQuat, DVec3) {
    let q = pose.rotation.quaternion();
    (
        DQuat::from_xyzw(q.i, q.j, q.k, q.w),
        vec3_to_glam(&pose.translation.vector),
    )
}

/// A pose from glam's rotation and translation; the quaternion is normalized.
pub fn isometry_from_glam(rotation: DQuat, translation: DVec3) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(translation.x, translation.y, translation.z),
        UnitQuaternion::from_quaternion(Quaternion::new(
            rotation.w, rotation.x, rotation.y, rotation.z,
        )),
    )
}

/// [`CameraModel`] operations on glam vectors.
pub trait CameraModelGlam {
    /// [`CameraModel::project`] on glam vectors.
    ///
    /// # Errors
    /// As [`CameraModel::project`].
    fn project_glam(&self, p_cam: DVec3) -> Result<DVec2, ProjectionError>;

    /// [`CameraModel::unproject`] on glam vectors: a unit ray.
    ///
    /// # Errors
    /// As [`CameraModel::unproject`].
    fn unproject_glam(&self, pixel: DVec2) -> Result<DVec3, UnprojectionError>;
}

impl<C: CameraModel + ?Sized> CameraModelGlam for C {
    fn project_glam(&self, p_cam: DVec3) -> Result<DVec2, ProjectionError> {
        self.project(&vec3_from_glam(p_cam))
            .map(|p| vec2_to_glam(&p))
    }

    fn unproject_glam(&self, pixel: DVec2) -> Result<DVec3, UnprojectionError> {
        self.unproject(&vec2_from_glam(pixel))
            .map(|r| vec3_to_glam(r.as_ref()))
    }
}
