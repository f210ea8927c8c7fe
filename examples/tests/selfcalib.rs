#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! `ibc_pipeline::sfm::self_calibrate`: a rig's extrinsics from its own log, no map (issue 17;
//! TrimBot2020 D3.1 §3.3.3). Bars from the issue: worst camera <= 0.003 deg and <= 0.5 mm
//! after aligning the scale, at sigma 0.5 px, on the garage car rig (100 frames), also with
//! spurious features; with wheel odometry the metric scale within 0.1 %. The anchor: COLMAP
//! 4.2.1's global mapping with unknown `sensor_from_rig` on the same world with perfect tracks,
//! 0.0030 deg / 0.52 mm (measured by the author). On TrimBot2020's pentagon the
//! rotation bar is below the maximum-likelihood spread even with perfect tracks; there the
//! rotation is held to that estimate's (see
//! `pentagon_rig_in_the_garden_is_as_close_as_perfect_tracks`).

use ibc_pipeline::data::RigLog;
use ibc_pipeline::ibc_bundle_adjust::{
    RigBundleAdjustment, RigBundleAdjustmentOptions, RobustLoss, ScaleGauge,
};
use ibc_pipeline::ibc_camera_models::Camera;
use ibc_pipeline::nalgebra::Isometry3;
use ibc_pipeline::sfm::{
    OdometryDistances, ScaleEstimate, ScaleSource, SelfCalibration, SelfCalibrationError,
    SelfCalibrationOptions, TrackCompletion, TrackOptions, build_tracks_with_rig, extrinsic_errors,
    self_calibrate,
};
use ibc_pipeline::sim::{Scenario, SimulatedWorld};

fn world(name: &str, scale: f64, spurious: Option<f64>) -> SimulatedWorld {
    let mut scenario = Scenario::builtin(name)
        .expect("built-in scenario")
        .with_scale(scale);
    if let Some(s) = spurious {
        scenario.noise.spurious_fraction = s;
    }
    SimulatedWorld::simulate(&scenario).expect("simulation")
}

fn cameras(world: &SimulatedWorld) -> Vec<Camera> {
    world.rig.cameras.iter().map(|c| c.camera.clone()).collect()
}

/// The least-squares factor that maps the estimate's lever arms (relative to camera 0) onto
/// the truth's: 1 for a perfect metric scale.
fn alignment_scale(result: &SelfCalibration, world: &SimulatedWorld) -> f64 {
    let rel = |p: &[Isometry3<f64>]| -> Vec<_> { p.iter().map(|x| p[0].inverse() * x).collect() };
    let (e, t) = (
        rel(&result.rig_from_camera),
        rel(&world.truth.rig_from_camera),
    );
    let num: f64 = e
        .iter()
        .zip(&t)
        .map(|(a, b)| a.translation.vector.dot(&b.translation.vector))
        .sum();
    let den: f64 = e.iter().map(|a| a.translation.vector.norm_squared()).sum();
    num / den
}

/// Checks the bars on one world; returns the worst (degrees, millimetres) after alignment.
fn check_bars(label: &str, world: &SimulatedWorld, result: &SelfCalibration) -> (f64, f64) {
    check_bars_with(label, world, result, 0.003)
}

/// [`check_bars`] with another rotation bar, degrees.
fn check_bars_with(
    label: &str,
    world: &SimulatedWorld,
    result: &SelfCalibration,
    rotation_bar_deg: f64,
) -> (f64, f64) {
    let errors = extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, true);
    let worst_deg = errors.iter().map(|e| e.0.to_degrees()).fold(0.0, f64::max);
    let worst_mm = errors.iter().map(|e| e.1 * 1e3).fold(0.0, f64::max);
    println!(
        "{label}: worst {worst_deg:.5} deg / {worst_mm:.3} mm after scale alignment; tracks {:?}; \
         rounds {}; scale {:?}, alignment factor {:.6}",
        result.tracks,
        result.rounds.len(),
        result.scale,
        alignment_scale(result, world)
    );
    assert!(result.converged, "{label}: the loop did not converge");
    assert!(worst_deg <= rotation_bar_deg, "{label}: {worst_deg} deg");
    assert!(worst_mm <= 0.5, "{label}: {worst_mm} mm");
    // The reported uncertainty covers the error: every camera within 4 standard deviations.
    // (The standard deviations are in the result's unit: metres times the alignment factor's
    // inverse.)
    let factor = alignment_scale(result, world);
    for (camera, (rotation, translation)) in errors.iter().enumerate().skip(1) {
        let (sr, st) = result.extrinsic_std(camera).expect("covariance");
        let st = st * factor;
        assert!(
            *rotation <= 4.0 * sr && *translation <= 4.0 * st.max(1e-6),
            "{label}: camera {camera} off by {rotation} rad / {translation} m against standard \
             deviations {sr} / {st}"
        );
    }
    (worst_deg, worst_mm)
}

#[test]
fn garage_car_rig_100_frames_meets_the_bars_with_odometry_scale() {
    let world = world("garage", 0.2, None);
    let result = self_calibrate(
        &world.log,
        &cameras(&world),
        &SelfCalibrationOptions::default(),
    )
    .expect("self-calibration");
    check_bars("garage", &world, &result);
    // Wheel odometry gives the metric scale within 0.1 %.
    assert!(matches!(result.scale, ScaleEstimate::Odometry { .. }));
    let factor = alignment_scale(&result, &world);
    assert!((factor - 1.0).abs() <= 1e-3, "scale off by {factor}");
    // The averaging alone is the start; the loop improves on it.
    let initial = extrinsic_errors(
        &result.initial_rig_from_camera,
        &world.truth.rig_from_camera,
        true,
    );
    let worst_initial = initial.iter().map(|e| e.0).fold(0.0, f64::max);
    let worst_final = extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, true)
        .iter()
        .map(|e| e.0)
        .fold(0.0, f64::max);
    assert!(worst_final < worst_initial);
}

#[test]
fn garage_with_20_percent_spurious_features_meets_the_bars() {
    let world = world("garage", 0.2, Some(0.2));
    let result = self_calibrate(
        &world.log,
        &cameras(&world),
        &SelfCalibrationOptions {
            scale: ScaleSource::Unknown,
            ..Default::default()
        },
    )
    .expect("self-calibration");
    assert!(matches!(result.scale, ScaleEstimate::Unknown));
    check_bars("garage, 20% spurious", &world, &result);
}

/// The rig's left and right cameras alone: they look at opposite walls. On the straight first
/// 15 frames of the drive they share no track, so nothing determines one from the other: the
/// error names the camera, never a confident number. Five frames more, into the first turn,
/// link them (one verified pair), and the result is within its own standard deviations.
#[test]
fn cameras_that_share_no_track_are_named_and_a_turn_links_them() {
    let world = world("garage", 0.2, None);
    let keep: Vec<usize> = ["left", "right"]
        .iter()
        .map(|n| {
            world
                .log
                .camera_names
                .iter()
                .position(|c| c == n)
                .expect("camera")
        })
        .collect();
    let log = |frames: usize| RigLog {
        camera_names: keep
            .iter()
            .map(|&c| world.log.camera_names[c].clone())
            .collect(),
        odometry: world.log.odometry,
        frames: world.log.frames[..frames]
            .iter()
            .map(|f| ibc_pipeline::data::Frame {
                images: keep.iter().map(|&c| f.images[c].clone()).collect(),
                ..f.clone()
            })
            .collect(),
    };
    let all = cameras(&world);
    let cams: Vec<_> = keep.iter().map(|&c| all[c].clone()).collect();
    let error = self_calibrate(&log(15), &cams, &SelfCalibrationOptions::default())
        .expect_err("left and right share nothing on a straight drive");
    let message = error.to_string();
    println!("{message}");
    assert!(
        matches!(&error, SelfCalibrationError::UndeterminedCamera { camera, .. } if camera == "right"),
        "{message}"
    );
    assert!(
        message.contains("`right`") && message.contains("turn"),
        "{message}"
    );

    let result = self_calibrate(&log(20), &cams, &SelfCalibrationOptions::default())
        .expect("a turn links the two cameras");
    let truth: Vec<_> = keep
        .iter()
        .map(|&c| world.truth.rig_from_camera[c])
        .collect();
    let (rotation, translation) = extrinsic_errors(&result.rig_from_camera, &truth, false)[1];
    let (sr, st) = result.extrinsic_std(1).expect("covariance");
    println!(
        "after the turn: {:.4} deg / {:.2} mm, standard deviations {:.4} deg / {:.2} mm",
        rotation.to_degrees(),
        translation * 1e3,
        sr.to_degrees(),
        st * 1e3
    );
    assert!(rotation <= 4.0 * sr && translation <= 4.0 * st);
}

#[test]
fn bad_input_is_a_typed_error() {
    let world = world("garage", 0.2, None);
    let all = cameras(&world);
    let error = self_calibrate(&world.log, &all[..3], &SelfCalibrationOptions::default())
        .expect_err("three cameras for a log of four");
    assert!(
        matches!(
            error,
            SelfCalibrationError::CameraCount { cameras: 3, log: 4 }
        ),
        "{error}"
    );
    for (options, option) in [
        (
            SelfCalibrationOptions {
                scale: ScaleSource::Baseline {
                    a: 1,
                    b: 1,
                    distance_m: 2.0,
                },
                ..Default::default()
            },
            "scale",
        ),
        (
            SelfCalibrationOptions {
                outlier_threshold_px: f64::NAN,
                ..Default::default()
            },
            "outlier_threshold_px",
        ),
        (
            SelfCalibrationOptions {
                max_rounds: 0,
                ..Default::default()
            },
            "max_rounds",
        ),
        (
            SelfCalibrationOptions {
                intermediate_function_tolerance: f64::NAN,
                ..Default::default()
            },
            "intermediate_function_tolerance",
        ),
        (
            SelfCalibrationOptions {
                odometry_distances: Some(OdometryDistances {
                    relative_sigma: 0.0,
                    ..Default::default()
                }),
                ..Default::default()
            },
            "odometry_distances.relative_sigma",
        ),
        (
            SelfCalibrationOptions {
                odometry_distances: Some(OdometryDistances {
                    max_turn_rad: f64::INFINITY,
                    ..Default::default()
                }),
                ..Default::default()
            },
            "odometry_distances.max_turn_rad",
        ),
        (
            SelfCalibrationOptions {
                track_completion: Some(TrackCompletion {
                    radius_px: f64::NAN,
                    ..Default::default()
                }),
                ..Default::default()
            },
            "track_completion.radius_px",
        ),
        (
            SelfCalibrationOptions {
                track_completion: Some(TrackCompletion {
                    max_descriptor_fraction: 0.0,
                    ..Default::default()
                }),
                ..Default::default()
            },
            "track_completion.max_descriptor_fraction",
        ),
    ] {
        let error = self_calibrate(&world.log, &all, &options).expect_err("invalid option");
        assert!(
            matches!(&error, SelfCalibrationError::InvalidOption { option: o, .. } if *o == option),
            "{error}"
        );
    }
    let empty = RigLog::<[u64; 4]> {
        camera_names: world.log.camera_names.clone(),
        odometry: world.log.odometry,
        frames: world
            .log
            .frames
            .iter()
            .map(|f| ibc_pipeline::data::Frame {
                images: vec![Default::default(); f.images.len()],
                ..f.clone()
            })
            .collect(),
    };
    let error =
        self_calibrate(&empty, &all, &SelfCalibrationOptions::default()).expect_err("no features");
    assert!(matches!(error, SelfCalibrationError::NoFeatures), "{error}");
    // Known extrinsics for the tracks: one per camera.
    let error = build_tracks_with_rig(
        &world.log,
        &all,
        Some(&[Isometry3::identity(); 2]),
        &TrackOptions::default(),
    )
    .expect_err("two extrinsics for four cameras");
    assert!(
        matches!(
            error,
            SelfCalibrationError::CameraCount { cameras: 2, log: 4 }
        ),
        "{error}"
    );
}

/// The survey phase and the main job on its map: the calibrated car rig drives the garage and
/// `build_map` reconstructs it; a rig whose left and right cameras then moved 9.7 and 10 cm
/// drives the same garage and is calibrated against the built map. Bars (issue 17): the
/// calibration's as against the true map (0.005 deg / 1 mm at sigma 0.5 px, or as well as
/// the true map itself does at this size, see the assertion), and the map's
/// points within a stated error of the truth: median 2.3 cm, 90th percentile 27 cm measured
/// (points 10-20 m from a drive without loop closure; asserted at 5 and 50 cm). The survey and
/// the calibration drive follow the same path (two simulations of one seed with different
/// rigs).
#[test]
fn a_built_map_calibrates_a_moved_rig_as_well_as_the_true_map() {
    use ibc_pipeline::calib::{CalibrationOptions, calibrate};
    use ibc_pipeline::sfm::{MapOptions, build_map};
    let survey = world("garage", 0.2, None);
    let built = build_map(&survey.log, &survey.rig, &MapOptions::default()).expect("map");
    // The map's frame is camera 0's at the first posed frame.
    let first = built
        .world_from_rig
        .iter()
        .position(Option::is_some)
        .expect("a posed frame");
    let map_from_world =
        (survey.truth.world_from_rig[first] * survey.truth.rig_from_camera[0]).inverse();
    // Each map point's landmark: the most frequent true id among the keypoints that observe it.
    let mut votes: Vec<std::collections::HashMap<u32, usize>> =
        vec![Default::default(); built.map.points.len()];
    for (image, &(frame, camera)) in built.map.images.iter().zip(&built.image_sources) {
        for (k, id) in image.point_ids.iter().enumerate() {
            if let (Some(id), Some(Some(truth))) = (id, survey.log_point_ids[frame][camera].get(k))
            {
                *votes[*id as usize].entry(*truth).or_default() += 1;
            }
        }
    }
    let mut errors: Vec<f64> = votes
        .iter()
        .zip(&built.map.points)
        .filter_map(|(v, p)| {
            let (&id, _) = v
                .iter()
                .max_by_key(|(id, n)| (**n, std::cmp::Reverse(**id)))?;
            let truth = map_from_world * survey.true_map_points[id as usize];
            Some((p - truth).norm())
        })
        .collect();
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p90 = errors[errors.len() * 9 / 10];
    println!(
        "built map: {} points, {:.1} observations per point, rms {:.3} px; point error median \
         {:.1} mm, 90th percentile {:.1} mm",
        built.map.points.len(),
        built.mean_observations_per_point,
        built.rms_px,
        median * 1e3,
        p90 * 1e3
    );
    assert!(built.map.points.len() > 10_000);
    // The survey log has wheel odometry: its distances shaped the averaged trajectory.
    assert!(built.odometry_distances > 0);
    assert!(median <= 0.05 && p90 <= 0.5, "{median} {p90}");

    let moved = world("garage-moved-cameras", 0.2, None);
    let calibration = calibrate(
        &built.map,
        &moved.log,
        &moved.map_rig,
        &CalibrationOptions::default(),
    )
    .expect("calibration against the built map");
    let against_true_map = calibrate(
        &moved.map,
        &moved.log,
        &moved.map_rig,
        &CalibrationOptions::default(),
    )
    .expect("calibration against the true map");
    let worst = |label: &str, c: &ibc_pipeline::calib::Calibration| {
        let errors = extrinsic_errors(&c.rig_from_camera, &moved.truth.rig_from_camera, false);
        let deg = errors.iter().map(|e| e.0.to_degrees()).fold(0.0, f64::max);
        let mm = errors.iter().map(|e| e.1 * 1e3).fold(0.0, f64::max);
        println!("calibration against the {label}: worst {deg:.5} deg / {mm:.3} mm");
        (deg, mm)
    };
    let (deg, mm) = worst("built map", &calibration);
    let (true_deg, true_mm) = worst("true map", &against_true_map);
    // The bar is the built map's: the true map's (0.005 deg / 1 mm), or, since at this size
    // (100 frames) the calibration's own spread is of the bar's order, within half as much
    // again as the true map's own result. Measured 2026-12-03: against the true map
    // 0.0053 deg / 0.59 mm; against maps built with five verification seeds, uniform or
    // progressive sampling, 0.0026-0.0061 deg / 0.28-0.75 mm, where the maps themselves
    // agreed to a millimetre (point errors median 22.5-23.8 mm, rig positions median
    // 1.2-2.9 mm). With the odometry's distances in the averaging and the pairs of one frame
    // verified by the known extrinsics (later that day): 0.0041 deg / 0.66 mm.
    assert!(
        deg <= 0.005_f64.max(1.5 * true_deg) && mm <= 1.0_f64.max(1.5 * true_mm),
        "built map: {deg} deg / {mm} mm (true map: {true_deg} deg / {true_mm} mm)"
    );
}

/// The maximum-likelihood extrinsics from perfect tracks (every log feature on a landmark, the
/// simulator's correspondences: COLMAP's input for its figures of issue 17): plain least
/// squares refined from the truth (the definition of the maximum-likelihood estimate),
/// the scale by the true baseline from camera 0 to camera 2. Worst camera after aligning the
/// scale, degrees and millimetres.
fn perfect_tracks_estimate(world: &SimulatedWorld) -> (f64, f64) {
    let (observations, kept) = world.free_point_observations(85_f64.to_radians());
    let truth = &world.truth.rig_from_camera;
    let problem = RigBundleAdjustment {
        cameras: cameras(world),
        rig_from_camera: truth.clone(),
        world_from_rig: world.truth.world_from_rig.clone(),
        points: kept
            .iter()
            .map(|&id| world.true_map_points[id as usize].coords)
            .collect(),
        observations,
    };
    let result = problem
        .solve(&RigBundleAdjustmentOptions {
            loss: RobustLoss::Trivial,
            scale: ScaleGauge::Baseline {
                camera: 2,
                distance_m: (truth[2].translation.vector - truth[0].translation.vector).norm(),
            },
            ..Default::default()
        })
        .expect("adjustment of the perfect tracks");
    let errors = extrinsic_errors(&result.rig_from_camera, truth, true);
    (
        errors.iter().map(|e| e.0.to_degrees()).fold(0.0, f64::max),
        errors.iter().map(|e| e.1 * 1e3).fold(0.0, f64::max),
    )
}

/// TrimBot2020's ten-camera pentagon (five stereo pairs of 82-degree pinholes) in the garden,
/// 100 frames of its drive. The 0.003 deg is below what the best estimator reaches on
/// most worlds of this scenario even with perfect tracks (`rig_bundle_adjust.rs`,
/// `pentagon_with_perfect_tracks_is_efficient_and_the_rotation_bar_below_its_spread`: a
/// median of 0.0036 deg over eight worlds, six above 0.003), so the rotation is held to the
/// nearest honest bar: within a quarter more than the maximum-likelihood estimate from perfect
/// tracks on this world ([`perfect_tracks_estimate`]; 0.0037 deg / 0.38 mm), the translation
/// to the 0.5 mm. Measured 2026-12-03: 0.0043 deg / 0.35 mm worst camera after scale
/// alignment (1.17 times the perfect tracks' 0.00366 deg), 3 rounds; the self-calibration took
/// 38.8 s user CPU on 2 cores (bar 40 s; COLMAP 404 s). The tracks completed after the first
/// round (115,888 observations added, 8,288 tracks merged; 262k observations of 7.7k points in
/// the last round) took it from 0.0079 deg / 0.57 mm. COLMAP 0.0030 / 0.51 with perfect tracks;
/// TrimBot2020 0.5 deg / 1.9 mm.
#[test]
fn pentagon_rig_in_the_garden_is_as_close_as_perfect_tracks() {
    let world = world("garden-pentagon", 1.0 / 3.0, None);
    let result = self_calibrate(
        &world.log,
        &cameras(&world),
        &SelfCalibrationOptions::default(),
    )
    .expect("self-calibration");
    for (c, e) in extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, true)
        .iter()
        .enumerate()
    {
        println!(
            "pentagon camera {c} {}: {:.5} deg / {:.3} mm, std {:?}",
            world.log.camera_names[c],
            e.0.to_degrees(),
            e.1 * 1e3,
            result.extrinsic_std(c)
        );
    }
    for r in &result.rounds {
        println!("{r:?}");
    }
    let (ml_deg, ml_mm) = perfect_tracks_estimate(&world);
    println!("pentagon, perfect tracks: {ml_deg:.5} deg / {ml_mm:.3} mm");
    check_bars_with("pentagon", &world, &result, 0.003_f64.max(1.25 * ml_deg));
}

/// A handheld rig of three fisheyes with a 6-DoF pose tracker, 100 frames: the metric scale
/// from the tracker by Daniilidis's rotation and the linear scale-aware least squares. The
/// issue's 0.1 % is for wheel odometry (met on the garage: 0.044 %); here 0.24 % was measured,
/// 0.10 % with the completed tracks (2026-12-03), asserted within 0.5 % (a wrong lever-arm
/// term or rotation would be off by percents).
#[test]
fn handheld_rig_with_6dof_odometry_gets_the_metric_scale() {
    let world = world("handheld-6dof", 1.0 / 3.0, None);
    let result = self_calibrate(
        &world.log,
        &cameras(&world),
        &SelfCalibrationOptions::default(),
    )
    .expect("self-calibration");
    let errors = extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, true);
    let factor = alignment_scale(&result, &world);
    println!(
        "handheld: {:?}; scale {:?}, alignment factor {factor:.6}; {:?}",
        errors
            .iter()
            .map(|e| (e.0.to_degrees(), e.1 * 1e3))
            .collect::<Vec<_>>(),
        result.scale,
        result.tracks
    );
    assert!(matches!(result.scale, ScaleEstimate::Odometry { .. }));
    assert!((factor - 1.0).abs() <= 5e-3, "scale off by {factor}");
}

/// A TUM-VI-like pair of 195-degree fisheyes (512x512, f = 191 px, 10 cm apart) walked
/// through the garage with a 6-DoF pose tracker, 100 frames: calibrated with the rays beyond
/// 90 degrees from the optical axis (the image corners) in the adjustment, which a solver that
/// divides by z (COLMAP, OpenCV) cannot use. Measured: 0.0018 deg / 0.60 mm, standard
/// deviations 0.0016 deg / 0.20 mm, 107 of 86,190 observations beyond 90 degrees, metric
/// scale 0.18 % off, before the track completion; the translation then lay three of its
/// deviations off. With the completed tracks (2026-12-03): 0.0017 deg / 0.28 mm, standard
/// deviations 0.0013 deg / 0.15 mm, 135 of 120,266 observations beyond 90 degrees, scale
/// 0.04 % off: the garage's bars (0.003 deg / 0.5 mm) are met, and asserted, with the
/// translation within three of its deviations.
#[test]
fn fisheye_pair_uses_its_rays_beyond_90_degrees() {
    let world = world("handheld-fisheye-pair", 1.0 / 3.0, None);
    let result = self_calibrate(
        &world.log,
        &cameras(&world),
        &SelfCalibrationOptions::default(),
    )
    .expect("self-calibration");
    let last = result.rounds.last().expect("a round");
    let errors = extrinsic_errors(&result.rig_from_camera, &world.truth.rig_from_camera, true);
    let (rotation, translation) = errors[1];
    let (sr, st) = result.extrinsic_std(1).expect("covariance");
    let factor = alignment_scale(&result, &world);
    println!(
        "fisheye pair: {:.5} deg / {:.3} mm, std {:.5} deg / {:.3} mm; {} of {} observations \
         at or beyond 90 degrees; {} rounds; scale {:?}, alignment factor {factor:.6}",
        rotation.to_degrees(),
        translation * 1e3,
        sr.to_degrees(),
        st * factor * 1e3,
        last.wide_observations,
        last.observations,
        result.rounds.len(),
        result.scale,
    );
    assert!(result.converged, "{:?}", result.rounds);
    assert!(rotation.to_degrees() <= 0.003, "{rotation} rad");
    assert!(rotation <= 3.0 * sr, "{rotation} rad against {sr}");
    assert!(translation <= 0.5e-3, "{translation} m");
    assert!(
        translation <= 3.0 * st * factor,
        "{translation} m against {st}"
    );
    assert!(st * factor <= 0.5e-3, "standard deviation {st} m");
    assert!(matches!(result.scale, ScaleEstimate::Odometry { .. }));
    assert!((factor - 1.0).abs() <= 5e-3, "scale off by {factor}");
    // The corners' rim: a tenth of a per cent of the rays, but used.
    assert!(last.wide_observations >= 50, "{last:?}");
}

/// `ibc map --refine-extrinsics`: the survey rig's camera file is off (the left camera 1 cm
/// and 0.2 degrees from where it is); the map is built with the extrinsics refined from the
/// file's, the scale held by the file's front-rear baseline, and the left camera is found
/// where it is, within the self-calibration's bars and its own standard deviations.
#[test]
fn a_map_with_refined_extrinsics_finds_the_camera_that_moved() {
    use ibc_pipeline::nalgebra::{Translation3, UnitQuaternion, Vector3};
    use ibc_pipeline::sfm::{MapOptions, build_map};
    let survey = world("garage", 0.2, None);
    let mut rig = survey.rig.clone();
    let left = &mut rig.cameras[1].rig_from_camera;
    *left = Isometry3::from_parts(
        Translation3::from(left.translation.vector + Vector3::new(0.006, -0.008, 0.0)),
        left.rotation
            * UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.2f64.to_radians(), 0.0)),
    );
    let built = build_map(
        &survey.log,
        &rig,
        &MapOptions {
            refine_extrinsics: true,
            ..Default::default()
        },
    )
    .expect("map");
    let errors = extrinsic_errors(&built.rig_from_camera, &survey.truth.rig_from_camera, false);
    let (rotation, translation) = errors[1];
    let cov = built.extrinsic_covariance[1].expect("covariance");
    let (sr, st) = (
        (3..6).map(|k| cov[(k, k)]).fold(0.0, f64::max).sqrt(),
        (0..3).map(|k| cov[(k, k)]).fold(0.0, f64::max).sqrt(),
    );
    println!(
        "refined survey extrinsics: left {:.5} deg / {:.3} mm off (std {:.5} deg / {:.3} mm); \
         all {:?}",
        rotation.to_degrees(),
        translation * 1e3,
        sr.to_degrees(),
        st * 1e3,
        errors
            .iter()
            .map(|e| (e.0.to_degrees(), e.1 * 1e3))
            .collect::<Vec<_>>()
    );
    for (camera, &(r, t)) in errors.iter().enumerate() {
        assert!(
            r.to_degrees() <= 0.005 && t <= 1e-3,
            "camera {camera}: {r} rad, {t} m"
        );
    }
    assert!(rotation <= 4.0 * sr && translation <= 4.0 * st.max(1e-6));
}
