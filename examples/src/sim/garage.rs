//! The indoor parking garage, after the paper's indoor experiment.
//!
//! One level, `L x 50 m` (`L` = 130 m at scale 1), 2.6 m floor to ceiling, ceiling beams over
//! each pillar column. Three driving lanes run along x (centre lines y = 8, 25 and 42 m) and
//! two across (x = 6 m and `L` − 6 m). Parking bays (2.5 m wide) line both walls and form two
//! double rows between the lanes, from x = 10 m to `L` − 10 m; three bays in four hold a car.
//! Pillars (0.6 m square) stand every 7.5 m at the lane edges of the double rows.
//!
//! - Calibration loop: around the outer lanes (y = 8 and 42 m, x = 6 and `L` − 6 m),
//!   counter-clockwise, corners of 5 m radius: 295 m at scale 1.
//! - Survey: a serpentine through all three long lanes, a metre off the loop's lines where
//!   they share a lane: 383 m at scale 1.
//! - Moving objects: cars going up and down the middle lane, pedestrians along the lane
//!   edges.

use nalgebra::{Point3, Vector2, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::environment::Layout;
use super::mover::{Mover, car_surfaces};
use super::path::Path2;
use super::surface::{Landmarks, Surface};

/// Length of the garage at scale 1 (metres).
const FULL_LENGTH: f64 = 130.0;
/// The shortest garage (metres): room for the loop's four turns and two pillar columns.
const MIN_LENGTH: f64 = 40.0;
/// Width (metres).
const WIDTH: f64 = 50.0;
/// Floor-to-ceiling height (metres).
const HEIGHT: f64 = 2.6;
/// Bay width and pillar spacing along x (metres).
const BAY: f64 = 2.5;
const PILLAR_SPACING: f64 = 7.5;
/// Where the bays start and end, from each end wall (metres).
const BAYS_FROM_WALL: f64 = 10.0;
/// Parking rows `(y0, y1)`: along the walls and the two double rows.
const ROWS: [(f64, f64); 6] = [
    (0.3, 5.0),
    (11.0, 16.5),
    (16.5, 22.0),
    (28.0, 33.5),
    (33.5, 39.0),
    (45.0, 49.7),
];
/// The y of the pillar rows.
const PILLAR_ROWS: [f64; 4] = [11.3, 21.7, 28.3, 38.7];
/// Probability that a bay holds a car.
const OCCUPANCY: f64 = 0.75;

/// Texture densities (landmarks per square metre), chosen so that a 190-degree fisheye sees
/// about a thousand features: concrete floor and walls are plain, cars, signs on the pillars
/// and the services under the ceiling are busy, painted lines are dense.
const FLOOR: f64 = 0.5;
const CEILING: f64 = 0.8;
const BEAM: f64 = 1.5;
const WALL: f64 = 2.0;
const PILLAR: f64 = 5.0;
const CAR: f64 = 2.5;
const LINE: f64 = 5.0;
/// Width of painted bay lines (metres).
const LINE_WIDTH: f64 = 0.12;

/// The garage's length at `scale`.
pub(crate) fn length(scale: f64) -> f64 {
    (FULL_LENGTH * scale).clamp(MIN_LENGTH, FULL_LENGTH.max(FULL_LENGTH * scale))
}

/// The x of every pillar column.
fn pillar_columns(l: f64) -> Vec<f64> {
    let n = ((l - 2.0 * BAYS_FROM_WALL) / PILLAR_SPACING).floor() as usize;
    (0..=n)
        .map(|k| BAYS_FROM_WALL + PILLAR_SPACING * k as f64)
        .collect()
}

/// The garage at `scale`.
pub(crate) fn layout(
    scale: f64,
    world: &mut ChaCha8Rng,
    movers: &mut ChaCha8Rng,
) -> Result<Layout, String> {
    let l = length(scale);
    let mut lm = Landmarks::default();
    // Floor, ceiling and the four walls, facing in.
    lm.texture(
        &Surface::horizontal(0.0, 0.0, l, WIDTH, 0.0, true),
        FLOOR,
        world,
    );
    lm.texture(
        &Surface::horizontal(0.0, 0.0, l, WIDTH, HEIGHT, false),
        CEILING,
        world,
    );
    let walls = [
        Surface::wall(0.0, 0.0, l, 0.0, 0.0, HEIGHT),
        Surface::wall(l, 0.0, l, WIDTH, 0.0, HEIGHT),
        Surface::wall(l, WIDTH, 0.0, WIDTH, 0.0, HEIGHT),
        Surface::wall(0.0, WIDTH, 0.0, 0.0, 0.0, HEIGHT),
    ];
    lm.texture_all(&walls, WALL, world);
    let columns = pillar_columns(l);
    for &x in &columns {
        // A beam across the ceiling: its underside and two sides.
        let z0 = HEIGHT - 0.45;
        let beam = [
            Surface::horizontal(x - 0.2, 0.0, x + 0.2, WIDTH, z0, false),
            Surface::wall(x - 0.2, 0.0, x - 0.2, WIDTH, z0, HEIGHT),
            Surface::wall(x + 0.2, WIDTH, x + 0.2, 0.0, z0, HEIGHT),
        ];
        lm.texture_all(&beam, BEAM, world);
        for &y in &PILLAR_ROWS {
            let faces = Surface::box_faces(
                Point3::new(x - 0.3, y - 0.3, 0.0),
                Point3::new(x + 0.3, y + 0.3, z0),
                false,
            );
            lm.texture_all(&faces, PILLAR, world);
        }
    }
    // Bays: painted lines between them, and parked cars.
    let n_bays = ((l - 2.0 * BAYS_FROM_WALL) / BAY).floor() as usize;
    for &(y0, y1) in &ROWS {
        for b in 0..=n_bays {
            let x = BAYS_FROM_WALL + BAY * b as f64;
            let line = Surface::horizontal(
                x - LINE_WIDTH / 2.0,
                y0,
                x + LINE_WIDTH / 2.0,
                y1,
                0.0,
                true,
            );
            lm.texture(&line, LINE, world);
            if b < n_bays && world.random::<f64>() < OCCUPANCY {
                let jitter = Vector3::new(
                    world.random_range(-0.1..0.1),
                    world.random_range(-0.2..0.2),
                    0.0,
                );
                let centre = Point3::new(x + BAY / 2.0, (y0 + y1) / 2.0, 0.0) + jitter;
                let faces = car_surfaces(centre, std::f64::consts::FRAC_PI_2, world);
                lm.texture_all(&faces, CAR, world);
            }
        }
    }

    let p = |x: f64, y: f64| Vector2::new(x, y);
    let calibration_path = Path2::rounded(
        &[p(6.0, 8.0), p(l - 6.0, 8.0), p(l - 6.0, 42.0), p(6.0, 42.0)],
        5.0,
        true,
    )?;
    let survey_path = Path2::rounded(
        &[
            p(6.0, 9.0),
            p(l - 6.0, 9.0),
            p(l - 6.0, 25.0),
            p(6.0, 25.0),
            p(6.0, 41.0),
            p(l - 6.0, 41.0),
        ],
        5.0,
        false,
    )?;

    let mut moving = Vec::new();
    let lane = Path2::rounded(&[p(8.0, 24.0), p(l - 8.0, 24.0)], 0.0, false)?;
    for _ in 0..((l / 45.0).round() as usize).max(1) {
        let speed = movers.random_range(2.5..4.5);
        let start = movers.random_range(0.0..2.0 * lane.length());
        moving.push(Mover::car(lane.clone(), speed, start, movers));
    }
    let walkways = [5.4, 10.6, 22.4, 27.6, 39.4, 44.6];
    for _ in 0..((l / 15.0).round() as usize).max(2) {
        let y = walkways[movers.random_range(0..walkways.len())];
        let path = Path2::rounded(
            &[p(BAYS_FROM_WALL, y), p(l - BAYS_FROM_WALL, y)],
            0.0,
            false,
        )?;
        let speed = movers.random_range(1.0..1.6);
        let start = movers.random_range(0.0..2.0 * path.length());
        moving.push(Mover::pedestrian(path, speed, start, movers));
    }
    Ok(Layout {
        landmarks: lm,
        movers: moving,
        calibration_path,
        survey_path,
    })
}
