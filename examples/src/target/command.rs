//! `ibc target`: a rig calibrated from image folders of an AprilGrid, its outputs (Kalibr
//! camchain with `rostopic` and `cam_overlaps`, CamOdoCal files, a JSON report, per-camera
//! residual plots, a top view of the rig), written all or nothing; and the built-in
//! simulated scenes that exercise it from pixels.

use std::path::{Path, PathBuf};

use ibc_camera_models::{CameraModel, Rig, RigCamera, camodocal};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use serde_json::{Value, json};

use super::aprilgrid::AprilGrid;
use super::calibrate::{
    CameraCorners, TargetCalibration, TargetCalibrationOptions, calibrate_rig_from_target,
};
use super::error::TargetError;
use super::images::{CameraDetections, detect_camera_folder, list_camera_folders};
use super::simulate::{
    SimulatedTargetImages, StaticBoardOptions, TargetSimulationOptions, simulate_static_boards,
    simulate_target_images,
};
use crate::data::io::StagedFiles;
use crate::intrinsics::IntrinsicModel;
use crate::intrinsics::simulate::preset_camera;
use crate::intrinsics::svg::residual_svg;
use crate::report::plot::{Axes, Svg, colour};

/// File name of the Kalibr camchain.
pub const CAMCHAIN_FILE: &str = "camchain.yaml";
/// File name of the JSON report.
pub const REPORT_FILE: &str = "target_report.json";
/// File name of the rig's top view.
pub const TOP_VIEW_FILE: &str = "rig_top_view.svg";
/// The report's `format`.
pub const REPORT_FORMAT: &str = "ibc-target-report";

/// The camera model of each camera folder: one for all, or one per camera name.
#[derive(Clone, Debug, PartialEq)]
pub enum ModelChoice {
    /// The same model for every camera.
    All(IntrinsicModel),
    /// A model per camera name (`cam0=kb,cam1=pinhole`); a camera not listed is an error.
    PerCamera(Vec<(String, IntrinsicModel)>),
}

impl ModelChoice {
    /// Parses `kb`, `pinhole`, or `NAME=MODEL,NAME=MODEL,...`.
    ///
    /// # Errors
    /// [`TargetError::InvalidInput`] for an unknown model or a malformed list.
    pub fn parse(text: &str) -> Result<Self, TargetError> {
        let model = |m: &str| {
            m.trim()
                .parse::<IntrinsicModel>()
                .map_err(|e| TargetError::InvalidInput(format!("--model: {e}")))
        };
        if !text.contains('=') {
            return Ok(Self::All(model(text)?));
        }
        text.split(',')
            .map(|item| {
                let (name, m) = item.split_once('=').ok_or_else(|| {
                    TargetError::InvalidInput(format!(
                        "--model: `{item}` is not NAME=MODEL (for instance cam0=kb)"
                    ))
                })?;
                Ok((name.trim().to_owned(), model(m)?))
            })
            .collect::<Result<_, _>>()
            .map(Self::PerCamera)
    }

    /// The model of camera `name`.
    ///
    /// # Errors
    /// [`TargetError::InvalidInput`] for a camera the list does not name.
    pub fn model_of(&self, name: &str) -> Result<IntrinsicModel, TargetError> {
        match self {
            Self::All(m) => Ok(*m),
            Self::PerCamera(list) => list
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, m)| *m)
                .ok_or_else(|| {
                    TargetError::InvalidInput(format!(
                        "--model names no model for camera folder `{name}`"
                    ))
                }),
        }
    }
}

/// What `ibc target` computed.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct TargetOutcome {
    /// The detections, camera by camera.
    pub detections: Vec<CameraDetections>,
    /// The calibration.
    pub calibration: TargetCalibration,
    /// The JSON report.
    pub report: Value,
    /// The files written.
    pub files: Vec<PathBuf>,
}

/// Detects `grid` in every camera folder of `images` (`progress` is called once per image)
/// and calibrates the rig.
///
/// # Errors
/// The errors of [`list_camera_folders`], [`detect_camera_folder`],
/// [`ModelChoice::model_of`] and [`calibrate_rig_from_target`].
pub fn calibrate_image_folders(
    images: &Path,
    grid: &AprilGrid,
    models: &ModelChoice,
    options: &TargetCalibrationOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<(Vec<CameraDetections>, TargetCalibration), TargetError> {
    let folders = list_camera_folders(images)?;
    let detections = folders
        .iter()
        .map(|f| detect_camera_folder(f, grid, progress))
        .collect::<Result<Vec<_>, _>>()?;
    let cameras = detections
        .iter()
        .map(|d| {
            Ok(CameraCorners {
                name: d.name.clone(),
                model: models.model_of(&d.name)?,
                corners: d.corners.clone(),
            })
        })
        .collect::<Result<Vec<_>, TargetError>>()?;
    let calibration = calibrate_rig_from_target(&cameras, &grid.planar_target(), options)?;
    Ok((detections, calibration))
}

fn pose_json(pose: &Isometry3<f64>) -> Value {
    let q = pose.rotation.quaternion();
    json!({
        "translation_m": [pose.translation.vector.x, pose.translation.vector.y, pose.translation.vector.z],
        "quaternion_xyzw": [q.i, q.j, q.k, q.w],
    })
}

/// The JSON report: status and warnings, the target, and per camera its detections, model,
/// parameters with standard deviations, RMS, extrinsic with standard deviations and how it
/// was linked; with `truth` (a rig whose camera names match) the errors against it.
pub fn report_json(
    grid: &AprilGrid,
    detections: &[CameraDetections],
    calibration: &TargetCalibration,
    truth: Option<&Rig>,
) -> Value {
    let warnings = calibration.warnings();
    let cameras: Vec<Value> = (0..calibration.names.len())
        .map(|c| {
            let name = &calibration.names[c];
            let d = detections.iter().find(|d| &d.name == name);
            let cal = &calibration.intrinsics[c];
            let link = &calibration.links[c];
            let mut entry = json!({
                "name": name,
                "model": cal.model.short_name(),
                "images": d.map(|d| d.corners.images.len()),
                "images_with_target": d.map(|d| d.corners.images.iter().filter(|i| !i.corners.is_empty()).count()),
                "corners": d.map(|d| d.corners.num_corners()),
                "foreign_tags": d.map(|d| d.foreign_tags),
                "outlier_corners": cal.outlier_corners,
                "params": calibration.cameras[c].params(),
                "param_std": calibration.intrinsic_std[c],
                "rms_px": calibration.rms_px[c],
                "per_image": cal.per_image.iter().map(|i| json!({
                    "name": i.name,
                    "corners": i.corners,
                    "status": i.status,
                    "outliers": i.outliers,
                    "rms_px": i.rms_px,
                    "max_px": i.max_px,
                })).collect::<Vec<_>>(),
                "rig_from_camera": pose_json(&calibration.rig_from_camera[c]),
                "extrinsic_std_deg": calibration.extrinsic_std[c].map(|s| s.0),
                "extrinsic_std_mm": calibration.extrinsic_std[c].map(|s| s.1 * 1e3),
                "linked_from": link.parent.map(|p| calibration.names[p].clone()),
                "linked_by": if link.parent.is_none() { "reference" } else if link.hand_eye { "hand_eye" } else { "shared_views" },
                "link_times": link.shared_views,
            });
            if let Some(t) = truth.and_then(|t| t.cameras.iter().find(|t| &t.name == name))
                && let Some(reference) = truth.and_then(|t| t.cameras.iter().find(|t| t.name == calibration.names[0]))
            {
                let true_pose = reference.rig_from_camera.inverse() * t.rig_from_camera;
                let d = true_pose.inverse() * calibration.rig_from_camera[c];
                entry["error"] = json!({
                    "rotation_deg": d.rotation.angle().to_degrees(),
                    "translation_mm": d.translation.vector.norm() * 1e3,
                    "params": calibration.cameras[c].params().iter().zip(t.camera.params()).map(|(e, t)| e - t).collect::<Vec<f64>>(),
                });
            }
            entry
        })
        .collect();
    json!({
        "format": REPORT_FORMAT,
        "version": 1,
        "status": if warnings.is_empty() { "ok" } else { "poor" },
        "warnings": warnings,
        "target": {
            "type": "aprilgrid",
            "tag_rows": grid.tag_rows,
            "tag_cols": grid.tag_cols,
            "tag_size_m": grid.tag_size,
            "tag_spacing": grid.tag_spacing,
        },
        "times": calibration.times,
        "observations": calibration.observations,
        "noise_sigma_px": calibration.noise_sigma_px,
        "converged": calibration.converged,
        "overlaps": calibration.overlaps.iter().map(|&(i, j, n)| json!([calibration.names[i], calibration.names[j], n])).collect::<Vec<_>>(),
        "cameras": cameras,
    })
}

/// Writes `camchain.yaml`, one `<name>_camera_calib.yaml` and one `<name>_residuals.svg` per
/// camera, `rig_top_view.svg` and `target_report.json` into `dir`, all or nothing.
///
/// # Errors
/// [`TargetError::Image`] naming the folder or file that could not be written.
pub fn write_outputs(
    dir: &Path,
    calibration: &TargetCalibration,
    report: &Value,
) -> Result<Vec<PathBuf>, TargetError> {
    let io = |path: &Path, e: String| TargetError::Image {
        path: path.to_owned(),
        reason: e,
    };
    let mut staged = StagedFiles::new(dir).map_err(|e| io(dir, e.to_string()))?;
    let mut stage = |name: String, bytes: &[u8]| -> Result<(), TargetError> {
        let path = dir.join(name);
        staged
            .stage(&path, bytes)
            .map_err(|e| io(&path, e.to_string()))
    };
    stage(
        CAMCHAIN_FILE.into(),
        calibration.to_rig().to_kalibr_string().as_bytes(),
    )?;
    for (c, name) in calibration.names.iter().enumerate() {
        stage(
            crate::intrinsics::output::camodocal_file_name(name),
            camodocal::format_camera(name, &calibration.cameras[c]).as_bytes(),
        )?;
        stage(
            format!("{name}_residuals.svg"),
            residual_svg(&calibration.intrinsics[c], &calibration.used_corners[c]).as_bytes(),
        )?;
    }
    stage(
        TOP_VIEW_FILE.into(),
        rig_top_view_svg(calibration).as_bytes(),
    )?;
    let text = serde_json::to_string_pretty(report).unwrap_or_default();
    stage(REPORT_FILE.into(), text.as_bytes())?;
    staged.commit().map_err(|e| io(dir, e.to_string()))
}

/// The rig seen from above: each camera's centre and optical axis on the reference camera's
/// `x` (right) and `z` (forward) axes, which are horizontal when the reference camera was
/// held level (its `y` axis points down), with each camera's name and the standard deviation
/// of its extrinsic.
pub fn rig_top_view_svg(calibration: &TargetCalibration) -> String {
    let (side, left, top) = (520.0, 70.0, 50.0);
    let mut svg = Svg::new(left + side + 40.0, top + side + 60.0);
    let plane = |v: &Vector3<f64>| Vector2::new(v.x, v.z);
    let centres: Vec<Vector2<f64>> = calibration
        .rig_from_camera
        .iter()
        .map(|p| plane(&p.translation.vector))
        .collect();
    let (mut lo, mut hi) = (Vector2::repeat(-0.05), Vector2::repeat(0.05));
    for c in &centres {
        lo = lo.inf(c);
        hi = hi.sup(c);
    }
    let span = (hi - lo).max();
    let (lo, hi) = (
        lo - Vector2::repeat(0.2 * span),
        hi + Vector2::repeat(0.2 * span),
    );
    let axes = Axes::equal(Vector2::new(left, top), side, lo, hi);
    axes.draw(
        &mut svg,
        "x (m), right of the reference camera",
        "z (m), forward",
    );
    svg.text(
        Vector2::new(left, 25.0),
        "start",
        "#222",
        "top view of the rig: camera centres and optical axes (reference camera's frame)",
    );
    for (c, (pose, centre)) in calibration.rig_from_camera.iter().zip(&centres).enumerate() {
        let axis = plane(&(pose.rotation * Vector3::z()));
        let tip = centre + axis.try_normalize(1e-9).unwrap_or_default() * 0.12 * span.max(0.1);
        let (a, b) = (axes.map(*centre), axes.map(tip));
        svg.line(a, b, colour(c), 2.0);
        svg.circle(a, 4.0, colour(c));
        let label = match calibration.extrinsic_std[c] {
            Some((r, t)) => format!(
                "{} (std {r:.3} deg, {:.2} mm)",
                calibration.names[c],
                t * 1e3
            ),
            None => format!("{} (reference)", calibration.names[c]),
        };
        svg.text(a + Vector2::new(6.0, -6.0), "start", colour(c), &label);
    }
    svg.finish()
}

/// The built-in simulated scenes of `ibc target --simulate`.
pub const SIMULATED_SCENES: [&str; 4] = ["stereo", "car", "fisheye", "mei"];

/// A built-in scene: `stereo` (two EuRoC-like pinholes 11 cm apart, a board held in front of
/// them, 12 views placed in front of each), `car` (four pinholes looking front, left, back
/// and right, each at its own board standing still while the rig turns: 40 times),
/// `fisheye` (one 190-degree Kannala-Brandt camera, 24 views) or `mei` (one 190-degree
/// unified camera, 40 views). `views` overrides the number of views (per camera for
/// `stereo`, times for `car`).
///
/// # Errors
/// [`TargetError::InvalidInput`] for an unknown scene or no views, and the simulation's
/// errors.
pub fn simulate_scene(
    name: &str,
    seed: u64,
    views: Option<usize>,
) -> Result<SimulatedTargetImages, TargetError> {
    if views == Some(0) {
        return Err(TargetError::InvalidInput(
            "a scene needs at least one view".into(),
        ));
    }
    let grid = AprilGrid::new(6, 6, 0.05, 0.3)?;
    let preset = |m| preset_camera(m).map_err(|e| TargetError::InvalidInput(e.to_string()));
    match name {
        "stereo" => {
            let camera = preset(IntrinsicModel::PinholeRadtan)?;
            let right = Isometry3::from_parts(
                Translation3::new(0.11, 0.002, -0.001),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 2f64.to_radians()),
            );
            let rig = Rig::new(vec![
                RigCamera::new("left", camera.clone(), Isometry3::identity()),
                RigCamera::new("right", camera, right),
            ]);
            simulate_target_images(
                &rig,
                &grid,
                &TargetSimulationOptions {
                    views_per_camera: 12,
                    seed,
                    ..Default::default()
                },
            )
        }
        "fisheye" | "mei" => {
            let (model, views) = if name == "mei" {
                // The unified model's xi, gamma and k1 trade off: it needs more views than
                // Kannala-Brandt for the same projection accuracy (tests/target_images.rs).
                (IntrinsicModel::Unified, 40)
            } else {
                (IntrinsicModel::KannalaBrandt, 24)
            };
            let rig = Rig::new(vec![RigCamera::new(
                "cam0",
                preset(model)?,
                Isometry3::identity(),
            )]);
            let mut options = TargetSimulationOptions {
                views_per_camera: views,
                seed,
                ..Default::default()
            };
            options.placement.max_incidence_deg = Some(85.0);
            simulate_target_images(&rig, &grid, &options)
        }
        "car" => {
            let camera = preset(IntrinsicModel::PinholeRadtan)?;
            // Camera z forward, x right, y down; the rig x forward, y left, z up.
            let base =
                UnitQuaternion::from_basis_unchecked(&[-Vector3::y(), -Vector3::z(), Vector3::x()]);
            let place = |name: &str, at: [f64; 3], yaw_deg: f64| {
                let turn =
                    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians());
                RigCamera::new(
                    name,
                    camera.clone(),
                    Isometry3::from_parts(Translation3::new(at[0], at[1], at[2]), turn * base),
                )
            };
            let rig = Rig::new(vec![
                place("front", [1.0, 0.0, 0.6], 0.0),
                place("left", [0.1, 0.5, 0.9], 90.0),
                place("rear", [-1.0, 0.02, 0.7], 180.0),
                place("right", [0.12, -0.5, 0.92], -90.0),
            ]);
            simulate_static_boards(
                &rig,
                &grid,
                &StaticBoardOptions {
                    times: 40,
                    seed,
                    ..Default::default()
                },
            )
        }
        other => Err(TargetError::InvalidInput(format!(
            "unknown scene `{other}`: expected one of {}",
            SIMULATED_SCENES.join(", ")
        ))),
    }
}

/// The model a simulated scene's cameras are calibrated with.
pub fn scene_models(sim: &SimulatedTargetImages) -> ModelChoice {
    ModelChoice::PerCamera(
        sim.rig
            .cameras
            .iter()
            .map(|c| {
                let model = IntrinsicModel::of(&c.camera).unwrap_or(IntrinsicModel::PinholeRadtan);
                (c.name.clone(), model)
            })
            .collect(),
    )
}
