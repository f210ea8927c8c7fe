//! Moving objects (driving cars, walking pedestrians): things that are not in the map but
//! give features. Each carries textured landmarks in its own frame (x forward, z up, origin
//! on the ground) and travels along a path: around it when the path is closed, back and forth
//! when it is open.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, RngExt};

use super::path::Path2;
use super::surface::{Landmarks, Surface};

/// A moving object.
#[derive(Clone, Debug, PartialEq)]
pub struct Mover {
    /// Landmarks in the object's frame.
    pub landmarks: Landmarks,
    /// The radius of a sphere about the object's origin that holds all its landmarks.
    pub radius: f64,
    /// The path it follows.
    pub path: Path2,
    /// Speed, metres per second.
    pub speed_m_s: f64,
    /// Arc length at time 0.
    pub start_m: f64,
}

/// Texture densities of moving objects, landmarks per square metre.
const CAR_DENSITY: f64 = 2.5;
const PEDESTRIAN_DENSITY: f64 = 8.0;

impl Mover {
    /// A car of random size (two boxes: body and cabin).
    pub(crate) fn car(path: Path2, speed_m_s: f64, start_m: f64, rng: &mut impl Rng) -> Self {
        let mut landmarks = Landmarks::default();
        for s in car_surfaces(Point3::origin(), 0.0, rng) {
            landmarks.texture(&s, CAR_DENSITY, rng);
        }
        Self::new(landmarks, path, speed_m_s, start_m)
    }

    /// A pedestrian: a cylinder for the body and a sphere for the head.
    pub(crate) fn pedestrian(
        path: Path2,
        speed_m_s: f64,
        start_m: f64,
        rng: &mut impl Rng,
    ) -> Self {
        let mut landmarks = Landmarks::default();
        let h = rng.random_range(1.55..1.9);
        let body = Surface::Cylinder {
            base: Point3::origin(),
            radius: rng.random_range(0.18..0.26),
            height: h - 0.25,
        };
        let head = Surface::Ellipsoid {
            center: Point3::new(0.0, 0.0, h - 0.12),
            radii: Vector3::repeat(0.11),
        };
        landmarks.texture(&body, PEDESTRIAN_DENSITY, rng);
        landmarks.texture(&head, PEDESTRIAN_DENSITY, rng);
        Self::new(landmarks, path, speed_m_s, start_m)
    }

    fn new(landmarks: Landmarks, path: Path2, speed_m_s: f64, start_m: f64) -> Self {
        let radius = landmarks
            .positions
            .iter()
            .map(|p| p.coords.norm())
            .fold(0.0, f64::max);
        Self {
            landmarks,
            radius,
            path,
            speed_m_s,
            start_m,
        }
    }

    /// The object's pose at time `t` (seconds).
    pub fn world_from_object(&self, t: f64) -> Isometry3<f64> {
        let travelled = self.start_m + self.speed_m_s * t;
        let len = self.path.length();
        let (p, heading) = if self.path.is_closed() || len <= 0.0 {
            self.path.at(travelled)
        } else {
            // Back and forth: a triangle wave over [0, len].
            let s = travelled.rem_euclid(2.0 * len);
            if s <= len {
                self.path.at(s)
            } else {
                let (p, h) = self.path.at(2.0 * len - s);
                (p, h + std::f64::consts::PI)
            }
        };
        Isometry3::from_parts(
            Translation3::new(p.x, p.y, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading),
        )
    }
}

/// The surfaces of a car of random size centred at `centre` (on the ground) with its length
/// along the direction `yaw` (radians; only 0 and pi/2 are used, so boxes stay axis-aligned).
pub(crate) fn car_surfaces(centre: Point3<f64>, yaw: f64, rng: &mut impl Rng) -> Vec<Surface> {
    let length = rng.random_range(4.1..4.9);
    let width = rng.random_range(1.7..1.9);
    let (hl, hw) = if yaw.abs() < 0.1 {
        (length / 2.0, width / 2.0)
    } else {
        (width / 2.0, length / 2.0)
    };
    let roof = rng.random_range(1.4..1.6);
    let body_top = 0.95;
    let mut faces = Surface::box_faces(
        centre + Vector3::new(-hl, -hw, 0.25),
        centre + Vector3::new(hl, hw, body_top),
        false,
    );
    // The cabin is shorter than the body along the car's length.
    let (cl, cw) = if yaw.abs() < 0.1 {
        (hl * 0.55, hw * 0.9)
    } else {
        (hl * 0.9, hw * 0.55)
    };
    faces.extend(Surface::box_faces(
        centre + Vector3::new(-cl, -cw, body_top),
        centre + Vector3::new(cl, cw, roof),
        false,
    ));
    faces
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::random::{Purpose, stream};
    use nalgebra::Vector2;

    #[test]
    fn movers_go_back_and_forth_on_open_paths() {
        let path = Path2::rounded(
            &[Vector2::new(0.0, 0.0), Vector2::new(10.0, 0.0)],
            0.0,
            false,
        )
        .unwrap();
        let mut rng = stream(1, Purpose::Movers, 0, 0);
        let m = Mover::pedestrian(path, 1.0, 0.0, &mut rng);
        let at = |t: f64| m.world_from_object(t).translation.vector.x;
        assert!((at(4.0) - 4.0).abs() < 1e-12);
        assert!((at(14.0) - 6.0).abs() < 1e-12);
        assert!((at(21.0) - 1.0).abs() < 1e-12);
        assert!(m.radius > 1.4 && m.radius < 2.0);
    }
}
