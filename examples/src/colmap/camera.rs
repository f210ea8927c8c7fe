//! COLMAP camera models and their ibc counterparts.
//!
//! Models, ids and parameter orders as COLMAP's documentation lists them
//! (<https://colmap.github.io/cameras.html>, and `CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]`
//! of <https://colmap.github.io/format.html>). COLMAP puts pixel centres at `+0.5` (the image
//! covers `[0, w] x [0, h]`), ibc at integer coordinates: the principal point moves by
//! `-0.5` on the way in and `+0.5` on the way out; every other parameter is the same number.
//!
//! | COLMAP | parameters | ibc |
//! |---|---|---|
//! | `SIMPLE_PINHOLE` (0) | `f, cx, cy` | pinhole-radtan `[0, 0, 0, 0, f, f, cx - .5, cy - .5]` |
//! | `PINHOLE` (1) | `fx, fy, cx, cy` | pinhole-radtan, no distortion |
//! | `SIMPLE_RADIAL` (2) | `f, cx, cy, k` | pinhole-radtan `[k, 0, 0, 0, f, f, ...]` |
//! | `RADIAL` (3) | `f, cx, cy, k1, k2` | pinhole-radtan `[k1, k2, 0, 0, f, f, ...]` |
//! | `OPENCV` (4) | `fx, fy, cx, cy, k1, k2, p1, p2` | pinhole-radtan `[k1, k2, p1, p2, fx, fy, ...]` |
//! | `OPENCV_FISHEYE` (5) | `fx, fy, cx, cy, k1, k2, k3, k4` | Kannala-Brandt `[k1, k2, k3, k4, fx, fy, ...]` |
//!
//! These are the same functions of the ray (OpenCV's radial-tangential distortion; the
//! equidistant polynomial `theta (1 + k1 theta^2 + ... + k4 theta^8)`), so the conversion is
//! exact. The other models are read and kept, but converting them to ibc is
//! [`ColmapError::UnsupportedCameraModel`]. ibc writes pinhole-radtan as `OPENCV` and
//! Kannala-Brandt as `OPENCV_FISHEYE`; the unified model has no COLMAP counterpart.

use ibc_camera_models::{Camera, CameraModel, KannalaBrandt, ParameterError, PinholeRadtan};

use super::error::{ColmapError, Result};

/// COLMAP's pixel centres are at `+0.5`, ibc's at integers: `ibc = colmap - PIXEL_SHIFT`.
pub const PIXEL_SHIFT: f64 = 0.5;

/// COLMAP's camera models: (id, name, number of parameters), from COLMAP's documentation and
/// `pycolmap.CameraModelId` of pycolmap 4.2.
const MODELS: [(i32, &str, usize); 18] = [
    (0, "SIMPLE_PINHOLE", 3),
    (1, "PINHOLE", 4),
    (2, "SIMPLE_RADIAL", 4),
    (3, "RADIAL", 5),
    (4, "OPENCV", 8),
    (5, "OPENCV_FISHEYE", 8),
    (6, "FULL_OPENCV", 12),
    (7, "FOV", 5),
    (8, "SIMPLE_RADIAL_FISHEYE", 4),
    (9, "RADIAL_FISHEYE", 5),
    (10, "THIN_PRISM_FISHEYE", 12),
    (11, "RAD_TAN_THIN_PRISM_FISHEYE", 16),
    (12, "SIMPLE_DIVISION", 4),
    (13, "DIVISION", 5),
    (14, "SIMPLE_FISHEYE", 3),
    (15, "FISHEYE", 4),
    (16, "EUCM", 6),
    (17, "EQUIRECTANGULAR", 2),
];

/// A COLMAP camera model, by its id in COLMAP's documented table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ColmapCameraModel(usize);

impl ColmapCameraModel {
    /// `OPENCV`.
    pub const OPENCV: Self = Self(4);
    /// `OPENCV_FISHEYE`.
    pub const OPENCV_FISHEYE: Self = Self(5);

    /// The model with this id (`cameras.bin`, the database's `cameras.model`).
    pub fn from_id(id: i64) -> Option<Self> {
        MODELS.iter().position(|m| i64::from(m.0) == id).map(Self)
    }

    /// The model with this name (`cameras.txt`).
    pub fn from_name(name: &str) -> Option<Self> {
        MODELS.iter().position(|m| m.1 == name).map(Self)
    }

    /// COLMAP's id.
    pub fn id(self) -> i32 {
        MODELS[self.0].0
    }

    /// COLMAP's name (`OPENCV_FISHEYE`).
    pub fn name(self) -> &'static str {
        MODELS[self.0].1
    }

    /// Number of parameters.
    pub fn num_params(self) -> usize {
        MODELS[self.0].2
    }
}

/// A camera as COLMAP stores it: parameters in COLMAP's order, principal point in COLMAP's
/// pixel convention (centres at `+0.5`).
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// COLMAP's camera id.
    pub camera_id: u32,
    /// The model.
    pub model: ColmapCameraModel,
    /// Image width, pixels.
    pub width: u64,
    /// Image height, pixels.
    pub height: u64,
    /// The parameters, as many as the model has.
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// The ibc camera: the same projection, with ibc's pixel centres (see the module docs).
    ///
    /// # Errors
    /// [`ColmapError::UnsupportedCameraModel`] naming a model with no exact ibc counterpart,
    /// [`ColmapError::CameraParameters`] when the parameters are invalid for the ibc model.
    pub fn to_ibc(&self) -> Result<Camera> {
        let camera_id = self.camera_id;
        let bad = |source| ColmapError::CameraParameters { camera_id, source };
        let size = |v: u64| {
            u32::try_from(v)
                .ok()
                .filter(|&v| v > 0)
                .ok_or(ColmapError::CameraSize {
                    camera_id,
                    width: self.width,
                    height: self.height,
                })
        };
        let (width, height) = (size(self.width)?, size(self.height)?);
        let p = &self.params;
        let s = PIXEL_SHIFT;
        let pinhole = |k: [f64; 4], fx: f64, fy: f64, cx: f64, cy: f64| {
            PinholeRadtan::new(
                width,
                height,
                [k[0], k[1], k[2], k[3], fx, fy, cx - s, cy - s],
            )
            .map(Camera::from)
            .map_err(bad)
        };
        if p.len() != self.model.num_params() {
            return Err(bad(ParameterError::WrongCount {
                model: self.model.name(),
                expected: self.model.num_params(),
                got: p.len(),
            }));
        }
        match self.model.name() {
            "SIMPLE_PINHOLE" => pinhole([0.0; 4], p[0], p[0], p[1], p[2]),
            "PINHOLE" => pinhole([0.0; 4], p[0], p[1], p[2], p[3]),
            "SIMPLE_RADIAL" => pinhole([p[3], 0.0, 0.0, 0.0], p[0], p[0], p[1], p[2]),
            "RADIAL" => pinhole([p[3], p[4], 0.0, 0.0], p[0], p[0], p[1], p[2]),
            "OPENCV" => pinhole([p[4], p[5], p[6], p[7]], p[0], p[1], p[2], p[3]),
            "OPENCV_FISHEYE" => KannalaBrandt::new(
                width,
                height,
                [p[4], p[5], p[6], p[7], p[0], p[1], p[2] - s, p[3] - s],
            )
            .map(Camera::from)
            .map_err(bad),
            other => Err(ColmapError::UnsupportedCameraModel {
                camera_id,
                model: other,
            }),
        }
    }

    /// The COLMAP camera of an ibc camera: `OPENCV` for pinhole-radtan, `OPENCV_FISHEYE` for
    /// Kannala-Brandt, the principal point moved by `+0.5`.
    ///
    /// # Errors
    /// [`ColmapError::UnsupportedIbcModel`] for a model COLMAP does not have (unified).
    pub fn from_ibc(camera_id: u32, name: &str, camera: &Camera) -> Result<Self> {
        let s = PIXEL_SHIFT;
        let (model, params) = if let Some(c) = camera.as_pinhole_radtan() {
            let [k1, k2, p1, p2, fx, fy, cx, cy] = c.params_array();
            (
                ColmapCameraModel::OPENCV,
                vec![fx, fy, cx + s, cy + s, k1, k2, p1, p2],
            )
        } else if let Some(c) = camera.as_kannala_brandt() {
            let [k1, k2, k3, k4, mu, mv, u0, v0] = c.params_array();
            (
                ColmapCameraModel::OPENCV_FISHEYE,
                vec![mu, mv, u0 + s, v0 + s, k1, k2, k3, k4],
            )
        } else {
            return Err(ColmapError::UnsupportedIbcModel {
                camera: name.to_owned(),
                model: camera.model_name(),
            });
        };
        Ok(Self {
            camera_id,
            model,
            width: u64::from(camera.width()),
            height: u64::from(camera.height()),
            params,
        })
    }
}
