//! The pinhole-radtan initialization: a division-model undistortion, Zhang's closed form and
//! his linear radial terms, alternated, and the board poses by PnP (Fitzgibbon, CVPR 2001;
//! Zhang, PAMI 2000, sections 3.1 to 3.3; see [`super::division_model`] and
//! [`super::zhang`]).
//!
//! 1. The corners are undistorted with the one-parameter division model that best straightens
//!    the boards: Zhang's closed form ignores distortion, and strong barrel distortion
//!    (EuRoC's `k1 = -0.28`) biases it by 5 to 20 percent when the boards reach the image
//!    corners, far enough for the refinement to end in a false minimum.
//! 2. A homography per image (normalized DLT) and Zhang's closed form for `fx, fy, cx, cy`.
//! 3. Board poses by PnP on the bearings of the undistorted corners.
//! 4. `k1, k2` by Zhang's linear least squares on the observed corners; `p1 = p2 = 0`.
//! 5. The corners undistorted with these terms give new homographies and a new closed form;
//!    steps 3 to 5 repeat up to [`ZHANG_ALTERNATIONS`] times or until `fx` moves by less than
//!    1e-6 relative (Zhang's section 3.3 alternation). A round whose terms cannot unproject
//!    every corner (a fold of the distortion inside the image) ends the alternation, and the
//!    last camera that could is kept.
//!
//! [`centred_initialization`] is the fallback when the closed form is poorly conditioned (views
//! that differ little in orientation, boards partly outside the image): the principal point
//! at the image centre, square pixels and no distortion leave one unknown, `1 / f^2`, which
//! Zhang's two constraints per homography (`h1' W h2 = 0`, `h1' W h1 = h2' W h2`) determine
//! by linear least squares over every image.

use ibc_camera_models::{Camera, CameraModel, PinholeRadtan};
use nalgebra::{Isometry3, Vector2};

use super::board_pose::{Correspondences, all_correspondences, board_pose};
use super::corners::CornerSet;
use super::division_model::{estimate_lambda, normalization, undistort};
use super::error::IntrinsicsError;
use super::homography::homography;
use super::target::PlanarTarget;
use super::zhang::{ZhangIntrinsics, zhang_intrinsics, zhang_radial_distortion};

/// Most rounds of Zhang's alternation between the closed form and the radial terms.
pub const ZHANG_ALTERNATIONS: usize = 10;

/// The result of [`pinhole_initialization`].
#[derive(Clone, Debug, PartialEq)]
pub struct PinholeInitialization {
    /// The division-model parameter of step 1 (half-diagonal units; 0 if none was found).
    pub division_lambda: f64,
    /// Zhang's closed-form intrinsics from the division-undistorted corners (step 2).
    pub zhang: ZhangIntrinsics,
    /// The initial camera after the alternation.
    pub camera: PinholeRadtan,
    /// Rounds of the alternation run.
    pub alternations: usize,
    /// `camera_from_board` of every image under `camera`.
    pub camera_from_board: Vec<Isometry3<f64>>,
}

/// Pixels of every image, one list per image.
type ImagePixels = Vec<Vec<Vector2<f64>>>;

/// Every image's board points and pixels, the raw pixels, and the pixels straightened by the
/// division model with its `lambda` (steps 1 of both starts).
fn straightened_corners(
    corners: &CornerSet,
    target: &PlanarTarget,
) -> (Correspondences, ImagePixels, f64, ImagePixels) {
    let data = all_correspondences(target, corners);
    let raw: Vec<Vec<Vector2<f64>>> = data.iter().map(|(_, px)| px.clone()).collect();
    let (division_lambda, straightened) = division_undistorted(&data, corners);
    (data, raw, division_lambda, straightened)
}

/// Board poses of every image for a camera, from `pixels` (one list per image).
fn all_board_poses(
    camera: &Camera,
    data: &Correspondences,
    pixels: &[Vec<Vector2<f64>>],
    corners: &CornerSet,
) -> Result<Vec<Isometry3<f64>>, IntrinsicsError> {
    data.iter()
        .zip(pixels)
        .zip(&corners.images)
        .map(|(((points, _), px), image)| {
            board_pose(camera, points, px, true).map_err(|source| IntrinsicsError::BoardPose {
                image: image.name.clone(),
                source,
            })
        })
        .collect()
}

/// Zhang's closed form on the homographies of `pixels` (one list per image).
fn closed_form(
    data: &Correspondences,
    pixels: &[Vec<Vector2<f64>>],
    corners: &CornerSet,
) -> Result<ZhangIntrinsics, IntrinsicsError> {
    let homographies = data
        .iter()
        .zip(pixels)
        .zip(&corners.images)
        .map(|(((points, _), px), image)| {
            let plane: Vec<Vector2<f64>> = points.iter().map(|p| p.xy().coords).collect();
            homography(&plane, px).ok_or_else(|| IntrinsicsError::CollinearCorners {
                image: image.name.clone(),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    zhang_intrinsics(&homographies, corners.width, corners.height)
}

/// Zhang's linear `k1, k2` for intrinsics `k` and poses, on the observed corners.
fn radial_terms(
    k: &ZhangIntrinsics,
    data: &Correspondences,
    poses: &[Isometry3<f64>],
) -> Option<(f64, f64)> {
    let mut samples = Vec::new();
    for ((points, pixels), pose) in data.iter().zip(poses) {
        for (x, obs) in points.iter().zip(pixels) {
            let p = pose * x;
            if p.z > 0.0 {
                samples.push((p.x / p.z, p.y / p.z, obs.x, obs.y));
            }
        }
    }
    zhang_radial_distortion(k, &samples)
}

/// The corners moved to where an undistorted pinhole with the same `fx, fy, cx, cy` would see
/// them, or `None` if a corner cannot be unprojected or lies behind the camera.
fn radtan_undistorted(
    camera: &PinholeRadtan,
    data: &Correspondences,
) -> Option<Vec<Vec<Vector2<f64>>>> {
    data.iter()
        .map(|(_, pixels)| {
            pixels
                .iter()
                .map(|p| {
                    let ray = camera.unproject_fast(p).ok()?;
                    (ray.z > 0.0).then(|| {
                        Vector2::new(
                            camera.fx() * ray.x / ray.z + camera.cx(),
                            camera.fy() * ray.y / ray.z + camera.cy(),
                        )
                    })
                })
                .collect()
        })
        .collect()
}

/// The corners undistorted by the division model that best straightens the boards, with its
/// `lambda` (0 and the corners unchanged if none is found).
fn division_undistorted(
    data: &Correspondences,
    corners: &CornerSet,
) -> (f64, Vec<Vec<Vector2<f64>>>) {
    let raw: Vec<Vec<Vector2<f64>>> = data.iter().map(|(_, px)| px.clone()).collect();
    let (c, s) = normalization(corners.width, corners.height);
    let plane: Vec<Vec<Vector2<f64>>> = data
        .iter()
        .map(|(points, _)| points.iter().map(|p| p.xy().coords).collect())
        .collect();
    let normalized: Vec<Vec<Vector2<f64>>> = raw
        .iter()
        .map(|px| px.iter().map(|p| (p - c) / s).collect())
        .collect();
    let Some(lambda) = estimate_lambda(&plane, &normalized) else {
        return (0.0, raw);
    };
    let undistorted: Option<Vec<Vec<Vector2<f64>>>> = normalized
        .iter()
        .map(|px| {
            px.iter()
                .map(|x| undistort(x, lambda).map(|u| c + u * s))
                .collect()
        })
        .collect();
    match undistorted {
        Some(u) => (lambda, u),
        None => (0.0, raw),
    }
}

/// The initialization of the pinhole-radtan parameters and of every board pose (see the
/// module docs). The corners must have been validated
/// ([`CornerSet::validate`](super::CornerSet::validate)).
///
/// # Errors
/// [`IntrinsicsError::CollinearCorners`] for an image without a homography,
/// [`IntrinsicsError::DegenerateViews`] and [`IntrinsicsError::Initialization`] from
/// [`zhang_intrinsics`], [`IntrinsicsError::BoardPose`] when an image has no pose.
pub fn pinhole_initialization(
    corners: &CornerSet,
    target: &PlanarTarget,
) -> Result<PinholeInitialization, IntrinsicsError> {
    let (data, raw, division_lambda, straightened) = straightened_corners(corners, target);
    let zhang = closed_form(&data, &straightened, corners)?;
    let (w, h) = (corners.width, corners.height);
    let mut k = zhang;
    let mut camera = PinholeRadtan::new(w, h, [0.0, 0.0, 0.0, 0.0, k.fx, k.fy, k.cx, k.cy])?;
    let mut poses = all_board_poses(&Camera::from(camera.clone()), &data, &straightened, corners)?;
    let mut alternations = 0;
    for _ in 0..ZHANG_ALTERNATIONS {
        let Some((k1, k2)) = radial_terms(&k, &data, &poses) else {
            break;
        };
        let Ok(distorted) = PinholeRadtan::new(w, h, [k1, k2, 0.0, 0.0, k.fx, k.fy, k.cx, k.cy])
        else {
            break;
        };
        let Some(ideal) = radtan_undistorted(&distorted, &data) else {
            break;
        };
        let Ok(next) = closed_form(&data, &ideal, corners) else {
            break;
        };
        let Ok(candidate) =
            PinholeRadtan::new(w, h, [k1, k2, 0.0, 0.0, next.fx, next.fy, next.cx, next.cy])
        else {
            break;
        };
        let Ok(next_poses) =
            all_board_poses(&Camera::from(candidate.clone()), &data, &raw, corners)
        else {
            break;
        };
        alternations += 1;
        let moved = (next.fx - k.fx).abs() / k.fx;
        k = next;
        camera = candidate;
        poses = next_poses;
        if moved < 1e-6 {
            break;
        }
    }
    if alternations == 0 {
        // No radial terms: the undistorted camera's poses from the raw corners.
        poses = all_board_poses(&Camera::from(camera.clone()), &data, &raw, corners)?;
    }
    Ok(PinholeInitialization {
        division_lambda,
        zhang,
        camera,
        alternations,
        camera_from_board: poses,
    })
}

/// The fallback initialization (see the module docs): the principal point at the image
/// centre, `fx = fy = f` from the homographies of the division-undistorted corners, no
/// distortion, and every board pose by PnP.
///
/// # Errors
/// [`IntrinsicsError::CollinearCorners`] for an image without a homography,
/// [`IntrinsicsError::Initialization`] when the constraints give no positive `1 / f^2`,
/// [`IntrinsicsError::BoardPose`] when an image has no pose.
pub fn centred_initialization(
    corners: &CornerSet,
    target: &PlanarTarget,
) -> Result<PinholeInitialization, IntrinsicsError> {
    let (data, raw, division_lambda, straightened) = straightened_corners(corners, target);
    let (w, h) = (corners.width, corners.height);
    let (cx, cy) = (0.5 * f64::from(w) - 0.5, 0.5 * f64::from(h) - 0.5);
    let (mut aa, mut ab) = (0.0, 0.0);
    for (((points, _), px), image) in data.iter().zip(&straightened).zip(&corners.images) {
        let plane: Vec<Vector2<f64>> = points.iter().map(|p| p.xy().coords).collect();
        let centred: Vec<Vector2<f64>> = px.iter().map(|p| p - Vector2::new(cx, cy)).collect();
        let hom =
            homography(&plane, &centred).ok_or_else(|| IntrinsicsError::CollinearCorners {
                image: image.name.clone(),
            })?;
        let scale = hom.column(0).norm().max(hom.column(1).norm());
        if !(scale.is_finite() && scale > 0.0) {
            continue;
        }
        let m = hom / scale;
        let (h1, h2) = (m.column(0), m.column(1));
        // a / f^2 + b = 0 for each of Zhang's two constraints.
        for (a, b) in [
            (h1.x * h2.x + h1.y * h2.y, h1.z * h2.z),
            (
                h1.x * h1.x + h1.y * h1.y - h2.x * h2.x - h2.y * h2.y,
                h1.z * h1.z - h2.z * h2.z,
            ),
        ] {
            aa += a * a;
            ab += a * b;
        }
    }
    let inverse_f2 = -ab / aa;
    if !(inverse_f2.is_finite() && inverse_f2 > 0.0) {
        return Err(IntrinsicsError::Initialization(
            "the homographies give no focal length with the principal point at the centre".into(),
        ));
    }
    let f = inverse_f2.sqrt().recip();
    let camera = PinholeRadtan::new(w, h, [0.0, 0.0, 0.0, 0.0, f, f, cx, cy])?;
    let poses = all_board_poses(&Camera::from(camera.clone()), &data, &raw, corners)?;
    Ok(PinholeInitialization {
        division_lambda,
        zhang: ZhangIntrinsics {
            fx: f,
            fy: f,
            cx,
            cy,
            condition: f64::NAN,
        },
        camera,
        alternations: 0,
        camera_from_board: poses,
    })
}
