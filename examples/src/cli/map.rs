//! `ibc map`: the survey phase, a map built from a calibrated rig's log.

use std::path::Path;

use ibc_pipeline::calib::camera_matching::match_cameras;
use ibc_pipeline::colmap::write_colmap;
use ibc_pipeline::data::Map;
use ibc_pipeline::data::io::write_map;
use ibc_pipeline::ibc_camera_models::Rig;
use ibc_pipeline::sfm::{MapOptions, build_map};
use ibc_vocab_tree::Descriptor;

use super::inputs::{log_layout, read_cameras, read_log_checked, with_descriptor};
use super::progress::Bars;
use super::{CliError, MapArgs, Outcome, print};

/// The log's descriptor types, with whether COLMAP can store them.
trait MapDescriptor: Descriptor {
    /// Values per descriptor when COLMAP cannot store this type (checked before the map is
    /// built).
    const NOT_FOR_COLMAP: Option<usize>;
    /// Writes `map` as COLMAP data into `dir`.
    fn write_colmap(
        dir: &Path,
        rig: &Rig,
        map: &Map<Self>,
        sources: &[(usize, usize)],
    ) -> Result<(), CliError>;
}

macro_rules! colmap_descriptor {
    ($($t:ty),*) => {$(
        impl MapDescriptor for $t {
            const NOT_FOR_COLMAP: Option<usize> = None;
            fn write_colmap(
                dir: &Path,
                rig: &Rig,
                map: &Map<Self>,
                sources: &[(usize, usize)],
            ) -> Result<(), CliError> {
                write_colmap(dir, rig, map, sources)
                    .map(|_| ())
                    .map_err(|source| CliError::Colmap {
                        what: "COLMAP output",
                        source,
                    })
            }
        }
    )*};
}
colmap_descriptor!([u64; 4], [u64; 8], [f32; 128]);

macro_rules! float_descriptor {
    ($($n:literal),*) => {$(
        impl MapDescriptor for [f32; $n] {
            const NOT_FOR_COLMAP: Option<usize> = Some($n);
            fn write_colmap(
                _: &Path,
                _: &Rig,
                _: &Map<Self>,
                _: &[(usize, usize)],
            ) -> Result<(), CliError> {
                Err(CliError::ColmapDescriptor { floats: $n })
            }
        }
    )*};
}
float_descriptor!(32, 64);

fn run_with<D: MapDescriptor>(args: &MapArgs, bars: &Bars) -> Result<Outcome, CliError> {
    if let (Some(_), Some(floats)) = (&args.colmap, D::NOT_FOR_COLMAP) {
        return Err(CliError::ColmapDescriptor { floats });
    }
    let prior = read_cameras(&args.cameras)?;
    let log = read_log_checked::<D>(&args.log, None, bars)?;
    let (rig, _) = match_cameras(&prior, &log.camera_names)?;
    bars.step("building the map (tracks, averaging, triangulation and bundle adjustment)");
    let built = build_map(
        &log,
        &rig,
        &MapOptions {
            refine_extrinsics: args.refine_extrinsics,
            ..Default::default()
        },
    );
    bars.done();
    let built = built?;
    // How far each camera was found from the camera file (both relative to the first
    // camera), with its standard deviation, when the extrinsics were refined.
    let moved: Vec<serde_json::Value> = if args.refine_extrinsics {
        let first = rig.cameras.first().map(|c| c.rig_from_camera.inverse());
        rig.cameras
            .iter()
            .zip(&built.rig_from_camera)
            .zip(&built.extrinsic_covariance)
            .map(|((camera, refined), cov)| {
                let prior = first.map_or(camera.rig_from_camera, |f| f * camera.rig_from_camera);
                let sd = |k: usize| cov.map(|c| c[(k, k)].max(0.0).sqrt());
                serde_json::json!({
                    "name": camera.name,
                    "moved_mm": (refined.translation.vector - prior.translation.vector).norm() * 1e3,
                    "turned_deg": prior.rotation.angle_to(&refined.rotation).to_degrees(),
                    "std_mm": (0..3).map(|k| sd(k).map(|v| v * 1e3)).collect::<Vec<_>>(),
                    "std_deg": (3..6).map(|k| sd(k).map(f64::to_degrees)).collect::<Vec<_>>(),
                })
            })
            .collect()
    } else {
        Vec::new()
    };
    write_map(&args.out, &built.map).map_err(|source| CliError::Data {
        what: "map",
        source,
    })?;
    if let Some(dir) = &args.colmap {
        // The rig as the map was built: its extrinsics relative to the first camera.
        let mut used = rig.clone();
        for (camera, pose) in used.cameras.iter_mut().zip(&built.rig_from_camera) {
            camera.rig_from_camera = *pose;
        }
        D::write_colmap(dir, &used, &built.map, &built.image_sources)?;
    }
    let posed = built.world_from_rig.iter().flatten().count();
    let summary = serde_json::json!({
        "format": "ibc-map-report",
        "version": 1,
        "map": args.out.display().to_string(),
        "frames": built.world_from_rig.len(),
        "frames_posed": posed,
        "images": built.map.images.len(),
        "points": built.map.points.len(),
        "mean_observations_per_point": built.mean_observations_per_point,
        "reprojection_error_px": built.rms_px,
        "rounds": built.rounds.len(),
        "verified_pairs": built.tracks.verified_pairs,
        "extrinsics": if args.refine_extrinsics { "refined" } else { "held" },
        "cameras": moved,
        "covariance_error": built.covariance_error,
        "odometry_distances": built.odometry_distances,
    });
    if args.json {
        print(&(serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n"))?;
    } else {
        print(&format!(
            "map of {} points ({:.1} observations per point, rms {:.3} px) from {} of {} frames, \
             {} images\nwrote {}\n",
            built.map.points.len(),
            built.mean_observations_per_point,
            built.rms_px,
            posed,
            built.world_from_rig.len(),
            built.map.images.len(),
            args.out.display()
        ))?;
        for m in &moved {
            print(&format!(
                "{}: moved {:.3} mm and turned {:.5} deg from the camera file\n",
                m["name"].as_str().unwrap_or("?"),
                m["moved_mm"].as_f64().unwrap_or(f64::NAN),
                m["turned_deg"].as_f64().unwrap_or(f64::NAN)
            ))?;
        }
        if let Some(reason) = &built.covariance_error {
            print(&format!(
                "the refined extrinsics have no standard deviations: {reason}\n"
            ))?;
        }
    }
    Ok(Outcome::Done)
}

/// Runs `ibc map`.
pub fn run(args: &MapArgs) -> Result<Outcome, CliError> {
    let bars = Bars::new(args.quiet);
    let layout = log_layout(&args.log)?;
    with_descriptor!(layout, run_with(args, &bars))
}
