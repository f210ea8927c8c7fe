//! Simulated target images for any rig, with truth: board poses drawn as
//! [`crate::intrinsics::simulate::simulate_boards`] draws them for one camera at a time,
//! turned so that the camera sees the printed face, and rendered ([`super::render`]) in every
//! camera of the rig that sees the board then.
//!
//! Time `t` is placed in front of camera `t % n` (so each camera gets its share of close,
//! tilted views); whether the other cameras see the board at that time depends on the rig: a
//! stereo pair with overlap sees most boards twice, a rig whose cameras look apart never.

use std::path::Path;

use ibc_camera_models::{Camera, Rig, RigCamera};
use image::GrayImage;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

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
    /// `camera_from_board` of every image, `[camera][time]` (`None` where the camera does
    /// not see its board).
    pub camera_from_board: Vec<Vec<Option<Isometry3<f64>>>>,
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
    let mut rendered = Rendering::new(rig, grid);
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
        rendered.add_time(&options.render, options.seed, |_, rc| {
            rc.rig_from_camera.inverse() * board
        })?;
    }
    Ok(rendered.images)
}

/// The images of a simulation as they are rendered, time after time.
struct Rendering<'a> {
    images: SimulatedTargetImages,
    rig: &'a Rig,
}

impl<'a> Rendering<'a> {
    fn new(rig: &'a Rig, grid: &AprilGrid) -> Self {
        let n = rig.cameras.len();
        Self {
            images: SimulatedTargetImages {
                rig: rig.clone(),
                grid: *grid,
                times: Vec::new(),
                camera_from_board: vec![Vec::new(); n],
                images: vec![Vec::new(); n],
            },
            rig,
        }
    }

    /// Renders the next time: camera `j` sees its board at `camera_from_board(j, camera)`.
    fn add_time(
        &mut self,
        render: &RenderOptions,
        seed: u64,
        camera_from_board: impl Fn(usize, &RigCamera) -> Isometry3<f64>,
    ) -> Result<(), TargetError> {
        let t = self.images.times.len();
        let n = self.rig.cameras.len();
        for (j, rc) in self.rig.cameras.iter().enumerate() {
            let pose = camera_from_board(j, rc);
            let image = render_if_seen(rc, &pose, &self.images.grid, render, seed, t * n + j)?;
            self.images.camera_from_board[j].push(image.is_some().then_some(pose));
            self.images.images[j].push(image);
        }
        self.images.times.push(format!("t{t:04}"));
        Ok(())
    }
}

/// The image of `grid` at `camera_from_board` in `camera` if the camera sees the printed face
/// and at least [`MIN_RENDERED_CORNERS`] corners; `index` picks the noise stream.
fn render_if_seen(
    camera: &RigCamera,
    camera_from_board: &Isometry3<f64>,
    grid: &AprilGrid,
    render: &RenderOptions,
    seed: u64,
    index: usize,
) -> Result<Option<GrayImage>, TargetError> {
    let target = grid.planar_target();
    // The printed face looks along +z: a camera behind the board sees its back.
    let camera_in_board = camera_from_board.inverse().translation.vector;
    let seen = camera_in_board.z > 0.0
        && rendered_corners(&camera.camera, camera_from_board, &target, 2.0).len()
            >= MIN_RENDERED_CORNERS;
    if !seen {
        return Ok(None);
    }
    let render = RenderOptions {
        seed: seed.wrapping_mul(7_919).wrapping_add(index as u64),
        ..render.clone()
    };
    render_april_grid(&camera.camera, camera_from_board, grid, &render).map(Some)
}

/// Options of [`simulate_static_boards`].
#[derive(Clone, Debug)]
pub struct StaticBoardOptions {
    /// Times (rig poses). Default 40.
    pub times: usize,
    /// Largest rotation of the rig away from its rest pose, degrees (about a random axis).
    /// Default 25.
    pub max_rotation_deg: f64,
    /// Largest translation of the rig from its rest pose along each axis, metres. Default 0.1.
    pub max_translation_m: f64,
    /// Distance of each board from its camera at the rest pose, metres. Default 0.5.
    pub board_distance_m: f64,
    /// Rendering (blur, noise, levels).
    pub render: RenderOptions,
    /// Seed of the board placements, the motion and the noise.
    pub seed: u64,
}

impl Default for StaticBoardOptions {
    fn default() -> Self {
        Self {
            times: 40,
            max_rotation_deg: 25.0,
            max_translation_m: 0.1,
            board_distance_m: 0.5,
            render: RenderOptions::default(),
            seed: 0,
        }
    }
}

/// A rig moving in front of boards standing still, one board in front of each camera (the
/// way to calibrate cameras that never see one board at the same time: each camera sees its
/// own board while the rig turns about several axes). Board `j` faces camera `j` at the rest
/// pose, `board_distance_m` along its optical axis, tilted up to 20 degrees; at each time the
/// rig turns by up to `max_rotation_deg` and moves by up to `max_translation_m`, and every
/// camera renders its own board when it sees it. The boards are identical prints (camera `j`
/// never sees board `k != j` here, so which board is which needs no tag offsets).
///
/// # Errors
/// [`TargetError::InvalidInput`] for a rig without cameras or invalid options.
pub fn simulate_static_boards(
    rig: &Rig,
    grid: &AprilGrid,
    options: &StaticBoardOptions,
) -> Result<SimulatedTargetImages, TargetError> {
    let n = rig.cameras.len();
    if n == 0 {
        return Err(TargetError::InvalidInput("the rig has no cameras".into()));
    }
    let valid = options.max_rotation_deg.is_finite()
        && (0.0..=90.0).contains(&options.max_rotation_deg)
        && options.max_translation_m.is_finite()
        && options.max_translation_m >= 0.0
        && options.board_distance_m.is_finite()
        && options.board_distance_m > 0.0;
    if !valid {
        return Err(TargetError::InvalidInput(format!(
            "static boards: rotation {} deg must be in [0, 90], translation {} m >= 0 and \
             distance {} m > 0",
            options.max_rotation_deg, options.max_translation_m, options.board_distance_m
        )));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let target = grid.planar_target();
    let centre = target.center().coords;
    // world_from_board of each camera's board, the rig at rest being the world.
    let boards: Vec<Isometry3<f64>> = rig
        .cameras
        .iter()
        .map(|c| {
            let tilt = UnitQuaternion::from_scaled_axis(
                random_unit(&mut rng) * 20f64.to_radians() * rng.random::<f64>(),
            );
            let spin = UnitQuaternion::from_axis_angle(
                &Vector3::z_axis(),
                std::f64::consts::TAU * rng.random::<f64>(),
            );
            // Board z towards the camera: the board turned half a turn about x from facing
            // away, then tilted and spun.
            let facing = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
            let rotation = tilt * facing * spin;
            let translation = Vector3::z() * options.board_distance_m - rotation * centre;
            c.rig_from_camera * Isometry3::from_parts(translation.into(), rotation)
        })
        .collect();
    let mut rendered = Rendering::new(rig, grid);
    for _ in 0..options.times {
        let angle = options.max_rotation_deg.to_radians() * rng.random::<f64>();
        let rotation = UnitQuaternion::from_scaled_axis(random_unit(&mut rng) * angle);
        let shift =
            Vector3::from_fn(|_, _| (2.0 * rng.random::<f64>() - 1.0) * options.max_translation_m);
        let world_from_rig = Isometry3::from_parts(shift.into(), rotation);
        rendered.add_time(&options.render, options.seed, |j, rc| {
            (world_from_rig * rc.rig_from_camera).inverse() * boards[j]
        })?;
    }
    Ok(rendered.images)
}

/// A random unit vector (uniform on the sphere).
fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    let z = 2.0 * rng.random::<f64>() - 1.0;
    let phi = std::f64::consts::TAU * rng.random::<f64>();
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vector3::new(r * phi.cos(), r * phi.sin(), z)
}
