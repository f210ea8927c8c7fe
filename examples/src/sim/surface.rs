//! Textured surfaces and the landmarks they carry.
//!
//! Every surface of an environment (a floor, a wall, a pillar face, a tree crown) is a
//! primitive with an outward normal and a texture density (landmarks per square metre). Its
//! landmarks are drawn uniformly over its area; each gets the surface normal at its position
//! (so the renderer can cull points seen from behind their surface) and its own random
//! 256-bit descriptor.

use nalgebra::{Point3, Vector3};
use rand::{Rng, RngExt};

use super::random::random_descriptor;
use crate::data::BinaryDescriptor;

/// A surface primitive with outward normals.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Surface {
    /// The parallelogram `origin + a u + b v`, `a, b` in `[0, 1]`, with a fixed normal.
    Rect {
        origin: Point3<f64>,
        u: Vector3<f64>,
        v: Vector3<f64>,
        normal: Vector3<f64>,
    },
    /// The side of a vertical cylinder standing on `base`, normals pointing away from its axis.
    Cylinder {
        base: Point3<f64>,
        radius: f64,
        height: f64,
    },
    /// An axis-aligned ellipsoid, normals pointing out.
    Ellipsoid {
        center: Point3<f64>,
        radii: Vector3<f64>,
    },
}

impl Surface {
    /// A rectangle whose normal is `u x v` normalized, or its opposite with `flip`.
    pub(crate) fn rect(origin: Point3<f64>, u: Vector3<f64>, v: Vector3<f64>, flip: bool) -> Self {
        let n = u.cross(&v).normalize();
        Self::Rect {
            origin,
            u,
            v,
            normal: if flip { -n } else { n },
        }
    }

    /// A horizontal rectangle `[x0, x1] x [y0, y1]` at height `z`, facing up or down.
    pub(crate) fn horizontal(x0: f64, y0: f64, x1: f64, y1: f64, z: f64, up: bool) -> Self {
        Self::rect(
            Point3::new(x0, y0, z),
            Vector3::new(x1 - x0, 0.0, 0.0),
            Vector3::new(0.0, y1 - y0, 0.0),
            !up,
        )
    }

    /// A vertical rectangle from `(x0, y0)` to `(x1, y1)`, from `z0` to `z1`, facing left of
    /// the direction from the first point to the second.
    pub(crate) fn wall(x0: f64, y0: f64, x1: f64, y1: f64, z0: f64, z1: f64) -> Self {
        // (d, 0) x (0, 0, h) points right of d; flip to face left.
        Self::rect(
            Point3::new(x0, y0, z0),
            Vector3::new(x1 - x0, y1 - y0, 0.0),
            Vector3::new(0.0, 0.0, z1 - z0),
            true,
        )
    }

    /// The faces of the axis-aligned box `[min, max]` with outward normals; the bottom face
    /// only with `bottom`.
    pub(crate) fn box_faces(min: Point3<f64>, max: Point3<f64>, bottom: bool) -> Vec<Self> {
        let (x0, y0, z0) = (min.x, min.y, min.z);
        let (x1, y1, z1) = (max.x, max.y, max.z);
        let mut faces = vec![
            Self::wall(x0, y0, x0, y1, z0, z1), // x = x0, facing -x
            Self::wall(x1, y1, x1, y0, z0, z1), // x = x1, facing +x
            Self::wall(x1, y0, x0, y0, z0, z1), // y = y0, facing -y
            Self::wall(x0, y1, x1, y1, z0, z1), // y = y1, facing +y
            Self::horizontal(x0, y0, x1, y1, z1, true),
        ];
        if bottom {
            faces.push(Self::horizontal(x0, y0, x1, y1, z0, false));
        }
        faces
    }

    /// Area in square metres (Knud Thomsen's approximation for the ellipsoid, within 1.1%).
    pub(crate) fn area(&self) -> f64 {
        match self {
            Self::Rect { u, v, .. } => u.cross(v).norm(),
            Self::Cylinder { radius, height, .. } => 2.0 * std::f64::consts::PI * radius * height,
            Self::Ellipsoid { radii, .. } => {
                let p = 1.6075;
                let (a, b, c) = (radii.x.powf(p), radii.y.powf(p), radii.z.powf(p));
                4.0 * std::f64::consts::PI * ((a * b + a * c + b * c) / 3.0).powf(1.0 / p)
            }
        }
    }

    /// A random point of the surface and its unit normal.
    pub(crate) fn sample(&self, rng: &mut impl Rng) -> (Point3<f64>, Vector3<f64>) {
        match self {
            Self::Rect {
                origin,
                u,
                v,
                normal,
            } => {
                let (a, b): (f64, f64) = (rng.random(), rng.random());
                (origin + u * a + v * b, *normal)
            }
            Self::Cylinder {
                base,
                radius,
                height,
            } => {
                let phi = rng.random::<f64>() * std::f64::consts::TAU;
                let h = rng.random::<f64>() * height;
                let n = Vector3::new(phi.cos(), phi.sin(), 0.0);
                (base + n * *radius + Vector3::z() * h, n)
            }
            Self::Ellipsoid { center, radii } => {
                // A uniform direction, scaled onto the ellipsoid; the normal is the gradient.
                let z = 2.0 * rng.random::<f64>() - 1.0;
                let phi = rng.random::<f64>() * std::f64::consts::TAU;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let s = Vector3::new(r * phi.cos(), r * phi.sin(), z);
                let p = s.component_mul(radii);
                let n = s.component_div(radii).normalize();
                (center + p, n)
            }
        }
    }
}

/// Landmarks in structure-of-arrays form: world positions, unit normals, descriptors.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Landmarks {
    /// Positions, metres (the world frame, or an object's own frame for moving objects).
    pub positions: Vec<Point3<f64>>,
    /// Outward unit normals of the surface at each landmark.
    pub normals: Vec<Vector3<f64>>,
    /// Each landmark's own random 256-bit descriptor.
    pub descriptors: Vec<BinaryDescriptor>,
}

impl Landmarks {
    /// Number of landmarks.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Draws landmarks on `surface` at `density` per square metre: the count is the expected
    /// count rounded up or down at random (so small surfaces get their share on average).
    pub(crate) fn texture(&mut self, surface: &Surface, density: f64, rng: &mut impl Rng) {
        let expected = (surface.area() * density).max(0.0);
        let mut n = expected.floor();
        if rng.random::<f64>() < expected - n {
            n += 1.0;
        }
        for _ in 0..n as usize {
            let (p, normal) = surface.sample(rng);
            self.positions.push(p);
            self.normals.push(normal);
            self.descriptors.push(random_descriptor(rng));
        }
    }

    /// [`texture`](Self::texture) for several surfaces.
    pub(crate) fn texture_all(&mut self, surfaces: &[Surface], density: f64, rng: &mut impl Rng) {
        for s in surfaces {
            self.texture(s, density, rng);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::random::{Purpose, stream};
    use approx::assert_relative_eq;

    #[test]
    fn box_normals_point_out_and_samples_lie_on_the_surface() {
        let (min, max) = (Point3::new(1.0, 2.0, 0.0), Point3::new(3.0, 5.0, 1.5));
        let centre = nalgebra::center(&min, &max);
        let mut rng = stream(3, Purpose::World, 0, 0);
        for face in Surface::box_faces(min, max, true) {
            for _ in 0..20 {
                let (p, n) = face.sample(&mut rng);
                assert!((p - centre).dot(&n) > 0.0, "normal {n} points in at {p}");
                let eps = 1e-12;
                assert!(p.x >= min.x - eps && p.x <= max.x + eps);
                assert!(p.y >= min.y - eps && p.y <= max.y + eps);
                assert!(p.z >= min.z - eps && p.z <= max.z + eps);
            }
        }
        let total: f64 = Surface::box_faces(min, max, true)
            .iter()
            .map(Surface::area)
            .sum();
        assert_relative_eq!(
            total,
            2.0 * (2.0 * 3.0 + 2.0 * 1.5 + 3.0 * 1.5),
            epsilon = 1e-12
        );
    }

    #[test]
    fn curved_surfaces_have_outward_normals() {
        let mut rng = stream(4, Purpose::World, 0, 0);
        let cyl = Surface::Cylinder {
            base: Point3::new(1.0, 1.0, 0.0),
            radius: 0.3,
            height: 2.0,
        };
        let ell = Surface::Ellipsoid {
            center: Point3::new(0.0, 0.0, 4.0),
            radii: Vector3::new(2.0, 1.5, 1.0),
        };
        for _ in 0..50 {
            let (p, n) = cyl.sample(&mut rng);
            assert_relative_eq!(
                (p - Point3::new(1.0, 1.0, p.z)).norm(),
                0.3,
                epsilon = 1e-12
            );
            assert!((p - Point3::new(1.0, 1.0, p.z)).dot(&n) > 0.0);
            let (p, n) = ell.sample(&mut rng);
            let q = (p - Point3::new(0.0, 0.0, 4.0)).component_div(&Vector3::new(2.0, 1.5, 1.0));
            assert_relative_eq!(q.norm(), 1.0, epsilon = 1e-12);
            assert!((p - Point3::new(0.0, 0.0, 4.0)).dot(&n) > 0.0);
        }
        // Thomsen's formula is exact for a sphere.
        let sphere = Surface::Ellipsoid {
            center: Point3::origin(),
            radii: Vector3::repeat(2.0),
        };
        assert_relative_eq!(sphere.area(), 16.0 * std::f64::consts::PI, epsilon = 1e-9);
    }
}
