//! The crate as a user calls it: every options struct in one expression, the crate's
//! `Result`, the re-exported `nalgebra`, and errors that name the option at fault.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use ibc_rig_averaging::nalgebra::{Isometry3, UnitQuaternion, Vector3};
use ibc_rig_averaging::{
    Averaging, ImageScore, RigAveragingError, RigInitOptions, RigInitialization, RobustOptions,
    initialize_rig, robust_quaternion_mean,
};

#[test]
fn options_are_written_in_one_expression() {
    let robust = RobustOptions {
        rotation_scale: Some(0.01),
        max_iterations: 20,
        ..Default::default()
    };
    assert_eq!(robust.translation_scale, None);
    assert_eq!(robust.tolerance, 1e-10);
    // The builders give the same options.
    assert_eq!(
        robust,
        RobustOptions::default()
            .with_rotation_scale(0.01)
            .with_max_iterations(20)
    );
    let init = RigInitOptions {
        extrinsic_averaging: Averaging::Robust(robust),
        rig_pose_averaging: Averaging::Plain,
        ..Default::default()
    };
    assert!(init.averaged_extrinsics);
    assert_eq!(
        init,
        RigInitOptions::default().with_extrinsic_averaging(Averaging::Robust(robust))
    );
}

fn initialize(options: &RigInitOptions) -> ibc_rig_averaging::Result<RigInitialization> {
    let rig_from_camera_1 =
        Isometry3::new(Vector3::new(0.5, 0.0, 0.0), Vector3::new(0.0, 0.2, 0.0));
    let sets: Vec<Vec<Option<Isometry3<f64>>>> = (0..4)
        .map(|s| {
            let world_from_rig =
                Isometry3::new(Vector3::new(f64::from(s), 0.0, 0.0), Vector3::zeros());
            vec![
                Some(world_from_rig.inverse()),
                Some((world_from_rig * rig_from_camera_1).inverse()),
            ]
        })
        .collect();
    let scorer = |_: usize, _: usize, _: &Isometry3<f64>| ImageScore::new(0.5, 1);
    initialize_rig(&sets, &scorer, options)
}

#[test]
fn entry_points_take_the_options_and_name_bad_ones() {
    let init = initialize(&RigInitOptions {
        averaged_extrinsics: false,
        ..Default::default()
    })
    .unwrap();
    assert!(init.averaged.is_none());
    assert!((init.rig_from_camera[1].translation.vector.x - 0.5).abs() < 1e-12);
    let bad = RigInitOptions {
        rig_pose_averaging: Averaging::Robust(RobustOptions {
            tolerance: -1.0,
            ..Default::default()
        }),
        ..Default::default()
    };
    let err = initialize(&bad).unwrap_err();
    assert!(matches!(
        err,
        RigAveragingError::InvalidRobustOptions {
            option: "tolerance",
            ..
        }
    ));
    assert!(err.to_string().contains("`tolerance`"), "{err}");
    let q = [UnitQuaternion::identity(); 3];
    assert!(matches!(
        robust_quaternion_mean(
            &q,
            None,
            &RobustOptions {
                rotation_scale: Some(0.0),
                ..Default::default()
            }
        ),
        Err(RigAveragingError::InvalidRobustOptions {
            option: "rotation_scale",
            ..
        })
    ));
}

/// The viewing-graph options of issue 16, written as a caller outside the crate writes them.
#[test]
fn viewing_graph_options_are_one_expression() {
    use ibc_rig_averaging::{RotationAveragingOptions, ScaleGauge, TranslationAveragingOptions};
    let rotations = RotationAveragingOptions {
        robust_scale: Some(2f64.to_radians()),
        reference_camera: 1,
        ..Default::default()
    };
    assert_eq!(rotations.irls_iterations, 50);
    let translations = TranslationAveragingOptions {
        robust: false,
        scale: ScaleGauge::ViewDistance {
            from: 0,
            to: 3,
            distance: 1.5,
        },
        ..Default::default()
    };
    assert_eq!(translations.reference_camera, 0);
    assert_eq!(
        TranslationAveragingOptions::default().scale,
        ScaleGauge::MeanBaseline
    );
}
