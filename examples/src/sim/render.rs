//! Rendering the features of one image.
//!
//! A landmark at `X` (world) gives a feature in a camera when, with `c` the camera centre,
//! `d = |c - X|` and `n` the landmark's surface normal:
//!
//! 1. `min_range <= d <= max_range`;
//! 2. it faces the camera and is not seen too obliquely: `n . (c - X) >= cos(max_view_angle) d`
//!    (this also culls points seen from behind their surface);
//! 3. it is inside the lens's field of view: the angle between the optical axis and the ray is
//!    at most the lens's half field of view;
//! 4. the camera model projects it (`ibc-camera-models`) into the image;
//! 5. it is detected: with probability `(1 - missed_detection) * falloff(d)`, where the
//!    falloff is 1 up to `full_range` and decreases linearly to 0 at `max_range`;
//! 6. its keypoint, the projection plus Gaussian noise of `pixel_sigma_px` per axis, is still
//!    in the image.
//!
//! Its descriptor is the landmark's with each bit flipped with probability
//! `descriptor_bit_flip`. Moving objects are rendered the same way at the image's time stamp.
//! Then clutter features (a uniformly random pixel inside the lens's field of view with a
//! random descriptor) are added until `spurious_fraction` of the features are not on static
//! landmarks, and the features are shuffled, so their order tells nothing.

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Matrix3, Point3, Vector2, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::environment::Environment;
use super::options::{DetectionOptions, NoiseOptions};
use super::random::{BitFlips, random_descriptor};
use super::surface::Landmarks;
use crate::data::BinaryDescriptor;

/// Attempts to place one clutter feature inside the lens's field of view.
const CLUTTER_ATTEMPTS: usize = 20;

/// One rendered feature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Observation {
    /// The noisy keypoint.
    pub pixel: Vector2<f64>,
    /// The noisy descriptor.
    pub descriptor: BinaryDescriptor,
    /// The static landmark it is on, or `None` (moving object, clutter).
    pub landmark: Option<u32>,
}

/// A camera at one pose.
pub(crate) struct View<'a> {
    pub camera: &'a Camera,
    pub camera_from_world: Isometry3<f64>,
    /// Cosine of the lens's half field of view.
    pub cos_max_incidence: f64,
}

/// The noise and detection settings, with derived constants.
pub(crate) struct Settings {
    pixel: Option<Normal<f64>>,
    flip: BitFlips,
    detect: f64,
    spurious: f64,
    min_r2: f64,
    max_r2: f64,
    full: f64,
    max: f64,
    cos_view: f64,
}

impl Settings {
    pub(crate) fn new(noise: &NoiseOptions, detection: &DetectionOptions) -> Self {
        Self {
            pixel: (noise.pixel_sigma_px > 0.0)
                .then(|| Normal::new(0.0, noise.pixel_sigma_px).ok())
                .flatten(),
            flip: BitFlips::new(noise.descriptor_bit_flip),
            detect: 1.0 - noise.missed_detection,
            spurious: noise.spurious_fraction,
            min_r2: detection.min_range_m.powi(2),
            max_r2: detection.max_range_m.powi(2),
            full: detection.full_range_m,
            max: detection.max_range_m,
            cos_view: detection.max_view_angle_deg.to_radians().cos(),
        }
    }

    /// Detection probability at range `d`.
    fn detection_probability(&self, d: f64) -> f64 {
        if d <= self.full || self.max <= self.full {
            self.detect
        } else {
            self.detect * ((self.max - d) / (self.max - self.full)).max(0.0)
        }
    }

    /// Largest range at which anything is detected.
    pub(crate) fn max_range(&self) -> f64 {
        self.max
    }
}

/// Renders the landmarks `indices` of `landmarks`, given in a frame `f`, into the camera at
/// `camera_from_f` (whose centre in `f` is `centre`).
#[allow(clippy::too_many_arguments)] // one call site per kind of landmark; a struct would only rename them
fn observe(
    landmarks: &Landmarks,
    indices: impl Iterator<Item = u32>,
    camera_from_f: &Isometry3<f64>,
    view: &View<'_>,
    s: &Settings,
    tag_static: bool,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<Observation>,
) {
    let r: Matrix3<f64> = camera_from_f.rotation.to_rotation_matrix().into_inner();
    let t: Vector3<f64> = camera_from_f.translation.vector;
    let centre: Vector3<f64> = -(r.transpose() * t);
    let camera = view.camera;
    for i in indices {
        let k = i as usize;
        let p: &Point3<f64> = &landmarks.positions[k];
        let v = centre - p.coords;
        let d2 = v.norm_squared();
        if d2 > s.max_r2 || d2 < s.min_r2 {
            continue;
        }
        let nv = landmarks.normals[k].dot(&v);
        if nv <= 0.0 {
            continue;
        }
        let d = d2.sqrt();
        if nv < s.cos_view * d {
            continue;
        }
        let pc = r * p.coords + t;
        if pc.z < view.cos_max_incidence * d {
            continue;
        }
        let Ok(pixel) = camera.project(&pc) else {
            continue;
        };
        if !camera.in_image(&pixel) {
            continue;
        }
        if rng.random::<f64>() >= s.detection_probability(d) {
            continue;
        }
        let noisy = match &s.pixel {
            Some(n) => pixel + Vector2::new(n.sample(rng), n.sample(rng)),
            None => pixel,
        };
        if !camera.in_image(&noisy) {
            continue;
        }
        out.push(Observation {
            pixel: noisy,
            descriptor: s.flip.apply(&landmarks.descriptors[k], rng),
            landmark: tag_static.then_some(i),
        });
    }
}

/// The features of one image taken at time `t`: static landmarks among `candidates`, moving
/// objects, clutter; shuffled, in `out` (cleared first: a buffer reused from image to image,
/// so rendering does not allocate and free large blocks, whose page faults serialize
/// threads).
pub(crate) fn render_image(
    env: &Environment,
    candidates: &[u32],
    view: &View<'_>,
    t: f64,
    s: &Settings,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<Observation>,
) {
    out.clear();
    observe(
        &env.landmarks,
        candidates.iter().copied(),
        &view.camera_from_world,
        view,
        s,
        true,
        rng,
        out,
    );
    let n_static = out.len();
    let world_from_camera = view.camera_from_world.inverse();
    for mover in &env.movers {
        let world_from_object = mover.world_from_object(t);
        let gap =
            (world_from_object.translation.vector - world_from_camera.translation.vector).norm();
        if gap > s.max_range() + mover.radius {
            continue;
        }
        let camera_from_object = view.camera_from_world * world_from_object;
        let n = mover.landmarks.len() as u32;
        observe(
            &mover.landmarks,
            0..n,
            &camera_from_object,
            view,
            s,
            false,
            rng,
            out,
        );
    }
    if s.spurious > 0.0 {
        let wanted = (s.spurious / (1.0 - s.spurious) * n_static as f64).round() as usize;
        let have = out.len() - n_static;
        for _ in have..wanted {
            if let Some(pixel) = clutter_pixel(view, rng) {
                out.push(Observation {
                    pixel,
                    descriptor: random_descriptor(rng),
                    landmark: None,
                });
            }
        }
    }
    // Fisher-Yates.
    for i in (1..out.len()).rev() {
        let j = rng.random_range(0..=i);
        out.swap(i, j);
    }
}

/// A uniformly random pixel whose ray is inside the lens's field of view.
fn clutter_pixel(view: &View<'_>, rng: &mut ChaCha8Rng) -> Option<Vector2<f64>> {
    let w = f64::from(view.camera.width());
    let h = f64::from(view.camera.height());
    for _ in 0..CLUTTER_ATTEMPTS {
        let pixel = Vector2::new(rng.random::<f64>() * w - 0.5, rng.random::<f64>() * h - 0.5);
        if let Ok(ray) = view.camera.unproject_fast(&pixel)
            && ray.z >= view.cos_max_incidence
            && view.camera.in_image(&pixel)
        {
            return Some(pixel);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::random::{Purpose, stream};
    use ibc_camera_models::PinholeRadtan;

    #[test]
    fn landmarks_behind_their_surface_oblique_or_out_of_range_are_culled() {
        let camera = Camera::from(
            PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 319.5, 239.5]).unwrap(),
        );
        let view = View {
            camera: &camera,
            camera_from_world: Isometry3::identity(),
            cos_max_incidence: 0.0,
        };
        let noise = NoiseOptions {
            pixel_sigma_px: 0.0,
            missed_detection: 0.0,
            ..NoiseOptions::default()
        };
        let s = Settings::new(&noise, &DetectionOptions::default());
        let facing = Vector3::new(0.0, 0.0, -1.0);
        let cases = [
            (Point3::new(0.0, 0.0, 5.0), facing, true),
            (Point3::new(1.0, 0.0, 5.0), -facing, false), // seen from behind
            (Point3::new(0.0, 1.0, 5.0), Vector3::x(), false), // 90 degrees off its normal
            (Point3::new(0.0, 0.0, 40.0), facing, false), // past the range
            (Point3::new(0.0, 0.0, -5.0), -facing, false), // behind the camera
            (Point3::new(0.0, 0.0, 0.1), facing, false),  // too near
            (Point3::new(50.0, 0.0, 5.0), facing, false), // outside the image
        ];
        let landmarks = Landmarks {
            positions: cases.iter().map(|c| c.0).collect(),
            normals: cases.iter().map(|c| c.1).collect(),
            descriptors: vec![[7; 4]; cases.len()],
        };
        let mut rng = stream(1, Purpose::LogImage, 0, 0);
        let mut out = Vec::new();
        let n = cases.len() as u32;
        observe(
            &landmarks,
            0..n,
            &Isometry3::identity(),
            &view,
            &s,
            true,
            &mut rng,
            &mut out,
        );
        let seen: Vec<u32> = out.iter().filter_map(|o| o.landmark).collect();
        assert_eq!(seen, [0]);
        assert!((out[0].pixel - Vector2::new(319.5, 239.5)).norm() < 1e-12);
        // Detection falls off linearly from 20 to 30 m.
        assert!((s.detection_probability(25.0) - 0.5).abs() < 1e-12);
        assert_eq!(s.detection_probability(10.0), 1.0);
    }
}
