//! Intrinsic calibration of one camera from the corners of a planar target (issue 9): the
//! Kannala-Brandt method of Heng et al. (ICRA 2014, section III), pinhole-radtan from
//! Zhang's closed form and the unified (Mei) model from Mei and Rives's line conics, each
//! refined jointly with every board pose.
//!
//! # Method
//! - **Kannala-Brandt** ([`kb_init`]): start from the equidistant camera `k1..k4 = 0`,
//!   `mu = mv = f`, `(u0, v0) = (w / 2, h / 2)`; in every image fit a circle through the
//!   corners of each board row ([`circle_fit`], Pratt's fit), intersect the circles in the two
//!   vanishing points `v1, v2` and take `f = |v1 - v2| / pi` ([`vanishing_points`], Hughes et
//!   al., TPAMI 2010). Each image gives a hypothesis (here also one from its columns); each is
//!   scored by the reprojection error after EPnP on the bearing vectors of every image, and
//!   the best is kept.
//! - **Pinhole-radtan** ([`pinhole_init`]): the corners straightened by a one-parameter
//!   division model ([`division_model`], Fitzgibbon, CVPR 2001), a homography per image
//!   ([`homography`]), Zhang's closed form for `fx, fy, cx, cy` and his linear `k1, k2`
//!   ([`zhang`], TPAMI 2000), alternated; `p1 = p2 = 0`. When that start refines to an RMS
//!   above [`PINHOLE_FALLBACK_RMS_PX`] or the closed form has no solution (views that differ
//!   little in orientation, boards partly outside the image: a rig turning in front of a board
//!   standing still ended 1-3 px off with principal points hundreds of pixels away), the
//!   calibration is run again from a centred start (principal point at the image centre, one
//!   focal length from the homographies, [`pinhole_init::centred_initialization`]) and kept
//!   when it fits at least twice as well.
//! - **Unified (Mei)** ([`mei_init`]): Mei and Rives (ICRA 2007, section IV): `xi = 1`, no
//!   distortion, the principal point at the image centre; with `xi = 1` the corners of a
//!   board line satisfy one linear equation in `(n_x, n_y, n_z gamma, n_z / gamma)`, so each
//!   row and column fitted gives `gamma`; each image's median over its rows (and columns) is
//!   a hypothesis, scored like Kannala-Brandt's, and the refinement frees `xi`.
//! - **Refinement** (all): Levenberg-Marquardt over the model's intrinsics (8, or 9 with
//!   `xi`) and every
//!   `camera_from_board` with `ibc-bundle-adjust` (poses eliminated by the Schur complement)
//!   and the analytic intrinsic Jacobians of `ibc-camera-models`. The parameter covariance is
//!   the inverse Schur complement scaled by the a-posteriori noise variance
//!   `sum r^2 / (m - n)`.
//! - **Outliers** ([`robust`]): an image with fewer than [`MIN_CORNERS_PER_IMAGE`] corners (a
//!   detector that failed on it) is skipped and named ([`ImageStatus::TooFewCorners`]); when
//!   some corner does not fit, Cauchy-weighted refinements find the outlier corners, which
//!   are excluded and flagged in the report (a view left with fewer than half its corners is
//!   excluded whole, [`ImageStatus::Outliers`]), and the inliers are refined alone.
//! - **Quality gates** ([`IntrinsicsWarning`]): an RMS above [`MAX_RMS_PX`], a focal length or
//!   principal point whose standard deviation exceeds [`MAX_FOCAL_RELATIVE_STD`] of its value
//!   or [`MAX_CENTER_RELATIVE_STD`] of the image size, more than [`MAX_OUTLIER_SHARE`] outlier
//!   corners, or a refinement that did not converge make the calibration
//!   [`IntrinsicsStatus::Poor`]; `ibc intrinsics` still writes it and exits with code 3.
//!
//! Bad input is a typed [`IntrinsicsError`]: too few usable images ([`MIN_IMAGES`]), a corner
//! outside the image or off the board, boards that are all parallel to each other (for
//! instance all parallel to the image: [`IntrinsicsError::DegenerateViews`], detected by the
//! spread of the board normals, [`MIN_NORMAL_SPREAD_DEG`], and for the pinhole also by the
//! conditioning of Zhang's constraints, [`zhang::ZHANG_MIN_CONDITION`]).
//!
//! # Corner file format (JSON)
//! Any detector's output (OpenCV's `findChessboardCorners` + `cornerSubPix`, Kalibr's
//! AprilGrid, ...) can be fed in as one JSON file per camera:
//!
//! ```json
//! {
//!   "format": "ibc-corners",
//!   "version": 1,
//!   "image_width": 1280,
//!   "image_height": 960,
//!   "board": {"rows": 6, "cols": 9, "square": 0.04},
//!   "images": [
//!     {"name": "img_0001.png", "corners": [
//!       {"row": 0, "col": 0, "u": 412.37, "v": 300.12},
//!       {"row": 0, "col": 1, "u": 440.91, "v": 298.50}
//!     ]}
//!   ]
//! }
//! ```
//!
//! - `format` must be `"ibc-corners"` and `version` 1 ([`CORNER_FORMAT`],
//!   [`CORNER_FORMAT_VERSION`]); unknown fields are refused.
//! - `board` is optional (`rows` x `cols` inner corners, `square` metres apart); without it
//!   give `--board ROWSxCOLS --square M`. Board corner `(row, col)` is at
//!   `(col * square, row * square, 0)` in the board frame ([`PlanarTarget`]); indices start
//!   at 0.
//! - Each image lists its detected corners in any order, each `(row, col)` at most once;
//!   missing corners are simply absent. `u, v` are pixels with pixel centres at integer
//!   coordinates (OpenCV's convention; add 0.5 to neither), inside
//!   `[-0.5, width - 0.5] x [-0.5, height - 0.5]`.
//!
//! # Command line
//! `ibc intrinsics --corners FILE --model kb|pinhole|mei [--board ROWSxCOLS --square M] --out DIR
//! [--json]`, or `ibc intrinsics --simulate [--model kb|pinhole|mei] [--views N] [--noise PX]
//! [--missing FRACTION] [--seed N] [--true-camera FILE] --out DIR` ([`command`]). Outputs
//! ([`output`]), written all or nothing: `<name>_camera_calib.yaml` (CamOdoCal),
//! `camchain.yaml` (Kalibr), `intrinsics_report.json` (parameters with standard deviations,
//! RMS and per-image errors, the initialization; [`report`]) and `residuals.svg` ([`svg`]);
//! simulated mode adds `corners.json` and `truth_camera_calib.yaml`.
//!
//! ```
//! use ibc_pipeline::intrinsics::simulate::{BoardSimulationOptions, preset_camera, simulate_boards};
//! use ibc_pipeline::intrinsics::{IntrinsicModel, IntrinsicsOptions, PlanarTarget, calibrate_intrinsics};
//!
//! let model = IntrinsicModel::KannalaBrandt;
//! let truth = preset_camera(model)?; // a 190-degree fisheye
//! let target = PlanarTarget::new(6, 9, 0.04)?;
//! let sim = simulate_boards(&truth, &target, &BoardSimulationOptions::for_model(model))?;
//! let cal = calibrate_intrinsics(&sim.corners, &target, model, &IntrinsicsOptions::default())?;
//! assert!(cal.rms_px < 0.25); // 0.2 px noise per coordinate
//! # Ok::<(), ibc_pipeline::intrinsics::IntrinsicsError>(())
//! ```

mod board_pose;
mod calibrate;
pub mod circle_fit;
pub mod command;
mod corners;
pub mod division_model;
mod error;
pub mod homography;
pub mod kb_init;
pub mod mei_init;
pub mod output;
pub mod pinhole_init;
mod refine;
pub mod report;
pub mod robust;
pub mod simulate;
pub mod svg;
mod target;
pub mod vanishing_points;
pub mod zhang;

pub use calibrate::{
    CornerResidual, ImageError, ImageStatus, Initialization, IntrinsicCalibration, IntrinsicModel,
    IntrinsicsOptions, IntrinsicsStatus, IntrinsicsWarning, MAX_CENTER_RELATIVE_STD,
    MAX_FOCAL_RELATIVE_STD, MAX_OUTLIER_SHARE, MAX_RMS_PX, MIN_CORNERS_PER_IMAGE, MIN_IMAGES,
    MIN_NORMAL_SPREAD_DEG, PINHOLE_FALLBACK_RMS_PX, calibrate_intrinsics, normal_spread_deg,
};
pub use corners::{CORNER_FORMAT, CORNER_FORMAT_VERSION, Corner, CornerSet, ImageCorners};
pub use error::IntrinsicsError;
pub use kb_init::MIN_LINE_CORNERS;
pub use target::PlanarTarget;
