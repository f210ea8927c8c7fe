//! The crate's error type and the reasons it carries.
//!
//! [`CameraError`] is the one error enum of the crate ([`Result`](crate::Result) defaults to
//! it). The model operations return the narrower
//! reason enums directly ([`ProjectionError`], [`UnprojectionError`], [`ParameterError`],
//! [`PlausibilityError`]) so a hot loop can match on them without boxing; every one converts
//! into [`CameraError`] with `?`.
//!
//! A [`CameraFileError`] from a reader that takes a path names that file exactly once: errors that
//! carry their own path ([`CameraFileError::Io`], [`CameraFileError::ConflictingCameraFiles`]) are returned as they are,
//! every other one is wrapped in [`CameraFileError::InFile`].

use std::path::{Path, PathBuf};

use crate::io::IoError;

/// Why a 3D point has no pixel.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ProjectionError {
    /// A coordinate of the point is NaN or infinite.
    #[error("the point has a non-finite coordinate")]
    NonFinitePoint,
    /// The point is the camera centre: it has no direction.
    #[error("the point is the camera centre (zero vector): it has no direction")]
    ZeroPoint,
    /// A pinhole camera only sees points with z > 0.
    #[error("the point is not in front of the pinhole camera (z = {z}, needs z > 0)")]
    BehindCamera {
        /// The point's z coordinate in the camera frame.
        z: f64,
    },
    /// Kannala-Brandt: the angle of incidence is beyond `theta_max`, where r(theta) stops
    /// increasing (the fold) or pi, whichever comes first.
    #[error("the angle of incidence {theta} rad is beyond the model's limit {theta_max} rad")]
    BeyondFold {
        /// Angle between the ray and the optical axis (radians).
        theta: f64,
        /// The model's limit (radians).
        theta_max: f64,
    },
    /// Kannala-Brandt: the point lies on the negative optical axis (theta = pi exactly), whose
    /// image is a whole circle rather than one pixel.
    #[error("the point is on the negative optical axis (theta = pi): its image is not one pixel")]
    OnNegativeAxis,
    /// Unified (Mei): the point is outside z > -w |P| (w = xi for xi <= 1, 1/xi for xi > 1).
    #[error(
        "the point is outside the unified model's domain: z/|P| = {cos_theta}, needs > {limit}"
    )]
    OutsideMeiDomain {
        /// z / |P| of the point.
        cos_theta: f64,
        /// The bound -w that z/|P| must exceed.
        limit: f64,
    },
    /// The undistorted normalized point is beyond the radius inside which the radial-tangential
    /// distortion is invertible.
    #[error(
        "the normalized radius {radius} is beyond the distortion's injective radius {injective_radius}"
    )]
    BeyondInjectiveRadius {
        /// Radius of the undistorted normalized point.
        radius: f64,
        /// The parameter set's injective radius.
        injective_radius: f64,
    },
}

/// Why a pixel has no ray.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum UnprojectionError {
    /// A pixel coordinate is NaN or infinite.
    #[error("the pixel has a non-finite coordinate")]
    NonFinitePixel,
    /// Kannala-Brandt: the pixel's normalized radius is beyond r(theta_max), so no angle of
    /// incidence in [0, theta_max] maps to it (the pixel lies beyond the fold).
    #[error("the normalized radius {radius} is beyond the model's largest radius {max_radius}")]
    BeyondFold {
        /// Normalized radius sqrt(((u - u0) / mu)^2 + ((v - v0) / mv)^2).
        radius: f64,
        /// r(theta_max).
        max_radius: f64,
    },
    /// Kannala-Brandt companion path: the eigenvalue iteration found no real root in
    /// [0, theta_max] although one must exist (the matrix was too ill-conditioned).
    #[error("no real root of the Kannala-Brandt polynomial was found in [0, theta_max]")]
    NoRealRoot,
    /// Kannala-Brandt companion path: the eigenvalue iteration reached its bound.
    #[error("the companion-matrix eigenvalue iteration did not converge in {iterations} steps")]
    EigenvalueIterationLimit {
        /// The iteration bound that was reached.
        iterations: usize,
    },
    /// The Newton inverse of the radial-tangential distortion did not converge.
    #[error("undistortion did not converge: residual {residual} after {iterations} iterations")]
    NotConverged {
        /// Iterations run.
        iterations: usize,
        /// Norm of the final residual (normalized units).
        residual: f64,
    },
    /// The undistorted point lies beyond the distortion's injective radius: the pixel is the image
    /// of more than one ray, or of none.
    #[error(
        "the undistorted radius {radius} is beyond the distortion's injective radius {injective_radius}"
    )]
    BeyondInjectiveRadius {
        /// Radius of the undistorted normalized point.
        radius: f64,
        /// The parameter set's injective radius.
        injective_radius: f64,
    },
    /// Unified (Mei) with xi > 1: the undistorted point is outside r^2 <= 1 / (xi^2 - 1), so it
    /// lifts to no point of the unit sphere.
    #[error("the undistorted squared radius {r2} is beyond the unified model's limit {max_r2}")]
    OutsideMeiDomain {
        /// Squared radius of the undistorted normalized point.
        r2: f64,
        /// 1 / (xi^2 - 1).
        max_r2: f64,
    },
}

/// Why a parameter vector or image size was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParameterError {
    /// The slice has the wrong number of parameters for the model.
    #[error("{model} takes {expected} parameters, got {got}")]
    WrongCount {
        /// Model name.
        model: &'static str,
        /// The model's parameter count.
        expected: usize,
        /// Length of the slice passed.
        got: usize,
    },
    /// A parameter is NaN or infinite.
    #[error("parameter {name} is not finite ({value})")]
    NonFinite {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A focal length (or mu, mv, gamma) is not strictly positive.
    #[error("parameter {name} must be > 0, got {value}")]
    NotPositive {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The unified model's xi is negative.
    #[error("parameter {name} must be >= 0, got {value}")]
    Negative {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// Image width or height is zero.
    #[error("image size {width}x{height} is empty")]
    EmptyImage {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
}

/// A number for messages: six significant digits, trailing zeros dropped, in exponent form
/// outside [1e-4, 1e9) (`458.654`, `0.1`, `4.3e9`, `3.4e38`).
struct Sig(f64);

impl std::fmt::Display for Sig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let x = self.0;
        let a = x.abs();
        if x == 0.0 || !x.is_finite() {
            return write!(f, "{x}");
        }
        if (1e-4..1e9).contains(&a) {
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // 0..=13
            let decimals = (5 - a.log10().floor() as i32).max(0) as usize;
            let s = format!("{x:.decimals$}");
            let s = if s.contains('.') {
                s.trim_end_matches('0').trim_end_matches('.')
            } else {
                &s
            };
            f.write_str(s)
        } else {
            let s = format!("{x:.5e}");
            match s.split_once('e') {
                Some((m, e)) => {
                    let m = m.trim_end_matches('0').trim_end_matches('.');
                    write!(f, "{m}e{e}")
                }
                None => f.write_str(&s),
            }
        }
    }
}

/// Why a valid camera is not a plausible one: its parameters describe no real lens and sensor
/// (see [`Camera::check_plausible`](crate::Camera::check_plausible) for the rules and
/// [`plausibility`](crate::plausibility) for the thresholds). Every variant names the
/// parameter at fault by the model's name for it (`mu`, `fy`, `gamma1`, `v0`, `k2`, ...) and
/// gives its value; [`parameter`](Self::parameter) and [`value`](Self::value) read them.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlausibilityError {
    /// A parameter is NaN or infinite.
    #[error(
        "parameter {name} is not finite ({})",
        Sig(*value)
    )]
    NonFinite {
        /// Parameter name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A focal length is too short or too long for the image size.
    #[error(
        "parameter {name} = {} gives a paraxial focal length of {} px, outside \
         the plausible [{}, {}] px for a {width}x{height} image",
        Sig(*value), Sig(*focal_px), Sig(*min_px), Sig(*max_px)
    )]
    FocalLength {
        /// Parameter name (`mu`, `mv`, `fx`, `fy`, `gamma1`, `gamma2`).
        name: &'static str,
        /// Its value.
        value: f64,
        /// The paraxial focal length it gives in pixels (`gamma / (1 + xi)` for the unified
        /// model, the parameter itself otherwise).
        focal_px: f64,
        /// The shortest plausible focal length for this image.
        min_px: f64,
        /// The longest plausible focal length for this image.
        max_px: f64,
        /// Image width in pixels.
        width: u32,
        /// Image height in pixels.
        height: u32,
    },
    /// The horizontal and vertical focal lengths differ too much: pixels that far from square
    /// come from a failed calibration, not a sensor.
    #[error(
        "the focal lengths {name} = {} and {other_name} = {} differ by a \
         factor of {}, more than the plausible {}",
        Sig(*value), Sig(*other_value), Sig(*ratio), Sig(*max_ratio)
    )]
    AspectRatio {
        /// The parameter that is the larger of the two.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The other focal parameter.
        other_name: &'static str,
        /// Its value.
        other_value: f64,
        /// The larger paraxial focal length over the smaller (>= 1).
        ratio: f64,
        /// The largest plausible ratio.
        max_ratio: f64,
    },
    /// The principal point lies outside the image.
    #[error(
        "parameter {name} = {} px puts the principal point outside the image, which spans \
         [{}, {}] px on that axis",
        Sig(*value), Sig(*min), Sig(*max)
    )]
    PrincipalPoint {
        /// Parameter name (`u0`, `v0`, `cx`, `cy`).
        name: &'static str,
        /// Its value.
        value: f64,
        /// The image's lower edge on that axis (-0.5).
        min: f64,
        /// The image's upper edge on that axis (size - 0.5).
        max: f64,
    },
    /// A pixel inside the image has no ray: the model folds (or leaves its domain) inside the
    /// image.
    #[error(
        "pixel ({}, {}), inside the image, has no ray ({reason}); the largest distortion \
         term there is {name} = {}",
        Sig(*u), Sig(*v), Sig(*value)
    )]
    NoRay {
        /// The parameter held responsible: the distortion coefficient whose term is largest at
        /// the model's limit (`xi` when the unified model's domain ends inside the image).
        name: &'static str,
        /// Its value.
        value: f64,
        /// Pixel column.
        u: f64,
        /// Pixel row.
        v: f64,
        /// Why it has no ray.
        reason: UnprojectionError,
    },
    /// The ray of a pixel inside the image does not project.
    #[error(
        "the ray of pixel ({}, {}) does not project back ({reason}); the largest distortion \
         term there is {name} = {}",
        Sig(*u), Sig(*v), Sig(*value)
    )]
    NoPixel {
        /// The distortion coefficient whose term is largest at the ray.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Pixel column.
        u: f64,
        /// Pixel row.
        v: f64,
        /// Why it does not project.
        reason: ProjectionError,
    },
    /// The ray of a pixel inside the image projects to another pixel: the model is not
    /// invertible there.
    #[error(
        "pixel ({}, {}) unprojects and projects back {} px away (more than \
         {} px); the largest distortion term there is {name} = {}",
        Sig(*u), Sig(*v), Sig(*error_px), Sig(*tolerance_px), Sig(*value)
    )]
    RoundTrip {
        /// The distortion coefficient whose term is largest at the ray.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Pixel column.
        u: f64,
        /// Pixel row.
        v: f64,
        /// Distance between the pixel and its round trip.
        error_px: f64,
        /// The tolerance.
        tolerance_px: f64,
    },
    /// At the edge of the image the distortion squeezes or stretches the angle of incidence
    /// far beyond what a lens does: the angle is much smaller or larger than the paraxial one
    /// (radius over focal length).
    #[error(
        "{} px from the principal point the angle of incidence is {} deg, \
         {} times the paraxial {} deg (plausible: {} to {} \
         times); the largest distortion term there is {name} = {}",
        Sig(*radius_px), Sig(*angle_deg), Sig(*ratio), Sig(*paraxial_deg), Sig(*min_ratio), Sig(*max_ratio), Sig(*value)
    )]
    AngleRatio {
        /// The distortion coefficient whose term is largest there (the focal parameter when
        /// the model has no distortion).
        name: &'static str,
        /// Its value.
        value: f64,
        /// Distance of the sample from the principal point in pixels.
        radius_px: f64,
        /// The sample's angle of incidence in degrees.
        angle_deg: f64,
        /// The paraxial angle (radius over focal length) in degrees.
        paraxial_deg: f64,
        /// angle_deg / paraxial_deg.
        ratio: f64,
        /// The smallest plausible ratio.
        min_ratio: f64,
        /// The largest plausible ratio.
        max_ratio: f64,
    },
    /// The image sees almost nothing: the angle of incidence at the edge of the largest circle
    /// around the principal point that fits in the image is tiny.
    #[error(
        "{} px from the principal point the angle of incidence is only {} \
         deg (at least {} deg is plausible); parameter {name} = {} narrows the \
         field of view",
        Sig(*radius_px), Sig(*angle_deg), Sig(*min_deg), Sig(*value)
    )]
    NarrowField {
        /// The parameter held responsible: the principal point's coordinate nearest an edge
        /// when that circle is small, the longer focal length otherwise.
        name: &'static str,
        /// Its value.
        value: f64,
        /// Radius of the circle in pixels.
        radius_px: f64,
        /// The angle of incidence there in degrees.
        angle_deg: f64,
        /// The smallest plausible angle in degrees.
        min_deg: f64,
    },
}

impl PlausibilityError {
    /// The name of the parameter at fault (the model's name for it).
    pub fn parameter(&self) -> &'static str {
        match self {
            Self::NonFinite { name, .. }
            | Self::FocalLength { name, .. }
            | Self::AspectRatio { name, .. }
            | Self::PrincipalPoint { name, .. }
            | Self::NoRay { name, .. }
            | Self::NoPixel { name, .. }
            | Self::RoundTrip { name, .. }
            | Self::AngleRatio { name, .. }
            | Self::NarrowField { name, .. } => name,
        }
    }

    /// The value of the parameter at fault.
    pub fn value(&self) -> f64 {
        match self {
            Self::NonFinite { value, .. }
            | Self::FocalLength { value, .. }
            | Self::AspectRatio { value, .. }
            | Self::PrincipalPoint { value, .. }
            | Self::NoRay { value, .. }
            | Self::NoPixel { value, .. }
            | Self::RoundTrip { value, .. }
            | Self::AngleRatio { value, .. }
            | Self::NarrowField { value, .. } => *value,
        }
    }
}

/// Why a camera or rig file could not be read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraFileError {
    /// The file could not be read or written (not a regular file, too large, not text, or
    /// the operating system's error); names the file.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The file is wrapped around an error that does not name it: `<path>: <source>`.
    #[error("{}: {source}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What was wrong in it.
        source: Box<CameraFileError>,
    },
    /// The text is not well-formed YAML.
    #[error("not valid YAML: {message}")]
    Yaml {
        /// The parser's message, with line and column.
        message: String,
    },
    /// The YAML uses an alias (`*name`). Camera files never need one, and expanding aliases
    /// can turn a few hundred bytes into gigabytes ("billion laughs"), so they are refused
    /// before the document is built. Anchors (`&name`) alone are harmless and accepted.
    #[error("line {line}: YAML aliases (`*name`) are not supported in camera files")]
    YamlAlias {
        /// 1-based line of the alias.
        line: usize,
    },
    /// The YAML nests deeper than [`MAX_YAML_DEPTH`](crate::MAX_YAML_DEPTH): no camera file
    /// does, and a deep enough document would exhaust the stack when it is dropped.
    #[error("line {line}: YAML nested deeper than {limit} levels, which no camera file needs")]
    YamlTooDeep {
        /// 1-based line where the limit was passed.
        line: usize,
        /// The limit.
        limit: usize,
    },
    /// The YAML holds no document (empty or truncated file).
    #[error("the file holds no YAML document")]
    Empty,
    /// A required key is absent.
    #[error("missing key `{key}`")]
    MissingKey {
        /// Dotted path of the key, for example `projection_parameters.mu`.
        key: String,
    },
    /// A key holds a value of the wrong type.
    #[error("key `{key}` should be {expected}")]
    WrongType {
        /// Dotted path of the key.
        key: String,
        /// What was expected ("a number", "a list of 4 numbers", ...).
        expected: &'static str,
    },
    /// A model name this crate does not know.
    #[error("unknown camera model `{name}`")]
    UnknownModel {
        /// The name found in the file.
        name: String,
    },
    /// A model this crate knows of but does not implement (Kalibr ds, eucm, fov, ...).
    #[error("unsupported camera model `{name}` (supported: {supported})")]
    UnsupportedModel {
        /// The model (and distortion) named in the file.
        name: String,
        /// What is supported.
        supported: &'static str,
    },
    /// A line of a text file (CamOdoCal `extrinsic.txt`) is malformed.
    #[error("line {line}: {message}")]
    Malformed {
        /// 1-based line number.
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// The file's parameters are not a valid camera.
    #[error("camera `{camera}`: {source}")]
    Parameters {
        /// Camera name (or key) in the file.
        camera: String,
        /// Why the parameters were refused.
        source: ParameterError,
    },
    /// The file's parameters are a valid camera but not a plausible one (see
    /// [`Camera::check_plausible`](crate::Camera::check_plausible)).
    #[error("camera `{camera}` is implausible: {source}")]
    Implausible {
        /// Camera name in the file (CamOdoCal `camera_name`, Kalibr `camN`).
        camera: String,
        /// What is implausible.
        source: PlausibilityError,
    },
    /// A CamOdoCal rig folder holds both `<name>_calib.yaml` and `<name>_camera_calib.yaml`
    /// for one camera, and they describe different cameras.
    #[error(
        "camera `{camera}`: {} and {} both exist and describe different cameras (remove one)",
        first.display(),
        second.display()
    )]
    ConflictingCameraFiles {
        /// The camera's name in `extrinsic.txt`.
        camera: String,
        /// CamOdoCal `CameraSystem`'s file, `<name>_calib.yaml`.
        first: PathBuf,
        /// The intrinsic calibration tool's file, `<name>_camera_calib.yaml`.
        second: PathBuf,
    },
    /// The file is consistent YAML but describes an inconsistent rig (duplicate names, a
    /// transform that is not rigid, cameras missing from a directory, ...).
    #[error("inconsistent rig: {message}")]
    Rig {
        /// What was inconsistent.
        message: String,
    },
}

impl CameraFileError {
    /// The file this error names, if it names one (the first of the two for
    /// [`CameraFileError::ConflictingCameraFiles`]).
    pub fn path(&self) -> Option<&Path> {
        match self {
            Self::Io(e) => Some(e.path()),
            Self::InFile { path, .. } | Self::ConflictingCameraFiles { first: path, .. } => {
                Some(path)
            }
            _ => None,
        }
    }

    /// This error with the file it is about: wrapped in [`CameraFileError::InFile`] unless it already
    /// names a file (so a path is never printed twice).
    #[cfg(feature = "files")]
    pub(crate) fn in_file(self, path: &Path) -> Self {
        if self.path().is_some() {
            self
        } else {
            Self::InFile {
                path: path.to_owned(),
                source: Box::new(self),
            }
        }
    }
}

/// The crate's error: any of the reasons above.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CameraError {
    /// A point could not be projected.
    #[error("projection failed: {0}")]
    Projection(#[from] ProjectionError),
    /// A pixel could not be unprojected.
    #[error("unprojection failed: {0}")]
    Unprojection(#[from] UnprojectionError),
    /// Parameters were refused.
    #[error("invalid parameters: {0}")]
    Parameter(#[from] ParameterError),
    /// A camera is not plausible.
    #[error("implausible camera: {0}")]
    Plausibility(#[from] PlausibilityError),
    /// A file could not be read or written.
    #[error("file error: {0}")]
    File(#[from] CameraFileError),
}
