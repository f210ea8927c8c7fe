//! Matching the camera file's cameras to the rig log's, by name.
//!
//! A CamOdoCal folder names its cameras, and so does the log: when the two sets of names are
//! the same, the file's cameras are taken in the log's order, whatever the file's order (a
//! CamOdoCal `extrinsic.txt` listing front, right, rear, left against a log of front, left,
//! rear, right is matched correctly). A Kalibr camchain carries no names (its cameras read
//! back as `cam0`, `cam1`, ...), nor does a CamOdoCal rig written without names (`camera_0`,
//! `camera_1`, ...): such files are matched by order, and the calibration says so
//! ([`CameraMatching::ByOrder`]). Any other disagreement is an error that lists both sets of
//! names.

use ibc_camera_models::Rig;

use super::error::CalibrationError;

/// How the camera file's cameras were matched to the log's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CameraMatching {
    /// By name: the file and the log name the same cameras.
    #[default]
    ByName,
    /// By order, because the file carries no names (`cam0, cam1, ...` of a Kalibr camchain,
    /// or `camera_0, camera_1, ...` of an unnamed CamOdoCal rig).
    ByOrder,
}

/// True when the names are placeholders `<prefix><i>` in order, as written by tools that keep
/// no camera names.
fn unnamed(rig: &Rig) -> bool {
    ["cam", "camera_"].iter().any(|prefix| {
        rig.cameras
            .iter()
            .enumerate()
            .all(|(i, c)| c.name.strip_prefix(prefix) == Some(i.to_string().as_str()))
    })
}

/// The camera file's cameras in the log's order (see the module docs), and how they were
/// matched.
///
/// # Errors
/// [`CalibrationError::CameraCountMismatch`] when the counts differ,
/// [`CalibrationError::CameraNamesMismatch`] when the file names cameras the log does not
/// have (or not all it has).
pub fn match_cameras(
    rig: &Rig,
    log_names: &[String],
) -> Result<(Rig, CameraMatching), CalibrationError> {
    if rig.cameras.len() != log_names.len() {
        return Err(CalibrationError::CameraCountMismatch {
            cameras: rig.cameras.len(),
            log_cameras: log_names.len(),
        });
    }
    let by_name: Option<Vec<_>> = log_names
        .iter()
        .map(|name| rig.camera(name).cloned())
        .collect();
    match by_name {
        Some(cameras) => Ok((Rig::new(cameras), CameraMatching::ByName)),
        None if unnamed(rig) => Ok((rig.clone(), CameraMatching::ByOrder)),
        None => Err(CalibrationError::CameraNamesMismatch {
            file: rig.cameras.iter().map(|c| c.name.clone()).collect(),
            log: log_names.to_vec(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ibc_camera_models::{Camera, KannalaBrandt, RigCamera};
    use nalgebra::{Isometry3, Vector3};

    fn rig(names: &[&str]) -> Rig {
        let camera = Camera::from(
            KannalaBrandt::new(640, 480, [0.0, 0.0, 0.0, 0.0, 300.0, 300.0, 320.0, 240.0]).unwrap(),
        );
        Rig::new(
            names
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    let pose = Isometry3::new(Vector3::x() * i as f64, Vector3::zeros());
                    RigCamera::new(*n, camera.clone(), pose)
                })
                .collect(),
        )
    }

    fn names(n: &[&str]) -> Vec<String> {
        n.iter().map(|s| (*s).to_owned()).collect()
    }

    #[test]
    fn names_decide_the_order() {
        let file = rig(&["front", "right", "rear", "left"]);
        let log = names(&["front", "left", "rear", "right"]);
        let (matched, how) = match_cameras(&file, &log).unwrap();
        assert_eq!(how, CameraMatching::ByName);
        let order: Vec<&str> = matched.cameras.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(order, ["front", "left", "rear", "right"]);
        // `left` keeps its own extrinsic (file index 3).
        assert_eq!(matched.cameras[1].rig_from_camera.translation.x, 3.0);
    }

    #[test]
    fn unnamed_files_are_matched_by_order() {
        let log = names(&["front", "left"]);
        for placeholders in [["cam0", "cam1"], ["camera_0", "camera_1"]] {
            let (matched, how) = match_cameras(&rig(&placeholders), &log).unwrap();
            assert_eq!(how, CameraMatching::ByOrder);
            assert_eq!(matched.cameras[1].name, placeholders[1]);
        }
        // Placeholders out of order are names like any other.
        assert!(match_cameras(&rig(&["cam1", "cam0"]), &log).is_err());
    }

    #[test]
    fn a_name_mismatch_lists_both_sets() {
        let e = match_cameras(&rig(&["front", "back"]), &names(&["front", "left"])).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("front, back") && m.contains("front, left"),
            "{m}"
        );
        assert!(matches!(
            match_cameras(&rig(&["front"]), &names(&["front", "left"])),
            Err(CalibrationError::CameraCountMismatch { .. })
        ));
    }
}
