//! Rig initialization on a synthetic 4-camera rig with 100 frame sets, some incomplete and some
//! missing camera 0 (Heng et al. 2014, section IV-C).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{SyntheticRig, pinhole, pose_error, synthetic_rig};
use ibc_rig_averaging::{
    Averaging, HypothesisSource, ImageScore, ObservationScorer, RigAveragingError, RigInitOptions,
    RigInitialization, RobustOptions, initialize_rig, pose_mean, rig_poses,
};
use nalgebra::{Isometry3, Point2, Point3, UnitQuaternion, Vector3};

const SETS: usize = 100;
const POINTS: usize = 30;

/// The synthetic cameras' projection as a function pointer, so the scorer type can be named.
type Projection = fn(usize, &Point3<f64>) -> Option<Point2<f64>>;

fn scorer(rig: &SyntheticRig) -> ObservationScorer<Projection> {
    ObservationScorer::new(rig.images.clone(), pinhole as Projection)
}

/// Largest (rotation, translation) error of the extrinsics and of the rig poses against the
/// truth in the initialization's gauge.
fn errors(rig: &SyntheticRig, init: &RigInitialization) -> ((f64, f64), (f64, f64)) {
    (
        worst_error(&init.rig_from_camera, &rig.gauge_rig_from_camera()),
        worst_error(&init.world_from_rig, &rig.gauge_world_from_rig()),
    )
}

/// Largest rotation and largest translation error over paired poses.
fn worst_error(estimates: &[Isometry3<f64>], truth: &[Isometry3<f64>]) -> (f64, f64) {
    estimates
        .iter()
        .zip(truth)
        .map(|(a, b)| pose_error(a, b))
        .fold((0.0f64, 0.0f64), |(a, b), (r, t)| (a.max(r), b.max(t)))
}

#[test]
fn exact_camera_poses_recover_extrinsics_and_rig_poses() {
    let rig = synthetic_rig(1, SETS, POINTS, 0.0, 0.0, 0.0);
    let complete = rig.complete_sets();
    assert_eq!(complete.len(), 60);
    assert_eq!(rig.sets.iter().filter(|s| s[0].is_none()).count(), 20);
    let init = initialize_rig(&rig.sets, &scorer(&rig), &RigInitOptions::default()).unwrap();
    let ((er, et), (pr, pt)) = errors(&rig, &init);
    println!("exact: extrinsics {er:.1e} rad {et:.1e} m, rig poses {pr:.1e} rad {pt:.1e} m");
    assert!(er < 1e-9 && et < 1e-9 && pr < 1e-9 && pt < 1e-9);
    assert_eq!(init.rig_from_camera[0], Isometry3::identity());
    assert_eq!(init.world_from_rig.len(), SETS);
    assert_eq!(init.set_scores.len(), 60);
    assert!(init.score.mean_error < 1e-9);
    assert_eq!(init.score.observations, SETS * 4 * POINTS);
    // Averaging exact data changes nothing either.
    let (averaged, averaged_score) = init.averaged.clone().unwrap();
    for (a, b) in averaged.iter().zip(rig.gauge_rig_from_camera()) {
        let (r, t) = pose_error(a, &b);
        assert!(r < 1e-9 && t < 1e-9);
    }
    assert!(averaged_score.mean_error < 1e-9);
    assert!(init.min_rig_pose_conditioning > 0.99);
}

/// The score of a hypothesis recomputed independently: extrinsics from the set, rig poses by
/// `pose_mean` of each set's estimates, pixel errors by an explicit loop.
fn reference_score(rig: &SyntheticRig, rig_from_camera: &[Isometry3<f64>]) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for (s, set) in rig.sets.iter().enumerate() {
        let estimates: Vec<Isometry3<f64>> = set
            .iter()
            .zip(rig_from_camera)
            .filter_map(|(c, e)| c.map(|c| c.inverse() * e.inverse()))
            .collect();
        let world_from_rig = pose_mean(&estimates, None).unwrap().mean;
        for (c, e) in rig_from_camera.iter().enumerate() {
            let camera_from_world = (world_from_rig * e).inverse();
            for obs in &rig.images[s][c] {
                let p = camera_from_world * obs.point_in_world;
                sum += (pinhole(c, &p).unwrap() - obs.pixel).norm();
                count += 1;
            }
        }
    }
    sum / count as f64
}

fn extrinsics_of_set(set: &[Option<Isometry3<f64>>]) -> Vec<Isometry3<f64>> {
    let c0 = set[0].unwrap();
    set.iter().map(|c| c0 * c.unwrap().inverse()).collect()
}

#[test]
fn noisy_camera_poses_choose_the_lowest_score() {
    // 0.3 degree and 2 cm localization noise, 0.5 px pixel noise.
    let rig = synthetic_rig(2, SETS, POINTS, 0.3f64.to_radians(), 0.02, 0.5);
    let init = initialize_rig(&rig.sets, &scorer(&rig), &RigInitOptions::default()).unwrap();

    // Every single-set score agrees with the independent recomputation, and the chosen
    // hypothesis is the minimum over all of them and the averaged extrinsics.
    let mut reference_best = f64::INFINITY;
    for &(s, score) in &init.set_scores {
        let reference = reference_score(&rig, &extrinsics_of_set(&rig.sets[s]));
        approx::assert_relative_eq!(score.mean_error, reference, max_relative = 1e-9);
        reference_best = reference_best.min(reference);
    }
    let (averaged, averaged_score) = init.averaged.clone().unwrap();
    approx::assert_relative_eq!(
        averaged_score.mean_error,
        reference_score(&rig, &averaged),
        max_relative = 1e-9
    );
    reference_best = reference_best.min(averaged_score.mean_error);
    assert_eq!(init.score.mean_error, reference_best);
    assert!(
        init.set_scores
            .iter()
            .all(|(_, s)| init.score.mean_error <= s.mean_error)
    );

    let ((er, et), (pr, pt)) = errors(&rig, &init);
    let best_single = &init.best_set;
    println!(
        "noisy: chosen {:?} score {:.3} px; best set {} score {:.3} px; averaged {:.3} px; \
         extrinsics error {:.3} deg {:.4} m, rig poses {:.3} deg {:.4} m",
        init.source,
        init.score.mean_error,
        best_single.0,
        best_single.1.mean_error,
        averaged_score.mean_error,
        er.to_degrees(),
        et,
        pr.to_degrees(),
        pt
    );
    // Averaging 60 hypotheses beats any single set here, and the extrinsics are accurate to
    // a fraction of the per-pose noise.
    assert_eq!(init.source, HypothesisSource::AveragedExtrinsics);
    assert!(init.averaged_is_better());
    assert!(er < 0.3f64.to_radians() && et < 0.02);
}

#[test]
fn a_corrupted_set_does_not_win() {
    let mut rig = synthetic_rig(3, SETS, POINTS, 0.3f64.to_radians(), 0.02, 0.5);
    // Corrupt camera 2 of complete set 10: 5 degrees and 30 cm off.
    let corrupted = 10;
    assert!(rig.sets[corrupted].iter().all(Option::is_some));
    let wrong = Isometry3::new(
        Vector3::new(0.3, 0.0, 0.0),
        Vector3::new(0.0, 5f64.to_radians(), 0.0),
    );
    rig.sets[corrupted][2] = Some(wrong * rig.sets[corrupted][2].unwrap());
    for options in [
        RigInitOptions::default(),
        RigInitOptions::default().with_averaged_extrinsics(false),
        RigInitOptions::default().with_extrinsic_averaging(Averaging::Plain),
        RigInitOptions::default()
            .with_rig_pose_averaging(Averaging::Robust(RobustOptions::default())),
    ] {
        let init = initialize_rig(&rig.sets, &scorer(&rig), &options).unwrap();
        assert_ne!(init.source, HypothesisSource::CompleteSet(corrupted));
        let corrupted_score = init
            .set_scores
            .iter()
            .find(|(s, _)| *s == corrupted)
            .unwrap()
            .1;
        println!(
            "corrupted set score {:.2} px, chosen {:?} {:.3} px",
            corrupted_score.mean_error, init.source, init.score.mean_error
        );
        assert!(corrupted_score.mean_error > 3.0 * init.score.mean_error);
        // A single set's extrinsics carry the noise of two camera poses (about
        // sqrt(6) * 0.3 = 0.73 degrees RMS); the average over 60 sets far less.
        let ((er, et), _) = errors(&rig, &init);
        let (max_r, max_t) = match init.source {
            HypothesisSource::AveragedExtrinsics => (0.3f64.to_radians(), 0.02),
            HypothesisSource::CompleteSet(_) => (2f64.to_radians(), 0.15),
        };
        assert!(er < max_r && et < max_t, "{er} {et}");
    }
}

#[test]
fn robust_extrinsic_averaging_shrugs_off_the_corrupted_set() {
    let mut rig = synthetic_rig(4, SETS, POINTS, 0.0, 0.0, 0.0);
    let wrong = Isometry3::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.5, 0.0));
    rig.sets[0][1] = Some(wrong * rig.sets[0][1].unwrap());
    let truth = rig.gauge_rig_from_camera();
    let robust = initialize_rig(&rig.sets, &scorer(&rig), &RigInitOptions::default()).unwrap();
    let plain = initialize_rig(
        &rig.sets,
        &scorer(&rig),
        &RigInitOptions::default().with_extrinsic_averaging(Averaging::Plain),
    )
    .unwrap();
    let robust_err = pose_error(&robust.averaged.unwrap().0[1], &truth[1]);
    let plain_err = pose_error(&plain.averaged.unwrap().0[1], &truth[1]);
    println!("camera 1 extrinsic, averaged over sets: robust {robust_err:?}, plain {plain_err:?}");
    assert!(robust_err.0 < 1e-9 && robust_err.1 < 1e-9);
    assert!(plain_err.0 > 1e-3 && plain_err.1 > 1e-3);
}

#[test]
fn result_is_independent_of_the_thread_count() {
    let rig = synthetic_rig(5, 40, 10, 0.2f64.to_radians(), 0.01, 0.5);
    let sc = scorer(&rig);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| initialize_rig(&rig.sets, &sc, &RigInitOptions::default()).unwrap())
    };
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(5));
}

#[test]
fn rig_poses_for_known_extrinsics() {
    let rig = synthetic_rig(6, 30, 0, 0.0, 0.0, 0.0);
    // With the true extrinsics (camera 0 not at the identity) the true rig poses come back.
    let poses = rig_poses(&rig.sets, &rig.rig_from_camera, &Averaging::Plain).unwrap();
    for (p, truth) in poses.iter().zip(&rig.world_from_rig) {
        let (r, t) = pose_error(&p.mean, truth);
        assert!(r < 1e-12 && t < 1e-12);
        assert!(p.rotation.conditioning > 0.999);
    }
    assert!(matches!(
        rig_poses(&rig.sets, &rig.rig_from_camera[..3], &Averaging::Plain),
        Err(RigAveragingError::ExtrinsicCountMismatch {
            expected: 4,
            found: 3
        })
    ));
    let mut broken = rig.rig_from_camera.clone();
    broken[2].translation.vector.x = f64::NAN;
    assert!(matches!(
        rig_poses(&rig.sets, &broken, &Averaging::Plain),
        Err(RigAveragingError::InvalidExtrinsic { camera: 2 })
    ));
}

#[test]
fn a_closure_can_score() {
    let rig = synthetic_rig(7, 20, 5, 0.0, 0.0, 0.0);
    let truth = rig.gauge_world_from_rig();
    let extrinsics = rig.gauge_rig_from_camera();
    // Score by the distance of the camera centre from the truth (not a reprojection error,
    // but any non-negative error works).
    let closure = |s: usize, c: usize, camera_from_world: &Isometry3<f64>| {
        let centre = camera_from_world.inverse().translation.vector;
        let true_centre = (truth[s] * extrinsics[c]).translation.vector;
        ImageScore::new((centre - true_centre).norm(), 1)
    };
    let init = initialize_rig(&rig.sets, &closure, &RigInitOptions::default()).unwrap();
    assert!(init.score.mean_error < 1e-9);
    assert_eq!(init.score.observations, 20 * 4);
}

#[test]
fn invalid_frame_sets_are_typed_errors() {
    let options = RigInitOptions::default();
    let score = |_: usize, _: usize, _: &Isometry3<f64>| ImageScore::new(1.0, 1);
    let pose = Some(Isometry3::identity());
    let empty: Vec<Vec<Option<Isometry3<f64>>>> = vec![];
    assert_eq!(
        initialize_rig(&empty, &score, &options),
        Err(RigAveragingError::NoFrameSets)
    );
    assert_eq!(
        initialize_rig(&[vec![pose]], &score, &options),
        Err(RigAveragingError::TooFewRigCameras { cameras: 1 })
    );
    assert_eq!(
        initialize_rig(
            &[vec![pose, pose], vec![pose, pose, pose]],
            &score,
            &options
        ),
        Err(RigAveragingError::CameraCountMismatch {
            set: 1,
            expected: 2,
            found: 3
        })
    );
    assert_eq!(
        initialize_rig(
            &[vec![pose, pose, None], vec![pose, None, None]],
            &score,
            &options
        ),
        Err(RigAveragingError::SetTooFewCameras {
            set: 1,
            localized: 1
        })
    );
    assert_eq!(
        initialize_rig(
            &[vec![pose, pose, None], vec![None, pose, pose]],
            &score,
            &options
        ),
        Err(RigAveragingError::NoCompleteSet { sets: 2 })
    );
    let mut nan = Isometry3::identity();
    nan.translation.vector.z = f64::NAN;
    assert_eq!(
        initialize_rig(&[vec![pose, Some(nan)]], &score, &options),
        Err(RigAveragingError::InvalidCameraPose { set: 0, camera: 1 })
    );
    let mut not_unit = Isometry3::identity();
    not_unit.rotation =
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(0.5, 0.0, 0.0, 0.0));
    assert_eq!(
        initialize_rig(&[vec![Some(not_unit), pose]], &score, &options),
        Err(RigAveragingError::InvalidCameraPose { set: 0, camera: 0 })
    );
    // A scorer without observations leaves no finite score.
    let nothing = |_: usize, _: usize, _: &Isometry3<f64>| ImageScore::default();
    assert_eq!(
        initialize_rig(&[vec![pose, pose]], &nothing, &options),
        Err(RigAveragingError::NoFiniteScore)
    );
    let bad_robust = options.with_rig_pose_averaging(Averaging::Robust(
        RobustOptions::default().with_max_iterations(0),
    ));
    assert!(matches!(
        initialize_rig(&[vec![pose, pose]], &score, &bad_robust),
        Err(RigAveragingError::InvalidRobustOptions { .. })
    ));
    // The message names the set.
    let message = initialize_rig(&[vec![pose, pose], vec![pose, None]], &score, &options)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("frame set 1 localizes 1 camera"),
        "{message}"
    );
}

#[test]
fn points_behind_a_hypothesis_camera_are_penalized_not_fatal() {
    let rig = synthetic_rig(8, 20, 10, 0.0, 0.0, 0.0);
    let sc = scorer(&rig);
    let init = initialize_rig(&rig.sets, &sc, &RigInitOptions::default()).unwrap();
    // Turning camera 1 around puts its points behind it: every observation costs the penalty.
    let mut flipped = init.rig_from_camera.clone();
    flipped[1] *= UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI);
    let camera_from_world = (init.world_from_rig[0] * flipped[1]).inverse();
    let score = ibc_rig_averaging::ImageScorer::score_image(&sc, 0, 1, &camera_from_world);
    assert_eq!(score.observations, 10);
    assert_eq!(
        score.error_sum,
        10.0 * ibc_rig_averaging::DEFAULT_FAILURE_PENALTY_PX
    );
}
