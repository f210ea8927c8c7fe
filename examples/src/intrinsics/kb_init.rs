//! The Kannala-Brandt initialization of Heng et al. (ICRA 2014, section III).
//!
//! L. Heng, B. Li and M. Pollefeys, "CamOdoCal: Automatic intrinsic and extrinsic calibration
//! of a rig with multiple generic cameras and odometry", IROS 2013, and L. Heng, M. Bürki,
//! G. H. Lee, P. Furgale, R. Siegwart and M. Pollefeys, "Infrastructure-based calibration of a
//! multi-camera rig", ICRA 2014, section III:
//!
//! 1. Start from `k1 = k2 = k3 = k4 = 0`, `mu = mv = f`, `u0 = w / 2`, `v0 = h / 2`: the
//!    equidistant model.
//! 2. In every image, fit a circle through the corners of each board row; the circles meet in
//!    two vanishing points `v1`, `v2`, and `f = |v1 - v2| / pi` (Hughes et al., PAMI 2010; see
//!    [`super::vanishing_points`]). Each image gives a hypothesis of `f`.
//! 3. For each hypothesis, solve every board pose by PnP on the bearing vectors of that
//!    equidistant camera, and score it by the total reprojection error; keep the best.
//!
//! Here the board columns are a second family of parallel lines: when
//! [`KbInitOptions::use_columns`] is set (the default) each image also gives a column
//! hypothesis, and the scoring chooses among both. Corners are fitted in coordinates centred
//! on the image and divided by its half-diagonal, so the circle coefficients are of one scale.

use ibc_camera_models::{Camera, KannalaBrandt};
use nalgebra::{Isometry3, Vector2};
use rayon::prelude::*;
use serde::Serialize;

use super::board_pose::{all_correspondences, board_pose, capped_squared_error};
use super::circle_fit::{AlgebraicCircle, fit_circle};
use super::corners::{CornerSet, ImageCorners};
use super::error::IntrinsicsError;
use super::target::PlanarTarget;
use super::vanishing_points::common_points;

/// Corners a board row (or column) needs before a circle is fitted through it. Three points
/// define a circle; a fourth makes the fit a least-squares one that averages noise.
pub const MIN_LINE_CORNERS: usize = 4;

/// Options of the Kannala-Brandt initialization.
#[derive(Clone, Debug, PartialEq)]
pub struct KbInitOptions {
    /// Corners a row or column needs to be fitted. Default [`MIN_LINE_CORNERS`].
    pub min_line_corners: usize,
    /// Also take a hypothesis from the board columns of each image (the paper fits rows only).
    /// Default true.
    pub use_columns: bool,
    /// Cap, in pixels, of one corner's reprojection error in the hypothesis score, so that an
    /// image whose PnP fails under a wrong focal length cannot drown the others. Default 20 px.
    pub score_cap_px: f64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl KbInitOptions {
    /// The line families hypotheses are taken from: rows, and columns when
    /// [`Self::use_columns`] is set.
    pub(crate) fn families(&self) -> &'static [LineFamily] {
        if self.use_columns {
            &[LineFamily::Rows, LineFamily::Columns]
        } else {
            &[LineFamily::Rows]
        }
    }
}

impl Default for KbInitOptions {
    fn default() -> Self {
        Self {
            min_line_corners: MIN_LINE_CORNERS,
            use_columns: true,
            score_cap_px: 20.0,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

/// Which family of board lines a hypothesis came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LineFamily {
    /// Board rows (the paper's choice).
    Rows,
    /// Board columns.
    Columns,
}

/// One focal-length hypothesis and its score.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FocalHypothesis {
    /// Index of the image it came from.
    pub image: usize,
    /// The line family whose vanishing points gave it.
    pub family: LineFamily,
    /// Number of circles fitted.
    pub lines: usize,
    /// The focal length `|v1 - v2| / pi`, pixels.
    pub focal: f64,
    /// RMS reprojection error (per coordinate, capped per corner) over all images after PnP
    /// with the equidistant camera of this focal length, pixels.
    pub rms_px: f64,
}

/// The result of a line-based initialization: [`KbInitialization`] (the equidistant camera
/// of the best hypothesis) or [`UnifiedInitialization`](super::mei_init::UnifiedInitialization)
/// (the parabolic camera of the best hypothesis).
#[derive(Clone, Debug, PartialEq)]
pub struct LineInitialization<C> {
    /// The camera of the best hypothesis.
    pub camera: C,
    /// Every hypothesis, in image order, scored.
    pub hypotheses: Vec<FocalHypothesis>,
    /// Index into `hypotheses` of the one kept.
    pub chosen: usize,
    /// `camera_from_board` of every image under the chosen camera (PnP, refined).
    pub camera_from_board: Vec<Isometry3<f64>>,
}

/// The result of [`kannala_brandt_initialization`].
pub type KbInitialization = LineInitialization<KannalaBrandt>;

/// The focal-length hypotheses of one image (rows, then columns), in pixels, for an image
/// centred at `centre` with half-diagonal `scale`.
pub fn image_focal_hypotheses(
    image: &ImageCorners,
    centre: Vector2<f64>,
    scale: f64,
    options: &KbInitOptions,
) -> Vec<(LineFamily, usize, f64)> {
    let mut out = Vec::new();
    for &family in options.families() {
        let circles: Vec<AlgebraicCircle> = board_lines(image, family, centre, scale, options)
            .iter()
            .filter_map(|pts| fit_circle(pts))
            .collect();
        if let Some(vp) = common_points(&circles) {
            let f = vp.equidistant_focal() * scale;
            if f.is_finite() && f > 0.0 {
                out.push((family, circles.len(), f));
            }
        }
    }
    out
}

/// The corners of each board row (or column) of an image with at least
/// [`KbInitOptions::min_line_corners`] of them (and at least 3), in coordinates centred at
/// `centre` and divided by `scale`.
pub(crate) fn board_lines(
    image: &ImageCorners,
    family: LineFamily,
    centre: Vector2<f64>,
    scale: f64,
    options: &KbInitOptions,
) -> Vec<Vec<Vector2<f64>>> {
    let mut lines: std::collections::BTreeMap<u32, Vec<Vector2<f64>>> = Default::default();
    for c in &image.corners {
        let key = match family {
            LineFamily::Rows => c.row,
            LineFamily::Columns => c.col,
        };
        lines
            .entry(key)
            .or_default()
            .push((c.pixel() - centre) / scale);
    }
    lines
        .into_values()
        .filter(|pts| pts.len() >= options.min_line_corners.max(3))
        .collect()
}

/// The paper's equidistant camera for a focal length: `k = 0`, `mu = mv = f`,
/// `(u0, v0) = (w / 2, h / 2)`.
///
/// # Errors
/// [`IntrinsicsError::Camera`] for a focal length that is not finite and positive.
pub fn equidistant_camera(
    width: u32,
    height: u32,
    focal: f64,
) -> Result<KannalaBrandt, IntrinsicsError> {
    let (u0, v0) = (0.5 * f64::from(width), 0.5 * f64::from(height));
    Ok(KannalaBrandt::new(
        width,
        height,
        [0.0, 0.0, 0.0, 0.0, focal, focal, u0, v0],
    )?)
}

/// The paper's initialization of the Kannala-Brandt parameters and of every board pose (see
/// the module docs). The corners must have been validated
/// ([`CornerSet::validate`](super::CornerSet::validate)).
///
/// # Errors
/// [`IntrinsicsError::NoFocalHypothesis`] when no image gives a hypothesis, and
/// [`IntrinsicsError::BoardPose`] when an image has no pose under the chosen camera.
pub fn kannala_brandt_initialization(
    corners: &CornerSet,
    target: &PlanarTarget,
    options: &KbInitOptions,
) -> Result<KbInitialization, IntrinsicsError> {
    choose_hypothesis(corners, target, options, image_focal_hypotheses, |focal| {
        equidistant_camera(corners.width, corners.height, focal)
    })
}

/// An image's hypotheses, `(line family, lines fitted, focal)`, from its corners, the image
/// centre, its half-diagonal and the options ([`image_focal_hypotheses`] and the unified
/// model's `image_gamma_hypotheses`).
pub(crate) type ImageHypotheses =
    fn(&ImageCorners, Vector2<f64>, f64, &KbInitOptions) -> Vec<(LineFamily, usize, f64)>;

/// Takes every image's hypotheses (`per_image`, in image coordinates centred on the image and
/// divided by its half-diagonal), scores each by the capped reprojection error after PnP
/// (unrefined) in every image with the camera `camera_of(focal)`, keeps the best, and solves
/// every board pose under it (refined). Shared by the Kannala-Brandt and the unified
/// initializations.
///
/// # Errors
/// [`IntrinsicsError::NoFocalHypothesis`] when `raw` is empty or no hypothesis gives a camera,
/// and [`IntrinsicsError::BoardPose`] when an image has no pose under the chosen camera.
pub(crate) fn choose_hypothesis<C: Clone + Into<Camera>>(
    corners: &CornerSet,
    target: &PlanarTarget,
    options: &KbInitOptions,
    per_image: ImageHypotheses,
    camera_of: impl Fn(f64) -> Result<C, IntrinsicsError> + Sync,
) -> Result<LineInitialization<C>, IntrinsicsError> {
    let none = IntrinsicsError::NoFocalHypothesis {
        min_corners: options.min_line_corners,
    };
    let (w, h) = (f64::from(corners.width), f64::from(corners.height));
    let centre = Vector2::new(0.5 * w, 0.5 * h);
    let scale = 0.5 * w.hypot(h);
    let raw: Vec<(usize, LineFamily, usize, f64)> = corners
        .images
        .iter()
        .enumerate()
        .flat_map(|(i, image)| {
            per_image(image, centre, scale, options)
                .into_iter()
                .map(move |(family, lines, f)| (i, family, lines, f))
        })
        .collect();
    if raw.is_empty() {
        return Err(none);
    }
    let data = all_correspondences(target, corners);
    let total_coords = 2.0 * corners.num_corners() as f64;
    let cap = options.score_cap_px;
    let hypotheses: Vec<FocalHypothesis> = raw
        .par_iter()
        .map(|&(image, family, lines, focal)| {
            let sum = match camera_of(focal).map(Into::<Camera>::into) {
                Ok(camera) => data
                    .iter()
                    .map(
                        |(points, pixels)| match board_pose(&camera, points, pixels, false) {
                            Ok(pose) => capped_squared_error(&camera, &pose, points, pixels, cap),
                            Err(_) => cap * cap * points.len() as f64,
                        },
                    )
                    .sum::<f64>(),
                Err(_) => f64::INFINITY,
            };
            FocalHypothesis {
                image,
                family,
                lines,
                focal,
                rms_px: (sum / total_coords).sqrt(),
            }
        })
        .collect();
    let chosen = hypotheses
        .iter()
        .enumerate()
        .filter(|(_, h)| h.rms_px.is_finite())
        .min_by(|a, b| a.1.rms_px.total_cmp(&b.1.rms_px))
        .map(|(i, _)| i)
        .ok_or(none)?;
    let camera = camera_of(hypotheses[chosen].focal)?;
    let as_camera: Camera = camera.clone().into();
    let camera_from_board = data
        .iter()
        .zip(&corners.images)
        .map(|((points, pixels), image)| {
            board_pose(&as_camera, points, pixels, true).map_err(|source| {
                IntrinsicsError::BoardPose {
                    image: image.name.clone(),
                    source,
                }
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(LineInitialization {
        camera,
        hypotheses,
        chosen,
        camera_from_board,
    })
}
