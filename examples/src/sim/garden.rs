//! The garden for the pentagon robot, after the TrimBot2020 test gardens.
//!
//! A lawn of `G x 28 m` (`G` = 44 m at scale 1) closed by hedges 1.6 to 2 m tall on three
//! sides and a house front on the fourth, with flower beds and shrubs along the hedges, trees,
//! topiary, garden furniture and a shed in the middle and the corners.
//!
//! - Calibration loop: a rectangle 5 m in from the boundary, counter-clockwise, corners of
//!   2.5 m radius: 100 m at scale 1.
//! - Survey: a rectangle 6.5 m in, clockwise.
//! - Moving objects: two people walking.

use nalgebra::{Point3, Vector2, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::environment::Layout;
use super::mover::Mover;
use super::path::Path2;
use super::surface::{Landmarks, Surface};

/// The garden's length at scale 1, and its shortest (metres).
const FULL_LENGTH: f64 = 44.0;
const MIN_LENGTH: f64 = 22.0;
/// Its depth (metres).
const DEPTH: f64 = 28.0;
/// The loops' insets from the boundary (metres).
const LOOP_INSET: f64 = 5.0;
const SURVEY_INSET: f64 = 6.5;
/// Trees and furniture keep this far inside the survey loop (metres).
const CLEARANCE: f64 = 2.5;

/// Texture densities (landmarks per square metre).
const LAWN: f64 = 1.0;
const BED: f64 = 5.0;
const HEDGE: f64 = 6.0;
const HOUSE: f64 = 4.0;
const TRUNK: f64 = 6.0;
const CROWN: f64 = 3.0;
const SHRUB: f64 = 5.0;
const WOOD: f64 = 3.0;

/// The garden at `scale`.
pub(crate) fn layout(
    scale: f64,
    world: &mut ChaCha8Rng,
    movers: &mut ChaCha8Rng,
) -> Result<Layout, String> {
    let g = (FULL_LENGTH * scale).max(MIN_LENGTH);
    let d = DEPTH;
    let mut lm = Landmarks::default();
    lm.texture(
        &Surface::horizontal(-1.0, -1.0, g + 1.0, d, 0.0, true),
        LAWN,
        world,
    );
    // Hedges on the south, west and east sides; the house on the north.
    let hedges = [
        (Point3::new(-1.0, -1.0, 0.0), Point3::new(g + 1.0, 0.0, 1.8)),
        (Point3::new(-1.0, 0.0, 0.0), Point3::new(0.0, d, 1.6)),
        (Point3::new(g, 0.0, 0.0), Point3::new(g + 1.0, d, 2.0)),
    ];
    for (lo, hi) in hedges {
        lm.texture_all(&Surface::box_faces(lo, hi, false), HEDGE, world);
    }
    lm.texture(&Surface::wall(g + 1.0, d, -1.0, d, 0.0, 6.5), HOUSE, world);
    // Flower beds and shrubs in the 1.5 m band inside the hedges.
    for (x0, y0, x1, y1) in [(0.0, 0.0, g, 1.5), (0.0, 1.5, 1.5, d), (g - 1.5, 1.5, g, d)] {
        lm.texture(&Surface::horizontal(x0, y0, x1, y1, 0.01, true), BED, world);
        let n = ((x1 - x0) * (y1 - y0) / 8.0).round() as usize;
        for _ in 0..n {
            let c = Point3::new(
                world.random_range(x0..x1),
                world.random_range(y0..y1),
                world.random_range(0.3..0.6),
            );
            let r = world.random_range(0.35..0.7);
            let shrub = Surface::Ellipsoid {
                center: c,
                radii: Vector3::new(r, r, r * 0.8),
            };
            lm.texture(&shrub, SHRUB, world);
        }
    }
    // A shed in the south-west corner, a bench in the south-east one.
    lm.texture_all(
        &Surface::box_faces(
            Point3::new(0.3, 0.3, 0.0),
            Point3::new(3.3, 2.8, 2.2),
            false,
        ),
        WOOD,
        world,
    );
    lm.texture_all(
        &Surface::box_faces(
            Point3::new(g - 3.0, 0.5, 0.0),
            Point3::new(g - 0.8, 1.1, 0.5),
            false,
        ),
        WOOD,
        world,
    );
    // Trees, topiary and a table in the middle, clear of the survey loop.
    let (cx0, cy0) = (SURVEY_INSET + CLEARANCE, SURVEY_INSET + CLEARANCE);
    let (cx1, cy1) = (g - cx0, d - cy0);
    if cx1 > cx0 && cy1 > cy0 {
        let area = (cx1 - cx0) * (cy1 - cy0);
        for k in 0..((area / 40.0).round() as usize).max(1) {
            let c = Vector2::new(world.random_range(cx0..cx1), world.random_range(cy0..cy1));
            if k % 3 == 2 {
                let r = world.random_range(0.5..0.9);
                let topiary = Surface::Ellipsoid {
                    center: Point3::new(c.x, c.y, r),
                    radii: Vector3::repeat(r),
                };
                lm.texture(&topiary, SHRUB, world);
                continue;
            }
            let h = world.random_range(1.8..3.0);
            let trunk = Surface::Cylinder {
                base: Point3::new(c.x, c.y, 0.0),
                radius: world.random_range(0.12..0.3),
                height: h,
            };
            let r = world.random_range(1.2..2.5f64).min(CLEARANCE);
            let crown = Surface::Ellipsoid {
                center: Point3::new(c.x, c.y, h + r * 0.8),
                radii: Vector3::new(r, r, r * 0.9),
            };
            lm.texture(&trunk, TRUNK, world);
            lm.texture(&crown, CROWN, world);
        }
        let t = Vector2::new((cx0 + cx1) / 2.0, (cy0 + cy1) / 2.0);
        lm.texture_all(
            &Surface::box_faces(
                Point3::new(t.x - 0.8, t.y - 0.45, 0.0),
                Point3::new(t.x + 0.8, t.y + 0.45, 0.75),
                false,
            ),
            WOOD,
            world,
        );
    }

    let p = Vector2::new;
    let rect = |inset: f64, ccw: bool| {
        let mut w = vec![
            p(inset, inset),
            p(g - inset, inset),
            p(g - inset, d - inset),
            p(inset, d - inset),
        ];
        if !ccw {
            w.reverse();
        }
        Path2::rounded(&w, 2.5, true)
    };
    let calibration_path = rect(LOOP_INSET, true)?;
    let survey_path = rect(SURVEY_INSET, false)?;
    let mut moving = Vec::new();
    for inset in [3.0f64, 8.0] {
        let path = rect(inset.min(d / 2.0 - 3.0), movers.random::<bool>())?;
        let start = movers.random_range(0.0..path.length());
        moving.push(Mover::pedestrian(
            path,
            movers.random_range(0.8..1.3),
            start,
            movers,
        ));
    }
    Ok(Layout {
        landmarks: lm,
        movers: moving,
        calibration_path,
        survey_path,
    })
}
