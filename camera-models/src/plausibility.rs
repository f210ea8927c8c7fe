//! Plausibility of a camera: whether a valid parameter set describes a real lens on a real
//! sensor.
//!
//! The constructors accept any finite parameters with positive focal lengths, because code
//! builds odd cameras on purpose (tests, simulations, intermediate states of an optimizer).
//! A camera read from a file is held to more: the readers
//! ([`camodocal::parse_camera`](crate::camodocal::parse_camera), the rig readers) refuse one
//! that fails [`Camera::check_plausible`] with
//! [`CameraFileError::Implausible`](crate::CameraFileError::Implausible). The checks, in order, each
//! naming the parameter at fault in its [`PlausibilityError`]:
//!
//! 1. Every parameter is finite.
//! 2. Each paraxial focal length (`mu`, `mv`; `fx`, `fy`; `gamma1 / (1 + xi)`,
//!    `gamma2 / (1 + xi)`) lies within [`MIN_FOCAL_PER_SIDE`] to [`MAX_FOCAL_PER_SIDE`] times
//!    the image's larger side, and the two differ by at most a factor [`MAX_ASPECT_RATIO`].
//! 3. The principal point lies in the image, `[-0.5, width - 0.5] x [-0.5, height - 0.5]`.
//! 4. The distortion keeps the model invertible and sane over the image. Pixels are sampled in
//!    [`SAMPLE_DIRECTIONS`] directions on circles around the principal point whose radii are
//!    the fractions [`SAMPLE_RADII`] of the largest circle that fits in the image. Each must
//!    unproject (within the Kannala-Brandt fold, the radial-tangential injective radius and
//!    the unified model's domain, which the models compute) and project back to within
//!    [`ROUND_TRIP_TOLERANCE_PX`]. On the largest circle, the angle of incidence must be
//!    within [`MIN_ANGLE_RATIO`] to [`MAX_ANGLE_RATIO`] times the paraxial angle (the
//!    distance to the principal point in focal lengths) and at least [`MIN_EDGE_ANGLE_DEG`].
//!
//! A distortion failure names the distortion coefficient whose term is largest where the
//! failure is (at the ray's undistorted radius, or at the model's limit for a pixel with no
//! ray), or `xi` when the unified model's domain ends inside the image.
//!
//! The thresholds are wide on purpose: every real camera in the repository's tests, examples
//! and simulations (35 cameras) passes with a margin of more than 4 on each (see
//! `tests/plausibility.rs`), while the absurd files that motivated the checks (fx = 3.4e38,
//! fx = 4.3e9, k2 = 4.3e9, v0 = -476 px) fail on the first check that applies. The round trip
//! and the ray that does not project back are guards: no camera the constructors accept was
//! found to trip them (200 000 random parameter sets), since the models unproject only inside
//! the domain where they are invertible.

use std::f64::consts::TAU;

use nalgebra::{Vector2, Vector3};

use crate::camera::Camera;
use crate::error::{PlausibilityError, UnprojectionError};
use crate::model::CameraModel;
use crate::{KannalaBrandt, PinholeRadtan, Unified};

/// The shortest plausible paraxial focal length, as a fraction of the image's larger side:
/// 0.05. The widest lens maps 360 degrees onto the image: an equidistant fisheye with
/// `theta = pi` at half the larger side has `f = side / (2 pi) = 0.16 side` (compressing
/// mappings such as the equisolid one need longer focal lengths). The widest camera in the
/// repository (the simulated 190-degree fisheye, `mv = 301.2` on 1280 px) has 0.235.
pub const MIN_FOCAL_PER_SIDE: f64 = 0.05;

/// The longest plausible paraxial focal length, as a multiple of the image's larger side: 100,
/// a horizontal field of view of `2 atan(1 / 200) = 0.57` degrees, narrower than a 3000 mm
/// telephoto on a full-frame sensor. The longest camera in the repository has 0.95
/// (CamOdoCal's pinhole test camera, `fy = 714.8` on 752 px).
pub const MAX_FOCAL_PER_SIDE: f64 = 100.0;

/// The largest plausible ratio between the two paraxial focal lengths: 3. Square-pixel
/// sensors give 1 to within a percent or two; the strongest anamorphic lenses in use squeeze 2x.
/// The repository's cameras are within 1.015 (a camera of the simulated pentagon rig).
pub const MAX_ASPECT_RATIO: f64 = 3.0;

/// Directions sampled around the principal point: 32, one every 11.25 degrees, enough to
/// catch a tangential distortion that folds on one side of the image only.
pub const SAMPLE_DIRECTIONS: usize = 32;

/// Radii sampled, as fractions of the largest circle around the principal point that fits in
/// the image.
pub const SAMPLE_RADII: [f64; 4] = [0.25, 0.5, 0.75, 1.0];

/// Largest distance in pixels between a sample and the projection of its ray: 1e-6 px. The
/// models' inverses are exact to about 1e-12 rad, a few nanopixels at any plausible focal
/// length; the repository's cameras stay below 1e-12 px.
pub const ROUND_TRIP_TOLERANCE_PX: f64 = 1e-6;

/// Smallest plausible angle of incidence on the largest circle around the principal point,
/// in degrees: 0.1. The longest plausible focal length ([`MAX_FOCAL_PER_SIDE`]) sees 0.18
/// degrees at the edge of a centred 752 x 480 image; the repository's cameras see at least
/// 19.1 degrees. It catches a principal point on the image's border (a circle of a fraction of
/// a pixel) and a long focal length on a thin strip of sensor. A distortion that squeezes the
/// image (`k2 = 4.3e9` puts EuRoC cam0's whole image within 0.59 degrees) is caught first by
/// [`MIN_ANGLE_RATIO`].
pub const MIN_EDGE_ANGLE_DEG: f64 = 0.1;

/// Smallest plausible ratio between the angle of incidence and the paraxial angle (the
/// distance to the principal point divided by the focal length) on the largest circle: 0.1.
/// A distortion-free pinhole at the shortest plausible focal length has `atan(10) / 10 =
/// 0.15`; the repository's cameras are between 0.92 and 1.08.
pub const MIN_ANGLE_RATIO: f64 = 0.1;

/// Largest plausible ratio between the angle of incidence and the paraxial angle on the
/// largest circle: 10, ten times wider than the lens's centre suggests. Inside their domains
/// the models' radius maps are monotone with unit slope at the centre, which keeps the ratio
/// within a few units (no camera of 200 000 random parameter sets exceeded 10), so this bound
/// is a guard for the band's symmetry and for future models.
pub const MAX_ANGLE_RATIO: f64 = 10.0;

/// Where a distortion failure was seen, for naming its culprit.
enum At<'a> {
    /// A ray of the model: the culprit is the term largest at its undistorted radius.
    Ray(&'a Vector3<f64>),
    /// A pixel without a ray: the culprit is the term largest at the model's limit.
    NoRay(&'a Vector2<f64>, &'a UnprojectionError),
}

/// What the checks need to know of a model beyond [`CameraModel`].
trait Describe: CameraModel {
    /// `(name, value, paraxial focal length in pixels)`, horizontal then vertical.
    fn focal_lengths(&self) -> [(&'static str, f64, f64); 2];

    /// The names of the principal point's coordinates.
    fn principal_point_names(&self) -> [&'static str; 2];

    /// The distortion parameter held responsible for a failure at `at`: the one whose term
    /// is largest there, or the horizontal focal parameter when the model has no distortion.
    fn culprit(&self, at: At<'_>) -> (&'static str, f64);
}

/// The name and value of the largest of `terms` (`(name, value, size of its term)`), or
/// `fallback` when every term is zero.
fn largest(
    terms: &[(&'static str, f64, f64)],
    fallback: (&'static str, f64),
) -> (&'static str, f64) {
    terms
        .iter()
        .filter(|t| t.2 > 0.0)
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .map_or(fallback, |t| (t.0, t.1))
}

/// Angle between a ray and the optical axis, accurate for tiny angles.
fn incidence(ray: &Vector3<f64>) -> f64 {
    ray.x.hypot(ray.y).atan2(ray.z)
}

/// The radial-tangential culprit at undistorted radius `r`: terms k1 r^3, k2 r^5 and the
/// tangential 3 p r^2 (the largest a tangential term reaches over the directions).
fn radtan_culprit(
    [k1, k2, p1, p2]: [f64; 4],
    names: [&'static str; 4],
    r: f64,
    fallback: (&'static str, f64),
) -> (&'static str, f64) {
    let r2 = r * r;
    largest(
        &[
            (names[0], k1, (k1 * r2 * r).abs()),
            (names[1], k2, (k2 * r2 * r2 * r).abs()),
            (names[2], p1, (3.0 * p1 * r2).abs()),
            (names[3], p2, (3.0 * p2 * r2).abs()),
        ],
        fallback,
    )
}

impl Describe for KannalaBrandt {
    fn focal_lengths(&self) -> [(&'static str, f64, f64); 2] {
        [("mu", self.mu(), self.mu()), ("mv", self.mv(), self.mv())]
    }

    fn principal_point_names(&self) -> [&'static str; 2] {
        ["u0", "v0"]
    }

    fn culprit(&self, at: At<'_>) -> (&'static str, f64) {
        let theta = match at {
            At::Ray(ray) => incidence(ray),
            At::NoRay(pixel, _) => {
                let d =
                    ((pixel.x - self.u0()) / self.mu()).hypot((pixel.y - self.v0()) / self.mv());
                d.min(self.theta_max())
            }
        };
        let [k1, k2, k3, k4] = self.k();
        let t2 = theta * theta;
        let t3 = t2 * theta;
        largest(
            &[
                ("k1", k1, (k1 * t3).abs()),
                ("k2", k2, (k2 * t3 * t2).abs()),
                ("k3", k3, (k3 * t3 * t2 * t2).abs()),
                ("k4", k4, (k4 * t3 * t3 * t3).abs()),
            ],
            ("mu", self.mu()),
        )
    }
}

impl Describe for PinholeRadtan {
    fn focal_lengths(&self) -> [(&'static str, f64, f64); 2] {
        [("fx", self.fx(), self.fx()), ("fy", self.fy(), self.fy())]
    }

    fn principal_point_names(&self) -> [&'static str; 2] {
        ["cx", "cy"]
    }

    fn culprit(&self, at: At<'_>) -> (&'static str, f64) {
        let r = match at {
            At::Ray(ray) if ray.z > 0.0 => ray.x.hypot(ray.y) / ray.z,
            At::Ray(_) => self.injective_radius(),
            At::NoRay(pixel, _) => ((pixel.x - self.cx()) / self.fx())
                .hypot((pixel.y - self.cy()) / self.fy())
                .min(self.injective_radius()),
        };
        radtan_culprit(
            self.distortion(),
            ["k1", "k2", "p1", "p2"],
            r,
            ("fx", self.fx()),
        )
    }
}

impl Describe for Unified {
    fn focal_lengths(&self) -> [(&'static str, f64, f64); 2] {
        let s = 1.0 + self.xi();
        [
            ("gamma1", self.gamma1(), self.gamma1() / s),
            ("gamma2", self.gamma2(), self.gamma2() / s),
        ]
    }

    fn principal_point_names(&self) -> [&'static str; 2] {
        ["u0", "v0"]
    }

    fn culprit(&self, at: At<'_>) -> (&'static str, f64) {
        let r = match at {
            At::NoRay(_, UnprojectionError::OutsideMeiDomain { .. }) => {
                return ("xi", self.xi());
            }
            // The unit ray's undistorted point: (x, y) / (z + xi).
            At::Ray(ray) if ray.z + self.xi() > 0.0 => ray.x.hypot(ray.y) / (ray.z + self.xi()),
            At::Ray(_) => self.injective_radius(),
            At::NoRay(pixel, _) => ((pixel.x - self.u0()) / self.gamma1())
                .hypot((pixel.y - self.v0()) / self.gamma2())
                .min(self.injective_radius()),
        };
        radtan_culprit(
            self.distortion(),
            ["k1", "k2", "p1", "p2"],
            r,
            ("gamma1", self.gamma1()),
        )
    }
}

/// The checks of the module documentation, on any model.
fn check<C: Describe>(camera: &C) -> Result<(), PlausibilityError> {
    for (&name, &value) in camera.param_names().iter().zip(camera.params()) {
        if !value.is_finite() {
            return Err(PlausibilityError::NonFinite { name, value });
        }
    }
    let (width, height) = (camera.width(), camera.height());
    let (w, h) = (f64::from(width), f64::from(height));
    let side = w.max(h);
    let (min_px, max_px) = (MIN_FOCAL_PER_SIDE * side, MAX_FOCAL_PER_SIDE * side);
    let focals = camera.focal_lengths();
    for (name, value, focal_px) in focals {
        if !(focal_px >= min_px && focal_px <= max_px) {
            return Err(PlausibilityError::FocalLength {
                name,
                value,
                focal_px,
                min_px,
                max_px,
                width,
                height,
            });
        }
    }
    let [(x_name, x_value, fx), (y_name, y_value, fy)] = focals;
    let (long, short) = if fx >= fy {
        ((x_name, x_value), (y_name, y_value))
    } else {
        ((y_name, y_value), (x_name, x_value))
    };
    let ratio = fx.max(fy) / fx.min(fy);
    if ratio > MAX_ASPECT_RATIO {
        return Err(PlausibilityError::AspectRatio {
            name: long.0,
            value: long.1,
            other_name: short.0,
            other_value: short.1,
            ratio,
            max_ratio: MAX_ASPECT_RATIO,
        });
    }
    let pp = camera.principal_point();
    let [u_name, v_name] = camera.principal_point_names();
    for (name, value, max) in [(u_name, pp.x, w - 0.5), (v_name, pp.y, h - 0.5)] {
        if !(value >= -0.5 && value <= max) {
            return Err(PlausibilityError::PrincipalPoint {
                name,
                value,
                min: -0.5,
                max,
            });
        }
    }
    // The largest circle around the principal point inside the image, and the principal
    // point's coordinate nearest an edge (the culprit when that circle is small).
    let edges = [
        (pp.x + 0.5, u_name, pp.x),
        (w - 0.5 - pp.x, u_name, pp.x),
        (pp.y + 0.5, v_name, pp.y),
        (h - 0.5 - pp.y, v_name, pp.y),
    ];
    let (radius, nearest_name, nearest_value) = edges
        .into_iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .unwrap_or((0.0, u_name, pp.x));
    for fraction in SAMPLE_RADII {
        for i in 0..SAMPLE_DIRECTIONS {
            #[allow(clippy::cast_precision_loss)] // small counts
            let phi = TAU * i as f64 / SAMPLE_DIRECTIONS as f64;
            let offset = Vector2::new(phi.cos(), phi.sin()) * (radius * fraction);
            let pixel = pp + offset;
            let (u, v) = (pixel.x, pixel.y);
            let ray = camera.unproject(&pixel).map_err(|reason| {
                let (name, value) = camera.culprit(At::NoRay(&pixel, &reason));
                PlausibilityError::NoRay {
                    name,
                    value,
                    u,
                    v,
                    reason,
                }
            })?;
            let back = camera.project(&ray).map_err(|reason| {
                let (name, value) = camera.culprit(At::Ray(&ray));
                PlausibilityError::NoPixel {
                    name,
                    value,
                    u,
                    v,
                    reason,
                }
            })?;
            let error_px = (back - pixel).norm();
            // (A NaN error fails too.)
            if error_px.is_nan() || error_px > ROUND_TRIP_TOLERANCE_PX {
                let (name, value) = camera.culprit(At::Ray(&ray));
                return Err(PlausibilityError::RoundTrip {
                    name,
                    value,
                    u,
                    v,
                    error_px,
                    tolerance_px: ROUND_TRIP_TOLERANCE_PX,
                });
            }
            if fraction < 1.0 {
                continue;
            }
            let angle = incidence(&ray);
            let paraxial = (offset.x / fx).hypot(offset.y / fy);
            let radius_px = offset.norm();
            if paraxial > 0.0 {
                let ratio = angle / paraxial;
                if !(MIN_ANGLE_RATIO..=MAX_ANGLE_RATIO).contains(&ratio) {
                    let (name, value) = camera.culprit(At::Ray(&ray));
                    return Err(PlausibilityError::AngleRatio {
                        name,
                        value,
                        radius_px,
                        angle_deg: angle.to_degrees(),
                        paraxial_deg: paraxial.to_degrees(),
                        ratio,
                        min_ratio: MIN_ANGLE_RATIO,
                        max_ratio: MAX_ANGLE_RATIO,
                    });
                }
            }
            if angle.to_degrees() < MIN_EDGE_ANGLE_DEG {
                // A small circle (principal point near an edge) or a long focal length.
                let (name, value) = if radius < 0.25 * w.min(h) {
                    (nearest_name, nearest_value)
                } else {
                    long
                };
                return Err(PlausibilityError::NarrowField {
                    name,
                    value,
                    radius_px,
                    angle_deg: angle.to_degrees(),
                    min_deg: MIN_EDGE_ANGLE_DEG,
                });
            }
        }
    }
    Ok(())
}

impl KannalaBrandt {
    /// Whether the camera is plausible: see [`Camera::check_plausible`].
    ///
    /// # Errors
    /// [`PlausibilityError`] naming the parameter at fault.
    pub fn check_plausible(&self) -> Result<(), PlausibilityError> {
        check(self)
    }
}

impl PinholeRadtan {
    /// Whether the camera is plausible: see [`Camera::check_plausible`].
    ///
    /// # Errors
    /// [`PlausibilityError`] naming the parameter at fault.
    pub fn check_plausible(&self) -> Result<(), PlausibilityError> {
        check(self)
    }
}

impl Unified {
    /// Whether the camera is plausible: see [`Camera::check_plausible`].
    ///
    /// # Errors
    /// [`PlausibilityError`] naming the parameter at fault.
    pub fn check_plausible(&self) -> Result<(), PlausibilityError> {
        check(self)
    }
}

impl Camera {
    /// Whether the camera describes a real lens on a real sensor, beyond being a valid model:
    /// finite parameters, focal lengths between [`MIN_FOCAL_PER_SIDE`] and
    /// [`MAX_FOCAL_PER_SIDE`] times the image's larger side and within a factor
    /// [`MAX_ASPECT_RATIO`] of each other, the principal point in the image, and a distortion
    /// that keeps the model invertible over the image and the angle of incidence at its edge
    /// within [`MIN_ANGLE_RATIO`] to [`MAX_ANGLE_RATIO`] times the paraxial one and above
    /// [`MIN_EDGE_ANGLE_DEG`] (details in the [`plausibility`](crate::plausibility) module).
    /// File readers apply it; the constructors do not.
    ///
    /// About 250 unprojections and projections: microseconds, once per file.
    ///
    /// # Errors
    /// [`PlausibilityError`] naming the parameter at fault.
    pub fn check_plausible(&self) -> Result<(), PlausibilityError> {
        match self {
            Self::KannalaBrandt(c) => check(c),
            Self::PinholeRadtan(c) => check(c),
            Self::Unified(c) => check(c),
        }
    }
}
