//! Bad input to `calibrate_intrinsics` gives typed errors, never a wrong calibration or a
//! panic: degenerate views, too few images or corners, corners outside the image or off the
//! board, malformed corner files, an unknown model.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod intrinsics_common;

use ibc_pipeline::intrinsics::simulate::BoardSimulationOptions;
use ibc_pipeline::intrinsics::{
    CornerSet, ImageStatus, IntrinsicModel, IntrinsicsError, IntrinsicsOptions,
    MIN_CORNERS_PER_IMAGE, MIN_IMAGES, calibrate_intrinsics, normal_spread_deg,
};
use intrinsics_common::{simulated, simulated_with};

const MODELS: [IntrinsicModel; 3] = [
    IntrinsicModel::KannalaBrandt,
    IntrinsicModel::PinholeRadtan,
    IntrinsicModel::Unified,
];

fn run(corners: &CornerSet, model: IntrinsicModel) -> Result<(), IntrinsicsError> {
    let target = corners.board.unwrap();
    calibrate_intrinsics(corners, &target, model, &IntrinsicsOptions::default()).map(|_| ())
}

#[test]
fn boards_all_parallel_to_the_image_are_degenerate() {
    for model in MODELS {
        for (rows, cols) in [(6, 9), (20, 20)] {
            let options = BoardSimulationOptions {
                parallel_to_image: true,
                seed: 3,
                ..BoardSimulationOptions::for_model(model)
            };
            let sim = simulated_with(model, rows, cols, &options);
            // The simulator really did place them parallel.
            assert!(normal_spread_deg(&sim.camera_from_board) < 1e-9);
            let err = run(&sim.corners, model).unwrap_err();
            assert!(
                matches!(err, IntrinsicsError::DegenerateViews { .. }),
                "{model:?} {rows}x{cols}: {err}"
            );
            assert!(err.to_string().contains("parallel"), "{err}");
        }
    }
}

#[test]
fn too_few_images_or_corners() {
    for model in MODELS {
        let sim = simulated(model, 6, 9, 1);
        let mut few = sim.corners.clone();
        few.images.truncate(MIN_IMAGES - 1);
        assert!(matches!(
            run(&few, model),
            Err(IntrinsicsError::TooFewImages { got, needed: MIN_IMAGES }) if got == MIN_IMAGES - 1
        ));
        // An image with too few corners (a detector that failed on it) is skipped, named in
        // the result, and the others calibrate.
        let mut sparse = sim.corners.clone();
        sparse.images[4].corners.truncate(MIN_CORNERS_PER_IMAGE - 1);
        let target = sparse.board.unwrap();
        let c =
            calibrate_intrinsics(&sparse, &target, model, &IntrinsicsOptions::default()).unwrap();
        assert_eq!(c.per_image[4].name, "view_004");
        assert_eq!(c.per_image[4].status, ImageStatus::TooFewCorners);
        assert!(c.per_image[4].residuals.is_empty() && c.camera_from_board[4].is_none());
        assert!(
            c.per_image
                .iter()
                .enumerate()
                .all(|(i, e)| i == 4 || e.status == ImageStatus::Used)
        );
        assert!(c.warnings.is_empty(), "{:?}", c.warnings);
        // Too few images left: an error that counts the usable ones.
        for image in &mut sparse.images[MIN_IMAGES - 1..] {
            image.corners.truncate(MIN_CORNERS_PER_IMAGE - 1);
        }
        assert!(matches!(
            run(&sparse, model),
            Err(IntrinsicsError::TooFewImages { got, needed: MIN_IMAGES }) if got == MIN_IMAGES - 1
        ));
    }
}

#[test]
fn corners_outside_the_image_or_off_the_board() {
    let model = IntrinsicModel::KannalaBrandt;
    let sim = simulated(model, 6, 9, 2);
    let mut outside = sim.corners.clone();
    outside.images[2].corners[3].u = f64::from(outside.width) + 4.0;
    let err = run(&outside, model).unwrap_err();
    assert!(
        matches!(&err, IntrinsicsError::CornerOutsideImage { image, .. } if image == "view_002"),
        "{err}"
    );
    let mut nan = sim.corners.clone();
    nan.images[0].corners[0].v = f64::NAN;
    assert!(matches!(
        run(&nan, model),
        Err(IntrinsicsError::CornerOutsideImage { .. })
    ));
    let mut off = sim.corners.clone();
    off.images[1].corners[0].row = 6;
    assert!(matches!(
        run(&off, model),
        Err(IntrinsicsError::CornerNotOnBoard { row: 6, .. })
    ));
}

#[test]
fn corner_files_round_trip_and_malformed_ones_are_named() {
    let sim = simulated(IntrinsicModel::KannalaBrandt, 6, 9, 4);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("corners.json");
    sim.corners.write(&path).unwrap();
    assert_eq!(CornerSet::read(&path).unwrap(), sim.corners);

    let text = std::fs::read_to_string(&path).unwrap();
    let cut = &text[..text.len() / 2];
    std::fs::write(&path, cut).unwrap();
    let err = CornerSet::read(&path).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, IntrinsicsError::CornerJson { .. }));
    assert!(
        message.contains("corners.json") && message.contains("line"),
        "{message}"
    );
    assert!(!message.contains('\n'), "{message}");

    let missing = CornerSet::read(dir.path().join("absent.json")).unwrap_err();
    assert!(matches!(missing, IntrinsicsError::Io(_)), "{missing}");
}

#[test]
fn models_are_parsed_by_name_and_an_unknown_one_is_refused() {
    for (name, model) in [
        ("kb", IntrinsicModel::KannalaBrandt),
        ("pinhole", IntrinsicModel::PinholeRadtan),
        ("mei", IntrinsicModel::Unified),
        ("unified", IntrinsicModel::Unified),
        ("omni", IntrinsicModel::Unified),
    ] {
        assert_eq!(name.parse::<IntrinsicModel>().unwrap(), model);
    }
    let err = "fisheye".parse::<IntrinsicModel>().unwrap_err();
    assert!(
        matches!(err, IntrinsicsError::InvalidInput(_)) && err.to_string().contains("`fisheye`"),
        "{err}"
    );
}
