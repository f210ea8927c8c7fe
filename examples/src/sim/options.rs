//! Noise and detection options of a scenario.

use super::error::SimError;

/// Noise levels of a simulated world. The defaults are the paper's setting: sigma 0.5 px and
/// an exact map.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseOptions {
    /// Standard deviation of the keypoint noise, pixels per axis (Gaussian). Default 0.5.
    pub pixel_sigma_px: f64,
    /// Probability that each of a descriptor's 256 bits is flipped, independently, in each
    /// image (the landmark's own descriptor is the noiseless one). Default 0.05: 12.8 bits on
    /// average, so two views of a landmark differ by about 24 bits and unrelated descriptors
    /// by 128.
    pub descriptor_bit_flip: f64,
    /// Probability that a visible landmark is not detected in an image. Default 0.1.
    pub missed_detection: f64,
    /// Fraction of an image's features that are not on static landmarks: features on moving
    /// objects first, then random clutter (a random pixel with a random descriptor) to make up
    /// the rest. Default 0.1.
    pub spurious_fraction: f64,
    /// Standard deviation of the error added to every map point, metres per axis (Gaussian);
    /// the log is rendered from the true points. Default 0 (an exact map).
    pub map_point_sigma_m: f64,
    /// Odometry translation noise per step, as a fraction of the step length (standard
    /// deviation per axis). Default 0.005.
    pub odometry_translation: f64,
    /// Odometry rotation noise per step, radians per metre travelled (standard deviation per
    /// axis). Default 0.0005 (0.03 degrees per metre).
    pub odometry_rotation_rad_per_m: f64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for NoiseOptions {
    fn default() -> Self {
        Self {
            pixel_sigma_px: 0.5,
            descriptor_bit_flip: 0.05,
            missed_detection: 0.1,
            spurious_fraction: 0.1,
            map_point_sigma_m: 0.0,
            odometry_translation: 0.005,
            odometry_rotation_rad_per_m: 0.0005,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// When a landmark is detected in an image.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectionOptions {
    /// Landmarks farther than this from the camera are not detected, metres. Default 30.
    pub max_range_m: f64,
    /// Up to this range every visible landmark is detected (but for missed detections); from
    /// here to `max_range_m` the detection probability falls linearly to zero. Default 20.
    pub full_range_m: f64,
    /// Landmarks nearer than this are not detected (out of focus, too large), metres.
    /// Default 0.3.
    pub min_range_m: f64,
    /// Largest angle between a landmark's surface normal and the direction to the camera,
    /// degrees: beyond it the landmark is seen too obliquely (or from behind its surface) to
    /// be detected. Default 85.
    pub max_view_angle_deg: f64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for DetectionOptions {
    fn default() -> Self {
        Self {
            max_range_m: 30.0,
            full_range_m: 20.0,
            min_range_m: 0.3,
            max_view_angle_deg: 85.0,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// `Ok` when `value` is finite and in `[lo, hi]`, else an error naming `key`.
pub(crate) fn check_range(key: &str, value: f64, lo: f64, hi: f64) -> Result<(), SimError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(SimError::Invalid(format!(
            "{key} = {value} is not in [{lo}, {hi}]"
        )))
    }
}

impl NoiseOptions {
    /// Checks every value's range.
    ///
    /// # Errors
    /// [`SimError::Invalid`] naming the first value out of range.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("noise.pixel_sigma_px", self.pixel_sigma_px, 0.0, 100.0)?;
        check_range(
            "noise.descriptor_bit_flip",
            self.descriptor_bit_flip,
            0.0,
            0.5,
        )?;
        check_range("noise.missed_detection", self.missed_detection, 0.0, 0.99)?;
        check_range("noise.spurious_fraction", self.spurious_fraction, 0.0, 0.95)?;
        check_range("noise.map_point_sigma_m", self.map_point_sigma_m, 0.0, 10.0)?;
        check_range(
            "noise.odometry_translation",
            self.odometry_translation,
            0.0,
            1.0,
        )?;
        check_range(
            "noise.odometry_rotation_rad_per_m",
            self.odometry_rotation_rad_per_m,
            0.0,
            1.0,
        )
    }
}

impl DetectionOptions {
    /// Checks every value's range and their order.
    ///
    /// # Errors
    /// [`SimError::Invalid`] naming the first value out of range.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("detection.min_range_m", self.min_range_m, 0.0, 1000.0)?;
        check_range(
            "detection.full_range_m",
            self.full_range_m,
            self.min_range_m,
            1000.0,
        )?;
        check_range(
            "detection.max_range_m",
            self.max_range_m,
            self.full_range_m,
            1000.0,
        )?;
        check_range(
            "detection.max_view_angle_deg",
            self.max_view_angle_deg,
            1.0,
            180.0,
        )
    }
}
