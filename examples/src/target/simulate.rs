//! Simulated target images for any rig, with truth: board poses drawn as
//! [`crate::intrinsics::simulate::simulate_boards`] draws them for one camera at a time,
//! turned so that the camera sees the printed face, and rendered ([`super::render`]) in every
//! camera of the rig that sees the board then.
//!
//! Time `t` is placed in front of camera `t % n` (so each camera gets its share of close,
//! tilted views); whether the other cameras see the board at that time depends on the rig: a
//! stereo pair with overlap sees most boards twice, a rig whose cameras look apart never.

use std::path::Path;

use ibc_camera_models::{Camera, Rig};
use image::GrayImage;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::aprilgrid::AprilGrid;
use super::error::TargetError;
use super::render::{RenderOptions, render_april_grid, rendered_corners};
use crate::data::io::StagedFiles;
use crate::intrinsics::simulate::{BoardSimulationOptions, simulate_boards};

/// A camera renders a board only when at least this many of its corners project into the
/// image (fewer are not worth an image).
pub const MIN_RENDERED_CORNERS: usize = 12;

/// Options of [`simulate_target_images`].
#[derive(Clone, Debug)]
pub struct TargetSimulationOptions {
    /// Board poses placed in front of each camera (the rig's `n` cameras get `n` times as
    /// many times). Default 20.
    pub views_per_camera: usize,
    /// How a board is placed in front of a camera (distance, tilt, visibility, field of
    /// view); `views` and `seed` are ignored. Default: 0.4 to 0.8 board diagonals away,
    /// tilted 10 to 40 degrees, at least 60 % of the corners in view, within 70 degrees of
    /// the optical axis (a detector finds grids that are not too oblique).
    pub placement: BoardSimulationOptions,
    /// Rendering (blur, noise, levels).
    pub render: RenderOptions,
    /// Seed of the placements and the noise.
    pub seed: u64,
}

impl Default for TargetSimulationOptions {
    fn default() -> Self {
        Self {
            views_per_camera: 20,
            placement: BoardSimulationOptions {
                distance_range: (0.4, 0.8),
                min_tilt_deg: 10.0,
                max_tilt_deg: 40.0,
                min_visible_fraction: 0.6,
                max_incidence_deg: Some(70.0),
                ..Default::default()
            },
            render: RenderOptions::default(),
            seed: 0,
        }
    }
}

/// Rendered images of a rig with their truth.
#[derive(Clone, Debug)]
pub struct SimulatedTargetImages {
    /// The true rig.
    pub rig: Rig,
    /// The grid.
    pub grid: AprilGrid,
    /// Image names (one per time: `t0000`, `t0001`, ...).
    pub times: Vec<String>,
    /// `rig_from_board` at each time.
    pub rig_from_board: Vec<Isometry3<f64>>,
    /// The images, `[camera][time]`, `None` where the camera does not see the board.
    pub images: Vec<Vec<Option<GrayImage>>>,
}

impl SimulatedTargetImages {
    /// Writes the images as Kalibr-style folders: `DIR/CAMERA/TIME.png`, atomically (all or
    /// nothing), and the target definition as `DIR/target.yaml`.
    ///
    /// # Errors
    /// [`TargetError::Image`] naming the file that could not be encoded or written.
    pub fn write(&self, dir: impl AsRef<Path>) -> Result<(), TargetError> {
        let dir = dir.as_ref();
        let io = |path: &Path, e: String| TargetError::Image {
            path: path.to_owned(),
            reason: e,
        };
        let mut staged = StagedFiles::new(dir).map_err(|e| io(dir, e.to_string()))?;
        for (camera, images) in self.rig.cameras.iter().zip(&self.images) {
            for (time, image) in self.times.iter().zip(images) {
                let Some(image) = image else { continue };
                let path = dir.join(&camera.name).join(format!("{time}.png"));
                let mut bytes = Vec::new();
                image
                    .write_to(
                        &mut std::io::Cursor::new(&mut bytes),
                        image::ImageFormat::Png,
                    )
                    .map_err(|e| io(&path, e.to_string()))?;
                staged
                    .stage(&path, &bytes)
                    .map_err(|e| io(&path, e.to_string()))?;
            }
        }
        let target = dir.join("target.yaml");
        staged
            .stage(&target, self.grid.to_kalibr_string().as_bytes())
            .map_err(|e| io(&target, e.to_string()))?;
        staged.commit().map_err(|e| io(dir, e.to_string()))?;
        Ok(())
    }
}

/// The board pose that `simulate_boards` gives (board `z` away from the camera, a
/// chessboard's convention) turned about the board's middle row line so that the camera
/// sees the AprilGrid's printed face (`z` towards the viewer, Kalibr's frame).
fn facing(camera_from_board: &Isometry3<f64>, height: f64) -> Isometry3<f64> {
    let flip = Isometry3::from_parts(
        Translation3::new(0.0, height, 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
    );
    camera_from_board * flip
}

/// Renders `options.views_per_camera` board poses in front of each camera of `rig`, every
/// pose in every camera that sees it (see the module docs).
///
/// # Errors
/// [`TargetError::InvalidInput`] for a rig without cameras, invalid options, or a board that
/// cannot be placed in front of a camera.
pub fn simulate_target_images(
    rig: &Rig,
    grid: &AprilGrid,
    options: &TargetSimulationOptions,
) -> Result<SimulatedTargetImages, TargetError> {
    let n = rig.cameras.len();
    if n == 0 {
        return Err(TargetError::InvalidInput("the rig has no cameras".into()));
    }
    let target = grid.planar_target();
    let height = target.coordinate(target.rows - 1);
    let total = n * options.views_per_camera;
    let mut times = Vec::with_capacity(total);
    let mut rig_from_board = Vec::with_capacity(total);
    let mut images: Vec<Vec<Option<GrayImage>>> = vec![Vec::with_capacity(total); n];
    for t in 0..total {
        let c = t % n;
        let camera: &Camera = &rig.cameras[c].camera;
        let placed = simulate_boards(
            camera,
            &target,
            &BoardSimulationOptions {
                views: 1,
                noise_px: 0.0,
                seed: options.seed.wrapping_mul(1_000_003).wrapping_add(t as u64),
                ..options.placement.clone()
            },
        )
        .map_err(|e| TargetError::InvalidInput(format!("camera `{}`: {e}", rig.cameras[c].name)))?;
        let Some(pose) = placed.camera_from_board.first() else {
            return Err(TargetError::InvalidInput(format!(
                "camera `{}`: no board placed",
                rig.cameras[c].name
            )));
        };
        let board = rig.cameras[c].rig_from_camera * facing(pose, height);
        for (j, rc) in rig.cameras.iter().enumerate() {
            let camera_from_board = rc.rig_from_camera.inverse() * board;
            // The printed face looks along +z: a camera behind the board sees its back.
            let camera_in_board = camera_from_board.inverse().translation.vector;
            let seen = camera_in_board.z > 0.0
                && rendered_corners(&rc.camera, &camera_from_board, &target, 2.0).len()
                    >= MIN_RENDERED_CORNERS;
            images[j].push(if seen {
                let render = RenderOptions {
                    seed: options
                        .seed
                        .wrapping_mul(7_919)
                        .wrapping_add((t * n + j) as u64),
                    ..options.render.clone()
                };
                Some(render_april_grid(
                    &rc.camera,
                    &camera_from_board,
                    grid,
                    &render,
                )?)
            } else {
                None
            });
        }
        times.push(format!("t{t:04}"));
        rig_from_board.push(board);
    }
    Ok(SimulatedTargetImages {
        rig: rig.clone(),
        grid: *grid,
        times,
        rig_from_board,
        images,
    })
}
