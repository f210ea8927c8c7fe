//! The text summary of a calibration, laid out like the paper's Table I (Heng et al., ICRA
//! 2014): the frame sets, poses per set, correspondences and reprojection errors, then one row
//! per camera with its extrinsic, its standard deviations and, with ground truth, the three
//! error metrics relative to camera 0; then the hand-eye result.

use std::fmt::Write as _;

use nalgebra::{Quaternion, UnitQuaternion};

use super::json::{PoseJson, Report};
use crate::calib::quality::is_listed_change;

fn num(v: Option<f64>, scale: f64, decimals: usize) -> String {
    v.map_or_else(|| "-".to_owned(), |v| format!("{:.*}", decimals, v * scale))
}

/// The rotation vector of a pose, degrees.
fn rotation_vector_deg(p: &PoseJson) -> [f64; 3] {
    let [w, x, y, z] = p.rotation_wxyz;
    let q = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
    let v = q.scaled_axis();
    [v.x.to_degrees(), v.y.to_degrees(), v.z.to_degrees()]
}

fn max_std(v: &[Option<f64>; 3]) -> Option<f64> {
    v.iter().try_fold(0.0f64, |m, x| x.map(|x| m.max(x)))
}

/// The per-camera quality block, then the status and the warnings.
fn quality_rows(s: &mut String, report: &Report) {
    let _ = writeln!(
        s,
        "{:<12} {:>11} {:>9} {:>9} {:>15} {:>15} {:>9} {:>8}",
        "camera",
        "localized",
        "inliers",
        "corresp.",
        "rms [px] b / a",
        "mad [px] b / a",
        "outliers",
        "pattern"
    );
    for c in &report.cameras {
        let r = &c.reprojection_px;
        let _ = writeln!(
            s,
            "{:<12} {:>11} {:>9} {:>9} {:>15} {:>15} {:>8.1}% {:>8}",
            c.name,
            format!("{}/{}", c.images_localized, report.frames),
            c.inliers,
            c.correspondences,
            format!(
                "{} / {}",
                num(r.initial.rms, 1.0, 3),
                num(r.r#final.rms, 1.0, 3)
            ),
            format!(
                "{} / {}",
                num(r.initial.mad, 1.0, 3),
                num(r.r#final.mad, 1.0, 3)
            ),
            c.outlier_fraction * 100.0,
            num(c.residual_pattern.as_ref().map(|p| p.pattern_px), 1.0, 3)
        );
    }
    let _ = writeln!(
        s,
        "(b / a: before / after refinement; mad: robust spread per axis; outliers: errors the \
         Cauchy loss cuts below a tenth of their weight; pattern: residual offset over the \
         image, px)"
    );
    let _ = writeln!(s, "status: {}", report.status.name());
    for w in &report.warnings {
        let _ = writeln!(s, "warning: {}", w.message);
    }
    for n in &report.notes {
        let _ = writeln!(s, "note: {n}");
    }
}

/// The refined intrinsics, a line per camera: each parameter's camera-file and refined values
/// with its standard deviation, then the held ones.
fn intrinsics_rows(s: &mut String, report: &Report) {
    for c in &report.cameras {
        let Some(r) = &c.intrinsics_refinement else {
            continue;
        };
        let refined: Vec<String> = r
            .refined
            .iter()
            .map(|p| {
                let std = p.std.map_or_else(|| "?".to_owned(), |v| format!("{v:.3}"));
                format!(
                    "{} {:.3} -> {:.3} ({std})",
                    p.name, p.camera_file, p.refined
                )
            })
            .collect();
        let _ = writeln!(s, "intrinsics of {}: {}", c.name, refined.join(", "));
        if !r.held.is_empty() {
            let held: Vec<&str> = r.held.iter().map(|h| h.name.as_str()).collect();
            let _ = writeln!(
                s,
                "  held at the camera file (the data does not determine them): {}",
                held.join(", ")
            );
        }
    }
}

/// The text summary (see the module docs).
pub fn text_table(report: &Report) -> String {
    let mut s = String::new();
    let title = match (&report.scenario, report.seed) {
        (Some(name), Some(seed)) => format!("scenario `{name}`, seed {seed}"),
        (Some(name), None) => format!("scenario `{name}`"),
        _ => "user data".to_owned(),
    };
    let _ = writeln!(s, "ibc calibration: {title}");
    let share = 100.0 * report.images_localized as f64 / report.images.max(1) as f64;
    let _ = writeln!(
        s,
        "  {} frames x {} cameras: {} images localized ({share:.1}%)",
        report.frames,
        report.cameras.len(),
        report.images_localized
    );
    let _ = writeln!(
        s,
        "  frame sets {}, poses per set {:.2}, 2D-3D correspondences {}",
        report.frame_sets_used, report.mean_poses_per_set, report.correspondences
    );
    let r = &report.reprojection_error_px;
    let truth = r
        .at_truth
        .map_or(String::new(), |t| format!(" (at the true poses {t:.3} px)"));
    let _ = writeln!(
        s,
        "  mean reprojection error: {} px before refinement, {} px after{truth}",
        num(r.initial, 1.0, 3),
        num(r.r#final, 1.0, 3)
    );
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "{:<12} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>9} {:>9} {:>9}",
        "camera",
        "x [m]",
        "y [m]",
        "z [m]",
        "rx [deg]",
        "ry [deg]",
        "rz [deg]",
        "sd [mm]",
        "sd [deg]",
        "rot [deg]",
        "dir [deg]",
        "err [mm]"
    );
    for c in &report.cameras {
        let t = c.rig_from_camera.translation;
        let r = rotation_vector_deg(&c.rig_from_camera);
        let (sd_t, sd_r) = c.rig_from_camera_std.as_ref().map_or((None, None), |sd| {
            (max_std(&sd.translation_m), max_std(&sd.rotation_deg))
        });
        let _ = writeln!(
            s,
            "{:<12} {:>8.4} {:>8.4} {:>8.4} {:>8.3} {:>8.3} {:>8.3} {:>7} {:>8} {:>9} {:>9} {:>9}",
            c.name,
            t[0],
            t[1],
            t[2],
            r[0],
            r[1],
            r[2],
            num(sd_t, 1000.0, 3),
            num(sd_r, 1.0, 4),
            num(c.rotation_error_deg, 1.0, 4),
            num(c.translation_error_deg, 1.0, 4),
            num(c.translation_error_m, 1000.0, 3)
        );
    }
    let _ = writeln!(
        s,
        "(rig frame = camera {}; rx ry rz: rotation vector; sd: largest standard deviation; rot, \
         dir, err: errors against ground truth relative to camera {})",
        report.cameras.first().map_or("0", |c| c.name.as_str()),
        report.cameras.first().map_or("0", |c| c.name.as_str()),
    );
    let moved: Vec<String> = report
        .cameras
        .iter()
        .filter(|c| {
            is_listed_change((
                c.change_from_prior.distance_m,
                c.change_from_prior.rotation_deg,
            ))
        })
        .map(|c| {
            let doubt = if report
                .warnings
                .iter()
                .any(|w| w.camera.as_ref() == Some(&c.name) && w.kind != "intrinsics_changed")
            {
                " (doubtful: see the warnings)"
            } else {
                ""
            };
            format!(
                "{} moved {:.2} cm and turned {:.2} deg{doubt}",
                c.name,
                c.change_from_prior.distance_m * 100.0,
                c.change_from_prior.rotation_deg
            )
        })
        .collect();
    if !moved.is_empty() {
        let _ = writeln!(s, "changed since the camera file: {}", moved.join("; "));
    }
    intrinsics_rows(&mut s, report);
    let _ = writeln!(s);
    quality_rows(&mut s, report);
    let _ = writeln!(s);
    match &report.hand_eye {
        None => {
            let _ = writeln!(s, "hand-eye: no odometry");
        }
        Some(h) => match (&h.error, &h.rig_from_odometry) {
            (Some(e), _) => {
                let _ = writeln!(s, "hand-eye ({}): failed: {e}", h.method);
            }
            (None, Some(p)) => {
                let r = rotation_vector_deg(p);
                let height = if h.height_observable {
                    ""
                } else {
                    " (height above the odometry plane unobservable)"
                };
                let _ = writeln!(
                    s,
                    "hand-eye ({}, {} poses): rig_from_odometry t = [{:.4}, {:.4}, {:.4}] m, \
                     r = [{:.3}, {:.3}, {:.3}] deg{height}",
                    h.method,
                    h.poses,
                    p.translation[0],
                    p.translation[1],
                    p.translation[2],
                    r[0],
                    r[1],
                    r[2]
                );
                if h.rotation_error_deg.is_some() {
                    let _ = writeln!(
                        s,
                        "  errors: rotation {} deg, yaw {} deg, translation {} mm (in-plane {} mm)",
                        num(h.rotation_error_deg, 1.0, 4),
                        num(h.yaw_error_deg, 1.0, 4),
                        num(h.translation_error_m, 1000.0, 2),
                        num(h.in_plane_translation_error_m, 1000.0, 2)
                    );
                }
            }
            (None, None) => {}
        },
    }
    let t = &report.timing_s;
    let _ = writeln!(
        s,
        "time: vocabulary {:.2} s, localization {:.2} s, initialization {:.2} s, refinement {:.2} \
         s, hand-eye {:.2} s, total {:.2} s",
        t.vocabulary, t.localization, t.initialization, t.refinement, t.hand_eye, t.total
    );
    s
}
