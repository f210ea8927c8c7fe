//! The unified (Mei) initialization: the generalized focal length from the conics that board
//! lines project to when `xi = 1`.
//!
//! C. Mei and P. Rives, "Single view point omnidirectional camera calibration from planar
//! grids", ICRA 2007, section IV (initialization); the unified model of C. Geyer and
//! K. Daniilidis, "A unifying theory for central panoramic systems", ECCV 2000:
//!
//! 1. Start from `xi = 1` (the parabolic case), no distortion, `gamma1 = gamma2 = gamma` and
//!    the principal point at the image centre.
//! 2. With `xi = 1` a pixel `q` (relative to the principal point) lifts to the sphere along
//!    `(q_x, q_y, (gamma - |q|^2 / gamma) / 2)`: the stereographic inverse. The bearings of a
//!    3D line lie in a plane through the centre, `n . d = 0`, so every corner of a board row
//!    satisfies the linear equation
//!
//!    ```text
//!    c1 q_x + c2 q_y + c3 / 2 - c4 |q|^2 / 2 = 0,   c = (n_x, n_y, n_z gamma, n_z / gamma)
//!    ```
//!
//!    whose least-squares null vector (four or more corners) gives `gamma = sqrt(c3 / c4)`.
//!    A line whose plane contains the optical axis (`n_z` near 0: its image passes through
//!    the centre) does not determine `gamma` and is skipped. Mei and Rives fit one
//!    user-selected line; here every board row and column with enough corners is fitted, and
//!    each image gives the median of its rows' and of its columns' values as hypotheses.
//! 3. Each hypothesis is scored as in the Kannala-Brandt initialization: every board pose by
//!    PnP on the bearing vectors of that parabolic camera, the capped reprojection error
//!    summed; the best is kept, and the refinement frees `xi`, the distortion, both focal
//!    lengths and the principal point.
//!
//! Corners are fitted in coordinates centred on the image and divided by its half-diagonal,
//! so the four columns of the fit are of one scale.

use ibc_camera_models::Unified;
use nalgebra::{Matrix4, Vector2, Vector4};

use super::corners::{CornerSet, ImageCorners};
use super::error::IntrinsicsError;
use super::kb_init::{
    KbInitOptions, LineFamily, LineInitialization, board_lines, choose_hypothesis,
};
use super::target::PlanarTarget;

/// A line is skipped when the z component of its plane's unit normal is below this: its
/// image passes within a few percent of the principal point and its curvature does not
/// determine `gamma`.
pub const MIN_LINE_NORMAL_Z: f64 = 0.05;

/// The result of [`unified_initialization`]: the parabolic camera of the best hypothesis
/// (`xi = 1`, no distortion), every hypothesis (`focal` is `gamma`) and the board poses.
pub type UnifiedInitialization = LineInitialization<Unified>;

/// `gamma` (in the units of the points) from the points of one line image under `xi = 1`,
/// or `None` when the line does not determine it (see the module docs).
pub fn line_gamma(points: &[Vector2<f64>]) -> Option<f64> {
    if points.len() < 4 {
        return None;
    }
    let mut ata = Matrix4::zeros();
    for q in points {
        let row = Vector4::new(q.x, q.y, 0.5, -0.5 * q.norm_squared());
        ata += row * row.transpose();
    }
    let eigen = ata.symmetric_eigen();
    let smallest = eigen.eigenvalues.imin();
    let c = eigen.eigenvectors.column(smallest);
    let ratio = c[2] / c[3];
    if !(ratio.is_finite() && ratio > 0.0) {
        return None;
    }
    let gamma = ratio.sqrt();
    let normal = nalgebra::Vector3::new(c[0], c[1], c[2] / gamma);
    (normal.z.abs() >= MIN_LINE_NORMAL_Z * normal.norm()).then_some(gamma)
}

/// The `gamma` hypotheses of one image (rows, then columns), pixels, for an image centred at
/// `centre` with half-diagonal `scale`: the median over each family's lines.
pub fn image_gamma_hypotheses(
    image: &ImageCorners,
    centre: Vector2<f64>,
    scale: f64,
    options: &KbInitOptions,
) -> Vec<(LineFamily, usize, f64)> {
    let mut out = Vec::new();
    for &family in options.families() {
        let mut gammas: Vec<f64> = board_lines(image, family, centre, scale, options)
            .iter()
            .filter_map(|line| line_gamma(line))
            .collect();
        if gammas.is_empty() {
            continue;
        }
        gammas.sort_by(f64::total_cmp);
        let gamma = gammas[gammas.len() / 2] * scale;
        if gamma.is_finite() && gamma > 0.0 {
            out.push((family, gammas.len(), gamma));
        }
    }
    out
}

/// The parabolic camera of a generalized focal length: `xi = 1`, no distortion,
/// `gamma1 = gamma2 = gamma`, `(u0, v0) = (w / 2, h / 2)`.
///
/// # Errors
/// [`IntrinsicsError::Camera`] for a `gamma` that is not finite and positive.
pub fn parabolic_camera(width: u32, height: u32, gamma: f64) -> Result<Unified, IntrinsicsError> {
    let (u0, v0) = (0.5 * f64::from(width), 0.5 * f64::from(height));
    Ok(Unified::new(
        width,
        height,
        [1.0, 0.0, 0.0, 0.0, 0.0, gamma, gamma, u0, v0],
    )?)
}

/// Mei and Rives's initialization of the unified parameters and of every board pose (see the
/// module docs). The corners must have been validated
/// ([`CornerSet::validate`](super::CornerSet::validate)).
///
/// # Errors
/// [`IntrinsicsError::NoFocalHypothesis`] when no line of any image determines `gamma`, and
/// [`IntrinsicsError::BoardPose`] when an image has no pose under the chosen camera.
pub fn unified_initialization(
    corners: &CornerSet,
    target: &PlanarTarget,
    options: &KbInitOptions,
) -> Result<UnifiedInitialization, IntrinsicsError> {
    choose_hypothesis(corners, target, options, image_gamma_hypotheses, |gamma| {
        parabolic_camera(corners.width, corners.height, gamma)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ibc_camera_models::CameraModel;
    use nalgebra::Vector3;

    /// The image of a 3D line under an exact parabolic camera gives its `gamma` back.
    #[test]
    fn line_gamma_of_an_exact_parabolic_line() {
        let gamma = 0.6;
        let camera = Unified::new(
            1000,
            1000,
            [1.0, 0.0, 0.0, 0.0, 0.0, gamma, gamma, 0.0, 0.0],
        )
        .unwrap();
        let (a, b) = (Vector3::new(-2.0, 0.7, 1.0), Vector3::new(3.0, 0.4, -0.5));
        let points: Vec<Vector2<f64>> = (0..12)
            .map(|i| {
                camera
                    .project(&(a + (b - a) * f64::from(i) / 11.0))
                    .unwrap()
            })
            .collect();
        let found = line_gamma(&points).unwrap();
        assert!((found - gamma).abs() < 1e-9 * gamma, "{found}");
        // A line through the optical axis's plane images through the centre: skipped.
        let radial: Vec<Vector2<f64>> = (0..6)
            .map(|i| {
                let p = Vector3::new(f64::from(i) - 2.5, 0.0, 1.0);
                camera.project(&p).unwrap()
            })
            .collect();
        assert_eq!(line_gamma(&radial), None);
    }
}
