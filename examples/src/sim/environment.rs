//! Environments: the static world (textured surfaces carrying landmarks), the moving objects,
//! and the two drives through it (the survey that builds the map, and the calibration loop).
//!
//! Layouts are in [`garage`](super::garage), [`street`](super::street) and
//! [`garden`](super::garden). The world frame has z up and the ground at z = 0.

use super::error::SimError;
use super::grid::Grid;
use super::mover::Mover;
use super::path::Path2;
use super::random::{Purpose, stream};
use super::surface::Landmarks;

/// Side of the grid cells used to cull landmarks by range, metres.
const GRID_CELL_M: f64 = 4.0;

/// The kinds of environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvironmentKind {
    /// An indoor parking garage: concrete floor and ceiling with beams, outer walls, a grid of
    /// pillars, rows of parked cars, painted bay lines; cars and pedestrians moving in the
    /// lanes.
    Garage,
    /// An outdoor city block: building facades on both sides of the street, trees, lamp posts,
    /// parked cars, road markings; traffic and pedestrians.
    Street,
    /// A garden for the pentagon robot: lawn, hedges, a house, trees, shrubs, a shed, garden
    /// furniture; people walking.
    Garden,
}

impl EnvironmentKind {
    /// Every kind.
    pub const ALL: [Self; 3] = [Self::Garage, Self::Street, Self::Garden];

    /// Its name in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Garage => "garage",
            Self::Street => "street",
            Self::Garden => "garden",
        }
    }

    /// The kind of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// What a layout produces.
pub(crate) struct Layout {
    pub landmarks: Landmarks,
    pub movers: Vec<Mover>,
    pub calibration_path: Path2,
    pub survey_path: Path2,
}

/// A simulated environment.
#[derive(Clone, Debug)]
pub struct Environment {
    /// Its kind.
    pub kind: EnvironmentKind,
    /// The static landmarks (the candidates for map points), world frame.
    pub landmarks: Landmarks,
    /// Moving objects (never in the map).
    pub movers: Vec<Mover>,
    /// The calibration loop: where the rig drives while it records the log.
    pub calibration_path: Path2,
    /// The survey: where the map-building rig drove.
    pub survey_path: Path2,
    pub(crate) grid: Grid,
}

impl Environment {
    /// Builds the environment of `kind` for `scale` (in `(0, 1]`: the long side shrinks with
    /// it, down to a size that still holds a loop with four turns) from `seed`.
    ///
    /// # Errors
    /// [`SimError::Environment`] if the paths cannot be built at this scale (not expected for
    /// scales the scenario validation accepts).
    pub fn build(kind: EnvironmentKind, scale: f64, seed: u64) -> Result<Self, SimError> {
        let mut world = stream(seed, Purpose::World, 0, 0);
        let mut movers = stream(seed, Purpose::Movers, 0, 0);
        let layout = match kind {
            EnvironmentKind::Garage => super::garage::layout(scale, &mut world, &mut movers),
            EnvironmentKind::Street => super::street::layout(scale, &mut world, &mut movers),
            EnvironmentKind::Garden => super::garden::layout(scale, &mut world, &mut movers),
        }
        .map_err(|e| SimError::Environment(format!("{}: {e}", kind.name())))?;
        let grid = Grid::new(&layout.landmarks.positions, GRID_CELL_M);
        Ok(Self {
            kind,
            landmarks: layout.landmarks,
            movers: layout.movers,
            calibration_path: layout.calibration_path,
            survey_path: layout.survey_path,
            grid,
        })
    }
}
