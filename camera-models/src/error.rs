//! The crate's error type and the reasons it carries.
//!
//! [`Error`] is the one error enum of the crate. The model operations return the narrower
//! reason enums directly ([`ProjectionError`], [`UnprojectionError`], [`ParameterError`]) so a
//! hot loop can match on them without boxing; every one converts into [`Error`] with `?`.

use std::path::PathBuf;

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

/// Why a camera or rig file could not be read or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// The operating system refused to read or write the file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The text is not well-formed YAML.
    #[error("not valid YAML: {message}")]
    Yaml {
        /// The parser's message, with line and column.
        message: String,
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
    /// The file is consistent YAML but describes an inconsistent rig (duplicate names, a
    /// transform that is not rigid, cameras missing from a directory, ...).
    #[error("inconsistent rig: {message}")]
    Rig {
        /// What was inconsistent.
        message: String,
    },
}

/// The crate's error: any of the reasons above.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A point could not be projected.
    #[error("projection failed: {0}")]
    Projection(#[from] ProjectionError),
    /// A pixel could not be unprojected.
    #[error("unprojection failed: {0}")]
    Unprojection(#[from] UnprojectionError),
    /// Parameters were refused.
    #[error("invalid parameters: {0}")]
    Parameter(#[from] ParameterError),
    /// A file could not be read or written.
    #[error("file error: {0}")]
    File(#[from] FileError),
}
