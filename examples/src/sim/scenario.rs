//! Scenarios: everything that defines a simulated world (rig, environment, trajectory, noise,
//! seed, scale), the built-in ones, and how a name or a file picks one.

use std::path::{Path, PathBuf};

use ibc_camera_models::{Camera, CameraModel, Rig};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::environment::EnvironmentKind;
use super::error::SimError;
use super::options::{DetectionOptions, NoiseOptions, check_range};
use super::rigs::{BuiltinRig, SimRig, mount};
use super::trajectory::{Motion, TrajectorySpec};
use crate::data::OdometryKind;

/// The scenario `ibc` runs when none is named.
pub const DEFAULT_SCENARIO: &str = "garage";

/// The camera files a rig can come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraFileFormat {
    /// A Kalibr camchain YAML.
    Kalibr,
    /// A CamOdoCal rig folder (`extrinsic.txt` and `<name>_calib.yaml` or
    /// `<name>_camera_calib.yaml` per camera).
    CamOdoCal,
}

/// Where a scenario's rig comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum RigSource {
    /// A built-in rig.
    Builtin(BuiltinRig),
    /// A user's camera file.
    File {
        /// Its format.
        format: CameraFileFormat,
        /// The camchain file or the CamOdoCal folder (resolved against the scenario file's
        /// folder).
        path: PathBuf,
        /// `vehicle_from_rig`: where the file's rig frame (its camera 0 for a camchain) sits
        /// on the vehicle. Default: see [`default_mount`].
        mount: Isometry3<f64>,
        /// Maps odometry coordinates into the vehicle frame. Default: identity.
        rig_from_odometry: Isometry3<f64>,
        /// The lenses' full field of view, degrees (the same for every camera). Default: 190
        /// for fisheye models (Kannala-Brandt and unified), 180 for pinhole (whose image then
        /// bounds what it sees).
        field_of_view_deg: Option<f64>,
    },
}

/// The default mount of a rig from a file: its frame is camera 0's, looking forward, level,
/// 1.2 m above the ground for a driving rig; at the rig's centre for a handheld one.
pub fn default_mount(motion: Motion) -> Isometry3<f64> {
    let height = match motion {
        Motion::Drive => 1.2,
        Motion::Handheld => 0.0,
    };
    mount(Vector3::new(0.0, 0.0, height), 0.0, 0.0, 0.0)
}

/// How the calibrated rig differs from the configuration that built the map (whose camera
/// file the calibration gets): a camera moved and turned, and its lens changed (temperature,
/// a knock). The new extrinsic is `Translation(translation_m) * rig_from_camera *
/// Rotation(rotation_deg)`: the translation is in the rig (vehicle) frame, the rotation vector
/// (degrees, about the axis it points along) in the camera's own frame, about its centre. The
/// new intrinsics: both focal lengths times `1 + focal_change`, the principal point moved by
/// `principal_point_change_px`; the camera file keeps the old ones.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraChange {
    /// The camera's name.
    pub camera: String,
    /// Translation in the rig frame, metres.
    pub translation_m: Vector3<f64>,
    /// Rotation vector in the camera frame, degrees.
    pub rotation_deg: Vector3<f64>,
    /// Relative change of both focal lengths (`-0.0099`: the true ones 0.99 % shorter than the
    /// camera file's, which is then 1 % long). In (-0.5, 0.5).
    pub focal_change: f64,
    /// Change of the principal point, pixels.
    pub principal_point_change_px: [f64; 2],
    /// A slow drift of both focal lengths during the calibration drive, as a lens warming up:
    /// relative, 0 at its first frame, reached linearly by its last (on top of
    /// `focal_change`). In (-0.5, 0.5).
    pub focal_drift: f64,
}

impl CameraChange {
    /// A camera moved by `translation_m` in the rig frame.
    pub fn moved(camera: &str, translation_m: Vector3<f64>) -> Self {
        Self {
            camera: camera.to_owned(),
            translation_m,
            rotation_deg: Vector3::zeros(),
            focal_change: 0.0,
            principal_point_change_px: [0.0; 2],
            focal_drift: 0.0,
        }
    }

    /// A camera whose lens changed: focal lengths times `1 + focal_change`, principal point
    /// moved by `principal_point_change_px`.
    pub fn lens(camera: &str, focal_change: f64, principal_point_change_px: [f64; 2]) -> Self {
        Self {
            camera: camera.to_owned(),
            translation_m: Vector3::zeros(),
            rotation_deg: Vector3::zeros(),
            focal_change,
            principal_point_change_px,
            focal_drift: 0.0,
        }
    }

    /// A camera turned by `degrees` about its own `axis` (a unit vector of the camera frame).
    pub fn turned(camera: &str, axis: Vector3<f64>, degrees: f64) -> Self {
        Self {
            camera: camera.to_owned(),
            translation_m: Vector3::zeros(),
            rotation_deg: axis.normalize() * degrees,
            focal_change: 0.0,
            principal_point_change_px: [0.0; 2],
            focal_drift: 0.0,
        }
    }

    /// Whether the lens changed or drifts.
    pub fn changes_intrinsics(&self) -> bool {
        self.focal_change != 0.0
            || self.principal_point_change_px != [0.0; 2]
            || self.focal_drift != 0.0
    }

    /// The changed intrinsics of `camera`.
    ///
    /// # Errors
    /// [`SimError::Invalid`] naming the camera when its model refuses them.
    pub fn apply_to_intrinsics(&self, camera: &mut Camera) -> Result<(), SimError> {
        if !self.changes_intrinsics() {
            return Ok(());
        }
        let mut params = camera.params().to_vec();
        for i in camera.focal_length_indices() {
            params[i] *= 1.0 + self.focal_change;
        }
        for (i, d) in camera
            .principal_point_indices()
            .into_iter()
            .zip(self.principal_point_change_px)
        {
            params[i] += d;
        }
        camera.set_params(&params).map_err(|e| {
            SimError::Invalid(format!(
                "the lens change of camera `{}` is not valid for its model: {e}",
                self.camera
            ))
        })
    }

    /// The changed extrinsic.
    pub fn apply(&self, rig_from_camera: &Isometry3<f64>) -> Isometry3<f64> {
        let turn = UnitQuaternion::from_scaled_axis(self.rotation_deg.map(f64::to_radians));
        Isometry3::from_parts(
            Translation3::from(self.translation_m),
            UnitQuaternion::identity(),
        ) * rig_from_camera
            * Isometry3::from_parts(Translation3::identity(), turn)
    }
}

/// Everything that defines a simulated world. Build one with [`Scenario::builtin`],
/// [`Scenario::resolve`] or [`Scenario::from_yaml_file`], then change any public field.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct Scenario {
    /// Its name (recorded in the ground truth and the report).
    pub name: String,
    /// A one-line description.
    pub description: String,
    /// The seed of every random process. Same seed, same world.
    pub seed: u64,
    /// Size of the world in `(0, 1]`: frame counts (calibration and survey) are multiplied by
    /// it, and the environment's long side shrinks with it down to a size that still holds a
    /// loop with four turns. Tests use 0.05 to 0.2.
    pub scale: f64,
    /// The environment.
    pub environment: EnvironmentKind,
    /// The rig that built the map (and, with [`changes`](Self::changes), the calibrated one).
    pub rig: RigSource,
    /// How the calibrated rig differs from the map-building one.
    pub changes: Vec<CameraChange>,
    /// The drives.
    pub trajectory: TrajectorySpec,
    /// The odometry the log records.
    pub odometry: OdometryKind,
    /// Noise levels.
    pub noise: NoiseOptions,
    /// Detection limits.
    pub detection: DetectionOptions,
}

/// One built-in scenario: its name, description and how it differs from the default.
struct Builtin {
    name: &'static str,
    description: &'static str,
    make: fn(&mut Scenario),
}

const BUILTINS: [Builtin; 10] = [
    Builtin {
        name: "garage",
        description: "the paper's indoor setting: a car with 4 fisheyes (190 deg, 1280x960) drives a 300 m loop in a parking garage, 500 frames, wheel odometry",
        make: |_| {},
    },
    Builtin {
        name: "street",
        description: "the paper's outdoor setting: the same car around a city block (facades, trees, parked cars, traffic)",
        make: |s| s.environment = EnvironmentKind::Street,
    },
    Builtin {
        name: "garage-moved-cameras",
        description: "the left and right cameras moved 9.7 and 10.0 cm forward since the map was built",
        make: |s| {
            s.changes = vec![
                CameraChange::moved("left", Vector3::new(0.097, 0.0, 0.0)),
                CameraChange::moved("right", Vector3::new(0.100, 0.0, 0.0)),
            ];
        },
    },
    Builtin {
        name: "garage-left-roll-30",
        description: "the left camera turned 30 degrees about its x-axis since the map was built",
        make: |s| s.changes = vec![CameraChange::turned("left", Vector3::x(), 30.0)],
    },
    Builtin {
        name: "garage-left-yaw-15",
        description: "the left camera turned 15 degrees about its z-axis (optical axis) since the map was built",
        make: |s| s.changes = vec![CameraChange::turned("left", Vector3::z(), 15.0)],
    },
    Builtin {
        name: "garage-map-error",
        description: "the default scenario with 2 cm of error on every map point",
        make: |s| s.noise.map_point_sigma_m = 0.02,
    },
    Builtin {
        name: "garage-spurious-30",
        description: "the default scenario with 30% of the features on things not in the map",
        make: |s| s.noise.spurious_fraction = 0.3,
    },
    Builtin {
        name: "garden-pentagon",
        description: "the TrimBot2020 robot: ten pinhole cameras in five stereo pairs (82 deg, 752x480) on a pentagon, a 100 m loop in a garden, 300 frames, wheel odometry",
        make: |s| {
            s.environment = EnvironmentKind::Garden;
            s.rig = RigSource::Builtin(BuiltinRig::Pentagon);
            s.trajectory.frames = 300;
            s.trajectory.survey_spacing_m = 0.75;
            s.trajectory.speed_m_s = 0.5;
        },
    },
    Builtin {
        name: "handheld-6dof",
        description: "a handheld rig of 3 fisheyes with a 6-DoF pose tracker, walked through the garage swinging in every axis, 300 frames",
        make: |s| {
            s.rig = RigSource::Builtin(BuiltinRig::Handheld);
            s.trajectory.motion = Motion::Handheld;
            s.trajectory.frames = 300;
            s.trajectory.speed_m_s = 1.4;
            s.odometry = OdometryKind::SixDof;
        },
    },
    Builtin {
        name: "handheld-fisheye-pair",
        description: "a TUM-VI-like pair of 195 deg fisheyes (512x512, 10 cm apart) with a 6-DoF pose tracker, walked through the garage swinging in every axis, 300 frames",
        make: |s| {
            s.rig = RigSource::Builtin(BuiltinRig::FisheyePair);
            s.trajectory.motion = Motion::Handheld;
            s.trajectory.frames = 300;
            s.trajectory.speed_m_s = 1.4;
            s.odometry = OdometryKind::SixDof;
        },
    },
];

/// The names and one-line descriptions of the built-in scenarios, in listing order.
pub fn builtin_scenarios() -> Vec<(&'static str, &'static str)> {
    BUILTINS.iter().map(|b| (b.name, b.description)).collect()
}

/// The built-in scenarios as a text table, one per line (`ibc scenarios`).
pub fn scenario_list() -> String {
    let width = BUILTINS.iter().map(|b| b.name.len()).max().unwrap_or(0);
    let mut s = String::new();
    for b in &BUILTINS {
        let mark = if b.name == DEFAULT_SCENARIO {
            " (default)"
        } else {
            ""
        };
        s.push_str(&format!("{:<width$}  {}{mark}\n", b.name, b.description));
    }
    s
}

impl Scenario {
    /// The default scenario's settings, before a built-in changes them.
    fn base(name: &str, description: &str) -> Self {
        Self {
            name: name.to_owned(),
            description: description.to_owned(),
            seed: 1,
            scale: 1.0,
            environment: EnvironmentKind::Garage,
            rig: RigSource::Builtin(BuiltinRig::CarFisheye),
            changes: Vec::new(),
            trajectory: TrajectorySpec::default(),
            odometry: OdometryKind::Planar,
            noise: NoiseOptions::default(),
            detection: DetectionOptions::default(),
        }
    }

    /// The built-in scenario of this name (see [`builtin_scenarios`]).
    ///
    /// # Errors
    /// [`SimError::UnknownScenario`] listing the built-in names.
    pub fn builtin(name: &str) -> Result<Self, SimError> {
        let b =
            BUILTINS
                .iter()
                .find(|b| b.name == name)
                .ok_or_else(|| SimError::UnknownScenario {
                    name: name.to_owned(),
                    known: BUILTINS
                        .iter()
                        .map(|b| b.name)
                        .collect::<Vec<_>>()
                        .join(", "),
                })?;
        let mut s = Self::base(b.name, b.description);
        (b.make)(&mut s);
        Ok(s)
    }

    /// A scenario file when `name_or_path` names an existing file, else the built-in scenario
    /// of that name: what `--scenario NAME|FILE` means.
    ///
    /// # Errors
    /// [`SimError::UnknownScenario`] when it is neither; the file's errors otherwise.
    pub fn resolve(name_or_path: &str) -> Result<Self, SimError> {
        let path = Path::new(name_or_path);
        let builtin = BUILTINS.iter().any(|b| b.name == name_or_path);
        if path.is_file() || (path.exists() && !builtin) {
            // A path that exists but is no regular file (a FIFO, a device) is refused by the
            // reader, naming it.
            Self::from_yaml_file(path)
        } else {
            Self::builtin(name_or_path)
        }
    }

    /// The same scenario with another seed.
    #[must_use]
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same scenario at another scale (see [`scale`](Self::scale)).
    #[must_use]
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = scale;
        self
    }

    /// The rig that built the map, in the vehicle frame, with its odometry mount and lenses:
    /// a built-in rig, or the camera file read and mounted.
    ///
    /// # Errors
    /// [`SimError::CameraFile`] if the camera file cannot be read, [`SimError::EmptyRig`] if it
    /// has no camera.
    pub fn map_rig(&self) -> Result<SimRig, SimError> {
        match &self.rig {
            RigSource::Builtin(b) => b.build(),
            RigSource::File {
                format,
                path,
                mount,
                rig_from_odometry,
                field_of_view_deg,
            } => {
                let read = match format {
                    CameraFileFormat::Kalibr => Rig::read_kalibr(path),
                    CameraFileFormat::CamOdoCal => Rig::read_camodocal_dir(path),
                };
                let mut rig = read?;
                if rig.cameras.is_empty() {
                    return Err(SimError::EmptyRig { path: path.clone() });
                }
                let mut max_incidence_rad = Vec::with_capacity(rig.cameras.len());
                for c in &mut rig.cameras {
                    c.rig_from_camera = mount * c.rig_from_camera;
                    let fov = field_of_view_deg.unwrap_or(match c.camera.model_name() {
                        "pinhole_radtan" => 180.0,
                        _ => 190.0,
                    });
                    max_incidence_rad.push((fov / 2.0).to_radians());
                }
                Ok(SimRig {
                    rig,
                    rig_from_odometry: *rig_from_odometry,
                    max_incidence_rad,
                })
            }
        }
    }

    /// The calibrated rig: the map-building rig with the [`changes`](Self::changes) applied.
    ///
    /// # Errors
    /// As [`map_rig`](Self::map_rig), and [`SimError::Invalid`] for a change naming no camera.
    pub fn true_rig(&self) -> Result<SimRig, SimError> {
        let mut rig = self.map_rig()?;
        for change in &self.changes {
            let camera = rig
                .rig
                .cameras
                .iter_mut()
                .find(|c| c.name == change.camera)
                .ok_or_else(|| {
                    SimError::Invalid(format!(
                        "a camera change names `{}`, which is not a camera of the rig",
                        change.camera
                    ))
                })?;
            camera.rig_from_camera = change.apply(&camera.rig_from_camera);
            change.apply_to_intrinsics(&mut camera.camera)?;
        }
        Ok(rig)
    }

    /// The focal drift of each camera of `rig` over the calibration drive (see
    /// [`CameraChange::focal_drift`]), empty when none drifts.
    pub fn focal_drift(&self, rig: &Rig) -> Vec<f64> {
        if self.changes.iter().all(|c| c.focal_drift == 0.0) {
            return Vec::new();
        }
        rig.cameras
            .iter()
            .map(|camera| {
                self.changes
                    .iter()
                    .filter(|c| c.camera == camera.name)
                    .map(|c| c.focal_drift)
                    .sum()
            })
            .collect()
    }

    /// Checks every value: scale, frame counts, spacing and speed, noise and detection
    /// ranges, camera changes, the odometry against the motion.
    ///
    /// # Errors
    /// [`SimError::Invalid`] naming the first problem.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("scale", self.scale, 1e-3, 1.0)?;
        if !(2..=100_000).contains(&self.trajectory.frames) {
            return Err(SimError::Invalid(format!(
                "trajectory.frames = {} is not in [2, 100000]",
                self.trajectory.frames
            )));
        }
        check_range(
            "trajectory.survey_spacing_m",
            self.trajectory.survey_spacing_m,
            0.05,
            100.0,
        )?;
        check_range(
            "trajectory.speed_m_s",
            self.trajectory.speed_m_s,
            0.01,
            100.0,
        )?;
        self.noise.validate()?;
        self.detection.validate()?;
        for c in &self.changes {
            let finite = c
                .translation_m
                .iter()
                .chain(c.rotation_deg.iter())
                .chain(&c.principal_point_change_px)
                .all(|v| v.is_finite());
            if !finite {
                return Err(SimError::Invalid(format!(
                    "the change of camera `{}` has a non-finite value",
                    c.camera
                )));
            }
            for (name, v) in [
                ("focal_change", c.focal_change),
                ("focal_drift", c.focal_drift),
            ] {
                if !(v > -0.5 && v < 0.5) {
                    return Err(SimError::Invalid(format!(
                        "the change of camera `{}` has {name} = {v}, not in (-0.5, 0.5)",
                        c.camera
                    )));
                }
            }
        }
        if self.odometry == OdometryKind::Planar && self.trajectory.motion == Motion::Handheld {
            return Err(SimError::Invalid(
                "planar (wheel) odometry needs planar motion: use `odometry: six-dof` or \
                 `none` with handheld motion"
                    .to_owned(),
            ));
        }
        if let RigSource::File {
            field_of_view_deg: Some(fov),
            ..
        } = &self.rig
        {
            check_range("rig.field_of_view_deg", *fov, 1.0, 360.0)?;
        }
        Ok(())
    }

    /// Calibration frames at this scale.
    pub fn frames(&self) -> usize {
        scaled(
            self.trajectory.frames,
            self.scale,
            super::trajectory::MIN_FRAMES,
        )
        .min(self.trajectory.frames)
    }
}

/// `n * scale` rounded, at least `min`.
pub(crate) fn scaled(n: usize, scale: f64, min: usize) -> usize {
    ((n as f64 * scale).round() as usize).max(min)
}
