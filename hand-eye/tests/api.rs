//! The API as a caller outside the crate writes it: every options struct of the crate in one
//! expression with `..Default::default()` (the structs stay open to new fields through a hidden
//! marker field, so this is the only way to write them), the windowed pairing, the `Result`
//! alias, the re-exported `nalgebra`, and the error messages.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_hand_eye::nalgebra::{Isometry3, Vector3};
use ibc_hand_eye::{
    DaniilidisOptions, HandEyeError, Height, MotionScreening, NoiseModel, OptionField, Pairing,
    PlanarOptions, PoseFrame, PoseNoise, RefineOptions, Sensor, TrajectoryOptions, daniilidis,
    guo_planar, refine_trajectories, relative_motions,
};

/// A car driving a wavy loop (odometry in its plane) and the rig on it.
fn car(odometry_from_rig: &Isometry3<f64>) -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>) {
    let odometry: Vec<_> = (0..40)
        .map(|k| {
            let t = 0.2 * f64::from(k);
            let position = Vector3::new(10.0 * t.cos(), 6.0 * t.sin(), 0.0);
            Isometry3::new(position, Vector3::z() * (t + 0.3 * (2.0 * t).sin()))
        })
        .collect();
    let rig = odometry.iter().map(|o| o * odometry_from_rig).collect();
    (rig, odometry)
}

#[test]
fn every_options_struct_in_one_expression() -> ibc_hand_eye::Result<()> {
    let screening = MotionScreening {
        min_rotation: 1.0_f64.to_radians(),
        ..Default::default()
    };
    let refine = RefineOptions {
        max_iterations: 30,
        ..Default::default()
    };
    let daniilidis_options = DaniilidisOptions {
        screening,
        min_signal_to_noise: 5.0,
        refine: Some(refine),
        ..Default::default()
    };
    let planar_options = PlanarOptions {
        screening,
        height_prior: Some(0.8),
        refine: Some(RefineOptions {
            rotation_sigma: Some(0.002),
            translation_sigma: Some(0.005),
            ..refine
        }),
        ..Default::default()
    };
    let trajectory_options = TrajectoryOptions {
        noise: NoiseModel::Both {
            a: PoseNoise::new(PoseFrame::SensorFromWorld, 0.002, 0.005),
            b: PoseNoise::new(PoseFrame::WorldFromSensor, 0.001, 0.001),
        },
        refine,
        ..TrajectoryOptions::planar(false, 1.0)
    };
    assert_eq!(
        screening.max_rotation,
        MotionScreening::default().max_rotation
    );
    assert_eq!(
        daniilidis_options.refine.map(|r| r.max_iterations),
        Some(30)
    );
    assert!(!planar_options.estimate_scale);
    assert!(trajectory_options.planar);

    // The pipeline's use: a window of 8 frame sets, the planar method, then the refinement.
    let odometry_from_rig =
        Isometry3::new(Vector3::new(1.2, -0.3, 0.8), Vector3::new(1.2, -1.2, 1.2));
    let (rig_poses, odometry_poses) = car(&odometry_from_rig);
    let motions = relative_motions(&rig_poses, &odometry_poses, Pairing::Window { size: 8 })?;
    assert_eq!(motions.len(), 8 * (40 - 8) + 8 * 7 / 2);
    let planar = guo_planar(&motions, &planar_options)?;
    assert_eq!(planar.height, Height::Prior(0.8));
    let truth = odometry_from_rig.translation.vector;
    assert!((planar.b_from_a.translation.vector.xy() - truth.xy()).norm() < 1e-9);
    let fit = refine_trajectories(
        &rig_poses,
        &odometry_poses,
        &planar.a_from_b,
        &trajectory_options,
    )?;
    assert!((fit.b_from_a.translation.vector.xy() - truth.xy()).norm() < 1e-9);
    // Planar motion: Daniilidis names the degeneracy, whatever its options.
    assert!(matches!(
        daniilidis(&motions, &daniilidis_options),
        Err(HandEyeError::ParallelRotationAxes { .. })
    ));
    Ok(())
}

#[test]
fn errors_name_the_culprit_in_degrees_and_metres() {
    let poses = [Isometry3::identity(); 3];
    let window = relative_motions(&poses, &poses, Pairing::Window { size: 0 });
    assert_eq!(window, Err(HandEyeError::InvalidWindow { size: 0 }));
    assert_eq!(
        window.unwrap_err().to_string(),
        "Pairing::Window { size: 0 } pairs no poses: the size must be at least 1"
    );

    let screening = MotionScreening::new(0.5, 0.25);
    let error = daniilidis(
        &[],
        &DaniilidisOptions {
            screening,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert_eq!(
        error,
        HandEyeError::InvalidOptions {
            field: OptionField::MaxRotation,
            value: 0.25
        }
    );
    assert_eq!(
        error.to_string(),
        "invalid option: MotionScreening::max_rotation = 14.324 deg, must be in (min_rotation, 180 deg]"
    );

    let options = PlanarOptions {
        height_prior: Some(f64::INFINITY),
        ..Default::default()
    };
    let error = guo_planar(&[], &options).unwrap_err();
    assert_eq!(
        error.to_string(),
        "invalid option: PlanarOptions::height_prior = inf m, must be finite"
    );

    let options = TrajectoryOptions {
        noise: NoiseModel::Both {
            a: PoseNoise::new(PoseFrame::SensorFromWorld, 0.002, 0.005),
            b: PoseNoise::new(PoseFrame::WorldFromSensor, 0.001, -0.001),
        },
        ..Default::default()
    };
    let error = refine_trajectories(&poses, &poses, &Isometry3::identity(), &options).unwrap_err();
    assert_eq!(
        error,
        HandEyeError::InvalidOptions {
            field: OptionField::NoiseTranslation(Sensor::B),
            value: -0.001
        }
    );
    assert_eq!(
        error.to_string(),
        "invalid option: NoiseModel::Both { b: translation } = -0.0010 m, must be positive and finite"
    );
}
