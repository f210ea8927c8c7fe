//! SVG plots of a calibration, written by hand (plain SVG 1.1, no dependency):
//!
//! - [`top_view_svg`]: like the paper's figures 6b and 7b (Heng et al., ICRA 2014): the map
//!   points used by the refinement, the localized camera centres (one colour per camera) and
//!   the rig trajectory in the map's x-y plane (the map's z-axis is taken as up), and beside
//!   it the estimated rig seen from above: each camera's centre and optical axis in the rig
//!   frame, projected onto the plane perpendicular to the mean up direction of the map.
//! - [`error_histogram_svg`]: the distribution of the reprojection errors of the
//!   refinement's correspondences before and after refinement.

use std::fmt::Write as _;

use nalgebra::{Isometry3, Vector2, Vector3};

use crate::calib::{Calibration, finite_mean};

/// Colours of the cameras (matplotlib's `tab10`).
const COLOURS: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// Most map points drawn (evenly spaced over those used), to keep the file small.
const MAX_POINTS_DRAWN: usize = 20_000;

fn colour(c: usize) -> &'static str {
    COLOURS[c % COLOURS.len()]
}

/// A minimal SVG writer.
struct Svg {
    s: String,
}

impl Svg {
    fn new(width: f64, height: f64) -> Self {
        let mut s = String::new();
        let _ = write!(
            s,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{width}\" height=\"{height}\" \
             viewBox=\"0 0 {width} {height}\" font-family=\"sans-serif\" font-size=\"12\">\n\
             <rect width=\"{width}\" height=\"{height}\" fill=\"white\"/>\n"
        );
        Self { s }
    }

    fn line(&mut self, a: Vector2<f64>, b: Vector2<f64>, stroke: &str, width: f64) {
        let _ = writeln!(
            self.s,
            "<line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{stroke}\" \
             stroke-width=\"{width}\"/>",
            a.x, a.y, b.x, b.y
        );
    }

    fn circle(&mut self, c: Vector2<f64>, r: f64, fill: &str) {
        let _ = writeln!(
            self.s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"{r}\" fill=\"{fill}\"/>",
            c.x, c.y
        );
    }

    fn polyline(&mut self, points: &[Vector2<f64>], stroke: &str, width: f64) {
        if points.is_empty() {
            return;
        }
        let coords: Vec<String> = points
            .iter()
            .map(|p| format!("{:.1},{:.1}", p.x, p.y))
            .collect();
        let _ = writeln!(
            self.s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{stroke}\" stroke-width=\"{width}\"/>",
            coords.join(" ")
        );
    }

    fn text(&mut self, p: Vector2<f64>, anchor: &str, fill: &str, text: &str) {
        let escaped = text
            .replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;");
        let _ = writeln!(
            self.s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"{anchor}\" fill=\"{fill}\">{escaped}</text>",
            p.x, p.y
        );
    }

    fn frame(&mut self, x: f64, y: f64, w: f64, h: f64) {
        let _ = writeln!(
            self.s,
            "<rect x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" fill=\"none\" stroke=\"#444\"/>"
        );
    }

    fn finish(mut self) -> String {
        self.s.push_str("</svg>\n");
        self.s
    }
}

/// Maps a rectangle of data coordinates onto a panel, same scale on both axes, y up.
struct Panel {
    origin: Vector2<f64>,
    size: f64,
    min: Vector2<f64>,
    scale: f64,
}

impl Panel {
    fn new(origin: Vector2<f64>, size: f64, min: Vector2<f64>, max: Vector2<f64>) -> Self {
        let span = (max - min).max().max(1e-9);
        let margin = 0.05 * span;
        let scale = size / (span + 2.0 * margin);
        let centre = (min + max) / 2.0;
        let min = centre - Vector2::repeat(span / 2.0 + margin);
        Self {
            origin,
            size,
            min,
            scale,
        }
    }

    fn map(&self, p: Vector2<f64>) -> Vector2<f64> {
        let d = (p - self.min) * self.scale;
        Vector2::new(self.origin.x + d.x, self.origin.y + self.size - d.y)
    }

    fn contains(&self, p: Vector2<f64>) -> bool {
        let q = self.map(p);
        q.x >= self.origin.x
            && q.x <= self.origin.x + self.size
            && q.y >= self.origin.y
            && q.y <= self.origin.y + self.size
    }
}

fn bounds(points: impl Iterator<Item = Vector2<f64>>) -> Option<(Vector2<f64>, Vector2<f64>)> {
    points.fold(None, |acc, p| match acc {
        None => Some((p, p)),
        Some((lo, hi)) => Some((lo.inf(&p), hi.sup(&p))),
    })
}

/// The top view (see the module docs).
pub fn top_view_svg(calibration: &Calibration) -> String {
    let (map_size, rig_size, pad) = (760.0, 360.0, 30.0);
    let mut svg = Svg::new(pad * 3.0 + map_size + rig_size, map_size + 2.0 * pad + 20.0);
    let xy = |p: &Vector3<f64>| Vector2::new(p.x, p.y);
    let trajectory: Vec<Vector2<f64>> = calibration
        .refinement
        .world_from_rig
        .iter()
        .map(|p| xy(&p.translation.vector))
        .collect();
    let mut centres: Vec<(usize, Vector2<f64>)> = Vec::new();
    for (s, pose) in calibration.refinement.world_from_rig.iter().enumerate() {
        for (c, e) in calibration.rig_from_camera.iter().enumerate() {
            if calibration.frame_sets[s].camera_from_world[c].is_some() {
                centres.push((c, xy(&(pose * e).translation.vector)));
            }
        }
    }
    let mut points: Vec<Vector2<f64>> = calibration
        .observations
        .iter()
        .map(|o| xy(&o.point.coords))
        .collect();
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    // The panel spans the map points used, the trajectory and the camera centres.
    let (lo, hi) = bounds(
        trajectory
            .iter()
            .copied()
            .chain(centres.iter().map(|c| c.1))
            .chain(points.iter().copied()),
    )
    .unwrap_or((Vector2::zeros(), Vector2::repeat(1.0)));
    let panel = Panel::new(Vector2::new(pad, pad + 20.0), map_size, lo, hi);
    svg.text(
        Vector2::new(pad, pad),
        "start",
        "#000",
        "top view (map x-y): map points used, camera centres, rig trajectory",
    );
    svg.frame(pad, pad + 20.0, map_size, map_size);
    let step = points.len().div_ceil(MAX_POINTS_DRAWN).max(1);
    for p in points.iter().step_by(step).filter(|p| panel.contains(**p)) {
        svg.circle(panel.map(*p), 0.8, "#9a9a9a");
    }
    for (c, p) in &centres {
        svg.circle(panel.map(*p), 1.2, colour(*c));
    }
    let mapped: Vec<Vector2<f64>> = trajectory.iter().map(|p| panel.map(*p)).collect();
    svg.polyline(&mapped, "#000", 1.0);
    // Scale bar of 10 m.
    let bar = Vector2::new(pad + 15.0, pad + 20.0 + map_size - 15.0);
    svg.line(
        bar,
        bar + Vector2::new(10.0 * panel.scale, 0.0),
        "#000",
        2.0,
    );
    svg.text(
        bar + Vector2::new(5.0 * panel.scale, -5.0),
        "middle",
        "#000",
        "10 m",
    );
    draw_rig(
        &mut svg,
        calibration,
        Vector2::new(2.0 * pad + map_size, pad + 20.0),
        rig_size,
    );
    svg.finish()
}

/// The estimated rig seen from above (see the module docs).
fn draw_rig(svg: &mut Svg, calibration: &Calibration, origin: Vector2<f64>, size: f64) {
    svg.text(
        origin - Vector2::new(0.0, 20.0 - 0.0),
        "start",
        "#000",
        "estimated rig, from above",
    );
    svg.frame(origin.x, origin.y, size, size);
    // The map's up direction in the rig frame, averaged over the rig poses.
    let up = calibration
        .refinement
        .world_from_rig
        .iter()
        .map(|p: &Isometry3<f64>| p.rotation.inverse() * Vector3::z())
        .sum::<Vector3<f64>>();
    let up = if up.norm() > 1e-9 {
        up.normalize()
    } else {
        -Vector3::y()
    };
    let axis0 = calibration.rig_from_camera[0].rotation * Vector3::z();
    let mut forward = axis0 - up * up.dot(&axis0);
    if forward.norm() < 1e-6 {
        forward = Vector3::x() - up * up.x;
    }
    let forward = forward.normalize();
    let left = up.cross(&forward);
    let plane = |v: &Vector3<f64>| Vector2::new(-v.dot(&left), v.dot(&forward));
    let centres: Vec<Vector2<f64>> = calibration
        .rig_from_camera
        .iter()
        .map(|e| plane(&e.translation.vector))
        .collect();
    let (lo, hi) = bounds(centres.iter().copied()).unwrap_or((Vector2::zeros(), Vector2::zeros()));
    let span = (hi - lo).max().max(0.1);
    let panel = Panel::new(
        origin,
        size,
        lo - Vector2::repeat(0.4 * span),
        hi + Vector2::repeat(0.4 * span),
    );
    for (c, (e, p)) in calibration.rig_from_camera.iter().zip(&centres).enumerate() {
        let axis = plane(&(e.rotation * Vector3::z()));
        let tip = p + axis * (0.25 * span);
        svg.line(panel.map(*p), panel.map(tip), colour(c), 2.0);
        svg.circle(panel.map(*p), 4.0, colour(c));
        svg.text(
            panel.map(*p) + Vector2::new(6.0, -6.0),
            "start",
            colour(c),
            &calibration.camera_names[c],
        );
    }
    svg.text(
        Vector2::new(origin.x + size / 2.0, origin.y + size + 16.0),
        "middle",
        "#444",
        "camera 0 looks up the page; lines: optical axes",
    );
}

/// The reprojection-error distribution before and after refinement (see the module docs).
pub fn error_histogram_svg(calibration: &Calibration) -> String {
    let (w, h, pad) = (760.0, 420.0, 50.0);
    let mut svg = Svg::new(w, h);
    let sorted = |v: &[f64]| {
        let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        s.sort_by(f64::total_cmp);
        s
    };
    let before = sorted(&calibration.initial_errors_px);
    let after = sorted(&calibration.final_errors_px);
    let p99 = |s: &[f64]| {
        s.get(s.len().saturating_sub(1) * 99 / 100)
            .copied()
            .unwrap_or(1.0)
    };
    let x_max = (p99(&before).max(p99(&after)) * 1.1).max(1.0);
    let bins = 60usize;
    let histogram = |s: &[f64]| {
        let mut counts = vec![0usize; bins];
        for v in s {
            let b = ((v / x_max) * bins as f64) as usize;
            if b < bins {
                counts[b] += 1;
            }
        }
        counts
    };
    let (hb, ha) = (histogram(&before), histogram(&after));
    let y_max = hb.iter().chain(&ha).copied().max().unwrap_or(1).max(1) as f64;
    let (x0, y0, pw, ph) = (pad, h - pad, w - 2.0 * pad, h - 2.0 * pad - 20.0);
    let to = |x: f64, y: f64| Vector2::new(x0 + x / x_max * pw, y0 - y / y_max * ph);
    svg.text(
        Vector2::new(pad, 25.0),
        "start",
        "#000",
        "reprojection error of the refinement's correspondences [px]",
    );
    svg.line(Vector2::new(x0, y0), Vector2::new(x0 + pw, y0), "#000", 1.0);
    svg.line(Vector2::new(x0, y0), Vector2::new(x0, y0 - ph), "#000", 1.0);
    for i in 0..=5 {
        let x = x_max * f64::from(i) / 5.0;
        let p = to(x, 0.0);
        svg.line(p, p + Vector2::new(0.0, 5.0), "#000", 1.0);
        svg.text(
            p + Vector2::new(0.0, 18.0),
            "middle",
            "#000",
            &format!("{x:.2}"),
        );
    }
    let step = |counts: &[usize]| {
        let mut pts = vec![to(0.0, 0.0)];
        for (b, &n) in counts.iter().enumerate() {
            let (a, z) = (
                x_max * b as f64 / bins as f64,
                x_max * (b + 1) as f64 / bins as f64,
            );
            pts.push(to(a, n as f64));
            pts.push(to(z, n as f64));
        }
        pts.push(to(x_max, 0.0));
        pts
    };
    svg.polyline(&step(&hb), "#ff7f0e", 1.5);
    svg.polyline(&step(&ha), "#1f77b4", 1.5);
    let legend = Vector2::new(x0 + pw - 10.0, y0 - ph + 10.0);
    svg.text(
        legend,
        "end",
        "#ff7f0e",
        &format!("before refinement (mean {:.3} px)", finite_mean(&before)),
    );
    svg.text(
        legend + Vector2::new(0.0, 16.0),
        "end",
        "#1f77b4",
        &format!("after refinement (mean {:.3} px)", finite_mean(&after)),
    );
    svg.text(
        legend + Vector2::new(0.0, 32.0),
        "end",
        "#444",
        &format!(
            "{} correspondences, peak bin {}",
            before.len(),
            y_max as usize
        ),
    );
    svg.finish()
}
