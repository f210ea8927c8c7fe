//! CamOdoCal rig folders: `extrinsic.txt` and a YAML per camera, as CamOdoCal's
//! `CameraSystem` reads and writes them (and its intrinsic calibration tool names them).

use std::path::{Path, PathBuf};

use crate::camera::Camera;
use crate::camodocal;
use crate::error::CameraFileError;
use crate::io::{IoError, write_atomically};
use crate::rig::{Rig, RigCamera};

impl Rig {
    /// Read a CamOdoCal rig directory: [`EXTRINSIC_FILE_NAME`](camodocal::EXTRINSIC_FILE_NAME)
    /// and, for every camera named there, its YAML:
    /// [`calib_file_name`](camodocal::calib_file_name) (`<name>_calib.yaml`, CamOdoCal's
    /// `CameraSystem`) or [`camera_calib_file_name`](camodocal::camera_calib_file_name)
    /// (`<name>_camera_calib.yaml`, CamOdoCal's intrinsic calibration tool). When both exist
    /// they must describe the same camera. A YAML whose `camera_name` is empty (as
    /// `CameraSystem` writes a camera it lists as `camera_<i>`) takes its name from
    /// `extrinsic.txt`. Every camera must be plausible ([`Camera::check_plausible`]).
    ///
    /// # Errors
    /// [`CameraFileError`] naming the file at fault (wrapped in [`CameraFileError::InFile`] unless the
    /// error names it already): a missing, unreadable or malformed file, a camera with no YAML
    /// under either name, a YAML whose non-empty `camera_name` differs from its name in
    /// `extrinsic.txt`, duplicate names or names with a path separator;
    /// [`CameraFileError::ConflictingCameraFiles`] when the two YAML files of a camera disagree.
    pub fn read_camodocal_dir(dir: impl AsRef<Path>) -> Result<Self, CameraFileError> {
        let dir = dir.as_ref();
        let extrinsic = dir.join(camodocal::EXTRINSIC_FILE_NAME);
        let poses = camodocal::parse_extrinsics(&crate::yaml::read_text(&extrinsic)?)
            .map_err(|e| e.in_file(&extrinsic))?;
        let mut cameras = Vec::with_capacity(poses.len());
        for (name, rig_from_camera) in poses {
            if name.contains(['/', '\\']) {
                return Err(CameraFileError::Rig {
                    message: format!("camera name `{name}` contains a path separator"),
                }
                .in_file(&extrinsic));
            }
            let camera = read_camodocal_camera(dir, &extrinsic, &name)?;
            cameras.push(RigCamera::new(name, camera, rig_from_camera));
        }
        let rig = Self { cameras };
        rig.check_names().map_err(|e| e.in_file(&extrinsic))?;
        Ok(rig)
    }

    /// Write a CamOdoCal rig directory (created if needed) in CamOdoCal `CameraSystem`'s
    /// layout, so its `readFromDirectory` reads it: [`calib_file_name`](camodocal::calib_file_name)
    /// (`<name>_calib.yaml`) per camera, then
    /// [`EXTRINSIC_FILE_NAME`](camodocal::EXTRINSIC_FILE_NAME) (five lines per camera), each
    /// atomically. A `<name>_camera_calib.yaml` already in the folder is left alone; if it
    /// describes another camera, [`read_camodocal_dir`](Self::read_camodocal_dir) will refuse
    /// the folder as ambiguous.
    ///
    /// # Errors
    /// [`CameraFileError::Rig`] for duplicate or empty names, or names with white space (which
    /// `CameraSystem` would cut at the first word) or a path separator; [`CameraFileError::Io`].
    pub fn write_camodocal_dir(&self, dir: impl AsRef<Path>) -> Result<(), CameraFileError> {
        self.check_names()?;
        if let Some(c) = self.cameras.iter().find(|c| {
            c.name
                .contains(|ch: char| ch.is_whitespace() || ch == '/' || ch == '\\')
        }) {
            return Err(CameraFileError::Rig {
                message: format!(
                    "camera name `{}` has white space or a path separator, which a CamOdoCal \
                     rig folder cannot hold",
                    c.name
                ),
            });
        }
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| IoError::os(dir, e))?;
        for c in &self.cameras {
            camodocal::write_camera(
                dir.join(camodocal::calib_file_name(&c.name)),
                &c.name,
                &c.camera,
            )?;
        }
        let text = camodocal::format_extrinsics(
            self.cameras
                .iter()
                .map(|c| (c.name.as_str(), &c.rig_from_camera)),
        );
        Ok(write_atomically(
            &dir.join(camodocal::EXTRINSIC_FILE_NAME),
            text.as_bytes(),
        )?)
    }
}

/// The camera `name` of a CamOdoCal rig folder, from `<name>_calib.yaml` or
/// `<name>_camera_calib.yaml` (both, if both exist, describing the same camera).
fn read_camodocal_camera(
    dir: &Path,
    extrinsic: &Path,
    name: &str,
) -> Result<Camera, CameraFileError> {
    let candidates = [
        dir.join(camodocal::calib_file_name(name)),
        dir.join(camodocal::camera_calib_file_name(name)),
    ];
    let mut found: Vec<(PathBuf, Camera)> = Vec::with_capacity(2);
    for path in candidates {
        match std::fs::metadata(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(source) => return Err(IoError::os(&path, source).into()),
            Ok(_) => {}
        }
        let named = camodocal::read_camera(&path)?;
        // CamOdoCal writes an unnamed camera with an empty `camera_name`.
        if !named.name.is_empty() && named.name != name {
            return Err(CameraFileError::Rig {
                message: format!(
                    "the file names its camera `{}`, but {} names it `{name}`",
                    named.name,
                    camodocal::EXTRINSIC_FILE_NAME
                ),
            }
            .in_file(&path));
        }
        found.push((path, named.camera));
    }
    match <[_; 2]>::try_from(found) {
        Ok([(first, a), (second, b)]) => {
            if a == b {
                Ok(a)
            } else {
                Err(CameraFileError::ConflictingCameraFiles {
                    camera: name.to_owned(),
                    first,
                    second,
                })
            }
        }
        Err(mut found) => found.pop().map(|(_, c)| c).ok_or_else(|| {
            CameraFileError::Rig {
                message: format!(
                    "camera `{name}` has no file next to it: neither {} nor {} exists",
                    camodocal::calib_file_name(name),
                    camodocal::camera_calib_file_name(name)
                ),
            }
            .in_file(extrinsic)
        }),
    }
}
