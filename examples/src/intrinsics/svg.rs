//! An SVG of the reprojection residuals over the image, with pixel axes and a legend: each
//! corner where it was detected, its residual drawn as a line magnified by a stated factor,
//! coloured by image, the outliers ringed.

use ibc_camera_models::CameraModel;
use nalgebra::Vector2;

use super::calibrate::IntrinsicCalibration;
use super::corners::CornerSet;
use crate::report::plot::{Axes, Mark, Svg, legend, xml_escape};

/// Width of the image area in SVG units; the image is scaled to fit it.
const DRAWING_WIDTH: f64 = 1000.0;

/// The magnification that draws the 95th-percentile residual about 2% of the image width
/// long, rounded down to 1, 2 or 5 times a power of ten.
fn magnification(calibration: &IntrinsicCalibration, width: f64) -> f64 {
    let mut lengths: Vec<f64> = calibration
        .residuals
        .iter()
        .flatten()
        .map(|r| r.norm())
        .filter(|l| l.is_finite())
        .collect();
    if lengths.is_empty() {
        return 1.0;
    }
    lengths.sort_by(f64::total_cmp);
    let p95 = lengths[(lengths.len() * 95 / 100).min(lengths.len() - 1)];
    if p95.is_nan() || p95 <= 0.0 {
        return 1.0;
    }
    let raw = 0.02 * width / p95;
    let decade = 10f64.powf(raw.log10().floor());
    let mantissa = raw / decade;
    let step = if mantissa >= 5.0 {
        5.0
    } else if mantissa >= 2.0 {
        2.0
    } else {
        1.0
    };
    (step * decade).max(1.0)
}

/// The residual plot of a calibration (`corners` are the corners it was computed from): the
/// image with pixel axes, each corner where it was detected (one colour per image), its
/// residual magnified, the outlier corners ringed, and the principal point.
pub fn residual_svg(calibration: &IntrinsicCalibration, corners: &CornerSet) -> String {
    let (w, h) = (f64::from(corners.width), f64::from(corners.height));
    let (left, top) = (80.0, 64.0);
    let size = Vector2::new(DRAWING_WIDTH, DRAWING_WIDTH * h / w);
    let mut svg = Svg::new(left + size.x + 30.0, top + size.y + 60.0);
    let gain = magnification(calibration, w);
    // The image's v runs down the page: bottom-left is (-0.5, h - 0.5).
    let axes = Axes::new(
        Vector2::new(left, top),
        size,
        Vector2::new(-0.5, h - 0.5),
        Vector2::new(w - 0.5, -0.5),
    );
    svg.text(
        Vector2::new(left, 22.0),
        "start",
        "#000",
        &format!(
            "reprojection residuals, {} model: RMS {:.3} px per coordinate over {} corners in {} \
             images ({} outliers)",
            calibration.model.short_name(),
            calibration.rms_px,
            calibration.residuals.iter().map(Vec::len).sum::<usize>(),
            calibration
                .residuals
                .iter()
                .filter(|r| !r.is_empty())
                .count(),
            calibration.outlier_corners
        ),
    );
    axes.draw(&mut svg, "u [px]", "v [px]");
    let n = calibration.residuals.len().max(1);
    for (i, ((image, residuals), inliers)) in corners
        .images
        .iter()
        .zip(&calibration.residuals)
        .zip(&calibration.inliers)
        .enumerate()
    {
        let hue = 360.0 * i as f64 / n as f64;
        svg.raw(&format!(
            r#"<g color="hsl({hue:.0},70%,40%)"><title>{}</title>"#,
            xml_escape(&image.name)
        ));
        for ((c, r), inlier) in image.corners.iter().zip(residuals).zip(inliers) {
            let p = Vector2::new(c.u, c.v);
            let at = axes.map(p);
            svg.circle(at, 1.5, "currentColor");
            if r.x.is_finite() && r.y.is_finite() {
                svg.line(at, axes.map(p + r * gain), "currentColor", 1.0);
            }
            if !inlier {
                svg.ring(at, 5.0, "#d62728");
            }
        }
        svg.raw("</g>");
    }
    let pp = axes.map(calibration.camera.principal_point());
    svg.line(
        pp - Vector2::new(8.0, 0.0),
        pp + Vector2::new(8.0, 0.0),
        "#000",
        1.0,
    );
    svg.line(
        pp - Vector2::new(0.0, 8.0),
        pp + Vector2::new(0.0, 8.0),
        "#000",
        1.0,
    );
    legend(
        &mut svg,
        &axes,
        &[
            (
                Mark::Dot,
                "#555",
                "detected corner (one colour per image)".to_owned(),
            ),
            (
                Mark::Line,
                "#555",
                format!("residual, projected minus detected, x{gain}"),
            ),
            (
                Mark::Ring,
                "#d62728",
                "outlier corner (excluded)".to_owned(),
            ),
            (Mark::Line, "#000", "principal point (cross)".to_owned()),
        ],
    );
    svg.finish()
}
