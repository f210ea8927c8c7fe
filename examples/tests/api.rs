#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! The pipeline as a user outside the crate calls it: every options struct in one expression
//! with `..Default::default()`, nesting the library options it uses, and the crate's
//! re-exported `nalgebra` and `Result`.

use ibc_pipeline::calib::{
    CalibrationOptions, FrameSetOptions, HandEyeOptions, InitializationOptions,
    LocalizationOptions, RefinementOptions, VocabularyOptions, calibrate, default_pose_options,
};
use ibc_pipeline::colmap::ColmapLogOptions;
use ibc_pipeline::ibc_hand_eye::Pairing;
use ibc_pipeline::ibc_pnp::AbsolutePoseOptions;
use ibc_pipeline::intrinsics::kb_init::KbInitOptions;
use ibc_pipeline::intrinsics::simulate::BoardSimulationOptions;
use ibc_pipeline::intrinsics::{IntrinsicModel, IntrinsicsOptions};
use ibc_pipeline::nalgebra::Isometry3;
use ibc_pipeline::sfm::{MapOptions, SelfCalibrationOptions};
use ibc_pipeline::sim::{DetectionOptions, NoiseOptions, Scenario, SimulatedWorld};

#[test]
fn every_options_struct_is_one_expression() {
    let options = CalibrationOptions {
        vocabulary: VocabularyOptions {
            seed: 3,
            ..Default::default()
        },
        localization: LocalizationOptions {
            candidates: 12,
            pose: AbsolutePoseOptions {
                max_error_px: 1.5,
                ..default_pose_options()
            },
            ..Default::default()
        },
        frame_sets: FrameSetOptions {
            min_motion_m: 0.2,
            ..Default::default()
        },
        initialization: InitializationOptions {
            max_sets: 50,
            ..Default::default()
        },
        refinement: RefinementOptions {
            cauchy_scale_px: 1.5,
            ..Default::default()
        },
        hand_eye: HandEyeOptions {
            pairing: Pairing::Window { size: 4 },
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(options.validate().is_ok());
    assert_eq!(options.localization.pose.ransac.min_inliers, 25);
    let intrinsics = IntrinsicsOptions {
        kb_init: KbInitOptions {
            use_columns: false,
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(!intrinsics.kb_init.use_columns);
    let boards = BoardSimulationOptions {
        views: 8,
        ..BoardSimulationOptions::for_model(IntrinsicModel::KannalaBrandt)
    };
    assert_eq!(boards.views, 8);
    let noise = NoiseOptions {
        pixel_sigma_px: 0.3,
        ..Default::default()
    };
    let detection = DetectionOptions {
        max_range_m: 25.0,
        ..Default::default()
    };
    assert!(noise.pixel_sigma_px < detection.max_range_m);
    let map = MapOptions {
        refine_extrinsics: true,
        reconstruction: SelfCalibrationOptions {
            max_rounds: 3,
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(map.refine_extrinsics && map.reconstruction.max_rounds == 3);
    let colmap = ColmapLogOptions {
        seconds_per_unit: 1e-9,
        ..Default::default()
    };
    assert!(colmap.rig_id.is_none());
}

#[test]
fn a_calibration_in_a_few_lines_with_the_reexported_types() -> ibc_pipeline::Result<()> {
    let world =
        SimulatedWorld::simulate(&Scenario::builtin("garage").unwrap().with_scale(0.05)).unwrap();
    let calibration = calibrate(&world.map, &world.log, &world.map_rig, &Default::default())?;
    let front: &Isometry3<f64> = &calibration.rig_from_camera[0];
    assert_eq!(front.translation.vector.norm(), 0.0);
    assert_eq!(
        calibration.quality.status(),
        ibc_pipeline::calib::Status::Ok
    );
    Ok(())
}
