//! Pixel thresholds as angles.
//!
//! RANSAC here thresholds the angle between a bearing and its point's direction, which means
//! the same at every incidence. A pixel threshold `d` on a pinhole camera of focal length `f`
//! pixels spans, at the principal point, the angle `atan(d / f)`; off-axis a pixel spans a
//! smaller angle (by `cos^2` of the incidence radially), so this angle is the loosest one of
//! the image. [`crate::angle_from_pixels_at`] gives the angle for any `ibc-camera-models` camera
//! at any pixel.

use crate::error::{PnpError, Result};

/// The angle, in radians, that `pixels` pixels span at the principal point of a camera of
/// focal length `focal_px` pixels: `atan(pixels / focal_px)`.
///
/// # Errors
/// [`PnpError::InvalidOption`] if either argument is not finite and positive.
pub fn angle_from_pixels(pixels: f64, focal_px: f64) -> Result<f64> {
    check_positive("pixels", pixels)?;
    check_positive("focal_px", focal_px)?;
    Ok((pixels / focal_px).atan())
}

/// Refuses a value that is not finite and positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(PnpError::InvalidOption {
            name,
            reason: format!("must be finite and positive, got {value}"),
        })
    }
}
