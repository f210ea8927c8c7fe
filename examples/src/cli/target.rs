//! `ibc target`: a rig's intrinsics and extrinsics from images of a Kalibr AprilGrid.
//!
//! A thin layer over [`ibc_pipeline::target::command`]: the image folders are detected with
//! a progress bar, the rig calibrated, the outputs written all or nothing.

use std::path::PathBuf;

use clap::Args;
use ibc_pipeline::target::command::{
    ModelChoice, REPORT_FILE, calibrate_image_folders, report_json, scene_models, simulate_scene,
    write_outputs,
};
use ibc_pipeline::target::{AprilGrid, TargetCalibrationOptions, TargetError};

use super::progress::Bars;
use super::{CliError, Outcome};
use ibc_pipeline::calib::Progress;

/// Options of `ibc target`.
///
/// Calibrates every camera of a rig from images of an AprilGrid (Kalibr's target file):
/// one folder per camera under --images (`cam0/`, `cam1/`, ..., images of the same time with
/// the same file name), or the images directly in --images for one camera. Cameras that see
/// the board at the same time are linked by their shared views; cameras that never do, by
/// the rig's motion while each sees its own board standing still. Writes `camchain.yaml`
/// (Kalibr), `<camera>_camera_calib.yaml` (CamOdoCal), `<camera>_residuals.svg`,
/// `rig_top_view.svg` and `target_report.json` into --out.
#[derive(Debug, Clone, Args)]
pub struct TargetArgs {
    /// The image folder (one subfolder per camera). Required unless --simulate.
    #[arg(long, value_name = "DIR", required_unless_present = "simulate")]
    pub images: Option<PathBuf>,
    /// Kalibr's target YAML (`target_type: 'aprilgrid'`, tagCols, tagRows, tagSize,
    /// tagSpacing). Required unless --simulate.
    #[arg(long, value_name = "FILE", required_unless_present = "simulate")]
    pub target: Option<PathBuf>,
    /// The camera model: `kb`, `pinhole` or `mei` for every camera, or per camera folder
    /// (`cam0=kb,cam1=pinhole`).
    #[arg(long, value_name = "MODEL|NAME=MODEL,...", default_value = "pinhole")]
    pub model: String,
    /// Folder for the output files (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Print the JSON report on standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// No summary on standard output.
    #[arg(long)]
    pub quiet: bool,
    /// Render a built-in scene's images first (`stereo`, `car`: four cameras that never share
    /// a view, `fisheye`: a 190-degree Kannala-Brandt lens, `mei`: the same field with the
    /// unified model) into `--out/images`, with the target file and
    /// the true rig (`truth_camchain.yaml`), then calibrate them and compare with the truth.
    #[arg(long, value_name = "SCENE", conflicts_with_all = ["images", "target"])]
    pub simulate: Option<String>,
    /// Simulation: the seed of the scene [default: 0].
    #[arg(long, value_name = "N", requires = "simulate")]
    pub seed: Option<u64>,
    /// Simulation: the number of views (per camera for `stereo`, rig poses for `car`)
    /// [default: the scene's].
    #[arg(long, value_name = "N", requires = "simulate")]
    pub views: Option<usize>,
}

/// Runs `ibc target`.
///
/// # Errors
/// [`CliError::Target`] naming the folder, file, image or camera at fault.
pub fn run(args: &TargetArgs) -> Result<Outcome, CliError> {
    let (images, grid, models, truth) = match &args.simulate {
        Some(scene) => {
            let sim = simulate_scene(scene, args.seed.unwrap_or(0), args.views)?;
            let dir = args.out.join("images");
            sim.write(&dir)?;
            let truth_file = args.out.join("truth_camchain.yaml");
            ibc_camera_models::io::write_atomically(
                &truth_file,
                sim.rig.to_kalibr_string().as_bytes(),
            )
            .map_err(|e| TargetError::Image {
                path: truth_file.clone(),
                reason: e.to_string(),
            })?;
            (dir, sim.grid, scene_models(&sim), Some(sim.rig))
        }
        None => {
            let (Some(images), Some(target)) = (&args.images, &args.target) else {
                return Err(TargetError::InvalidInput(
                    "give --images DIR and --target FILE, or --simulate SCENE".into(),
                )
                .into());
            };
            let grid = AprilGrid::read_kalibr(target)?;
            (images.clone(), grid, ModelChoice::parse(&args.model)?, None)
        }
    };
    let bars = Bars::new(args.quiet || args.json);
    bars.step("detecting AprilGrids, calibrating");
    let calibrated = calibrate_image_folders(
        &images,
        &grid,
        &models,
        &TargetCalibrationOptions::default(),
        &|| bars.advance(1),
    );
    bars.done();
    let (detections, calibration) = calibrated?;
    let report = report_json(&grid, &detections, &calibration, truth.as_ref());
    write_outputs(&args.out, &calibration, &report)?;
    if args.json {
        super::print(&format!(
            "{}\n",
            serde_json::to_string_pretty(&report).unwrap_or_default()
        ))?;
    } else if !args.quiet {
        super::print(&summary(&report))?;
        super::print(&format!(
            "wrote {} (and the camchain, CamOdoCal files, residual plots, top view)\n",
            args.out.join(REPORT_FILE).display()
        ))?;
    }
    let warnings = calibration.warnings();
    Ok(if warnings.is_empty() {
        Outcome::Done
    } else {
        Outcome::Poor
    })
}

/// The text summary: one line per camera, then the warnings.
fn summary(report: &serde_json::Value) -> String {
    let mut s = String::new();
    let cameras = report["cameras"].as_array().cloned().unwrap_or_default();
    s.push_str(&format!(
        "AprilGrid calibration: {} cameras, {} times, {} corners, status {}\n",
        cameras.len(),
        report["times"],
        report["observations"],
        report["status"].as_str().unwrap_or("?")
    ));
    for c in &cameras {
        // Every model keeps its focal lengths and principal point last: [.., fx, fy, cx, cy].
        let params = c["params"].as_array().cloned().unwrap_or_default();
        let p = |k: usize| {
            params
                .len()
                .checked_sub(4 - k)
                .and_then(|i| params[i].as_f64())
                .unwrap_or(f64::NAN)
        };
        let mut line = format!(
            "  {:<8} {:<7} f {:.2} {:.2} c {:.2} {:.2}  rms {:.3} px  {} images, linked by {}",
            c["name"].as_str().unwrap_or("?"),
            c["model"].as_str().unwrap_or("?"),
            p(0),
            p(1),
            p(2),
            p(3),
            c["rms_px"].as_f64().unwrap_or(f64::NAN),
            c["images_with_target"],
            c["linked_by"].as_str().unwrap_or("?"),
        );
        if let (Some(r), Some(t)) = (
            c["extrinsic_std_deg"].as_f64(),
            c["extrinsic_std_mm"].as_f64(),
        ) {
            line.push_str(&format!(", std {r:.4} deg / {t:.3} mm"));
        }
        if let (Some(r), Some(t)) = (
            c["error"]["rotation_deg"].as_f64(),
            c["error"]["translation_mm"].as_f64(),
        ) {
            line.push_str(&format!(", error {r:.4} deg / {t:.3} mm"));
        }
        s.push_str(&line);
        s.push('\n');
    }
    for w in report["warnings"].as_array().cloned().unwrap_or_default() {
        s.push_str(&format!("  warning: {}\n", w.as_str().unwrap_or("?")));
    }
    s
}
