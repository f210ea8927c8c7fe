//! Simulated board views: corner observations of a planar target seen by a chosen true camera,
//! with pixel noise and missing corners, for tests, benchmarks and `ibc intrinsics --simulate`.
//!
//! Each view places the board centre along a random direction of the field of view (angle of
//! incidence uniform up to the field limit, azimuth uniform) at a random distance, facing the
//! camera and tilted about a random axis by up to [`BoardSimulationOptions::max_tilt_deg`],
//! turned by a random angle in its plane. Corners that do not project, fall outside the image
//! or beyond [`BoardSimulationOptions::max_incidence_deg`] (the lens's field of view) are not
//! seen; a view that shows fewer than [`BoardSimulationOptions::min_visible_fraction`] of the
//! board is drawn again. Seen corners are then dropped with probability
//! [`BoardSimulationOptions::missing_fraction`] and moved by Gaussian noise; a corner that the
//! noise moves out of the image is dropped.

use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use nalgebra::{Isometry3, Rotation3, Translation3, Unit, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::calibrate::{IntrinsicModel, MIN_CORNERS_PER_IMAGE};
use super::corners::{Corner, CornerSet, ImageCorners};
use super::error::IntrinsicsError;
use super::target::PlanarTarget;

/// Draws a view at most this many times before giving up on it.
pub const MAX_VIEW_ATTEMPTS: usize = 10_000;

/// Options of [`simulate_boards`].
#[derive(Clone, Debug, PartialEq)]
pub struct BoardSimulationOptions {
    /// Number of views. Default 20 (the test).
    pub views: usize,
    /// Standard deviation of the pixel noise per coordinate, pixels. Default 0.2.
    pub noise_px: f64,
    /// Probability that a seen corner is missing from the detection. Default 0.
    pub missing_fraction: f64,
    /// The lens's field of view as a largest angle of incidence (degrees); corners beyond are
    /// not seen. Default `None`: the model's valid domain and the image bound it.
    pub max_incidence_deg: Option<f64>,
    /// Board distance range, in board diagonals (first to last corner). Default 0.2 to 0.5:
    /// boards close enough to fill a good part of the image, as a careful calibration holds
    /// them.
    pub distance_range: (f64, f64),
    /// Smallest tilt of the board away from facing the camera, degrees. Default 30.
    pub min_tilt_deg: f64,
    /// Largest tilt of the board away from facing the camera, degrees. Default 60.
    pub max_tilt_deg: f64,
    /// Smallest fraction of the board's corners a view must show. Default 0.5 (boards may
    /// reach past the image border, which is where the distortion is best observed).
    pub min_visible_fraction: f64,
    /// Place every board parallel to the image plane (a degenerate set of views, for tests).
    /// Default false.
    pub parallel_to_image: bool,
    /// Seed of the random views and noise.
    pub seed: u64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for BoardSimulationOptions {
    fn default() -> Self {
        Self {
            views: 20,
            noise_px: 0.2,
            missing_fraction: 0.0,
            max_incidence_deg: None,
            distance_range: (0.2, 0.5),
            min_tilt_deg: 30.0,
            max_tilt_deg: 60.0,
            min_visible_fraction: 0.5,
            parallel_to_image: false,
            seed: 0,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

impl BoardSimulationOptions {
    /// The defaults for a model's preset camera ([`preset_camera`]). The Kannala-Brandt and
    /// unified fisheyes see up to 95 degrees of incidence (a 190 degree lens) and its boards are
    /// tilted by 40 to 70 degrees; the pinhole's by 20 to 50. These are the geometries that
    /// gave the smallest parameter standard deviations in a search over distance, tilt and
    /// visibility (20 views, 0.2 px noise; see BENCHMARKS.md).
    pub fn for_model(model: IntrinsicModel) -> Self {
        match model {
            IntrinsicModel::KannalaBrandt | IntrinsicModel::Unified => Self {
                max_incidence_deg: Some(95.0),
                min_tilt_deg: 40.0,
                max_tilt_deg: 70.0,
                ..Self::default()
            },
            IntrinsicModel::PinholeRadtan => Self {
                min_tilt_deg: 20.0,
                max_tilt_deg: 50.0,
                ..Self::default()
            },
        }
    }

    fn validate(&self) -> Result<(), IntrinsicsError> {
        let bad = |what: String| Err(IntrinsicsError::InvalidInput(what));
        if self.views == 0 {
            return bad("the simulation needs at least one view".into());
        }
        if !(self.noise_px.is_finite() && self.noise_px >= 0.0) {
            return bad(format!(
                "noise must be finite and >= 0 px, got {}",
                self.noise_px
            ));
        }
        if !(0.0..1.0).contains(&self.missing_fraction) {
            return bad(format!(
                "the missing fraction must be in [0, 1), got {}",
                self.missing_fraction
            ));
        }
        if let Some(m) = self.max_incidence_deg
            && !(m > 0.0 && m <= 180.0)
        {
            return bad(format!(
                "the field limit must be in (0, 180] degrees, got {m}"
            ));
        }
        let (lo, hi) = self.distance_range;
        if !(lo > 0.0 && hi >= lo && hi.is_finite()) {
            return bad(format!(
                "the distance range ({lo}, {hi}) is not 0 < min <= max"
            ));
        }
        if !(0.0 <= self.min_tilt_deg
            && self.min_tilt_deg <= self.max_tilt_deg
            && self.max_tilt_deg <= 85.0)
        {
            return bad(format!(
                "the tilt range must satisfy 0 <= min <= max <= 85 degrees, got {} to {}",
                self.min_tilt_deg, self.max_tilt_deg
            ));
        }
        if !(0.0..=1.0).contains(&self.min_visible_fraction) {
            return bad(format!(
                "the visible fraction must be in [0, 1], got {}",
                self.min_visible_fraction
            ));
        }
        Ok(())
    }
}

/// Simulated views with their truth.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulatedBoards {
    /// The true camera.
    pub camera: Camera,
    /// The target.
    pub target: PlanarTarget,
    /// The noisy corners (image names `view_000`, `view_001`, ...).
    pub corners: CornerSet,
    /// The true `camera_from_board` of each view.
    pub camera_from_board: Vec<Isometry3<f64>>,
}

/// A Kannala-Brandt fisheye of about 190 degrees: 1280 x 960 pixels, `mu = 301.7`,
/// `mv = 301.2`, principal point `(643.4, 478.1)` off the centre, and mild distortion
/// (`r(95 deg)` within 1.5% of the equidistant `theta`).
///
/// # Errors
/// Never in practice (the constants are a valid camera); the result type keeps library code
/// free of `unwrap`.
pub fn fisheye_190() -> Result<KannalaBrandt, IntrinsicsError> {
    Ok(KannalaBrandt::new(
        1280,
        960,
        [
            0.0123, -0.0046, 0.00071, -0.000041, 301.7, 301.2, 643.4, 478.1,
        ],
    )?)
}

/// A unified (Mei) fisheye of about 190 degrees on the same 1280 x 960 sensor as
/// [`fisheye_190`]: `xi = 0.95` (so rays up to 161 degrees of incidence are in its domain),
/// `gamma1 = 486.3`, `gamma2 = 485.8`, principal point `(638.9, 482.6)`, and radial-tangential
/// distortion `[-0.12, 0.03, 2e-4, -1.5e-4]` (injective over the whole image); 95 degrees of
/// incidence land about 500 px from the centre.
///
/// # Errors
/// Never in practice (the constants are a valid camera).
pub fn mei_fisheye() -> Result<Unified, IntrinsicsError> {
    Ok(Unified::new(
        1280,
        960,
        [0.95, -0.12, 0.03, 2e-4, -1.5e-4, 486.3, 485.8, 638.9, 482.6],
    )?)
}

/// The EuRoC MAV dataset's `cam0` distortion `[k1, k2, p1, p2]` (Burri et al., IJRR 2016,
/// `cam0/sensor.yaml`).
pub const EUROC_CAM0_DISTORTION: [f64; 4] = [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05];

/// The EuRoC MAV dataset's `cam0` projection `[fx, fy, cx, cy]` (pixels) of its 752 x 480
/// image (same source).
pub const EUROC_CAM0_PROJECTION: [f64; 4] = [458.654, 457.296, 367.215, 248.375];

/// A pinhole-radtan camera with the published intrinsics of the EuRoC MAV dataset's `cam0`:
/// [`EUROC_CAM0_DISTORTION`] and [`EUROC_CAM0_PROJECTION`], 752 x 480 pixels.
///
/// # Errors
/// Never in practice (the constants are a valid camera).
pub fn pinhole_euroc() -> Result<PinholeRadtan, IntrinsicsError> {
    let [k1, k2, p1, p2] = EUROC_CAM0_DISTORTION;
    let [fx, fy, cx, cy] = EUROC_CAM0_PROJECTION;
    Ok(PinholeRadtan::new(
        752,
        480,
        [k1, k2, p1, p2, fx, fy, cx, cy],
    )?)
}

/// The preset true camera of a model: [`fisheye_190`], [`pinhole_euroc`] or [`mei_fisheye`].
///
/// # Errors
/// Never in practice.
pub fn preset_camera(model: IntrinsicModel) -> Result<Camera, IntrinsicsError> {
    Ok(match model {
        IntrinsicModel::KannalaBrandt => fisheye_190()?.into(),
        IntrinsicModel::PinholeRadtan => pinhole_euroc()?.into(),
        IntrinsicModel::Unified => mei_fisheye()?.into(),
    })
}

/// The largest angle of incidence (radians) of the image border's rays, capped by `cap`.
fn field_limit(camera: &Camera, cap: Option<f64>) -> f64 {
    let (w, h) = (f64::from(camera.width()), f64::from(camera.height()));
    let mut widest: f64 = 0.0;
    let steps = 64;
    for i in 0..=steps {
        let s = f64::from(i) / f64::from(steps);
        for p in [
            Vector2::new(s * (w - 1.0), 0.0),
            Vector2::new(s * (w - 1.0), h - 1.0),
            Vector2::new(0.0, s * (h - 1.0)),
            Vector2::new(w - 1.0, s * (h - 1.0)),
        ] {
            if let Ok(ray) = camera.unproject(&p) {
                widest = widest.max(ray.z.clamp(-1.0, 1.0).acos());
            }
        }
    }
    match cap {
        Some(c) => widest.min(c),
        None => widest,
    }
}

/// A unit vector perpendicular to `v`.
fn perpendicular(v: &Vector3<f64>) -> Vector3<f64> {
    let other = if v.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    v.cross(&other).normalize()
}

/// Simulates `options.views` views of `target` by `camera` (see the module docs).
///
/// # Errors
/// [`IntrinsicsError::InvalidInput`] for invalid options, or when a view cannot be placed so
/// that enough of the board is seen in [`MAX_VIEW_ATTEMPTS`] draws (a board too large or too
/// close for the camera's field of view).
pub fn simulate_boards(
    camera: &Camera,
    target: &PlanarTarget,
    options: &BoardSimulationOptions,
) -> Result<SimulatedBoards, IntrinsicsError> {
    options.validate()?;
    target.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let noise = Normal::new(0.0, options.noise_px)
        .map_err(|e| IntrinsicsError::InvalidInput(format!("noise: {e}")))?;
    let cap = options.max_incidence_deg.map(f64::to_radians);
    let limit = field_limit(camera, cap);
    let max_incidence = cap.unwrap_or(std::f64::consts::PI);
    let diagonal = target.diagonal();
    let centre = target.center();
    let corners_needed = ((options.min_visible_fraction * target.num_corners() as f64).ceil()
        as usize)
        .max(MIN_CORNERS_PER_IMAGE);
    let mut images = Vec::with_capacity(options.views);
    let mut poses = Vec::with_capacity(options.views);
    for view in 0..options.views {
        let mut placed = None;
        for _ in 0..MAX_VIEW_ATTEMPTS {
            let theta = rng.random::<f64>() * limit;
            let phi = rng.random::<f64>() * std::f64::consts::TAU;
            let dir = Vector3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            );
            let (lo, hi) = options.distance_range;
            let distance = diagonal * (lo + (hi - lo) * rng.random::<f64>());
            let normal = if options.parallel_to_image {
                Vector3::z()
            } else {
                let axis = perpendicular(&dir);
                let turn = rng.random::<f64>() * std::f64::consts::TAU;
                let axis = Rotation3::from_axis_angle(&Unit::new_normalize(dir), turn) * axis;
                let (lo, hi) = (options.min_tilt_deg, options.max_tilt_deg);
                let tilt = (lo + (hi - lo) * rng.random::<f64>()).to_radians();
                Rotation3::from_axis_angle(&Unit::new_normalize(axis), tilt) * dir
            };
            let spin = rng.random::<f64>() * std::f64::consts::TAU;
            let x0 = perpendicular(&normal);
            let x_axis = Rotation3::from_axis_angle(&Unit::new_normalize(normal), spin) * x0;
            let y_axis = normal.cross(&x_axis);
            let r = Rotation3::from_basis_unchecked(&[x_axis, y_axis, normal]);
            let t = dir * distance - r * centre.coords;
            let pose = Isometry3::from_parts(
                Translation3::from(t),
                UnitQuaternion::from_rotation_matrix(&r),
            );
            let mut seen = Vec::with_capacity(target.num_corners());
            for row in 0..target.rows {
                for col in 0..target.cols {
                    let p = pose * target.point(row, col);
                    if p.coords.angle(&Vector3::z()) > max_incidence {
                        continue;
                    }
                    if let Ok(px) = camera.project(&p.coords)
                        && camera.in_image(&px)
                    {
                        seen.push((row, col, px));
                    }
                }
            }
            if seen.len() < corners_needed {
                continue;
            }
            let mut detected = Vec::with_capacity(seen.len());
            for (row, col, px) in seen {
                if options.missing_fraction > 0.0 && rng.random::<f64>() < options.missing_fraction
                {
                    continue;
                }
                let noisy = px + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng));
                if camera.in_image(&noisy) {
                    detected.push(Corner {
                        row,
                        col,
                        u: noisy.x,
                        v: noisy.y,
                    });
                }
            }
            if detected.len() >= MIN_CORNERS_PER_IMAGE {
                placed = Some((pose, detected));
                break;
            }
        }
        let Some((pose, detected)) = placed else {
            return Err(IntrinsicsError::InvalidInput(format!(
                "could not place view {view} so that {corners_needed} corners of the {}x{} board \
                 are seen in {MAX_VIEW_ATTEMPTS} draws: the board is too large or too close for \
                 the camera's field of view",
                target.rows, target.cols
            )));
        };
        poses.push(pose);
        images.push(ImageCorners {
            name: format!("view_{view:03}"),
            corners: detected,
        });
    }
    Ok(SimulatedBoards {
        camera: camera.clone(),
        target: *target,
        corners: CornerSet {
            width: camera.width(),
            height: camera.height(),
            board: Some(*target),
            images,
        },
        camera_from_board: poses,
    })
}
