//! CamOdoCal files: the per-camera YAML and the rig's `extrinsic.txt`.
//!
//! File names. CamOdoCal's `CameraSystem` (`readFromDirectory` / `writeToDirectory`) keeps a
//! rig in a folder: [`EXTRINSIC_FILE_NAME`] (`extrinsic.txt`) and, for each camera name listed
//! there, [`calib_file_name`] (`<name>_calib.yaml`). A camera without a name is listed and
//! filed as `camera_<i>` (`camera_<i>_calib.yaml`), and its YAML's `camera_name` is then
//! empty. CamOdoCal's intrinsic calibration tool writes [`camera_calib_file_name`]
//! (`<name>_camera_calib.yaml`).
//! [`Rig::read_camodocal_dir`](crate::Rig::read_camodocal_dir) reads either name;
//! [`Rig::write_camodocal_dir`](crate::Rig::write_camodocal_dir) writes `CameraSystem`'s.
//!
//! The camera YAML is OpenCV `FileStorage` output: a `%YAML:1.0` line (not a valid YAML 1.2
//! directive; the reader drops it), `---`, then:
//!
//! ```text
//! model_type: KANNALA_BRANDT | MEI | PINHOLE      (case-insensitive)
//! camera_name: <string>
//! image_width: <int>
//! image_height: <int>
//! mirror_parameters:       xi                      (MEI)
//! distortion_parameters:   k1, k2, p1, p2          (MEI, PINHOLE)
//! projection_parameters:   k2, k3, k4, k5, mu, mv, u0, v0   (KANNALA_BRANDT)
//!                          gamma1, gamma2, u0, v0           (MEI)
//!                          fx, fy, cx, cy                   (PINHOLE)
//! ```
//!
//! Kannala-Brandt's k2..k5 are accepted under either block (some third-party converters put
//! them under `distortion_parameters`). A missing key is an error, never a zero. Numbers are
//! written with 17 significant digits.
//!
//! `extrinsic.txt` lists, per camera, its name, three rows of four numbers (the top of the 4x4
//! matrix of CamOdoCal's "global camera pose", which maps camera coordinates into the rig
//! frame: our `rig_from_camera`), and a blank line. `CameraSystem` reads it by counting lines
//! in fives (name, three rows, one line skipped) and takes the first word of the name line, so
//! the writer emits exactly those five lines per camera; the reader here also skips extra
//! blank lines.
//!
//! Reading is bounded (regular files of at most [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES), no
//! YAML aliases), and a camera read from a file must be plausible
//! ([`Camera::check_plausible`]). Errors of the readers that take a path name the file
//! ([`CameraFileError::InFile`]).

use std::path::Path;

use nalgebra::{Isometry3, Matrix3, Vector3};

use crate::camera::Camera;
use crate::error::{CameraFileError, ParameterError};
use crate::model::CameraModel;
use crate::yaml::{self, fmt_f64, fmt_str};
use crate::{KannalaBrandt, PinholeRadtan, Unified};

/// The rig file of a CamOdoCal rig folder: `extrinsic.txt`.
pub const EXTRINSIC_FILE_NAME: &str = "extrinsic.txt";

/// The file name CamOdoCal's `CameraSystem` gives a camera's YAML in a rig folder:
/// `<name>_calib.yaml` (what [`Rig::write_camodocal_dir`](crate::Rig::write_camodocal_dir)
/// writes).
pub fn calib_file_name(camera_name: &str) -> String {
    format!("{camera_name}_calib.yaml")
}

/// The file name CamOdoCal's intrinsic calibration tool gives a camera's YAML:
/// `<name>_camera_calib.yaml` (read in a rig folder too).
pub fn camera_calib_file_name(camera_name: &str) -> String {
    format!("{camera_name}_camera_calib.yaml")
}

/// A camera with the name its file gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedCamera {
    /// `camera_name`.
    pub name: String,
    /// The model.
    pub camera: Camera,
}

fn params_error(name: &str) -> impl FnOnce(ParameterError) -> CameraFileError + '_ {
    move |source| CameraFileError::Parameters {
        camera: name.to_owned(),
        source,
    }
}

/// Parse a CamOdoCal camera YAML and check that the camera is plausible.
///
/// # Errors
/// [`CameraFileError`] for malformed YAML (or YAML with aliases), a missing or mistyped key, an
/// unknown model, parameters that are not a valid camera
/// ([`CameraFileError::Parameters`]) or not a plausible one ([`CameraFileError::Implausible`]).
pub fn parse_camera(text: &str) -> Result<NamedCamera, CameraFileError> {
    let doc = yaml::parse(text)?;
    let model = yaml::string(yaml::get(&doc, "", "model_type")?, "model_type")?;
    let name = yaml::string(yaml::get(&doc, "", "camera_name")?, "camera_name")?;
    let width = yaml::unsigned(yaml::get(&doc, "", "image_width")?, "image_width")?;
    let height = yaml::unsigned(yaml::get(&doc, "", "image_height")?, "image_height")?;
    let block = |key: &'static str| yaml::get(&doc, "", key);
    let camera: Camera = match model.to_ascii_uppercase().as_str() {
        "KANNALA_BRANDT" => {
            let proj = block("projection_parameters")?;
            // k2..k5 under projection_parameters (CamOdoCal) or distortion_parameters.
            let k_block = if yaml::get_opt(proj, "k2").is_some() {
                ("projection_parameters", proj)
            } else if let Some(dist) = yaml::get_opt(&doc, "distortion_parameters") {
                ("distortion_parameters", dist)
            } else {
                ("projection_parameters", proj)
            };
            let [k1, k2, k3, k4] = numbers_in(k_block.1, k_block.0, ["k2", "k3", "k4", "k5"])?;
            let [mu, mv, u0, v0] =
                numbers_in(proj, "projection_parameters", ["mu", "mv", "u0", "v0"])?;
            KannalaBrandt::new(width, height, [k1, k2, k3, k4, mu, mv, u0, v0])
                .map_err(params_error(&name))?
                .into()
        }
        "MEI" => {
            let [xi] = numbers_in(block("mirror_parameters")?, "mirror_parameters", ["xi"])?;
            let [k1, k2, p1, p2] = radtan_block(&doc)?;
            let [g1, g2, u0, v0] = numbers_in(
                block("projection_parameters")?,
                "projection_parameters",
                ["gamma1", "gamma2", "u0", "v0"],
            )?;
            Unified::new(width, height, [xi, k1, k2, p1, p2, g1, g2, u0, v0])
                .map_err(params_error(&name))?
                .into()
        }
        "PINHOLE" => {
            let [k1, k2, p1, p2] = radtan_block(&doc)?;
            let [fx, fy, cx, cy] = numbers_in(
                block("projection_parameters")?,
                "projection_parameters",
                ["fx", "fy", "cx", "cy"],
            )?;
            PinholeRadtan::new(width, height, [k1, k2, p1, p2, fx, fy, cx, cy])
                .map_err(params_error(&name))?
                .into()
        }
        "SCARAMUZZA" | "PINHOLE_FULL" => {
            return Err(CameraFileError::UnsupportedModel {
                name: model,
                supported: "KANNALA_BRANDT, MEI, PINHOLE",
            });
        }
        _ => return Err(CameraFileError::UnknownModel { name: model }),
    };
    camera
        .check_plausible()
        .map_err(|source| CameraFileError::Implausible {
            camera: name.clone(),
            source,
        })?;
    Ok(NamedCamera { name, camera })
}

/// The numbers under `keys` in the block `node` (named `path`).
fn numbers_in<const N: usize>(
    node: &yaml_rust2::Yaml,
    path: &str,
    keys: [&str; N],
) -> Result<[f64; N], CameraFileError> {
    let mut out = [0.0; N];
    for (o, key) in out.iter_mut().zip(keys) {
        *o = yaml::number_at(node, path, key)?;
    }
    Ok(out)
}

/// `distortion_parameters: k1, k2, p1, p2`.
fn radtan_block(doc: &yaml_rust2::Yaml) -> Result<[f64; 4], CameraFileError> {
    let node = yaml::get(doc, "", "distortion_parameters")?;
    numbers_in(node, "distortion_parameters", ["k1", "k2", "p1", "p2"])
}

/// Format a camera as CamOdoCal YAML (17 significant digits).
pub fn format_camera(name: &str, camera: &Camera) -> String {
    let mut s = String::from("%YAML:1.0\n---\n");
    let model = match camera {
        Camera::KannalaBrandt(_) => "KANNALA_BRANDT",
        Camera::Unified(_) => "MEI",
        Camera::PinholeRadtan(_) => "PINHOLE",
    };
    s.push_str(&format!("model_type: {model}\n"));
    s.push_str(&format!("camera_name: {}\n", fmt_str(name)));
    s.push_str(&format!("image_width: {}\n", camera.width()));
    s.push_str(&format!("image_height: {}\n", camera.height()));
    let block = |s: &mut String, title: &str, entries: &[(&str, f64)]| {
        s.push_str(title);
        s.push_str(":\n");
        for (k, v) in entries {
            s.push_str(&format!("   {k}: {}\n", fmt_f64(*v)));
        }
    };
    match camera {
        Camera::KannalaBrandt(c) => {
            let [k1, k2, k3, k4, mu, mv, u0, v0] = c.params_array();
            block(
                &mut s,
                "projection_parameters",
                &[
                    ("k2", k1),
                    ("k3", k2),
                    ("k4", k3),
                    ("k5", k4),
                    ("mu", mu),
                    ("mv", mv),
                    ("u0", u0),
                    ("v0", v0),
                ],
            );
        }
        Camera::Unified(c) => {
            let [xi, k1, k2, p1, p2, g1, g2, u0, v0] = c.params_array();
            block(&mut s, "mirror_parameters", &[("xi", xi)]);
            block(
                &mut s,
                "distortion_parameters",
                &[("k1", k1), ("k2", k2), ("p1", p1), ("p2", p2)],
            );
            block(
                &mut s,
                "projection_parameters",
                &[("gamma1", g1), ("gamma2", g2), ("u0", u0), ("v0", v0)],
            );
        }
        Camera::PinholeRadtan(c) => {
            let [k1, k2, p1, p2, fx, fy, cx, cy] = c.params_array();
            block(
                &mut s,
                "distortion_parameters",
                &[("k1", k1), ("k2", k2), ("p1", p1), ("p2", p2)],
            );
            block(
                &mut s,
                "projection_parameters",
                &[("fx", fx), ("fy", fy), ("cx", cx), ("cy", cy)],
            );
        }
    }
    s
}

/// Read a CamOdoCal camera YAML file (a regular file of at most
/// [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES)).
///
/// # Errors
/// [`CameraFileError::Io`] (not a regular file, too large, not text, or the
/// operating system's error), or an error of
/// [`parse_camera`] wrapped in [`CameraFileError::InFile`] with the path.
pub fn read_camera(path: impl AsRef<Path>) -> Result<NamedCamera, CameraFileError> {
    let path = path.as_ref();
    parse_camera(&yaml::read_text(path)?).map_err(|e| e.in_file(path))
}

/// Write a CamOdoCal camera YAML file atomically.
///
/// # Errors
/// [`CameraFileError::Io`].
pub fn write_camera(
    path: impl AsRef<Path>,
    name: &str,
    camera: &Camera,
) -> Result<(), CameraFileError> {
    yaml::write_atomic(path.as_ref(), &format_camera(name, camera))
}

/// Parse `extrinsic.txt`: `(camera name, rig_from_camera)` in file order.
///
/// # Errors
/// [`CameraFileError::Malformed`] (with the line) for a row that is not four finite numbers, a
/// truncated entry, or a rotation that is not a rotation (|R^T R - I| > 1e-6 or det < 0).
pub fn parse_extrinsics(text: &str) -> Result<Vec<(String, Isometry3<f64>)>, CameraFileError> {
    let mut out = Vec::new();
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    while let Some((name_line, name)) = lines.next() {
        let mut m = [[0.0; 4]; 3];
        for row in &mut m {
            let Some((line, text)) = lines.next() else {
                return Err(CameraFileError::Malformed {
                    line: name_line,
                    message: format!("camera `{name}`: expected three rows of four numbers"),
                });
            };
            let values: Vec<&str> = text.split_whitespace().collect();
            if values.len() != 4 {
                return Err(CameraFileError::Malformed {
                    line,
                    message: format!("expected four numbers, found {} fields", values.len()),
                });
            }
            for (slot, v) in row.iter_mut().zip(&values) {
                *slot = v
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| CameraFileError::Malformed {
                        line,
                        message: format!("`{v}` is not a finite number"),
                    })?;
            }
        }
        let pose = isometry_from_rows(&m).map_err(|message| CameraFileError::Malformed {
            line: name_line,
            message: format!("camera `{name}`: {message}"),
        })?;
        out.push((name.to_owned(), pose));
    }
    Ok(out)
}

/// Format `extrinsic.txt` (17 significant digits): per camera, exactly five lines (the name,
/// three rows of four numbers, a blank line), as `CameraSystem`'s line-counting reader expects.
pub fn format_extrinsics<'a>(
    poses: impl IntoIterator<Item = (&'a str, &'a Isometry3<f64>)>,
) -> String {
    let mut s = String::new();
    for (name, pose) in poses {
        s.push_str(name);
        s.push('\n');
        let h = pose.to_homogeneous();
        for r in 0..3 {
            let row: Vec<String> = (0..4).map(|c| fmt_f64(h[(r, c)])).collect();
            s.push_str(&row.join(" "));
            s.push('\n');
        }
        s.push('\n');
    }
    s
}

/// A rigid transform from the top three rows of a 4x4 matrix. The rotation must be orthonormal
/// within 1e-6 with determinant +1; it is then projected exactly onto the rotations.
pub(crate) fn isometry_from_rows(m: &[[f64; 4]; 3]) -> Result<Isometry3<f64>, String> {
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    let t = Vector3::new(m[0][3], m[1][3], m[2][3]);
    if !(r.iter().all(|x| x.is_finite()) && t.iter().all(|x| x.is_finite())) {
        return Err("the transform has non-finite entries".to_owned());
    }
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > 1e-6 || r.determinant() <= 0.0 {
        return Err(format!(
            "the rotation block is not a rotation (|R^T R - I| = {err:.3e}, det = {:.6})",
            r.determinant()
        ));
    }
    // The nearest rotation (polar decomposition R = U V^T), so files written with fewer digits
    // still give an exact rotation.
    let nearest = r
        .try_svd(true, true, 1e-15, 200)
        .and_then(|svd| Some(svd.u? * svd.v_t?))
        .filter(|q| q.determinant() > 0.0)
        .unwrap_or(r);
    let rot = nalgebra::Rotation3::from_matrix_unchecked(nearest);
    Ok(Isometry3::from_parts(
        t.into(),
        nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_non_rotations() {
        let m = [
            [2.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        assert!(isometry_from_rows(&m).is_err());
        let reflect = [
            [-1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ];
        assert!(isometry_from_rows(&reflect).is_err());
    }
}
