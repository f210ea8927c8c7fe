//! Scenario files (YAML), so users can simulate their own rig.
//!
//! ```yaml
//! # An ibc scenario. Lengths in metres, angles in degrees. Only `version` is required: every
//! # other key defaults to the `base` scenario's value (`garage` when there is no `base`).
//! version: 1
//! base: garage                 # a built-in scenario to start from (`ibc scenarios`)
//! name: my-rig
//! description: "my rig in the garage"
//! seed: 7
//! scale: 1.0                   # (0, 1]: frames and the world's long side shrink with it
//! environment: garage          # garage | street | garden
//! rig:                         # exactly one of builtin, kalibr, camodocal
//!   builtin: car-fisheye       # car-fisheye | pentagon | handheld
//!   # kalibr: cams/camchain.yaml        a Kalibr camchain, relative to this file
//!   # camodocal: cams/                  a CamOdoCal folder (extrinsic.txt + camera YAMLs)
//!   # With a file (not with builtin):
//!   # mount:                   # vehicle_from_rig: where the file's rig frame (camera 0 for a
//!   #   translation: [0, 0, 1.2]          # camchain) sits on the vehicle; default: camera 0
//!   #   rotation_wxyz: [0.5, -0.5, 0.5, -0.5]  # looking forward, level, 1.2 m up (driving)
//!   # rig_from_odometry: {translation: [0, 0, 0], rotation_wxyz: [1, 0, 0, 0]}
//!   # field_of_view_deg: 190   # lens field of view; default 190 (fisheye), 180 (pinhole)
//! changes:                     # how the calibrated rig differs from the map-building one
//!   - camera: left             # a camera name or index
//!     translation_m: [0.097, 0, 0]   # in the rig (vehicle) frame
//!     rotation_deg: [0, 0, 0]        # rotation vector about the camera's own axes
//!     focal_change: 0.0              # the lens: focal lengths times 1 + this (the camera
//!     principal_point_change_px: [0, 0]  # file keeps the old intrinsics)
//!     focal_drift: 0.0               # focal lengths drifting by this during the drive
//! trajectory:
//!   motion: drive              # drive (planar) | handheld (6-DoF)
//!   frames: 500                # calibration frames at scale 1
//!   survey_spacing_m: 1.5      # survey keyframe spacing at scale 1
//!   speed_m_s: 5.0
//! odometry: planar             # none | planar | six-dof
//! noise:
//!   pixel_sigma_px: 0.5
//!   descriptor_bit_flip: 0.05
//!   missed_detection: 0.1
//!   spurious_fraction: 0.1
//!   map_point_sigma_m: 0.0
//!   odometry_translation: 0.005
//!   odometry_rotation_rad_per_m: 0.0005
//! detection:
//!   max_range_m: 30
//!   full_range_m: 20
//!   min_range_m: 0.3
//!   max_view_angle_deg: 85
//! ```
//!
//! Unknown keys are errors (a misspelt key would otherwise be silently ignored), as are
//! missing files, values of the wrong type or out of range, and changes naming no camera.
//! Poses are `{translation: [x, y, z], rotation_wxyz: [w, x, y, z]}` with a unit quaternion.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use yaml_rust2::yaml::Hash;
use yaml_rust2::{Yaml, YamlLoader};

use super::environment::EnvironmentKind;
use super::error::SimError;
use super::rigs::BuiltinRig;
use super::scenario::{CameraChange, CameraFileFormat, RigSource, Scenario, default_mount};
use super::trajectory::Motion;
use crate::data::OdometryKind;

/// The version of the scenario format.
pub const SCENARIO_VERSION: i64 = 1;

/// A mapping key.
fn yk(k: &str) -> Yaml {
    Yaml::String(k.to_owned())
}

/// Parses with the file's path for messages.
struct Parser<'a> {
    path: Option<&'a Path>,
}

fn odometry_name(kind: OdometryKind) -> &'static str {
    match kind {
        OdometryKind::None => "none",
        OdometryKind::Planar => "planar",
        OdometryKind::SixDof => "six-dof",
    }
}

impl Parser<'_> {
    /// An error of a check that does not name the scenario file, with the file.
    fn wrap(&self, source: SimError) -> SimError {
        SimError::InScenario {
            path: self.path.map(Path::to_path_buf),
            source: Box::new(source),
        }
    }

    fn err(&self, message: impl Into<String>) -> SimError {
        SimError::Scenario {
            path: self.path.map(Path::to_path_buf),
            message: message.into(),
        }
    }

    fn mapping<'y>(&self, node: &'y Yaml, key: &str) -> Result<&'y Hash, SimError> {
        match node {
            Yaml::Hash(h) => Ok(h),
            _ => Err(self.err(format!("`{key}` must be a mapping"))),
        }
    }

    /// Fails on a key not in `allowed`.
    fn known_keys(&self, h: &Hash, allowed: &[&str], within: &str) -> Result<(), SimError> {
        for k in h.keys() {
            let name = k.as_str().unwrap_or("(not a string)");
            if !allowed.contains(&name) {
                let at = if within.is_empty() {
                    String::new()
                } else {
                    format!(" in `{within}`")
                };
                return Err(self.err(format!(
                    "unknown key `{name}`{at} (known: {})",
                    allowed.join(", ")
                )));
            }
        }
        Ok(())
    }

    fn number(&self, node: &Yaml, key: &str) -> Result<f64, SimError> {
        let v = match node {
            Yaml::Real(_) => node.as_f64(),
            #[allow(clippy::cast_precision_loss)] // scenario integers are small
            Yaml::Integer(i) => Some(*i as f64),
            _ => None,
        };
        v.filter(|v| v.is_finite())
            .ok_or_else(|| self.err(format!("`{key}` must be a finite number")))
    }

    fn count(&self, node: &Yaml, key: &str) -> Result<usize, SimError> {
        node.as_i64()
            .and_then(|i| usize::try_from(i).ok())
            .ok_or_else(|| self.err(format!("`{key}` must be a non-negative integer")))
    }

    fn text(&self, node: &Yaml, key: &str) -> Result<String, SimError> {
        match node {
            Yaml::String(s) => Ok(s.clone()),
            Yaml::Integer(i) => Ok(i.to_string()),
            Yaml::Real(s) => Ok(s.clone()),
            _ => Err(self.err(format!("`{key}` must be a string"))),
        }
    }

    /// A list of `N` finite numbers.
    fn numbers_list<const N: usize>(&self, node: &Yaml, key: &str) -> Result<[f64; N], SimError> {
        let wrong = || self.err(format!("`{key}` must be a list of {N} numbers"));
        let Yaml::Array(items) = node else {
            return Err(wrong());
        };
        if items.len() != N {
            return Err(wrong());
        }
        let mut out = [0.0; N];
        for (o, i) in out.iter_mut().zip(items) {
            *o = self.number(i, key).map_err(|_| wrong())?;
        }
        Ok(out)
    }

    fn vec3(&self, node: &Yaml, key: &str) -> Result<Vector3<f64>, SimError> {
        self.numbers_list::<3>(node, key).map(Vector3::from)
    }

    fn vec2(&self, node: &Yaml, key: &str) -> Result<[f64; 2], SimError> {
        self.numbers_list::<2>(node, key)
    }

    fn pose(&self, node: &Yaml, key: &str) -> Result<Isometry3<f64>, SimError> {
        let h = self.mapping(node, key)?;
        self.known_keys(h, &["translation", "rotation_wxyz"], key)?;
        let t = match h.get(&yk("translation")) {
            Some(n) => self.vec3(n, &format!("{key}.translation"))?,
            None => Vector3::zeros(),
        };
        let q = match h.get(&yk("rotation_wxyz")) {
            None => UnitQuaternion::identity(),
            Some(n) => {
                let k = format!("{key}.rotation_wxyz");
                let wrong = || self.err(format!("`{k}` must be a unit quaternion [w, x, y, z]"));
                let Yaml::Array(items) = n else {
                    return Err(wrong());
                };
                let v: Vec<f64> = items
                    .iter()
                    .map(|i| self.number(i, &k))
                    .collect::<Result<_, _>>()
                    .map_err(|_| wrong())?;
                if v.len() != 4 {
                    return Err(wrong());
                }
                let q = Quaternion::new(v[0], v[1], v[2], v[3]);
                if (q.norm() - 1.0).abs() > 1e-6 {
                    return Err(wrong());
                }
                crate::data::io::unit_quaternion(q)
            }
        };
        Ok(Isometry3::from_parts(Translation3::from(t), q))
    }

    fn parse(&self, text: &str, base_dir: &Path) -> Result<Scenario, SimError> {
        // Aliases and deep nesting would make the loader expand without bound.
        ibc_camera_models::check_yaml_input(text).map_err(|e| self.wrap(e.into()))?;
        let docs = YamlLoader::load_from_str(text)
            .map_err(|e| self.err(format!("not valid YAML: {e}")))?;
        let doc = docs
            .into_iter()
            .next()
            .ok_or_else(|| self.err("the file is empty"))?;
        let h = self.mapping(&doc, "(document)")?;
        self.known_keys(
            h,
            &[
                "version",
                "base",
                "name",
                "description",
                "seed",
                "scale",
                "environment",
                "rig",
                "changes",
                "trajectory",
                "odometry",
                "noise",
                "detection",
            ],
            "",
        )?;
        let get = |k: &str| h.get(&yk(k));
        match get("version") {
            Some(Yaml::Integer(SCENARIO_VERSION)) => {}
            Some(v) => {
                return Err(self.err(format!(
                    "`version` is {v:?}; this build reads scenario version {SCENARIO_VERSION}"
                )));
            }
            None => {
                return Err(self.err(format!(
                    "missing key `version` (write `version: {SCENARIO_VERSION}`)"
                )));
            }
        }
        let base = match get("base") {
            Some(b) => self.text(b, "base")?,
            None => super::scenario::DEFAULT_SCENARIO.to_owned(),
        };
        let mut s = Scenario::builtin(&base).map_err(|e| self.err(format!("`base`: {e}")))?;
        if let Some(n) = get("name") {
            s.name = self.text(n, "name")?;
        }
        if let Some(n) = get("description") {
            s.description = self.text(n, "description")?;
        }
        if let Some(n) = get("seed") {
            s.seed = match n {
                Yaml::Integer(i) => u64::try_from(*i).ok(),
                Yaml::String(t) => t.parse::<u64>().ok(),
                _ => None,
            }
            .ok_or_else(|| self.err("`seed` must be an integer in [0, 2^64)"))?;
        }
        if let Some(n) = get("scale") {
            s.scale = self.number(n, "scale")?;
        }
        if let Some(n) = get("environment") {
            let name = self.text(n, "environment")?;
            s.environment = EnvironmentKind::from_name(&name).ok_or_else(|| {
                self.err(format!(
                    "`environment` is `{name}`; known: garage, street, garden"
                ))
            })?;
        }
        if let Some(n) = get("trajectory") {
            self.trajectory(n, &mut s)?;
        }
        if let Some(n) = get("odometry") {
            let name = self.text(n, "odometry")?;
            s.odometry = [
                OdometryKind::None,
                OdometryKind::Planar,
                OdometryKind::SixDof,
            ]
            .into_iter()
            .find(|k| odometry_name(*k) == name)
            .ok_or_else(|| {
                self.err(format!(
                    "`odometry` is `{name}`; known: none, planar, six-dof"
                ))
            })?;
        }
        if let Some(n) = get("rig") {
            s.rig = self.rig(n, base_dir, s.trajectory.motion)?;
        }
        if let Some(n) = get("noise") {
            self.noise(n, &mut s)?;
        }
        if let Some(n) = get("detection") {
            self.detection(n, &mut s)?;
        }
        // Changes last: they name cameras of the rig.
        if let Some(n) = get("changes") {
            let rig = s.map_rig().map_err(|e| self.wrap(e))?;
            let names: Vec<&str> = rig.rig.cameras.iter().map(|c| c.name.as_str()).collect();
            s.changes = self.changes(n, &names)?;
        } else if !s.changes.is_empty() {
            // A base's changes must still fit the rig.
            s.true_rig().map_err(|e| self.wrap(e))?;
        }
        s.validate().map_err(|e| self.wrap(e))?;
        // Resolving the rig reads its files now, so a missing file is reported on loading.
        s.map_rig().map_err(|e| self.wrap(e))?;
        Ok(s)
    }

    fn trajectory(&self, node: &Yaml, s: &mut Scenario) -> Result<(), SimError> {
        let h = self.mapping(node, "trajectory")?;
        self.known_keys(
            h,
            &["motion", "frames", "survey_spacing_m", "speed_m_s"],
            "trajectory",
        )?;
        let get = |k: &str| h.get(&yk(k));
        let t = &mut s.trajectory;
        if let Some(n) = get("motion") {
            let name = self.text(n, "trajectory.motion")?;
            t.motion = Motion::from_name(&name).ok_or_else(|| {
                self.err(format!(
                    "`trajectory.motion` is `{name}`; known: drive, handheld"
                ))
            })?;
        }
        if let Some(n) = get("frames") {
            t.frames = self.count(n, "trajectory.frames")?;
        }
        if let Some(n) = get("survey_spacing_m") {
            t.survey_spacing_m = self.number(n, "trajectory.survey_spacing_m")?;
        }
        if let Some(n) = get("speed_m_s") {
            t.speed_m_s = self.number(n, "trajectory.speed_m_s")?;
        }
        Ok(())
    }

    fn rig(&self, node: &Yaml, base_dir: &Path, motion: Motion) -> Result<RigSource, SimError> {
        let h = self.mapping(node, "rig")?;
        self.known_keys(
            h,
            &[
                "builtin",
                "kalibr",
                "camodocal",
                "mount",
                "rig_from_odometry",
                "field_of_view_deg",
            ],
            "rig",
        )?;
        let get = |k: &str| h.get(&yk(k));
        let sources: Vec<&str> = ["builtin", "kalibr", "camodocal"]
            .into_iter()
            .filter(|k| get(k).is_some())
            .collect();
        if sources.len() != 1 {
            return Err(self.err(format!(
                "`rig` needs exactly one of `builtin`, `kalibr`, `camodocal` (found {})",
                if sources.is_empty() {
                    "none".to_owned()
                } else {
                    sources.join(", ")
                }
            )));
        }
        if let Some(n) = get("builtin") {
            if let Some(k) = ["mount", "rig_from_odometry", "field_of_view_deg"]
                .into_iter()
                .find(|k| get(k).is_some())
            {
                return Err(self.err(format!(
                    "`rig.{k}` is only for rigs from files (a built-in rig has its own)"
                )));
            }
            let name = self.text(n, "rig.builtin")?;
            return BuiltinRig::from_name(&name)
                .map(RigSource::Builtin)
                .ok_or_else(|| {
                    let known: Vec<&str> = BuiltinRig::ALL.iter().map(|r| r.name()).collect();
                    self.err(format!(
                        "`rig.builtin` is `{name}`; known: {}",
                        known.join(", ")
                    ))
                });
        }
        let (format, key) = if get("kalibr").is_some() {
            (CameraFileFormat::Kalibr, "kalibr")
        } else {
            (CameraFileFormat::CamOdoCal, "camodocal")
        };
        let file = self.text(get(key).unwrap_or(&Yaml::Null), &format!("rig.{key}"))?;
        let path = base_dir.join(&file);
        // Absolute, so that the scenario written back reads the same file from anywhere.
        let path = path.canonicalize().unwrap_or(path);
        let mount = match get("mount") {
            Some(n) => self.pose(n, "rig.mount")?,
            None => default_mount(motion),
        };
        let rig_from_odometry = match get("rig_from_odometry") {
            Some(n) => self.pose(n, "rig.rig_from_odometry")?,
            None => Isometry3::identity(),
        };
        let field_of_view_deg = get("field_of_view_deg")
            .map(|n| self.number(n, "rig.field_of_view_deg"))
            .transpose()?;
        Ok(RigSource::File {
            format,
            path,
            mount,
            rig_from_odometry,
            field_of_view_deg,
        })
    }

    fn changes(&self, node: &Yaml, names: &[&str]) -> Result<Vec<CameraChange>, SimError> {
        let Yaml::Array(items) = node else {
            return Err(self.err("`changes` must be a list"));
        };
        let mut out = Vec::with_capacity(items.len());
        for (i, item) in items.iter().enumerate() {
            let key = format!("changes[{i}]");
            let h = self.mapping(item, &key)?;
            self.known_keys(
                h,
                &[
                    "camera",
                    "translation_m",
                    "rotation_deg",
                    "focal_change",
                    "principal_point_change_px",
                    "focal_drift",
                ],
                &key,
            )?;
            let get = |k: &str| h.get(&yk(k));
            let camera = match get("camera") {
                Some(Yaml::Integer(k)) => usize::try_from(*k)
                    .ok()
                    .and_then(|k| names.get(k))
                    .map(|n| (*n).to_owned())
                    .ok_or_else(|| {
                        self.err(format!(
                            "`{key}.camera` is {k} but the rig has {} cameras",
                            names.len()
                        ))
                    })?,
                Some(n) => {
                    let name = self.text(n, &format!("{key}.camera"))?;
                    if !names.contains(&name.as_str()) {
                        return Err(self.err(format!(
                            "`{key}.camera` is `{name}`, not a camera of the rig ({})",
                            names.join(", ")
                        )));
                    }
                    name
                }
                None => return Err(self.err(format!("missing key `{key}.camera`"))),
            };
            let translation_m = get("translation_m")
                .map(|n| self.vec3(n, &format!("{key}.translation_m")))
                .transpose()?
                .unwrap_or_else(Vector3::zeros);
            let rotation_deg = get("rotation_deg")
                .map(|n| self.vec3(n, &format!("{key}.rotation_deg")))
                .transpose()?
                .unwrap_or_else(Vector3::zeros);
            let focal_change = get("focal_change")
                .map(|n| self.number(n, &format!("{key}.focal_change")))
                .transpose()?
                .unwrap_or(0.0);
            let principal_point_change_px = get("principal_point_change_px")
                .map(|n| self.vec2(n, &format!("{key}.principal_point_change_px")))
                .transpose()?
                .unwrap_or([0.0; 2]);
            let focal_drift = get("focal_drift")
                .map(|n| self.number(n, &format!("{key}.focal_drift")))
                .transpose()?
                .unwrap_or(0.0);
            out.push(CameraChange {
                camera,
                translation_m,
                rotation_deg,
                focal_change,
                principal_point_change_px,
                focal_drift,
            });
        }
        Ok(out)
    }

    fn noise(&self, node: &Yaml, s: &mut Scenario) -> Result<(), SimError> {
        let h = self.mapping(node, "noise")?;
        let n = &mut s.noise;
        let mut fields: [(&str, &mut f64); 7] = [
            ("pixel_sigma_px", &mut n.pixel_sigma_px),
            ("descriptor_bit_flip", &mut n.descriptor_bit_flip),
            ("missed_detection", &mut n.missed_detection),
            ("spurious_fraction", &mut n.spurious_fraction),
            ("map_point_sigma_m", &mut n.map_point_sigma_m),
            ("odometry_translation", &mut n.odometry_translation),
            (
                "odometry_rotation_rad_per_m",
                &mut n.odometry_rotation_rad_per_m,
            ),
        ];
        self.numbers(h, "noise", &mut fields)
    }

    fn detection(&self, node: &Yaml, s: &mut Scenario) -> Result<(), SimError> {
        let h = self.mapping(node, "detection")?;
        let d = &mut s.detection;
        let mut fields: [(&str, &mut f64); 4] = [
            ("max_range_m", &mut d.max_range_m),
            ("full_range_m", &mut d.full_range_m),
            ("min_range_m", &mut d.min_range_m),
            ("max_view_angle_deg", &mut d.max_view_angle_deg),
        ];
        self.numbers(h, "detection", &mut fields)
    }

    /// Sets each field present in `h`; unknown keys are errors.
    fn numbers(
        &self,
        h: &Hash,
        within: &str,
        fields: &mut [(&str, &mut f64)],
    ) -> Result<(), SimError> {
        let names: Vec<&str> = fields.iter().map(|(k, _)| *k).collect();
        self.known_keys(h, &names, within)?;
        for (k, v) in fields.iter_mut() {
            if let Some(n) = h.get(&yk(k)) {
                **v = self.number(n, &format!("{within}.{k}"))?;
            }
        }
        Ok(())
    }
}

/// A YAML double-quoted string (JSON's escaping is valid YAML).
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".to_owned())
}

/// A number that reads back bit for bit (Rust's shortest round-trip form).
fn num(v: f64) -> String {
    format!("{v:?}")
}

fn vec3(v: &Vector3<f64>) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

fn pose(p: &Isometry3<f64>) -> String {
    let q = p.rotation.quaternion();
    format!(
        "{{translation: {}, rotation_wxyz: [{}, {}, {}, {}]}}",
        vec3(&p.translation.vector),
        num(q.w),
        num(q.i),
        num(q.j),
        num(q.k)
    )
}

impl Scenario {
    /// Parses a scenario file's text; relative camera-file paths are resolved against
    /// `base_dir`. The rig's files are read once to check them.
    ///
    /// # Errors
    /// [`SimError::Scenario`] naming the key at fault (see the [module docs](self)).
    pub fn from_yaml_str(text: &str, base_dir: &Path) -> Result<Self, SimError> {
        Parser { path: None }.parse(text, base_dir)
    }

    /// Reads a scenario file.
    ///
    /// # Errors
    /// [`SimError::Io`] if it cannot be read, [`SimError::Scenario`] naming the file and the
    /// key at fault otherwise.
    pub fn from_yaml_file(path: impl AsRef<Path>) -> Result<Self, SimError> {
        let path = path.as_ref();
        let text = ibc_camera_models::io::read_text(path, crate::data::io::MAX_SCENARIO_BYTES)?;
        let base_dir = path.parent().map_or_else(PathBuf::new, Path::to_path_buf);
        Parser { path: Some(path) }.parse(&text, &base_dir)
    }

    /// The scenario as a scenario file that reads back to an equal scenario (every key
    /// written, numbers to the last bit, camera-file paths as resolved).
    pub fn to_yaml_string(&self) -> String {
        let mut y = String::new();
        // Writing to a String cannot fail.
        let _ = self.write_yaml_to(&mut y);
        y
    }

    fn write_yaml_to(&self, y: &mut String) -> std::fmt::Result {
        writeln!(
            y,
            "# An ibc scenario (see `ibc_pipeline::sim::scenario_yaml`)."
        )?;
        writeln!(y, "version: {SCENARIO_VERSION}")?;
        writeln!(y, "name: {}", quoted(&self.name))?;
        writeln!(y, "description: {}", quoted(&self.description))?;
        if i64::try_from(self.seed).is_ok() {
            writeln!(y, "seed: {}", self.seed)?;
        } else {
            writeln!(y, "seed: \"{}\"", self.seed)?;
        }
        writeln!(y, "scale: {}", num(self.scale))?;
        writeln!(y, "environment: {}", self.environment.name())?;
        writeln!(y, "rig:")?;
        match &self.rig {
            RigSource::Builtin(b) => writeln!(y, "  builtin: {}", b.name())?,
            RigSource::File {
                format,
                path,
                mount,
                rig_from_odometry,
                field_of_view_deg,
            } => {
                let key = match format {
                    CameraFileFormat::Kalibr => "kalibr",
                    CameraFileFormat::CamOdoCal => "camodocal",
                };
                writeln!(y, "  {key}: {}", quoted(&path.to_string_lossy()))?;
                writeln!(y, "  mount: {}", pose(mount))?;
                writeln!(y, "  rig_from_odometry: {}", pose(rig_from_odometry))?;
                if let Some(f) = field_of_view_deg {
                    writeln!(y, "  field_of_view_deg: {}", num(*f))?;
                }
            }
        }
        if self.changes.is_empty() {
            writeln!(y, "changes: []")?;
        } else {
            writeln!(y, "changes:")?;
            for c in &self.changes {
                writeln!(y, "  - camera: {}", quoted(&c.camera))?;
                writeln!(y, "    translation_m: {}", vec3(&c.translation_m))?;
                writeln!(y, "    rotation_deg: {}", vec3(&c.rotation_deg))?;
                if c.changes_intrinsics() {
                    writeln!(y, "    focal_change: {}", num(c.focal_change))?;
                    let [u, v] = c.principal_point_change_px;
                    writeln!(y, "    principal_point_change_px: [{}, {}]", num(u), num(v))?;
                }
            }
        }
        let t = &self.trajectory;
        writeln!(y, "trajectory:")?;
        writeln!(y, "  motion: {}", t.motion.name())?;
        writeln!(y, "  frames: {}", t.frames)?;
        writeln!(y, "  survey_spacing_m: {}", num(t.survey_spacing_m))?;
        writeln!(y, "  speed_m_s: {}", num(t.speed_m_s))?;
        writeln!(y, "odometry: {}", odometry_name(self.odometry))?;
        let n = &self.noise;
        writeln!(y, "noise:")?;
        writeln!(y, "  pixel_sigma_px: {}", num(n.pixel_sigma_px))?;
        writeln!(y, "  descriptor_bit_flip: {}", num(n.descriptor_bit_flip))?;
        writeln!(y, "  missed_detection: {}", num(n.missed_detection))?;
        writeln!(y, "  spurious_fraction: {}", num(n.spurious_fraction))?;
        writeln!(y, "  map_point_sigma_m: {}", num(n.map_point_sigma_m))?;
        writeln!(y, "  odometry_translation: {}", num(n.odometry_translation))?;
        writeln!(
            y,
            "  odometry_rotation_rad_per_m: {}",
            num(n.odometry_rotation_rad_per_m)
        )?;
        let d = &self.detection;
        writeln!(y, "detection:")?;
        writeln!(y, "  max_range_m: {}", num(d.max_range_m))?;
        writeln!(y, "  full_range_m: {}", num(d.full_range_m))?;
        writeln!(y, "  min_range_m: {}", num(d.min_range_m))?;
        writeln!(y, "  max_view_angle_deg: {}", num(d.max_view_angle_deg))
    }
}
