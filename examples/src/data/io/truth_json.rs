//! The ground truth of a simulated world as JSON (`truth.json`). The schema is documented in
//! the [`io`](super) module.

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use super::bytes::{pose_from_array, pose_to_array};
use crate::data::GroundTruth;

/// The `format` value of a ground-truth file.
pub const TRUTH_FORMAT: &str = "ibc-ground-truth";

/// A pose as JSON: translation in metres and a unit quaternion `[w, x, y, z]`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonPose {
    translation: [f64; 3],
    rotation_wxyz: [f64; 4],
}

impl From<&Isometry3<f64>> for JsonPose {
    fn from(p: &Isometry3<f64>) -> Self {
        let [tx, ty, tz, qw, qx, qy, qz] = pose_to_array(p);
        Self {
            translation: [tx, ty, tz],
            rotation_wxyz: [qw, qx, qy, qz],
        }
    }
}

impl JsonPose {
    fn to_pose<E: serde::de::Error>(&self, what: &str) -> Result<Isometry3<f64>, E> {
        let [tx, ty, tz] = self.translation;
        let [qw, qx, qy, qz] = self.rotation_wxyz;
        pose_from_array([tx, ty, tz, qw, qx, qy, qz])
            .map_err(|why| E::custom(format!("{what}: {why}")))
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonTruth {
    format: String,
    version: u32,
    scenario: String,
    seed: u64,
    pixel_noise_px: f64,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    camera_names: Vec<String>,
    rig_from_camera: Vec<JsonPose>,
    rig_from_odometry: Option<JsonPose>,
    world_from_rig: Vec<JsonPose>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    intrinsics: Vec<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    focal_drift: Vec<f64>,
}

/// The ground truth as pretty-printed JSON.
///
/// # Errors
/// A serde error if a number is not finite (JSON has no NaN).
pub fn truth_to_json(truth: &GroundTruth) -> Result<String, serde_json::Error> {
    let j = JsonTruth {
        format: TRUTH_FORMAT.to_owned(),
        version: super::FORMAT_VERSION,
        scenario: truth.scenario.clone(),
        seed: truth.seed,
        pixel_noise_px: truth.pixel_noise_px,
        camera_names: truth.camera_names.clone(),
        rig_from_camera: truth.rig_from_camera.iter().map(JsonPose::from).collect(),
        rig_from_odometry: truth.rig_from_odometry.as_ref().map(JsonPose::from),
        world_from_rig: truth.world_from_rig.iter().map(JsonPose::from).collect(),
        intrinsics: truth.intrinsics.clone(),
        focal_drift: truth.focal_drift.clone(),
    };
    if !truth.pixel_noise_px.is_finite()
        || truth.intrinsics.iter().flatten().any(|v| !v.is_finite())
    {
        return Err(serde::ser::Error::custom(
            "pixel_noise_px or an intrinsic parameter is not finite",
        ));
    }
    let mut s = serde_json::to_string_pretty(&j)?;
    s.push('\n');
    Ok(s)
}

/// Parses and validates ground-truth JSON: the `format` and `version`, unit quaternions
/// (within 1e-6, normalized), finite numbers, a non-negative pixel noise.
///
/// # Errors
/// A serde error with line and column for malformed JSON, a missing or unknown field, or an
/// invalid value.
pub fn truth_from_json(text: &str) -> Result<GroundTruth, serde_json::Error> {
    use serde::de::Error;
    let j: JsonTruth = serde_json::from_str(text)?;
    if j.format != TRUTH_FORMAT {
        return Err(Error::custom(format!(
            "`format` is {:?}, not {TRUTH_FORMAT:?}",
            j.format
        )));
    }
    if j.version != super::FORMAT_VERSION {
        return Err(Error::custom(format!(
            "version {} is not supported (this build reads version {})",
            j.version,
            super::FORMAT_VERSION
        )));
    }
    if !(j.pixel_noise_px.is_finite() && j.pixel_noise_px >= 0.0) {
        return Err(Error::custom(
            "pixel_noise_px must be finite and non-negative",
        ));
    }
    if !j.camera_names.is_empty() && j.camera_names.len() != j.rig_from_camera.len() {
        return Err(Error::custom(format!(
            "{} camera_names for {} rig_from_camera",
            j.camera_names.len(),
            j.rig_from_camera.len()
        )));
    }
    if !j.intrinsics.is_empty() && j.intrinsics.len() != j.rig_from_camera.len() {
        return Err(Error::custom(format!(
            "{} intrinsics for {} rig_from_camera",
            j.intrinsics.len(),
            j.rig_from_camera.len()
        )));
    }
    if !j.focal_drift.is_empty() && j.focal_drift.len() != j.rig_from_camera.len() {
        return Err(Error::custom(format!(
            "{} focal_drift for {} rig_from_camera",
            j.focal_drift.len(),
            j.rig_from_camera.len()
        )));
    }
    if j.intrinsics
        .iter()
        .flatten()
        .chain(&j.focal_drift)
        .any(|v| !v.is_finite())
    {
        return Err(Error::custom("intrinsics must be finite"));
    }
    let poses = |v: &[JsonPose], what: &str| -> Result<Vec<Isometry3<f64>>, serde_json::Error> {
        v.iter()
            .enumerate()
            .map(|(i, p)| p.to_pose(&format!("{what}[{i}]")))
            .collect()
    };
    Ok(GroundTruth {
        scenario: j.scenario,
        seed: j.seed,
        rig_from_camera: poses(&j.rig_from_camera, "rig_from_camera")?,
        world_from_rig: poses(&j.world_from_rig, "world_from_rig")?,
        rig_from_odometry: j
            .rig_from_odometry
            .as_ref()
            .map(|p| p.to_pose("rig_from_odometry"))
            .transpose()?,
        pixel_noise_px: j.pixel_noise_px,
        camera_names: j.camera_names,
        intrinsics: j.intrinsics,
        focal_drift: j.focal_drift,
    })
}
