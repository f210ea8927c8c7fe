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
