//! Zhang's closed-form pinhole intrinsics from plane homographies, and his linear estimate of
//! the radial distortion.
//!
//! Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11), 2000:
//! section 3.1 (each homography `H = K [r1 r2 t]` gives `h1^T B h2 = 0` and
//! `h1^T B h1 = h2^T B h2` on `B = K^-T K^-1`), appendix B (K from B), section 3.3 (the radial
//! terms `k1, k2` by linear least squares given K and the poses).
//!
//! Specifics of this implementation:
//! - Pixels are first moved to the image centre and divided by the half-diagonal, so `B` is
//!   well conditioned; each homography is scaled so its first two columns have unit RMS norm.
//! - The zero-skew constraint `B12 = 0` is added as a row (Zhang, section 3.1, "if gamma = 0"),
//!   since the camera models have no skew; two views in general position then suffice.
//! - A degenerate set of views (all boards parallel to each other, in particular all parallel
//!   to the image: section 3.3 of the paper) leaves a null space of `V` of dimension above
//!   one; it is reported when the second smallest singular value of `V` is below
//!   [`ZHANG_MIN_CONDITION`] times the largest.

use nalgebra::{Matrix3, SMatrix, SymmetricEigen, Vector3};

use super::error::IntrinsicsError;

/// Below this ratio of the second smallest to the largest singular value of Zhang's stacked
/// constraints the views do not determine the intrinsics (boards parallel to each other).
/// Measured on 20 simulated views of 9x6 and 20x20 boards with 0.2 px noise seen by the
/// EuRoC camera (`k1 = -0.28`): boards all parallel to the image gave 1.1e-3 to 2.2e-3 (not
/// zero: noise and the residual distortion), boards facing the camera from varied directions
/// or tilted 4.2e-2 to 0.38. The threshold sits at their geometric middle.
pub const ZHANG_MIN_CONDITION: f64 = 1e-2;

/// Pinhole intrinsics from [`zhang_intrinsics`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZhangIntrinsics {
    /// Focal length, horizontal (pixels).
    pub fx: f64,
    /// Focal length, vertical (pixels).
    pub fy: f64,
    /// Principal point, horizontal (pixels).
    pub cx: f64,
    /// Principal point, vertical (pixels).
    pub cy: f64,
    /// The second smallest over the largest singular value of the stacked constraints (see
    /// [`ZHANG_MIN_CONDITION`]).
    pub condition: f64,
}

/// Zhang's `v_ij` row for columns `i` and `j` of `H`.
fn v_row(h: &Matrix3<f64>, i: usize, j: usize) -> SMatrix<f64, 1, 6> {
    let (hi, hj) = (h.column(i), h.column(j));
    SMatrix::<f64, 1, 6>::from_row_slice(&[
        hi[0] * hj[0],
        hi[0] * hj[1] + hi[1] * hj[0],
        hi[1] * hj[1],
        hi[2] * hj[0] + hi[0] * hj[2],
        hi[2] * hj[1] + hi[1] * hj[2],
        hi[2] * hj[2],
    ])
}

/// Pinhole intrinsics (no skew) from the homographies `image ~ H (board x, board y, 1)` of at
/// least two views of a plane, for a `width x height` image.
///
/// # Errors
/// [`IntrinsicsError::TooFewImages`] for fewer than two homographies,
/// [`IntrinsicsError::DegenerateViews`] when the views do not determine the intrinsics, and
/// [`IntrinsicsError::Initialization`] when the solution is not a camera (`B` not positive
/// definite, which noise on nearly degenerate views can cause).
pub fn zhang_intrinsics(
    homographies: &[Matrix3<f64>],
    width: u32,
    height: u32,
) -> Result<ZhangIntrinsics, IntrinsicsError> {
    if homographies.len() < 2 {
        return Err(IntrinsicsError::TooFewImages {
            got: homographies.len(),
            needed: 2,
        });
    }
    let (w, h) = (f64::from(width), f64::from(height));
    let (c, s) = (Vector3::new(0.5 * w, 0.5 * h, 1.0), 0.5 * w.hypot(h));
    let n = Matrix3::new(
        1.0 / s,
        0.0,
        -c.x / s,
        0.0,
        1.0 / s,
        -c.y / s,
        0.0,
        0.0,
        1.0,
    );
    let mut vtv = SMatrix::<f64, 6, 6>::zeros();
    for hom in homographies {
        let mut hn = n * hom;
        let scale = ((hn.column(0).norm_squared() + hn.column(1).norm_squared()) / 2.0).sqrt();
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(IntrinsicsError::Initialization(
                "a board homography is singular".into(),
            ));
        }
        hn /= scale;
        let v12 = v_row(&hn, 0, 1);
        let d = v_row(&hn, 0, 0) - v_row(&hn, 1, 1);
        vtv += v12.transpose() * v12 + d.transpose() * d;
    }
    let skew = SMatrix::<f64, 1, 6>::from_row_slice(&[0.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
    vtv += skew.transpose() * skew;
    let eig = SymmetricEigen::new(vtv);
    let mut order = [0usize, 1, 2, 3, 4, 5];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let largest = eig.eigenvalues[order[5]].max(0.0);
    let condition = (eig.eigenvalues[order[1]].max(0.0) / largest).sqrt();
    if condition.is_nan() || condition < ZHANG_MIN_CONDITION {
        return Err(IntrinsicsError::DegenerateViews {
            reason: format!(
                "the board homographies do not determine the focal length (Zhang's constraints \
                 have condition {condition:.1e}, below {ZHANG_MIN_CONDITION:.0e}): the boards \
                 are all nearly parallel to each other, for instance all parallel to the image"
            ),
        });
    }
    let mut b = eig.eigenvectors.column(order[0]).into_owned();
    if b[0] < 0.0 {
        b = -b;
    }
    let (b11, b12, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4], b[5]);
    let det = b11 * b22 - b12 * b12;
    let not_a_camera = || {
        IntrinsicsError::Initialization(
            "Zhang's closed form gives no real focal length (B is not positive definite): the \
             views are too close to degenerate or the corners too noisy"
                .into(),
        )
    };
    if !(b11 > 0.0 && det > 0.0) {
        return Err(not_a_camera());
    }
    let v0 = (b12 * b13 - b11 * b23) / det;
    let lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
    let ratio = lambda / b11;
    if ratio.is_nan() || ratio <= 0.0 {
        return Err(not_a_camera());
    }
    let alpha = (lambda / b11).sqrt();
    let beta = (lambda * b11 / det).sqrt();
    let gamma = -b12 * alpha * alpha * beta / lambda;
    let u0 = gamma * v0 / beta - b13 * alpha * alpha / lambda;
    let out = ZhangIntrinsics {
        fx: alpha * s,
        fy: beta * s,
        cx: u0 * s + c.x,
        cy: v0 * s + c.y,
        condition,
    };
    if ![out.fx, out.fy, out.cx, out.cy]
        .iter()
        .all(|v| v.is_finite())
    {
        return Err(not_a_camera());
    }
    Ok(out)
}

/// Zhang's linear estimate of the radial terms (section 3.3): with the ideal pixel
/// `(u, v) = K (x, y)` of a corner at normalized coordinates `(x, y)`, `r^2 = x^2 + y^2`, and
/// its observed pixel `(u', v')`, `u' - u = (u - cx) (k1 r^2 + k2 r^4)` (and the same in v);
/// the stacked equations are solved for `(k1, k2)`. `samples` holds `(x, y, u', v')`.
///
/// Returns `None` when the system is singular (all corners at one radius).
pub fn zhang_radial_distortion(
    intrinsics: &ZhangIntrinsics,
    samples: &[(f64, f64, f64, f64)],
) -> Option<(f64, f64)> {
    let mut ata = nalgebra::Matrix2::zeros();
    let mut atb = nalgebra::Vector2::zeros();
    for &(x, y, uo, vo) in samples {
        let r2 = x * x + y * y;
        let (du, dv) = (intrinsics.fx * x, intrinsics.fy * y);
        let (u, v) = (du + intrinsics.cx, dv + intrinsics.cy);
        for (d, res) in [(du, uo - u), (dv, vo - v)] {
            let row = nalgebra::Vector2::new(d * r2, d * r2 * r2);
            ata += row * row.transpose();
            atb += row * res;
        }
    }
    let sol = ata.cholesky()?.solve(&atb);
    (sol.x.is_finite() && sol.y.is_finite()).then_some((sol.x, sol.y))
}
