//! Checks on parameters and points shared by the models.

use nalgebra::{Vector2, Vector3};

use crate::error::{ParameterError, ProjectionError};

/// The image must have pixels.
pub fn image_size(width: u32, height: u32) -> Result<(), ParameterError> {
    if width == 0 || height == 0 {
        return Err(ParameterError::EmptyImage { width, height });
    }
    Ok(())
}

/// Length and finiteness of a parameter slice, returned as a fixed array.
pub fn params<const N: usize>(
    model: &'static str,
    names: &[&'static str; N],
    params: &[f64],
) -> Result<[f64; N], ParameterError> {
    let arr: [f64; N] = params.try_into().map_err(|_| ParameterError::WrongCount {
        model,
        expected: N,
        got: params.len(),
    })?;
    for (value, name) in arr.iter().zip(names) {
        if !value.is_finite() {
            return Err(ParameterError::NonFinite {
                name,
                value: *value,
            });
        }
    }
    Ok(arr)
}

/// A focal-length-like parameter must be > 0.
pub fn positive(name: &'static str, value: f64) -> Result<(), ParameterError> {
    if value > 0.0 {
        Ok(())
    } else {
        Err(ParameterError::NotPositive { name, value })
    }
}

/// xi must be >= 0.
pub fn non_negative(name: &'static str, value: f64) -> Result<(), ParameterError> {
    if value >= 0.0 {
        Ok(())
    } else {
        Err(ParameterError::Negative { name, value })
    }
}

/// `Err(|m|)` when `|m| > max_radius` (an infinite `max_radius` never is), comparing squares
/// so that the hot paths take no square root when the point is inside.
#[inline]
pub fn within_radius(m: &Vector2<f64>, max_radius: f64) -> Result<(), f64> {
    if m.norm_squared() > max_radius * max_radius {
        Err(m.norm())
    } else {
        Ok(())
    }
}

/// A point must be finite and not the camera centre.
#[inline]
pub fn finite_nonzero_point(p: &Vector3<f64>) -> Result<(), ProjectionError> {
    if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
        return Err(ProjectionError::NonFinitePoint);
    }
    if p.x == 0.0 && p.y == 0.0 && p.z == 0.0 {
        return Err(ProjectionError::ZeroPoint);
    }
    Ok(())
}
