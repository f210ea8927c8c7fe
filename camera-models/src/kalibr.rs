//! Kalibr camchain YAML (`camchain.yaml`, `camchain-imucam.yaml`).
//!
//! One block per camera, `cam0`, `cam1`, ... in chain order:
//!
//! ```text
//! camN:
//!   camera_model: pinhole | omni              (ds, eucm, ... are refused as unsupported)
//!   intrinsics: [fu, fv, pu, pv]              ([xi, fu, fv, pu, pv] for omni)
//!   distortion_model: radtan | equidistant | none
//!   distortion_coeffs: [k1, k2, r1, r2] | [k1, k2, k3, k4] | []
//!   resolution: [width, height]
//!   rostopic: /topic                          (optional, kept)
//!   cam_overlaps: [i, j, ...]                 (optional, kept)
//!   T_cn_cnm1: 4x4 rows                       (camN > 0: maps cam(N-1) coordinates into camN)
//!   T_cam_imu: 4x4 rows                       (camchain-imucam, optional, kept: maps IMU
//!                                              coordinates into the camera)
//!   timeshift_cam_imu: seconds                (camchain-imucam, optional, kept:
//!                                              t_imu = t_cam + shift)
//! ```
//!
//! `pinhole` + `radtan` (or `none`) is [`PinholeRadtan`], `pinhole` + `equidistant` is
//! [`KannalaBrandt`] (Kalibr applies the equidistant polynomial to atan of the z = 1 radius,
//! which is the same map for z > 0), `omni` + `radtan` (or `none`) is [`Unified`]. `T_cam_imu`
//! is read into [`RigCamera::camera_from_imu`] (a rigid transform, checked as `T_cn_cnm1` is)
//! and `timeshift_cam_imu` into [`RigCamera::timeshift_cam_imu_s`] (a finite number); both are
//! written back when present. Other keys are ignored. Every camera must be plausible
//! ([`Camera::check_plausible`]); the file is read bounded (a regular file of at most
//! [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES), no YAML aliases), and
//! [`Rig::read_kalibr`] names the file in its errors ([`CameraFileError::InFile`]).
//!
//! Reading chains `T_cn_cnm1` into `rig_from_camera` with cam0 as the rig frame. Writing stores
//! only relative poses (`camN_from_rig * rig_from_cam(N-1)`), so a rig whose frame is not cam0
//! reads back re-based on cam0 (relative poses unchanged). Camera names are not stored: they
//! read back as `cam0`, `cam1`, ...

use std::path::Path;

use nalgebra::Isometry3;
use yaml_rust2::Yaml;

use crate::camera::Camera;
use crate::camodocal::isometry_from_rows;
use crate::error::CameraFileError;
use crate::model::CameraModel;
use crate::rig::{Rig, RigCamera};
use crate::yaml::{self, fmt_f64, fmt_str};
use crate::{KannalaBrandt, PinholeRadtan, Unified};

const SUPPORTED: &str = "pinhole + radtan/equidistant/none, omni + radtan/none";

impl Rig {
    /// Parse a Kalibr camchain.
    ///
    /// # Errors
    /// [`CameraFileError`] for malformed YAML (or YAML with aliases), missing or mistyped keys, an
    /// unsupported model, an invalid ([`CameraFileError::Parameters`]) or implausible
    /// ([`CameraFileError::Implausible`]) camera, a non-rigid `T_cn_cnm1` or `T_cam_imu`, a
    /// non-finite `timeshift_cam_imu`, or camera keys that do not run `cam0, cam1, ...`.
    pub fn from_kalibr_str(text: &str) -> Result<Self, CameraFileError> {
        let doc = yaml::parse(text)?;
        let Yaml::Hash(h) = &doc else {
            return Err(CameraFileError::WrongType {
                key: "(document)".to_owned(),
                expected: "a mapping of cam0, cam1, ...",
            });
        };
        let cam_keys = h
            .keys()
            .filter(|k| k.as_str().is_some_and(|s| s.starts_with("cam")))
            .count();
        if cam_keys == 0 {
            return Err(CameraFileError::MissingKey {
                key: "cam0".to_owned(),
            });
        }
        let mut cameras: Vec<RigCamera> = Vec::with_capacity(cam_keys);
        for i in 0..cam_keys {
            let key = format!("cam{i}");
            let node = yaml::get(&doc, "", &key).map_err(|_| CameraFileError::Rig {
                message: format!("{cam_keys} camera keys but no `{key}`: keys must be cam0..camN"),
            })?;
            let camera = parse_camera(node, &key)?;
            camera
                .check_plausible()
                .map_err(|source| CameraFileError::Implausible {
                    camera: key.clone(),
                    source,
                })?;
            let rig_from_camera = match cameras.last() {
                None => Isometry3::identity(),
                Some(prev) => {
                    let t = yaml::get(node, &key, "T_cn_cnm1")?;
                    let cn_from_cnm1 = parse_transform(t, &yaml::join(&key, "T_cn_cnm1"))?;
                    prev.rig_from_camera * cn_from_cnm1.inverse()
                }
            };
            let topic = yaml::get_opt(node, "rostopic")
                .map(|t| yaml::string(t, &yaml::join(&key, "rostopic")))
                .transpose()?;
            let overlaps = match yaml::get_opt(node, "cam_overlaps") {
                None => Vec::new(),
                Some(Yaml::Array(items)) => items
                    .iter()
                    .map(|v| {
                        v.as_i64()
                            .and_then(|i| usize::try_from(i).ok())
                            .ok_or_else(|| CameraFileError::WrongType {
                                key: yaml::join(&key, "cam_overlaps"),
                                expected: "a list of camera indices",
                            })
                    })
                    .collect::<Result<_, _>>()?,
                Some(_) => {
                    return Err(CameraFileError::WrongType {
                        key: yaml::join(&key, "cam_overlaps"),
                        expected: "a list of camera indices",
                    });
                }
            };
            let camera_from_imu = yaml::get_opt(node, "T_cam_imu")
                .map(|t| parse_transform(t, &yaml::join(&key, "T_cam_imu")))
                .transpose()?;
            let timeshift_cam_imu_s = yaml::get_opt(node, "timeshift_cam_imu")
                .map(|t| {
                    let k = yaml::join(&key, "timeshift_cam_imu");
                    yaml::number(t, &k).ok().filter(|s| s.is_finite()).ok_or(
                        CameraFileError::WrongType {
                            key: k,
                            expected: "a finite number of seconds",
                        },
                    )
                })
                .transpose()?;
            cameras.push(RigCamera {
                name: key,
                camera,
                rig_from_camera,
                topic,
                overlaps,
                camera_from_imu,
                timeshift_cam_imu_s,
            });
        }
        Ok(Self { cameras })
    }

    /// Format as a Kalibr camchain (17 significant digits), keys in Kalibr's (sorted) order;
    /// `T_cam_imu` and `timeshift_cam_imu` are written for the cameras that have them (a
    /// `camchain-imucam.yaml`).
    pub fn to_kalibr_string(&self) -> String {
        let mut s = String::new();
        let list = |v: &[f64]| {
            let items: Vec<String> = v.iter().map(|x| fmt_f64(*x)).collect();
            format!("[{}]", items.join(", "))
        };
        let matrix = |s: &mut String, key: &str, t: &Isometry3<f64>| {
            let h = t.to_homogeneous();
            s.push_str(&format!("  {key}:\n"));
            for r in 0..4 {
                let row: Vec<f64> = (0..4).map(|k| h[(r, k)]).collect();
                s.push_str(&format!("  - {}\n", list(&row)));
            }
        };
        for (i, c) in self.cameras.iter().enumerate() {
            s.push_str(&format!("cam{i}:\n"));
            if let Some(camera_from_imu) = &c.camera_from_imu {
                matrix(&mut s, "T_cam_imu", camera_from_imu);
            }
            if i > 0 {
                let cn_from_cnm1 =
                    c.rig_from_camera.inverse() * self.cameras[i - 1].rig_from_camera;
                matrix(&mut s, "T_cn_cnm1", &cn_from_cnm1);
            }
            let overlaps: Vec<String> = c.overlaps.iter().map(ToString::to_string).collect();
            s.push_str(&format!("  cam_overlaps: [{}]\n", overlaps.join(", ")));
            let (model, dist_model, intrinsics, coeffs): (&str, &str, Vec<f64>, Vec<f64>) =
                match &c.camera {
                    Camera::PinholeRadtan(p) => {
                        let [k1, k2, p1, p2, fx, fy, cx, cy] = p.params_array();
                        (
                            "pinhole",
                            "radtan",
                            vec![fx, fy, cx, cy],
                            vec![k1, k2, p1, p2],
                        )
                    }
                    Camera::KannalaBrandt(p) => {
                        let [k1, k2, k3, k4, mu, mv, u0, v0] = p.params_array();
                        (
                            "pinhole",
                            "equidistant",
                            vec![mu, mv, u0, v0],
                            vec![k1, k2, k3, k4],
                        )
                    }
                    Camera::Unified(p) => {
                        let [xi, k1, k2, p1, p2, g1, g2, u0, v0] = p.params_array();
                        (
                            "omni",
                            "radtan",
                            vec![xi, g1, g2, u0, v0],
                            vec![k1, k2, p1, p2],
                        )
                    }
                };
            s.push_str(&format!("  camera_model: {model}\n"));
            s.push_str(&format!("  distortion_coeffs: {}\n", list(&coeffs)));
            s.push_str(&format!("  distortion_model: {dist_model}\n"));
            s.push_str(&format!("  intrinsics: {}\n", list(&intrinsics)));
            s.push_str(&format!(
                "  resolution: [{}, {}]\n",
                c.camera.width(),
                c.camera.height()
            ));
            if let Some(topic) = &c.topic {
                s.push_str(&format!("  rostopic: {}\n", fmt_str(topic)));
            }
            if let Some(shift) = c.timeshift_cam_imu_s {
                s.push_str(&format!("  timeshift_cam_imu: {}\n", fmt_f64(shift)));
            }
        }
        s
    }

    /// Read a Kalibr camchain file (a regular file of at most
    /// [`MAX_FILE_BYTES`](crate::MAX_FILE_BYTES)).
    ///
    /// # Errors
    /// [`CameraFileError::Io`] (not a regular file, too large, not text, or the
    /// operating system's error), or an
    /// error of [`from_kalibr_str`](Self::from_kalibr_str) wrapped in [`CameraFileError::InFile`]
    /// with the path.
    pub fn read_kalibr(path: impl AsRef<Path>) -> Result<Self, CameraFileError> {
        let path = path.as_ref();
        Self::from_kalibr_str(&yaml::read_text(path)?).map_err(|e| e.in_file(path))
    }

    /// Write a Kalibr camchain file atomically.
    ///
    /// # Errors
    /// [`CameraFileError::Io`].
    pub fn write_kalibr(&self, path: impl AsRef<Path>) -> Result<(), CameraFileError> {
        yaml::write_atomic(path.as_ref(), &self.to_kalibr_string())
    }
}

/// One `camN` block's intrinsics.
fn parse_camera(node: &Yaml, key: &str) -> Result<Camera, CameraFileError> {
    let text = |k: &str| yaml::string(yaml::get(node, key, k)?, &yaml::join(key, k));
    let model = text("camera_model")?;
    let dist = text("distortion_model")?;
    let unsupported = || CameraFileError::UnsupportedModel {
        name: format!("{model} + {dist}"),
        supported: SUPPORTED,
    };
    match (model.as_str(), dist.as_str()) {
        ("pinhole", "radtan" | "none" | "equidistant") | ("omni", "radtan" | "none") => {}
        ("pinhole" | "omni" | "ds" | "eucm" | "fov" | "extended_unified" | "double_sphere", _) => {
            return Err(unsupported());
        }
        _ => return Err(CameraFileError::UnknownModel { name: model }),
    }
    let [width, height]: [f64; 2] = yaml::numbers(
        yaml::get(node, key, "resolution")?,
        &yaml::join(key, "resolution"),
        "a list of 2 positive integers",
    )?;
    let size = |v: f64| {
        if v.fract() == 0.0 && (1.0..=f64::from(u32::MAX)).contains(&v) {
            #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // checked above
            Ok(v as u32)
        } else {
            Err(CameraFileError::WrongType {
                key: yaml::join(key, "resolution"),
                expected: "a list of 2 positive integers",
            })
        }
    };
    let (width, height) = (size(width)?, size(height)?);
    let intrinsics = yaml::get(node, key, "intrinsics")?;
    let ikey = yaml::join(key, "intrinsics");
    let dkey = yaml::join(key, "distortion_coeffs");
    let coeffs4 = || -> Result<[f64; 4], CameraFileError> {
        yaml::numbers(
            yaml::get(node, key, "distortion_coeffs")?,
            &dkey,
            "a list of 4 numbers",
        )
    };
    let params_err = |source| CameraFileError::Parameters {
        camera: key.to_owned(),
        source,
    };
    let camera: Camera = match model.as_str() {
        "pinhole" => {
            let [fu, fv, pu, pv]: [f64; 4] =
                yaml::numbers(intrinsics, &ikey, "a list of 4 numbers [fu, fv, pu, pv]")?;
            match dist.as_str() {
                "radtan" => {
                    let [k1, k2, p1, p2] = coeffs4()?;
                    PinholeRadtan::new(width, height, [k1, k2, p1, p2, fu, fv, pu, pv])
                        .map_err(params_err)?
                        .into()
                }
                "none" => PinholeRadtan::new(width, height, [0.0, 0.0, 0.0, 0.0, fu, fv, pu, pv])
                    .map_err(params_err)?
                    .into(),
                "equidistant" => {
                    let [k1, k2, k3, k4] = coeffs4()?;
                    KannalaBrandt::new(width, height, [k1, k2, k3, k4, fu, fv, pu, pv])
                        .map_err(params_err)?
                        .into()
                }
                _ => return Err(unsupported()),
            }
        }
        "omni" => {
            let [xi, fu, fv, pu, pv]: [f64; 5] = yaml::numbers(
                intrinsics,
                &ikey,
                "a list of 5 numbers [xi, fu, fv, pu, pv]",
            )?;
            let [k1, k2, p1, p2] = match dist.as_str() {
                "radtan" => coeffs4()?,
                "none" => [0.0; 4],
                _ => return Err(unsupported()),
            };
            Unified::new(width, height, [xi, k1, k2, p1, p2, fu, fv, pu, pv])
                .map_err(params_err)?
                .into()
        }
        "ds" | "eucm" | "fov" | "extended_unified" | "double_sphere" => {
            return Err(unsupported());
        }
        _ => return Err(CameraFileError::UnknownModel { name: model }),
    };
    Ok(camera)
}

/// A 4x4 rigid transform given as four rows.
fn parse_transform(node: &Yaml, key: &str) -> Result<Isometry3<f64>, CameraFileError> {
    let wrong = || CameraFileError::WrongType {
        key: key.to_owned(),
        expected: "4 rows of 4 numbers",
    };
    let Yaml::Array(rows) = node else {
        return Err(wrong());
    };
    if rows.len() != 4 {
        return Err(wrong());
    }
    let mut m = [[0.0; 4]; 3];
    for (i, row) in rows.iter().enumerate() {
        let r: [f64; 4] = yaml::numbers(row, key, "4 rows of 4 numbers")?;
        if i < 3 {
            m[i] = r;
        } else if r != [0.0, 0.0, 0.0, 1.0] {
            return Err(CameraFileError::Rig {
                message: format!("`{key}`: the last row must be [0, 0, 0, 1]"),
            });
        }
    }
    isometry_from_rows(&m).map_err(|message| CameraFileError::Rig {
        message: format!("`{key}`: {message}"),
    })
}
