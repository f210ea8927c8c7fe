//! SVG plots of a calibration, with axes, round ticks, units and legends ([`super::plot`]):
//!
//! - [`top_view_svg`]: like the paper's figures 6b and 7b (Heng et al., ICRA 2014): the map
//!   points used by the refinement, the localized camera centres (one colour per camera) and
//!   the rig trajectory in the map's x-y plane (the map's z-axis is taken as up), and beside
//!   it the estimated rig seen from above: each camera's centre and optical axis in the rig
//!   frame, projected onto the plane perpendicular to the mean up direction of the map.
//! - [`error_histogram_svg`]: the distribution of the reprojection errors of the
//!   refinement's correspondences before and after refinement.

use nalgebra::{Isometry3, Vector2, Vector3};

use super::plot::{Axes, Mark, Svg, colour, legend};
use crate::calib::{Calibration, finite_mean};

/// Most map points drawn (evenly spaced over those used), to keep the file small.
const MAX_POINTS_DRAWN: usize = 20_000;

fn bounds(points: impl Iterator<Item = Vector2<f64>>) -> Option<(Vector2<f64>, Vector2<f64>)> {
    points.fold(None, |acc, p| match acc {
        None => Some((p, p)),
        Some((lo, hi)) => Some((lo.inf(&p), hi.sup(&p))),
    })
}

/// What a top view draws: the points, each rig pose, which cameras to draw a centre for at
/// each pose, and the rig.
pub(crate) struct TopView<'a> {
    /// The panel's title.
    pub title: &'a str,
    /// The legend's name of the points.
    pub points_label: &'a str,
    /// The points (world frame).
    pub points: Vec<Vector3<f64>>,
    /// `world_from_rig` of each pose drawn.
    pub world_from_rig: Vec<Isometry3<f64>>,
    /// For each pose, whether each camera's centre is drawn.
    pub camera_seen: Vec<Vec<bool>>,
    /// The extrinsics.
    pub rig_from_camera: &'a [Isometry3<f64>],
    /// The camera names.
    pub camera_names: &'a [String],
}

/// The top view (see the module docs).
pub fn top_view_svg(calibration: &Calibration) -> String {
    top_view(&TopView {
        title: "top view of the map: map points used, camera centres, rig trajectory",
        points_label: "map points used",
        points: calibration
            .observations
            .iter()
            .map(|o| o.point.coords)
            .collect(),
        world_from_rig: calibration.refinement.world_from_rig.clone(),
        camera_seen: calibration
            .frame_sets
            .iter()
            .map(|s| s.camera_from_world.iter().map(Option::is_some).collect())
            .collect(),
        rig_from_camera: &calibration.rig_from_camera,
        camera_names: &calibration.camera_names,
    })
}

/// A top view of `view` (the layout of [`top_view_svg`]).
pub(crate) fn top_view(view: &TopView<'_>) -> String {
    let (map_side, rig_side, left, top) = (700.0, 340.0, 80.0, 50.0);
    let mut svg = Svg::new(
        left * 2.0 + map_side + rig_side + 40.0,
        top + map_side + 60.0,
    );
    let xy = |p: &Vector3<f64>| Vector2::new(p.x, p.y);
    let trajectory: Vec<Vector2<f64>> = view
        .world_from_rig
        .iter()
        .map(|p| xy(&p.translation.vector))
        .collect();
    let mut centres: Vec<(usize, Vector2<f64>)> = Vec::new();
    for (pose, seen) in view.world_from_rig.iter().zip(&view.camera_seen) {
        for (c, e) in view.rig_from_camera.iter().enumerate() {
            if seen.get(c).copied().unwrap_or(false) {
                centres.push((c, xy(&(pose * e).translation.vector)));
            }
        }
    }
    let mut points: Vec<Vector2<f64>> = view.points.iter().map(xy).collect();
    points.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    points.dedup();
    // The panel spans the points, the trajectory and the camera centres.
    let (lo, hi) = bounds(
        trajectory
            .iter()
            .copied()
            .chain(centres.iter().map(|c| c.1))
            .chain(points.iter().copied()),
    )
    .unwrap_or((Vector2::zeros(), Vector2::repeat(1.0)));
    let axes = Axes::equal(Vector2::new(left, top), map_side, lo, hi);
    svg.text(Vector2::new(left, top - 16.0), "start", "#000", view.title);
    axes.draw(&mut svg, "x [m] (map frame)", "y [m] (map frame)");
    let step = points.len().div_ceil(MAX_POINTS_DRAWN).max(1);
    for p in points.iter().step_by(step).filter(|p| axes.contains(**p)) {
        svg.circle(axes.map(*p), 0.8, "#9a9a9a");
    }
    for (c, p) in &centres {
        svg.circle(axes.map(*p), 1.2, colour(*c));
    }
    let mapped: Vec<Vector2<f64>> = trajectory.iter().map(|p| axes.map(*p)).collect();
    svg.polyline(&mapped, "#000", 1.0);
    let mut entries = vec![(Mark::Dot, "#9a9a9a", view.points_label.to_owned())];
    for (c, name) in view.camera_names.iter().enumerate() {
        entries.push((Mark::Dot, colour(c), format!("camera `{name}` centres")));
    }
    entries.push((Mark::Line, "#000", "rig trajectory".to_owned()));
    legend(&mut svg, &axes, &entries);
    draw_rig(
        &mut svg,
        view,
        Vector2::new(2.0 * left + map_side + 20.0, top),
        rig_side,
    );
    svg.finish()
}

/// The estimated rig seen from above (see the module docs).
fn draw_rig(svg: &mut Svg, view: &TopView<'_>, origin: Vector2<f64>, side: f64) {
    svg.text(
        origin - Vector2::new(0.0, 16.0),
        "start",
        "#000",
        "estimated rig, seen from above",
    );
    // The map's up direction in the rig frame, averaged over the rig poses.
    let up = view
        .world_from_rig
        .iter()
        .map(|p: &Isometry3<f64>| p.rotation.inverse() * Vector3::z())
        .sum::<Vector3<f64>>();
    let up = if up.norm() > 1e-9 {
        up.normalize()
    } else {
        -Vector3::y()
    };
    let Some(first) = view.rig_from_camera.first() else {
        return;
    };
    let axis0 = first.rotation * Vector3::z();
    let mut forward = axis0 - up * up.dot(&axis0);
    if forward.norm() < 1e-6 {
        forward = Vector3::x() - up * up.x;
    }
    let forward = forward.normalize();
    let left = up.cross(&forward);
    let plane = |v: &Vector3<f64>| Vector2::new(-v.dot(&left), v.dot(&forward));
    let centres: Vec<Vector2<f64>> = view
        .rig_from_camera
        .iter()
        .map(|e| plane(&e.translation.vector))
        .collect();
    let (lo, hi) = bounds(centres.iter().copied()).unwrap_or((Vector2::zeros(), Vector2::zeros()));
    let span = (hi - lo).max().max(0.1);
    let axes = Axes::equal(
        origin,
        side,
        lo - Vector2::repeat(0.4 * span),
        hi + Vector2::repeat(0.4 * span),
    );
    axes.draw(svg, "to the right of camera 0 [m]", "ahead of camera 0 [m]");
    for (c, (e, p)) in view.rig_from_camera.iter().zip(&centres).enumerate() {
        let axis = plane(&(e.rotation * Vector3::z()));
        let tip = p + axis * (0.25 * span);
        svg.line(axes.map(*p), axes.map(tip), colour(c), 2.0);
        svg.circle(axes.map(*p), 4.0, colour(c));
        if let Some(name) = view.camera_names.get(c) {
            svg.text(
                axes.map(*p) + Vector2::new(6.0, -6.0),
                "start",
                colour(c),
                name,
            );
        }
    }
    svg.text(
        Vector2::new(origin.x + side / 2.0, origin.y + side + 56.0),
        "middle",
        "#444",
        "dots: camera centres; lines: optical axes",
    );
}

/// The reprojection-error distribution before and after refinement (see the module docs).
pub fn error_histogram_svg(calibration: &Calibration) -> String {
    let (w, h, left, top) = (780.0, 460.0, 80.0, 50.0);
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
    let bin_width = x_max / bins as f64;
    let histogram = |s: &[f64]| {
        let mut counts = vec![0usize; bins];
        for v in s {
            // A finite, non-negative value below `x_max` lands in a bin.
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
            let b = (v / bin_width) as usize;
            if b < bins {
                counts[b] += 1;
            }
        }
        counts
    };
    let (hb, ha) = (histogram(&before), histogram(&after));
    let y_max = hb.iter().chain(&ha).copied().max().unwrap_or(1).max(1) as f64;
    let axes = Axes::new(
        Vector2::new(left, top),
        Vector2::new(w - left - 30.0, h - top - 70.0),
        Vector2::zeros(),
        Vector2::new(x_max, y_max * 1.08),
    );
    svg.text(
        Vector2::new(left, top - 16.0),
        "start",
        "#000",
        &format!(
            "reprojection errors of the refinement's {} correspondences",
            before.len()
        ),
    );
    axes.draw(
        &mut svg,
        "reprojection error [px]",
        &format!("correspondences per bin of {bin_width:.3} px"),
    );
    let step = |counts: &[usize]| {
        let mut pts = vec![axes.map(Vector2::zeros())];
        for (b, &n) in counts.iter().enumerate() {
            let (a, z) = (bin_width * b as f64, bin_width * (b + 1) as f64);
            pts.push(axes.map(Vector2::new(a, n as f64)));
            pts.push(axes.map(Vector2::new(z, n as f64)));
        }
        pts.push(axes.map(Vector2::new(x_max, 0.0)));
        pts
    };
    svg.polyline(&step(&hb), "#ff7f0e", 1.5);
    svg.polyline(&step(&ha), "#1f77b4", 1.5);
    legend(
        &mut svg,
        &axes,
        &[
            (
                Mark::Line,
                "#ff7f0e",
                format!("before refinement (mean {:.3} px)", finite_mean(&before)),
            ),
            (
                Mark::Line,
                "#1f77b4",
                format!("after refinement (mean {:.3} px)", finite_mean(&after)),
            ),
        ],
    );
    svg.finish()
}
