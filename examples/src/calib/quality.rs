//! Judging a calibration camera by camera, so that a result the data contradict is never
//! reported as a good one.
//!
//! The refinement's covariance (hence every standard deviation in the report) assumes that
//! the residuals are independent zero-mean noise. Wrong prior intrinsics break that
//! assumption in a way the residuals show: the refinement moves the camera to absorb what it
//! can, and what is left is a **pattern over the image** (a focal length 1% long pushes every
//! residual outwards in proportion to its radius). Measured on the simulated garage (100
//! frames, 0.5 px noise), the pattern figure below is 0.015-0.030 px for every camera with
//! the true intrinsics and 0.048 px with 2 cm of map-point error, but 0.25 px for a focal
//! length 0.2% off, 0.45 px for 1% off and 0.51 px for a principal point 3 px off; the
//! ten-camera pentagon gives 0.021-0.034 px, and 0.21 px with one focal length 1% off. The
//! overall spread of a camera's residuals separates far less well (1.08x the others' for a
//! focal length 0.2% off, 1.14x for a legitimate camera of the map-error world), so it is
//! reported but gated only when it is gross.
//!
//! For every camera, from the refinement's correspondences:
//!
//! - **residual statistics** at the initial and at the refined estimate ([`ResidualStats`]):
//!   the mean and RMS of the error lengths and a robust spread, `1.4826 median |r_i|` over
//!   both coordinates of every residual `r` (the MAD about zero, a per-axis standard deviation
//!   for Gaussian noise, insensitive to outliers);
//! - the **outlier fraction** under the refinement's Cauchy loss: the share of refined
//!   residuals whose Cauchy weight `1 / (1 + |r|^2 / a^2)` is below [`OUTLIER_WEIGHT`], that is
//!   whose length exceeds `3 a` (3 px at the default scale `a = 1 px`);
//! - the **residual pattern**: the image is cut into [`PATTERN_GRID`] x [`PATTERN_GRID`]
//!   cells; in each cell with at least [`PATTERN_MIN_CELL`] non-outlier residuals, their mean
//!   `m_k` (of `n_k`); the pattern is `S = sqrt(sum n_k |m_k|^2 / sum n_k)` pixels, and its
//!   significance `chi^2 / dof = sum n_k |m_k|^2 / sigma^2 / (2 K)` over the `K` cells, with
//!   `sigma` the robust spread: about 1 for noise alone (noise alone gives
//!   `S = sigma sqrt(2 K / N)` on average).
//!
//! The gates, each a [`CalibrationWarning`] naming the camera and the likely cause:
//!
//! - [`CalibrationWarning::SystematicResiduals`]: `chi^2 / dof >= `
//!   [`PATTERN_MIN_CHI2_PER_DOF`] (the pattern is not chance) and
//!   `S >= `[`PATTERN_MIN_SIGMA_FRACTION`]` sigma` (it matters against the noise). Its
//!   standard deviations are then too small, and a change since the camera file may come from
//!   the intrinsics rather than from a moved camera; the message says both.
//! - [`CalibrationWarning::ResidualSpread`]: a camera's robust spread is more than
//!   [`SPREAD_RATIO_GATE`] times the median of the others'.
//! - [`CalibrationWarning::Outliers`]: more than [`OUTLIER_FRACTION_GATE`] of a camera's
//!   residuals are outliers.
//! - [`CalibrationWarning::NotConverged`]: the refinement stopped without converging.
//! - [`CalibrationWarning::NoCovariance`]: the standard deviations could not be computed.
//! - [`CalibrationWarning::IntrinsicsChanged`], a notice: with intrinsics refined, a focal
//!   length or principal point moved from the camera file by more than
//!   [`CHANGED_FOCAL_FRACTION`] or [`CHANGED_PRINCIPAL_POINT_PX`] and by more than
//!   [`CHANGED_INTRINSIC_SIGMAS`] standard deviations ("`left` focal length 1.00% longer than
//!   its camera file").
//!
//! A calibration with any warning but a notice has [`Status::Poor`]: it is still written and reported,
//! and `ibc` exits with its own code (3) rather than 0.

use ibc_camera_models::{Camera, CameraModel};
use nalgebra::{Isometry3, Vector2};
use serde::Serialize;

use crate::calib::accuracy::relative_to_first;
use crate::calib::refinement::{CameraIntrinsics, IntrinsicParameter};

/// Cells per side of the grid over which the residual pattern is measured. Four: 16 cells
/// keep a few hundred residuals each with 100 frames, and a focal-length or principal-point
/// error shows in every one of them.
pub const PATTERN_GRID: usize = 4;

/// Fewest non-outlier residuals in a cell for its mean to count.
pub const PATTERN_MIN_CELL: usize = 30;

/// Smallest `chi^2 / dof` of the cell means for a pattern to be systematic. Noise alone gave
/// 0.3-1.2 on every simulated world (map error included); the smallest intrinsic error
/// measured (one focal length 0.2% off) gave 68, one focal length 1% off on the pentagon 24.
pub const PATTERN_MIN_CHI2_PER_DOF: f64 = 4.0;

/// Smallest pattern, as a fraction of the camera's robust spread, that counts as systematic.
/// Noise alone gave at most 0.063 (the map-error world), intrinsic errors 0.36 and more.
pub const PATTERN_MIN_SIGMA_FRACTION: f64 = 0.15;

/// A camera whose robust spread exceeds this many times the median of the others' is flagged.
/// Legitimate cameras of one rig differed by up to 1.14x (2 cm of map error on a camera that
/// sees nearer points), and one focal length 1% off gave 1.16-1.57x; the pattern gate catches
/// the latter, this one the gross cases (a camera with another noise level or a wrong model).
pub const SPREAD_RATIO_GATE: f64 = 1.5;

/// A refined residual whose Cauchy weight `1 / (1 + |r|^2 / a^2)` falls below this is an
/// outlier: its length exceeds `3 a`.
pub const OUTLIER_WEIGHT: f64 = 0.1;

/// A camera with more than this share of outliers is flagged. Every simulated world with the
/// true intrinsics gave at most 0.2%, 30% of spurious features included (localization keeps
/// inliers only); every focal length 1% long gave 18% on one camera.
pub const OUTLIER_FRACTION_GATE: f64 = 0.05;

/// A camera is listed as changed since the camera file when its centre moved more than this
/// many metres, relative to camera 0.
pub const MOVED_DISTANCE_M: f64 = 0.005;

/// ... or turned more than this many degrees.
pub const MOVED_ROTATION_DEG: f64 = 0.5;

/// A refined focal length that moved by more than this fraction of the camera file's value
/// (and by more than [`CHANGED_INTRINSIC_SIGMAS`] standard deviations) is reported: 0.1 %,
/// half of the 0.2 % that already costs the garage's extrinsics 35 mm when held.
pub const CHANGED_FOCAL_FRACTION: f64 = 0.001;

/// A refined principal point that moved by more than this (pixels, either coordinate, and by
/// more than [`CHANGED_INTRINSIC_SIGMAS`] standard deviations) is reported.
pub const CHANGED_PRINCIPAL_POINT_PX: f64 = 0.5;

/// How many standard deviations a refined intrinsic must move to be reported as changed.
pub const CHANGED_INTRINSIC_SIGMAS: f64 = 5.0;

/// Statistics of one camera's reprojection residuals at one estimate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ResidualStats {
    /// Residuals that could be evaluated (the point projects).
    pub count: usize,
    /// Mean error length, pixels.
    pub mean_px: f64,
    /// RMS of the error lengths, pixels.
    pub rms_px: f64,
    /// Robust spread per axis, `1.4826 median |r|` over both coordinates, pixels.
    pub mad_px: f64,
}

impl ResidualStats {
    /// The statistics of a set of residuals (non-finite ones are skipped).
    pub fn of(residuals: &[Vector2<f64>]) -> Self {
        let finite: Vec<&Vector2<f64>> = residuals
            .iter()
            .filter(|r| r.x.is_finite() && r.y.is_finite())
            .collect();
        let n = finite.len();
        if n == 0 {
            return Self {
                count: 0,
                mean_px: f64::NAN,
                rms_px: f64::NAN,
                mad_px: f64::NAN,
            };
        }
        let mean = finite.iter().map(|r| r.norm()).sum::<f64>() / n as f64;
        let rms = (finite.iter().map(|r| r.norm_squared()).sum::<f64>() / n as f64).sqrt();
        let mut coordinates: Vec<f64> =
            finite.iter().flat_map(|r| [r.x.abs(), r.y.abs()]).collect();
        Self {
            count: n,
            mean_px: mean,
            rms_px: rms,
            mad_px: MAD_TO_SIGMA * median(&mut coordinates),
        }
    }
}

/// `1 / Phi^-1(3/4)`: the median absolute deviation of a Gaussian times this is its standard
/// deviation.
const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// The median of the values (the upper one of an even count), NaN for none.
fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// The residual pattern of one camera (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ResidualPattern {
    /// `S`: the count-weighted RMS of the cell means, pixels.
    pub pattern_px: f64,
    /// What noise alone gives on average, `sigma sqrt(2 K / N)`, pixels.
    pub noise_px: f64,
    /// `chi^2 / dof` of the cell means.
    pub chi2_per_dof: f64,
    /// Cells with enough residuals.
    pub cells: usize,
}

impl ResidualPattern {
    /// The pattern of residuals `residuals` observed at `pixels` in an image of `width` x
    /// `height`, with robust spread `sigma_px` and outlier bound `outlier_px`; `None` when no
    /// cell has [`PATTERN_MIN_CELL`] residuals.
    pub fn of(
        pixels: &[Vector2<f64>],
        residuals: &[Vector2<f64>],
        (width, height): (u32, u32),
        sigma_px: f64,
        outlier_px: f64,
    ) -> Option<Self> {
        let g = PATTERN_GRID;
        let mut cells = vec![(Vector2::<f64>::zeros(), 0usize); g * g];
        let cell = |v: f64, size: u32| {
            let i = (v + 0.5) / f64::from(size) * g as f64;
            // In range and finite: the cast truncates a value in [0, g).
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let i = i.clamp(0.0, (g - 1) as f64) as usize;
            i
        };
        for (p, r) in pixels.iter().zip(residuals) {
            let n = r.norm();
            if !(n.is_finite() && n <= outlier_px && p.x.is_finite() && p.y.is_finite()) {
                continue;
            }
            let k = cell(p.y, height) * g + cell(p.x, width);
            cells[k].0 += r;
            cells[k].1 += 1;
        }
        let used: Vec<(Vector2<f64>, usize)> = cells
            .into_iter()
            .filter(|(_, n)| *n >= PATTERN_MIN_CELL)
            .collect();
        let total: usize = used.iter().map(|(_, n)| n).sum();
        if used.is_empty() || sigma_px.is_nan() || sigma_px <= 0.0 {
            return None;
        }
        let energy: f64 = used
            .iter()
            .map(|(sum, n)| sum.norm_squared() / *n as f64)
            .sum();
        let k = used.len() as f64;
        Some(Self {
            pattern_px: (energy / total as f64).sqrt(),
            noise_px: sigma_px * (2.0 * k / total as f64).sqrt(),
            chi2_per_dof: energy / (sigma_px * sigma_px) / (2.0 * k),
            cells: used.len(),
        })
    }

    /// True when the pattern is systematic (see the module docs).
    pub fn is_systematic(&self, sigma_px: f64) -> bool {
        self.chi2_per_dof >= PATTERN_MIN_CHI2_PER_DOF
            && self.pattern_px >= PATTERN_MIN_SIGMA_FRACTION * sigma_px
    }
}

/// The quality figures of one camera.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CameraQuality {
    /// Images of this camera in the log.
    pub images: usize,
    /// Of them, localized against the map.
    pub images_localized: usize,
    /// Localization inliers summed over its localized images.
    pub inliers: usize,
    /// Its correspondences in the refinement.
    pub observations: usize,
    /// Residuals at the initial estimate.
    pub initial: ResidualStats,
    /// Residuals at the refined estimate.
    pub refined: ResidualStats,
    /// Share of refined residuals that are outliers under the Cauchy loss (weight below
    /// [`OUTLIER_WEIGHT`]).
    pub outlier_fraction: f64,
    /// The pattern of the refined residuals over the image, when measurable.
    pub pattern: Option<ResidualPattern>,
}

/// Why a calibration should not be trusted as it is. Each names the camera and the likely
/// cause; see the module docs for the rules.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CalibrationWarning {
    /// A camera's residuals follow a pattern over the image.
    #[error(
        "intrinsics of `{camera}` do not fit: its residuals follow a pattern over the image \
         ({pattern_px:.2} px, noise alone gives {noise_px:.2} px; spread {sigma_px:.2} px \
         against {others_px:.2} px for the others); stale intrinsics? Its standard deviations \
         assume noise alone and are too small{}; `--refine-intrinsics` refines them against \
         the map",
        moved.map_or(String::new(), |(d, r)| format!(
            ", and its change since the camera file ({:.2} cm, {r:.2} deg) may come from the \
             intrinsics, not from a moved camera",
            d * 100.0
        ))
    )]
    SystematicResiduals {
        /// The camera.
        camera: String,
        /// The pattern `S`, pixels.
        pattern_px: f64,
        /// What noise alone gives, pixels.
        noise_px: f64,
        /// The camera's robust spread, pixels.
        sigma_px: f64,
        /// The median robust spread of the other cameras, pixels.
        others_px: f64,
        /// Its change since the camera file (metres, degrees), when it is listed as changed.
        moved: Option<(f64, f64)>,
    },
    /// A camera's residuals are far wider than the others'.
    #[error(
        "residuals of `{camera}` are {ratio:.1} times the others' ({sigma_px:.2} px against \
         {others_px:.2} px): noisier features or wrong intrinsics? Its standard deviations \
         assume the others' noise and are too small"
    )]
    ResidualSpread {
        /// The camera.
        camera: String,
        /// Its robust spread, pixels.
        sigma_px: f64,
        /// The median of the others', pixels.
        others_px: f64,
        /// The ratio.
        ratio: f64,
    },
    /// Many of a camera's correspondences are outliers under the Cauchy loss.
    #[error(
        "{percent:.1}% of `{camera}`'s correspondences are outliers under the Cauchy loss \
         (errors above {threshold_px:.1} px): wrong matches or wrong intrinsics?",
        percent = fraction * 100.0
    )]
    Outliers {
        /// The camera.
        camera: String,
        /// The outlier share.
        fraction: f64,
        /// The error above which a residual is an outlier, pixels.
        threshold_px: f64,
    },
    /// The refinement stopped without converging.
    #[error(
        "the refinement stopped without converging (`{termination}` after {iterations} \
         iterations): the estimate may not be the optimum"
    )]
    NotConverged {
        /// Why it stopped.
        termination: String,
        /// Iterations run.
        iterations: usize,
    },
    /// The standard deviations could not be computed.
    #[error(
        "the standard deviations could not be computed (the refinement's information matrix \
         is singular or there are too few correspondences): some extrinsic may not be \
         determined by the data"
    )]
    NoCovariance,
    /// A refined intrinsic moved well beyond its standard deviation from the camera file: a
    /// notice (the calibration carries the refined value), not a reason to distrust it.
    #[error(
        "`{camera}` {what} {change} than its camera file ({name}: {prior:.3} -> {value:.3}, \
         std {std:.3}): the camera file is stale; the written calibration carries the \
         refined intrinsics"
    )]
    IntrinsicsChanged {
        /// The camera.
        camera: String,
        /// `focal length` or `principal point`.
        what: &'static str,
        /// How it changed (`1.00% longer`, `3.0 px further right` ...).
        change: String,
        /// The parameter that moved most.
        name: &'static str,
        /// The camera file's value.
        prior: f64,
        /// The refined value.
        value: f64,
        /// Its standard deviation.
        std: f64,
    },
}

impl CalibrationWarning {
    /// A short snake-case name of the kind (`systematic_residuals`, ...).
    pub fn kind(&self) -> &'static str {
        match self {
            Self::SystematicResiduals { .. } => "systematic_residuals",
            Self::ResidualSpread { .. } => "residual_spread",
            Self::Outliers { .. } => "outliers",
            Self::NotConverged { .. } => "not_converged",
            Self::NoCovariance => "no_covariance",
            Self::IntrinsicsChanged { .. } => "intrinsics_changed",
        }
    }

    /// The camera it names, if any.
    pub fn camera(&self) -> Option<&str> {
        match self {
            Self::SystematicResiduals { camera, .. }
            | Self::ResidualSpread { camera, .. }
            | Self::Outliers { camera, .. }
            | Self::IntrinsicsChanged { camera, .. } => Some(camera),
            Self::NotConverged { .. } | Self::NoCovariance => None,
        }
    }

    /// Whether it is a notice, which does not make the calibration [`Status::Poor`].
    pub fn is_notice(&self) -> bool {
        matches!(self, Self::IntrinsicsChanged { .. })
    }
}

/// Whether a calibration can be trusted as it is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Every gate passed.
    #[default]
    Ok,
    /// At least one gate failed: see the warnings.
    Poor,
}

impl Status {
    /// `"ok"` or `"poor"`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ok => "ok",
            Self::Poor => "poor",
        }
    }
}

/// The per-camera figures and the warnings of a calibration.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Quality {
    /// One entry per camera.
    pub cameras: Vec<CameraQuality>,
    /// The gates that failed.
    pub warnings: Vec<CalibrationWarning>,
}

impl Quality {
    /// [`Status::Poor`] when there is a warning that is not a notice.
    pub fn status(&self) -> Status {
        if self.warnings.iter().all(CalibrationWarning::is_notice) {
            Status::Ok
        } else {
            Status::Poor
        }
    }
}

/// What [`assess`] needs about the refinement.
#[derive(Clone, Debug)]
pub struct RefinementFacts<'a> {
    /// The cameras' names.
    pub names: &'a [String],
    /// Image sizes, `(width, height)` per camera.
    pub image_sizes: Vec<(u32, u32)>,
    /// Images, localized images and localization inliers per camera.
    pub localization: Vec<(usize, usize, usize)>,
    /// The observed pixel and the camera of every correspondence.
    pub observations: Vec<(usize, Vector2<f64>)>,
    /// Residual (projected minus observed) of every correspondence at the initial estimate
    /// (NaN where it does not project).
    pub initial: &'a [Vector2<f64>],
    /// The same at the refined estimate.
    pub refined: &'a [Vector2<f64>],
    /// The Cauchy scale, pixels.
    pub cauchy_scale_px: f64,
    /// Whether the refinement converged, and its termination and iterations.
    pub converged: (bool, &'a str, usize),
    /// Whether the standard deviations exist.
    pub covariance: bool,
    /// The prior and estimated extrinsics (for the change since the camera file).
    pub prior_rig_from_camera: &'a [Isometry3<f64>],
    /// See `prior_rig_from_camera`.
    pub rig_from_camera: &'a [Isometry3<f64>],
    /// The cameras (refined intrinsics) and what the refinement did with each camera's
    /// intrinsics.
    pub intrinsics: (&'a [Camera], &'a [CameraIntrinsics]),
}

/// The median of the robust spreads of every camera but `c` (NaN when there is none).
fn others_spread(cameras: &[CameraQuality], c: usize) -> f64 {
    let mut others: Vec<f64> = cameras
        .iter()
        .enumerate()
        .filter(|(o, q)| *o != c && q.refined.mad_px.is_finite())
        .map(|(_, q)| q.refined.mad_px)
        .collect();
    median(&mut others)
}

/// The change of every camera since the camera file relative to camera 0, as (distance in
/// metres, rotation in degrees).
pub fn changes_since_prior(
    prior: &[Isometry3<f64>],
    estimate: &[Isometry3<f64>],
) -> Vec<(f64, f64)> {
    relative_to_first(prior)
        .iter()
        .zip(&relative_to_first(estimate))
        .map(|(p, e)| {
            (
                (e.translation.vector - p.translation.vector).norm(),
                p.rotation.angle_to(&e.rotation).to_degrees(),
            )
        })
        .collect()
}

/// True when a change (metres, degrees) is large enough to be listed.
pub fn is_listed_change((distance_m, rotation_deg): (f64, f64)) -> bool {
    distance_m > MOVED_DISTANCE_M || rotation_deg > MOVED_ROTATION_DEG
}

/// The notices of a camera whose refined focal length or principal point moved from the
/// camera file by more than [`CHANGED_FOCAL_FRACTION`] or [`CHANGED_PRINCIPAL_POINT_PX`] and
/// by more than [`CHANGED_INTRINSIC_SIGMAS`] standard deviations (the coordinate that moved
/// most of each).
fn intrinsics_changes(
    name: &str,
    camera: &Camera,
    refined: &CameraIntrinsics,
) -> Vec<CalibrationWarning> {
    let significant = |p: &&IntrinsicParameter| {
        let moved = (p.value - p.prior).abs();
        // Without a standard deviation, the size of the move alone decides.
        p.std.is_nan() || moved > CHANGED_INTRINSIC_SIGMAS * p.std
    };
    let pick = |indices: [usize; 2], threshold: &dyn Fn(&IntrinsicParameter) -> bool| {
        refined
            .refined
            .iter()
            .filter(|p| indices.contains(&p.index) && threshold(p))
            .filter(significant)
            .max_by(|a, b| {
                (a.value - a.prior)
                    .abs()
                    .total_cmp(&(b.value - b.prior).abs())
            })
    };
    let mut out = Vec::new();
    let focal = pick(camera.focal_length_indices(), &|p| {
        (p.value - p.prior).abs() > CHANGED_FOCAL_FRACTION * p.prior.abs()
    });
    if let Some(p) = focal {
        let percent = (p.value / p.prior - 1.0) * 100.0;
        let change = format!(
            "{:.2}% {}",
            percent.abs(),
            if percent > 0.0 { "longer" } else { "shorter" }
        );
        out.push(changed(name, "focal length", change, p));
    }
    let centre = pick(camera.principal_point_indices(), &|p| {
        (p.value - p.prior).abs() > CHANGED_PRINCIPAL_POINT_PX
    });
    if let Some(p) = centre {
        let d = p.value - p.prior;
        let horizontal = camera.principal_point_indices()[0] == p.index;
        let direction = match (horizontal, d > 0.0) {
            (true, true) => "right",
            (true, false) => "left",
            (false, true) => "down",
            (false, false) => "up",
        };
        let change = format!("{:.2} px further {direction}", d.abs());
        out.push(changed(name, "principal point", change, p));
    }
    out
}

fn changed(
    camera: &str,
    what: &'static str,
    change: String,
    p: &IntrinsicParameter,
) -> CalibrationWarning {
    CalibrationWarning::IntrinsicsChanged {
        camera: camera.to_owned(),
        what,
        change,
        name: p.name,
        prior: p.prior,
        value: p.value,
        std: p.std,
    }
}

/// The per-camera figures and the gates (see the module docs).
pub fn assess(facts: &RefinementFacts<'_>) -> Quality {
    let k = facts.names.len();
    let outlier_px = facts.cauchy_scale_px * (1.0 / OUTLIER_WEIGHT - 1.0).sqrt();
    let mut cameras = Vec::with_capacity(k);
    for c in 0..k {
        let mine: Vec<usize> = (0..facts.observations.len())
            .filter(|&i| facts.observations[i].0 == c)
            .collect();
        let pick = |all: &[Vector2<f64>]| -> Vec<Vector2<f64>> {
            mine.iter()
                .map(|&i| all.get(i).copied().unwrap_or(Vector2::repeat(f64::NAN)))
                .collect()
        };
        let (initial, refined) = (pick(facts.initial), pick(facts.refined));
        let pixels: Vec<Vector2<f64>> = mine.iter().map(|&i| facts.observations[i].1).collect();
        let refined_stats = ResidualStats::of(&refined);
        let outliers = refined
            .iter()
            .filter(|r| r.norm().is_finite() && r.norm() > outlier_px)
            .count();
        let (images, images_localized, inliers) =
            facts.localization.get(c).copied().unwrap_or_default();
        cameras.push(CameraQuality {
            images,
            images_localized,
            inliers,
            observations: mine.len(),
            initial: ResidualStats::of(&initial),
            refined: refined_stats,
            outlier_fraction: if refined_stats.count == 0 {
                0.0
            } else {
                outliers as f64 / refined_stats.count as f64
            },
            pattern: facts.image_sizes.get(c).and_then(|&size| {
                ResidualPattern::of(&pixels, &refined, size, refined_stats.mad_px, outlier_px)
            }),
        });
    }
    let changes = changes_since_prior(facts.prior_rig_from_camera, facts.rig_from_camera);
    let mut warnings = Vec::new();
    for (c, q) in cameras.iter().enumerate() {
        let camera = facts.names[c].clone();
        let sigma = q.refined.mad_px;
        let others = others_spread(&cameras, c);
        if let Some(p) = q.pattern.filter(|p| p.is_systematic(sigma)) {
            warnings.push(CalibrationWarning::SystematicResiduals {
                camera: camera.clone(),
                pattern_px: p.pattern_px,
                noise_px: p.noise_px,
                sigma_px: sigma,
                others_px: others,
                moved: changes.get(c).copied().filter(|&m| is_listed_change(m)),
            });
        } else if others.is_finite() && sigma > SPREAD_RATIO_GATE * others {
            warnings.push(CalibrationWarning::ResidualSpread {
                camera: camera.clone(),
                sigma_px: sigma,
                others_px: others,
                ratio: sigma / others,
            });
        }
        if q.outlier_fraction > OUTLIER_FRACTION_GATE {
            warnings.push(CalibrationWarning::Outliers {
                camera,
                fraction: q.outlier_fraction,
                threshold_px: outlier_px,
            });
        }
    }
    let (converged, termination, iterations) = facts.converged;
    if !converged {
        warnings.push(CalibrationWarning::NotConverged {
            termination: termination.to_owned(),
            iterations,
        });
    }
    if !facts.covariance {
        warnings.push(CalibrationWarning::NoCovariance);
    }
    let (models, intrinsics) = facts.intrinsics;
    for ((name, camera), refined) in facts.names.iter().zip(models).zip(intrinsics) {
        warnings.extend(intrinsics_changes(name, camera, refined));
    }
    Quality { cameras, warnings }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robust_spread_of_gaussian_like_residuals() {
        // Residuals of +-1 on each axis: median |r| = 1.
        let r: Vec<Vector2<f64>> = (0..100)
            .map(|i| Vector2::new(if i % 2 == 0 { 1.0 } else { -1.0 }, 1.0))
            .chain([Vector2::new(f64::NAN, 0.0)])
            .collect();
        let s = ResidualStats::of(&r);
        assert_eq!(s.count, 100);
        assert!((s.mad_px - MAD_TO_SIGMA).abs() < 1e-12);
        assert!((s.rms_px - 2f64.sqrt()).abs() < 1e-12);
        assert!(ResidualStats::of(&[]).mean_px.is_nan());
    }

    #[test]
    fn a_radial_pattern_is_systematic_and_alternating_noise_is_not() {
        let size = (400, 400);
        let mut pixels = Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                pixels.push(Vector2::new(f64::from(i) * 10.0, f64::from(j) * 10.0));
            }
        }
        // Zero-mean residuals in every cell: +-0.5 alternating.
        let noise: Vec<Vector2<f64>> = (0..pixels.len())
            .map(|k| Vector2::repeat(if k % 2 == 0 { 0.5 } else { -0.5 }))
            .collect();
        let p = ResidualPattern::of(&pixels, &noise, size, 0.5, 3.0).unwrap();
        assert_eq!(p.cells, 16);
        assert!(p.pattern_px < 1e-12 && !p.is_systematic(0.5));
        // A 1% scale about the centre on top of it.
        let radial: Vec<Vector2<f64>> = pixels
            .iter()
            .zip(&noise)
            .map(|(p, n)| n + (p - Vector2::new(200.0, 200.0)) * 0.01)
            .collect();
        let p = ResidualPattern::of(&pixels, &radial, size, 0.5, 3.0).unwrap();
        assert!(p.is_systematic(0.5), "{p:?}");
        assert!(p.pattern_px > 1.0 && p.chi2_per_dof > 10.0);
    }
}
