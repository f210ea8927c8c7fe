//! An SVG of the reprojection residuals over the image: each corner where it was detected,
//! with its residual drawn as a line magnified by a stated factor, coloured by image.

use std::fmt::Write as _;

use ibc_camera_models::CameraModel;

use super::calibrate::IntrinsicCalibration;
use super::corners::CornerSet;

/// Width of the drawing in SVG units; the image is scaled to fit it.
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

/// The residual plot of a calibration (`corners` are the corners it was computed from).
pub fn residual_svg(calibration: &IntrinsicCalibration, corners: &CornerSet) -> String {
    let (w, h) = (f64::from(corners.width), f64::from(corners.height));
    let s = DRAWING_WIDTH / w;
    let (dw, dh) = (DRAWING_WIDTH, h * s);
    let header = 48.0;
    let gain = magnification(calibration, w);
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{dw:.0}" height="{:.0}" viewBox="0 0 {dw:.0} {:.0}" font-family="sans-serif">"#,
        dh + header,
        dh + header
    );
    let _ = writeln!(
        out,
        r#"<text x="8" y="20" font-size="16">Reprojection residuals, {} model: RMS {:.3} px per coordinate over {} corners in {} images</text>"#,
        calibration.model.short_name(),
        calibration.rms_px,
        calibration.residuals.iter().map(Vec::len).sum::<usize>(),
        calibration.residuals.len()
    );
    let _ = writeln!(
        out,
        r#"<text x="8" y="40" font-size="13">Dots: detected corners; lines: residual (projected minus detected) magnified {gain}x; one colour per image. Image {}x{} px.</text>"#,
        corners.width, corners.height
    );
    let _ = writeln!(
        out,
        r##"<rect x="0" y="{header}" width="{dw:.1}" height="{dh:.1}" fill="#fafafa" stroke="#333"/>"##
    );
    let n = calibration.residuals.len().max(1);
    for (i, (image, residuals)) in corners
        .images
        .iter()
        .zip(&calibration.residuals)
        .enumerate()
    {
        let hue = 360.0 * i as f64 / n as f64;
        let _ = writeln!(
            out,
            r#"<g stroke="hsl({hue:.0},70%,40%)" fill="hsl({hue:.0},70%,40%)"><title>{}</title>"#,
            xml_escape(&image.name)
        );
        for (c, r) in image.corners.iter().zip(residuals) {
            let (x, y) = ((c.u + 0.5) * s, (c.v + 0.5) * s + header);
            let (x2, y2) = (x + r.x * gain * s, y + r.y * gain * s);
            let _ = writeln!(
                out,
                r#"<circle cx="{x:.2}" cy="{y:.2}" r="1.5" stroke="none"/><line x1="{x:.2}" y1="{y:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke-width="1"/>"#
            );
        }
        out.push_str("</g>\n");
    }
    // The principal point.
    let pp = calibration.camera.principal_point();
    let (px, py) = ((pp.x + 0.5) * s, (pp.y + 0.5) * s + header);
    let _ = writeln!(
        out,
        r##"<g stroke="#000" stroke-width="1"><line x1="{:.1}" y1="{py:.1}" x2="{:.1}" y2="{py:.1}"/><line x1="{px:.1}" y1="{:.1}" x2="{px:.1}" y2="{:.1}"/><title>principal point</title></g>"##,
        px - 8.0,
        px + 8.0,
        py - 8.0,
        py + 8.0
    );
    out.push_str("</svg>\n");
    out
}

/// Escapes text for an XML text node.
fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
