//! The online calibrator (TrimBot2020 D3.1 §3.3.2): with the focal lengths drifting 0.5 %
//! over a drive (a lens warming up), the running estimate follows the truth within its
//! standard deviations; a straight drive without turns updates nothing and says why.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_bundle_adjust::{
    IntrinsicsSelection, OnlineCalibrator, OnlineEvent, OnlineFrameSet, OnlineObservation,
    OnlineOptions, SkipReason,
};
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, PinholeRadtan, Rig, RigCamera};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Three cameras looking forward, left and right.
fn rig() -> Rig {
    let cameras: [(Camera, f64); 3] = [
        (
            PinholeRadtan::new(
                752,
                480,
                [-0.28, 0.07, 1e-4, -2e-4, 460.0, 458.0, 370.0, 245.0],
            )
            .unwrap()
            .into(),
            0.0,
        ),
        (
            KannalaBrandt::new(
                1280,
                800,
                [0.01, -0.002, 0.0005, -0.0001, 350.0, 350.0, 640.0, 400.0],
            )
            .unwrap()
            .into(),
            1.6,
        ),
        (
            KannalaBrandt::new(
                1280,
                800,
                [0.01, -0.002, 0.0005, -0.0001, 352.0, 351.0, 641.0, 399.0],
            )
            .unwrap()
            .into(),
            -1.6,
        ),
    ];
    Rig::new(
        cameras
            .into_iter()
            .enumerate()
            .map(|(c, (camera, yaw))| {
                RigCamera::new(
                    format!("cam{c}"),
                    camera,
                    Isometry3::from_parts(
                        Translation3::new(0.3 * yaw, 0.05 * c as f64, -0.2 * yaw.abs()),
                        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), yaw),
                    ),
                )
            })
            .collect(),
    )
}

/// `cameras` with their focal lengths times `1 + change`.
fn drifted(cameras: &[Camera], change: f64) -> Vec<Camera> {
    cameras
        .iter()
        .map(|c| {
            let mut c = c.clone();
            let mut p = c.params().to_vec();
            for i in c.focal_length_indices() {
                p[i] *= 1.0 + change;
            }
            c.set_params(&p).unwrap();
            c
        })
        .collect()
}

/// Frame sets of a drive of `frames` poses (`turning`: a loop, else a straight line), each
/// camera seeing 60 points, pixels with 0.5 px noise, focal lengths drifting linearly by
/// `drift` over the drive; start poses a little off, as from localization.
fn drive(rig: &Rig, frames: usize, turning: bool, drift: f64, seed: u64) -> Vec<OnlineFrameSet> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.5).unwrap();
    let cameras: Vec<Camera> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    (0..frames)
        .map(|f| {
            let s = f as f64 / frames as f64;
            let pose = if turning {
                let a = s * std::f64::consts::TAU * 2.0;
                Isometry3::from_parts(
                    Translation3::new(30.0 * a.cos(), 0.0, 30.0 * a.sin()),
                    UnitQuaternion::from_axis_angle(&Vector3::y_axis(), -a),
                )
            } else {
                Isometry3::translation(0.0, 0.0, 0.5 * f as f64)
            };
            let truth = drifted(&cameras, drift * s);
            let mut observations = Vec::new();
            for (c, camera) in truth.iter().enumerate() {
                let world_from_camera = pose * rig.cameras[c].rig_from_camera;
                for _ in 0..60 {
                    let px = Vector2::new(
                        rng.random_range(20.0..f64::from(camera.width()) - 20.0),
                        rng.random_range(20.0..f64::from(camera.height()) - 20.0),
                    );
                    let ray = camera.unproject(&px).unwrap();
                    let p_cam = ray.into_inner() * rng.random_range(3.0..25.0);
                    let pixel = camera.project(&p_cam).unwrap()
                        + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng));
                    observations.push(OnlineObservation {
                        camera: c,
                        world_point: world_from_camera.transform_point(&p_cam.into()).coords,
                        pixel,
                    });
                }
            }
            let off = Isometry3::new(
                Vector3::new(0.02, -0.01, 0.015),
                Vector3::new(0.002, -0.001, 0.003),
            );
            OnlineFrameSet {
                world_from_rig: pose * off,
                observations,
            }
        })
        .collect()
}

#[test]
fn the_running_estimate_follows_a_drifting_focal_length() {
    let rig = rig();
    let frames = 600;
    let drift = 0.005;
    let options = OnlineOptions::default();
    let mut calibrator = OnlineCalibrator::new(&rig, options.clone()).unwrap();
    let cameras: Vec<Camera> = rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let (mut checks, mut within_3, mut updates) = (0usize, 0usize, 0usize);
    let mut worst_sigmas = 0.0f64;
    for set in drive(&rig, frames, true, drift, 1) {
        let OnlineEvent::Updated(update) = calibrator.push(set).unwrap() else {
            continue;
        };
        updates += 1;
        // The window's truth: the drift at its middle frame set.
        let middle = update.frame_sets as f64 - (options.window as f64 + 1.0) / 2.0;
        let truth = drifted(&cameras, drift * middle / frames as f64);
        for (c, (estimate, truth)) in update.cameras.iter().zip(&truth).enumerate() {
            let cov = update.intrinsic_covariance[c].as_ref().unwrap();
            for i in estimate.focal_length_indices() {
                let error = estimate.params()[i] - truth.params()[i];
                let sigma = cov[(i, i)].sqrt();
                assert!(sigma > 0.0 && sigma < 0.1, "camera {c}: sigma {sigma} px");
                let k = error.abs() / sigma;
                worst_sigmas = worst_sigmas.max(k);
                checks += 1;
                within_3 += usize::from(k <= 3.0);
            }
        }
        // Far from the start's: the drift is followed.
        let start = cameras[0].params()[4];
        let now = update.cameras[0].params()[4];
        let expected = start * drift * middle / frames as f64;
        assert!(
            ((now - start) - expected).abs() < 0.2,
            "moved {} px, drift {expected} px",
            now - start
        );
    }
    // Updates every 10 frame sets once 50 are in: 56, all accepted on a loop with turns.
    assert_eq!(
        updates,
        (frames - options.window) / options.update_every + 1
    );
    // Within 3 standard deviations, as Gaussian errors are (at least 97 % of the time), and
    // never beyond 4.
    println!("{within_3} of {checks} within 3 sigma, worst {worst_sigmas:.2} sigma");
    assert!(
        within_3 as f64 >= 0.97 * checks as f64,
        "{within_3} of {checks}"
    );
    assert!(worst_sigmas <= 4.0, "{worst_sigmas}");
}

#[test]
fn a_straight_drive_updates_nothing_and_says_why() {
    let rig = rig();
    let mut calibrator = OnlineCalibrator::new(&rig, OnlineOptions::default()).unwrap();
    let mut skipped = 0;
    for set in drive(&rig, 120, false, 0.0, 2) {
        match calibrator.push(set).unwrap() {
            OnlineEvent::Kept => {}
            OnlineEvent::Skipped(reason) => {
                skipped += 1;
                assert!(
                    matches!(reason, SkipReason::TooLittleRotation { spread_deg, .. } if spread_deg < 1.0),
                    "{reason}"
                );
                assert!(reason.to_string().contains("turned"), "{reason}");
            }
            other => panic!("not skipped on a straight drive: {other:?}"),
        }
    }
    assert_eq!(skipped, (120 - 50) / 10 + 1);
    // The estimate is the camera file's.
    for (estimate, start) in calibrator.cameras().iter().zip(&rig.cameras) {
        assert_eq!(estimate.params(), start.camera.params());
    }
}

#[test]
fn bad_options_and_frame_sets_are_typed_errors() {
    let rig = rig();
    for options in [
        OnlineOptions {
            window: 1,
            ..Default::default()
        },
        OnlineOptions {
            update_every: 0,
            ..Default::default()
        },
        OnlineOptions {
            min_rotation_deg: f64::NAN,
            ..Default::default()
        },
        OnlineOptions {
            intrinsics: IntrinsicsSelection::All,
            min_observability: 2.0,
            ..Default::default()
        },
    ] {
        assert!(OnlineCalibrator::new(&rig, options).is_err());
    }
    let mut calibrator = OnlineCalibrator::new(&rig, OnlineOptions::default()).unwrap();
    let mut set = drive(&rig, 1, true, 0.0, 3).remove(0);
    set.observations[5].camera = 7;
    assert!(calibrator.push(set.clone()).is_err());
    set.observations[5].camera = 0;
    set.observations[6].pixel.x = f64::NAN;
    assert!(calibrator.push(set).is_err());
}
