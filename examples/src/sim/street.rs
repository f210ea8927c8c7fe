//! The outdoor street: a city block and its eight neighbours, after the paper's outdoor
//! experiment.
//!
//! The centre block is `B x 36 m` (`B` = 92 m at scale 1); streets between blocks are 17.5 m
//! from facade to facade: a 3 m sidewalk, a 2.5 m parking lane, two 3.25 m lanes, a parking
//! lane and a sidewalk. Every block side is a row of buildings 8 to 20 m wide and 8 to 20 m
//! tall with busy shop fronts on the ground floor. Trees and lamp posts stand on the
//! sidewalks, cars are parked in the parking lanes, dashed lines mark the lanes.
//!
//! - Calibration loop: clockwise around the centre block in the lane next to it (right-hand
//!   traffic), corners of 6 m radius: 302 m at scale 1.
//! - Survey: counter-clockwise in the other lane.
//! - Moving objects: cars in both lanes, pedestrians on the sidewalks.

use nalgebra::{Point3, Vector2};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::environment::Layout;
use super::mover::{Mover, car_surfaces};
use super::path::Path2;
use super::surface::{Landmarks, Surface};

/// The centre block's length at scale 1, and its shortest (metres).
const FULL_LENGTH: f64 = 92.0;
const MIN_LENGTH: f64 = 30.0;
/// The centre block's depth at scale 1, and its shortest (metres).
const FULL_DEPTH: f64 = 36.0;
const MIN_DEPTH: f64 = 20.0;
/// Facade to facade across a street (metres).
const STREET: f64 = 17.5;
/// How far the neighbouring blocks reach (metres): past the detection range of the loop.
const NEIGHBOUR: f64 = 30.0;
/// Offsets from a facade into the street (metres).
const TREE_OFFSET: f64 = 2.2;
const LAMP_OFFSET: f64 = 2.8;
const PARKED_OFFSET: f64 = 4.25;
const NEAR_LANE: f64 = 7.1;
const FAR_LANE: f64 = 10.4;
const CENTRE_LINE: f64 = 8.75;

/// Texture densities (landmarks per square metre).
const FACADE: f64 = 1.2;
const SHOP: f64 = 3.5;
const SIDEWALK: f64 = 0.6;
const ROAD: f64 = 0.15;
const LINE: f64 = 5.0;
const CAR: f64 = 2.5;
const TRUNK: f64 = 3.0;
const CROWN: f64 = 1.8;
const LAMP: f64 = 3.0;

/// One side of a block, walked with the block on the right (so walls face left, outward).
struct Side {
    a: Vector2<f64>,
    b: Vector2<f64>,
}

impl Side {
    fn len(&self) -> f64 {
        (self.b - self.a).norm()
    }

    fn dir(&self) -> Vector2<f64> {
        (self.b - self.a) / self.len()
    }

    /// The point `s` metres along the side and `offset` metres out into the street.
    fn at(&self, s: f64, offset: f64) -> Vector2<f64> {
        let d = self.dir();
        self.a + d * s + Vector2::new(-d.y, d.x) * offset
    }

    /// Whether the side runs along x.
    fn along_x(&self) -> bool {
        self.dir().x.abs() > 0.5
    }
}

/// The four sides of the block `[x0, x1] x [y0, y1]`, walked clockwise.
fn sides(x0: f64, y0: f64, x1: f64, y1: f64) -> [Side; 4] {
    let v = Vector2::new;
    [
        Side {
            a: v(x0, y0),
            b: v(x0, y1),
        },
        Side {
            a: v(x0, y1),
            b: v(x1, y1),
        },
        Side {
            a: v(x1, y1),
            b: v(x1, y0),
        },
        Side {
            a: v(x1, y0),
            b: v(x0, y0),
        },
    ]
}

/// The street at `scale`.
pub(crate) fn layout(
    scale: f64,
    world: &mut ChaCha8Rng,
    movers: &mut ChaCha8Rng,
) -> Result<Layout, String> {
    let bx = (FULL_LENGTH * scale).max(MIN_LENGTH);
    let by = (FULL_DEPTH * scale).clamp(MIN_DEPTH, FULL_DEPTH.max(FULL_DEPTH * scale));
    let mut lm = Landmarks::default();
    let (gx0, gy0) = (-STREET - NEIGHBOUR, -STREET - NEIGHBOUR);
    let (gx1, gy1) = (bx + STREET + NEIGHBOUR, by + STREET + NEIGHBOUR);
    lm.texture(
        &Surface::horizontal(gx0, gy0, gx1, gy1, 0.0, true),
        ROAD,
        world,
    );

    let xs = [
        (-STREET - NEIGHBOUR, -STREET),
        (0.0, bx),
        (bx + STREET, bx + STREET + NEIGHBOUR),
    ];
    let ys = [
        (-STREET - NEIGHBOUR, -STREET),
        (0.0, by),
        (by + STREET, by + STREET + NEIGHBOUR),
    ];
    for &(x0, x1) in &xs {
        for &(y0, y1) in &ys {
            for side in sides(x0, y0, x1, y1) {
                block_side(&side, &mut lm, world);
            }
        }
    }
    // Dashed centre lines of the four streets around the centre block.
    for side in sides(0.0, 0.0, bx, by) {
        let d = side.dir();
        let mut s = -STREET;
        while s + 3.0 <= side.len() + STREET {
            let p0 = side.at(s, CENTRE_LINE);
            let p1 = side.at(s + 3.0, CENTRE_LINE);
            let w = Vector2::new(-d.y, d.x) * 0.075;
            let (lo, hi) = ((p0 - w).inf(&(p1 + w)), (p0 - w).sup(&(p1 + w)));
            lm.texture(
                &Surface::horizontal(lo.x, lo.y, hi.x, hi.y, 0.0, true),
                LINE,
                world,
            );
            s += 6.0;
        }
    }

    let p = Vector2::new;
    let loop_at = |o: f64, clockwise: bool| {
        let mut w = vec![p(-o, -o), p(-o, by + o), p(bx + o, by + o), p(bx + o, -o)];
        if !clockwise {
            w.reverse();
        }
        Path2::rounded(&w, 6.0, true)
    };
    let calibration_path = loop_at(NEAR_LANE, true)?;
    let survey_path = loop_at(FAR_LANE, false)?;

    let mut moving = Vec::new();
    let n_cars = ((bx / 30.0).round() as usize).max(2);
    for i in 0..n_cars {
        let path = loop_at(if i % 2 == 0 { FAR_LANE } else { NEAR_LANE }, i % 2 == 1)?;
        let speed = movers.random_range(5.0..9.0);
        let start = movers.random_range(0.0..path.length());
        moving.push(Mover::car(path, speed, start, movers));
    }
    for i in 0..((bx / 10.0).round() as usize).max(3) {
        let offset = if i % 2 == 0 { 1.5 } else { STREET - 1.5 };
        let path = loop_at(offset, movers.random::<bool>())?;
        let speed = movers.random_range(1.0..1.6);
        let start = movers.random_range(0.0..path.length());
        moving.push(Mover::pedestrian(path, speed, start, movers));
    }
    Ok(Layout {
        landmarks: lm,
        movers: moving,
        calibration_path,
        survey_path,
    })
}

/// The buildings, sidewalk, trees, lamp posts and parked cars of one block side.
fn block_side(side: &Side, lm: &mut Landmarks, rng: &mut ChaCha8Rng) {
    let len = side.len();
    // Buildings.
    let mut s = 0.0;
    while s < len - 1e-9 {
        let w = rng.random_range(8.0..20.0f64).min(len - s);
        let (a, b) = (side.at(s, 0.0), side.at(s + w, 0.0));
        let h = rng.random_range(8.0..20.0);
        let density = FACADE * rng.random_range(0.6..1.4);
        lm.texture(&Surface::wall(a.x, a.y, b.x, b.y, 3.5, h), density, rng);
        lm.texture(&Surface::wall(a.x, a.y, b.x, b.y, 0.0, 3.5), SHOP, rng);
        s += w;
    }
    // Sidewalk.
    let (a, b) = (side.at(0.0, 0.0), side.at(len, 3.0));
    let (lo, hi) = (a.inf(&b), a.sup(&b));
    lm.texture(
        &Surface::horizontal(lo.x, lo.y, hi.x, hi.y, 0.0, true),
        SIDEWALK,
        rng,
    );
    // Trees every 9 m, lamp posts every 25 m, parked cars in 6 m slots away from corners.
    let mut s = 4.5;
    while s < len - 4.5 {
        if rng.random::<f64>() < 0.6 {
            let c = side.at(s, TREE_OFFSET);
            let trunk = Surface::Cylinder {
                base: Point3::new(c.x, c.y, 0.0),
                radius: rng.random_range(0.15..0.25),
                height: 3.0,
            };
            let r = rng.random_range(1.6..2.0);
            let crown = Surface::Ellipsoid {
                center: Point3::new(c.x, c.y, 3.0 + rng.random_range(1.5..2.2)),
                radii: nalgebra::Vector3::new(r, r, rng.random_range(1.5..2.2)),
            };
            lm.texture(&trunk, TRUNK, rng);
            lm.texture(&crown, CROWN, rng);
        }
        s += 9.0;
    }
    let mut s = 12.5;
    while s < len - 5.0 {
        let c = side.at(s, LAMP_OFFSET);
        let post = Surface::Cylinder {
            base: Point3::new(c.x, c.y, 0.0),
            radius: 0.09,
            height: 6.0,
        };
        lm.texture(&post, LAMP, rng);
        s += 25.0;
    }
    let mut s = 8.0;
    while s < len - 8.0 {
        if rng.random::<f64>() < 0.55 {
            let c = side.at(s, PARKED_OFFSET);
            let yaw = if side.along_x() {
                0.0
            } else {
                std::f64::consts::FRAC_PI_2
            };
            lm.texture_all(
                &car_surfaces(Point3::new(c.x, c.y, 0.0), yaw, rng),
                CAR,
                rng,
            );
        }
        s += 6.0;
    }
}
