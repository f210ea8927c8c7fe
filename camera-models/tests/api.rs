//! The crate as a user outside it calls it: the re-exported `nalgebra`, the `Result` alias,
//! and the `io` module every ibc crate reads and writes files through.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use ibc_camera_models::io::{IoError, read_bytes, read_text, write_atomically};
use ibc_camera_models::nalgebra::Vector3;
use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, Result};

fn fisheye() -> Result<Camera> {
    Ok(KannalaBrandt::new(640, 480, [0.0, 0.0, 0.0, 0.0, 200.0, 200.0, 319.5, 239.5])?.into())
}

#[test]
fn a_camera_through_the_reexported_nalgebra_and_the_result_alias() {
    let camera = fisheye().unwrap();
    let pixel = camera.project(&Vector3::new(0.0, 0.0, 1.0)).unwrap();
    assert_eq!(pixel.x, 319.5);
}

#[test]
fn files_are_written_atomically_and_read_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("note.txt");
    write_atomically(&path, b"hello").unwrap();
    assert_eq!(read_text(&path, 5).unwrap(), "hello");
    assert!(matches!(
        read_bytes(&path, 4),
        Err(IoError::TooLarge {
            size: 5,
            limit: 4,
            ..
        })
    ));
    assert!(matches!(
        read_bytes(dir.path(), 4),
        Err(IoError::NotRegularFile { .. })
    ));
    let missing = read_bytes(&dir.path().join("absent"), 4).unwrap_err();
    assert_eq!(missing.path(), dir.path().join("absent"));
    // Nothing but the file itself is left in the folder.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn focal_length_and_principal_point_indices_name_those_parameters_in_every_model() {
    use ibc_camera_models::{PinholeRadtan, Unified};
    let cameras: [Camera; 3] = [
        fisheye().unwrap(),
        PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0])
            .unwrap()
            .into(),
        Unified::new(
            640,
            480,
            [0.8, 0.0, 0.0, 0.0, 0.0, 700.0, 700.0, 320.0, 240.0],
        )
        .unwrap()
        .into(),
    ];
    let expected = [
        (["mu", "mv"], ["u0", "v0"]),
        (["fx", "fy"], ["cx", "cy"]),
        (["gamma1", "gamma2"], ["u0", "v0"]),
    ];
    for (camera, (focal, centre)) in cameras.iter().zip(expected) {
        let names = camera.param_names();
        assert_eq!(camera.focal_length_indices().map(|i| names[i]), focal);
        assert_eq!(camera.principal_point_indices().map(|i| names[i]), centre);
    }
}
