//! Rendering AprilGrid images through any camera model, with truth: the simulator of
//! `ibc target` (so that detection, intrinsics and extrinsics are tested from pixels).
//!
//! # Method
//! Every pixel corner `(u - 1/2, v - 1/2)` is unprojected through the camera
//! ([`CameraModel::unproject`]), the ray intersected with the board plane `z = 0` and its
//! board point kept. Each pixel is then sampled at `n x n` points, their board points
//! interpolated bilinearly between the pixel's four corners (the map from pixel to board is
//! smooth: the interpolation error within one pixel is second order, far below the 0.1 px this
//! simulator is for), and the pattern's black and white averaged (area sampling, an ideal
//! lens and pixel); the pattern is on the face the board's `z` axis points out of (Kalibr's
//! frame), and a camera behind the board sees blank paper. The image is then blurred with a Gaussian of `blur_px`, Gaussian noise of
//! `noise_levels` grey levels added, and rounded to 8 bits. Rays that miss the board, point
//! away from it or leave the model's domain see the background.
//!
//! The truth is the projection of every grid corner in front of the camera and inside the
//! image ([`rendered_corners`]).

use ibc_camera_models::{Camera, CameraModel};
use image::GrayImage;
use nalgebra::{Isometry3, Vector2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

use super::aprilgrid::AprilGrid;
use super::error::TargetError;
use crate::intrinsics::{Corner, PlanarTarget};

/// Options of [`render_april_grid`].
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Samples per pixel side (area sampling). Default 4 (16 samples a pixel).
    pub samples: u32,
    /// Standard deviation of the Gaussian blur (optics and sensor), pixels. Default 0.7.
    pub blur_px: f64,
    /// Standard deviation of the additive noise, grey levels. Default 2.
    pub noise_levels: f64,
    /// Grey level of the printed black. Default 30.
    pub black: u8,
    /// Grey level of the paper. Default 220.
    pub white: u8,
    /// Grey level of everything that is not the target. Default 90.
    pub background: u8,
    /// Seed of the noise.
    pub seed: u64,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            samples: 4,
            blur_px: 0.7,
            noise_levels: 2.0,
            black: 30,
            white: 220,
            background: 90,
            seed: 0,
        }
    }
}

impl RenderOptions {
    fn validate(&self) -> Result<(), TargetError> {
        let bad = |m: String| Err(TargetError::InvalidInput(m));
        if !(1..=16).contains(&self.samples) {
            return bad(format!(
                "samples per pixel side must be 1..=16, got {}",
                self.samples
            ));
        }
        if !(self.blur_px.is_finite() && (0.0..=10.0).contains(&self.blur_px)) {
            return bad(format!("blur must be in [0, 10] px, got {}", self.blur_px));
        }
        if !(self.noise_levels.is_finite() && self.noise_levels >= 0.0) {
            return bad(format!(
                "noise must be finite and >= 0 grey levels, got {}",
                self.noise_levels
            ));
        }
        Ok(())
    }
}

/// Renders `grid` seen by `camera` with the board at `camera_from_board` (see the module docs).
///
/// # Errors
/// [`TargetError::InvalidInput`] for invalid options or an image larger than 16384 pixels a
/// side.
pub fn render_april_grid(
    camera: &Camera,
    camera_from_board: &Isometry3<f64>,
    grid: &AprilGrid,
    options: &RenderOptions,
) -> Result<GrayImage, TargetError> {
    options.validate()?;
    let (w, h) = (camera.width(), camera.height());
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(TargetError::InvalidInput(format!(
            "cannot render a {w} x {h} image (1..=16384 pixels a side)"
        )));
    }
    let board_from_camera = camera_from_board.inverse();
    let origin = board_from_camera.translation.vector;
    // The pattern is printed on the face the board's z axis points out of; a camera behind
    // the board sees blank paper.
    let front = origin.z > 0.0;
    // Board points at the pixel corners, row by row: (w + 1) x (h + 1).
    let stride = w as usize + 1;
    let corners: Vec<Option<Vector2<f64>>> = (0..=h)
        .into_par_iter()
        .flat_map_iter(|j| {
            (0..=w).map(move |i| {
                let px = Vector2::new(f64::from(i) - 0.5, f64::from(j) - 0.5);
                let ray = board_from_camera.rotation * camera.unproject(&px).ok()?.into_inner();
                if ray.z.abs() < 1e-12 {
                    return None;
                }
                let t = -origin.z / ray.z;
                (t > 0.0).then(|| (origin + ray * t).xy())
            })
        })
        .collect();
    let n = options.samples;
    let (black, white, background) = (
        f64::from(options.black),
        f64::from(options.white),
        f64::from(options.background),
    );
    let mut values: Vec<f64> = (0..h as usize)
        .into_par_iter()
        .flat_map_iter(|j| {
            let corners = &corners;
            (0..w as usize).map(move |i| {
                let c = [
                    corners[j * stride + i],
                    corners[j * stride + i + 1],
                    corners[(j + 1) * stride + i],
                    corners[(j + 1) * stride + i + 1],
                ];
                let [Some(c00), Some(c10), Some(c01), Some(c11)] = c else {
                    return background;
                };
                let mut sum = 0.0;
                for a in 0..n {
                    let fy = (f64::from(a) + 0.5) / f64::from(n);
                    for b in 0..n {
                        let fx = (f64::from(b) + 0.5) / f64::from(n);
                        let p = c00 * ((1.0 - fx) * (1.0 - fy))
                            + c10 * (fx * (1.0 - fy))
                            + c01 * ((1.0 - fx) * fy)
                            + c11 * (fx * fy);
                        sum += match grid.is_black(p.x, p.y) {
                            Some(true) if front => black,
                            Some(_) => white,
                            None => background,
                        };
                    }
                }
                sum / f64::from(n * n)
            })
        })
        .collect();
    if options.blur_px > 0.0 {
        gaussian_blur(&mut values, w as usize, h as usize, options.blur_px);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let noise = Normal::new(0.0, options.noise_levels)
        .map_err(|e| TargetError::InvalidInput(format!("noise: {e}")))?;
    let pixels: Vec<u8> = values
        .iter()
        .map(|v| (v + noise.sample(&mut rng)).round().clamp(0.0, 255.0) as u8)
        .collect();
    GrayImage::from_raw(w, h, pixels)
        .ok_or_else(|| TargetError::InvalidInput("image buffer of the wrong size".into()))
}

/// Separable Gaussian blur of a row-major `w x h` image, edges clamped.
fn gaussian_blur(values: &mut [f64], w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = kernel.iter().sum();
    let kernel: Vec<f64> = kernel.iter().map(|k| k / total).collect();
    let clamp = |i: isize, n: usize| i.clamp(0, n as isize - 1) as usize;
    let mut tmp = vec![0.0; values.len()];
    tmp.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = kernel
                .iter()
                .enumerate()
                .map(|(k, c)| c * values[y * w + clamp(x as isize + k as isize - radius, w)])
                .sum();
        }
    });
    values.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = kernel
                .iter()
                .enumerate()
                .map(|(k, c)| c * tmp[clamp(y as isize + k as isize - radius, h) * w + x])
                .sum();
        }
    });
}

/// The true pixels of the grid corners that `camera` sees at `camera_from_board`: every corner
/// in front of the camera, inside the model's domain and inside the image, with a margin of
/// `margin_px` from the image border.
pub fn rendered_corners(
    camera: &Camera,
    camera_from_board: &Isometry3<f64>,
    target: &PlanarTarget,
    margin_px: f64,
) -> Vec<Corner> {
    let (w, h) = (f64::from(camera.width()), f64::from(camera.height()));
    let mut out = Vec::new();
    for row in 0..target.rows {
        for col in 0..target.cols {
            let p = camera_from_board * target.point(row, col);
            let Ok(px) = camera.project(&p.coords) else {
                continue;
            };
            if px.x >= margin_px - 0.5
                && px.y >= margin_px - 0.5
                && px.x <= w - 0.5 - margin_px
                && px.y <= h - 0.5 - margin_px
            {
                out.push(Corner {
                    row,
                    col,
                    u: px.x,
                    v: px.y,
                });
            }
        }
    }
    out
}
