//! COLMAP's text sparse model (`cameras.txt`, `images.txt`, `points3D.txt`, and `rigs.txt`,
//! `frames.txt` since COLMAP 3.12), read and written after the documented layout
//! (<https://colmap.github.io/format.html>, "Text Format"). Lines starting with `#` are
//! comments; values are separated by spaces:
//!
//! - `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`.
//! - `images.txt`: two lines per image, `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`
//!   (`cam_from_world`), then `POINTS2D[]` as `(X, Y, POINT3D_ID)` with `-1` for none (the
//!   second line is empty for an image without 2D points).
//! - `points3D.txt`: `POINT3D_ID X Y Z R G B ERROR TRACK[]` as `(IMAGE_ID, POINT2D_IDX)`.
//! - `rigs.txt`: `RIG_ID NUM_SENSORS REF_SENSOR_TYPE REF_SENSOR_ID SENSORS[]` as
//!   `(SENSOR_TYPE, SENSOR_ID, HAS_POSE, [QW QX QY QZ TX TY TZ])` (`sensor_from_rig`, present
//!   when `HAS_POSE` is 1).
//! - `frames.txt`: `FRAME_ID RIG_ID QW QX QY QZ TX TY TZ NUM_DATA_IDS DATA_IDS[]` as
//!   `(SENSOR_TYPE, SENSOR_ID, DATA_ID)` (`rig_from_world`).
//!
//! Sensor types are written `CAMERA` or `IMU`. Numbers are written with 17 significant
//! digits, so every `f64` reads back bit for bit.

use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;

use nalgebra::{Point3, Vector2};

use super::camera::{ColmapCamera, ColmapCameraModel};
use super::error::{ColmapError, Result};
use super::model::{
    ColmapFrame, ColmapImage, ColmapModel, ColmapPoint2D, ColmapPoint3D, ColmapRig, NO_POINT3D,
    Sensor, SensorKind, pose, pose_values,
};
use crate::data::io::MAX_BINARY_INPUT_BYTES;

/// The tokens of one line, with the file and line number for errors.
struct Line<'a> {
    path: &'a Path,
    number: usize,
    tokens: std::str::SplitAsciiWhitespace<'a>,
}

impl<'a> Line<'a> {
    fn new(path: &'a Path, number: usize, line: &'a str) -> Self {
        Self {
            path,
            number,
            tokens: line.split_ascii_whitespace(),
        }
    }

    fn error(&self, what: String) -> ColmapError {
        ColmapError::Parse {
            path: self.path.to_owned(),
            line: self.number,
            what,
        }
    }

    fn token(&mut self, what: &str) -> Result<&'a str> {
        self.tokens
            .next()
            .ok_or_else(|| self.error(format!("the line ends before {what}")))
    }

    fn value<T: FromStr>(&mut self, what: &str) -> Result<T> {
        let t = self.token(what)?;
        t.parse()
            .map_err(|_| self.error(format!("{what} {t:?} is not a valid number")))
    }

    fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N]> {
        let mut v = [0.0; N];
        for x in &mut v {
            *x = self.value(what)?;
        }
        Ok(v)
    }

    fn pose(&mut self, what: &str) -> Result<nalgebra::Isometry3<f64>> {
        let v = self.f64s::<7>(what)?;
        pose(v).ok_or_else(|| {
            self.error(format!(
                "{what}: not a pose (a non-finite value or a quaternion that is not a unit)"
            ))
        })
    }

    fn sensor(&mut self) -> Result<Sensor> {
        let t = self.token("a sensor type")?;
        let kind = SensorKind::from_name(t)
            .ok_or_else(|| self.error(format!("unknown sensor type {t:?}")))?;
        Ok(Sensor {
            kind,
            id: self.value("a sensor id")?,
        })
    }

    fn end(&mut self) -> Result<()> {
        match self.tokens.next() {
            Some(t) => Err(self.error(format!("unexpected {t:?} after the last value"))),
            None => Ok(()),
        }
    }

    /// The remaining tokens, in groups of `n` (a list of tuples).
    fn groups(&mut self, n: usize, what: &str) -> Result<Vec<Vec<&'a str>>> {
        let rest: Vec<&str> = self.tokens.by_ref().collect();
        if !rest.len().is_multiple_of(n) {
            return Err(self.error(format!(
                "{} values in the list of {what}, not a multiple of {n}",
                rest.len()
            )));
        }
        Ok(rest.chunks(n).map(<[&str]>::to_vec).collect())
    }
}

fn parse<T: FromStr>(line: &Line<'_>, t: &str, what: &str) -> Result<T> {
    t.parse()
        .map_err(|_| line.error(format!("{what} {t:?} is not a valid number")))
}

/// The data lines of a text file: `(line number, line)`, comments dropped.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim_start().starts_with('#'))
}

fn read(path: &Path) -> Result<String> {
    Ok(ibc_camera_models::io::read_text(
        path,
        MAX_BINARY_INPUT_BYTES,
    )?)
}

/// Reads `dir`'s text model (not yet checked: [`super::read_model`] checks it).
pub(crate) fn read_model_text(dir: &Path) -> Result<ColmapModel> {
    let file = |name: &str| dir.join(name);
    let p = file("cameras.txt");
    let cameras = cameras_from_text(&read(&p)?, &p)?;
    let p = file("images.txt");
    let images = images_from_text(&read(&p)?, &p)?;
    let p = file("points3D.txt");
    let points3d = points_from_text(&read(&p)?, &p)?;
    let p = file("rigs.txt");
    let rigs = if p.exists() {
        rigs_from_text(&read(&p)?, &p)?
    } else {
        Vec::new()
    };
    let p = file("frames.txt");
    let frames = if p.exists() {
        frames_from_text(&read(&p)?, &p)?
    } else {
        Vec::new()
    };
    Ok(ColmapModel {
        cameras,
        images,
        points3d,
        rigs,
        frames,
    })
}

/// Parses `cameras.txt`; `path` names it in errors.
///
/// # Errors
/// [`ColmapError::Parse`] naming the line, [`ColmapError::UnknownCameraModel`].
pub fn cameras_from_text(text: &str, path: &Path) -> Result<Vec<ColmapCamera>> {
    let mut cameras = Vec::new();
    for (number, l) in data_lines(text).filter(|(_, l)| !l.trim().is_empty()) {
        let mut line = Line::new(path, number, l);
        let camera_id = line.value("the camera id")?;
        let name = line.token("the model")?;
        let model =
            ColmapCameraModel::from_name(name).ok_or_else(|| ColmapError::UnknownCameraModel {
                path: path.to_owned(),
                camera_id,
                model: name.to_owned(),
            })?;
        let width = line.value("the width")?;
        let height = line.value("the height")?;
        let mut params = Vec::with_capacity(model.num_params());
        for _ in 0..model.num_params() {
            params.push(line.value("a parameter")?);
        }
        line.end()?;
        cameras.push(ColmapCamera {
            camera_id,
            model,
            width,
            height,
            params,
        });
    }
    Ok(cameras)
}

/// Parses `images.txt`; `path` names it in errors.
///
/// # Errors
/// [`ColmapError::Parse`] naming the line.
pub fn images_from_text(text: &str, path: &Path) -> Result<Vec<ColmapImage>> {
    let mut images = Vec::new();
    let mut lines = data_lines(text);
    while let Some((number, l)) = lines.next() {
        if l.trim().is_empty() {
            continue;
        }
        let mut line = Line::new(path, number, l);
        let image_id = line.value("the image id")?;
        let cam_from_world = line.pose("the pose")?;
        let camera_id = line.value("the camera id")?;
        // The name is the rest of the line (it may hold spaces).
        let name = line.tokens.by_ref().collect::<Vec<_>>().join(" ");
        if name.is_empty() {
            return Err(line.error("the line ends before the image name".to_owned()));
        }
        let mut points2d = Vec::new();
        if let Some((number, l)) = lines.next() {
            let mut line = Line::new(path, number, l);
            for g in line.groups(3, "2D points (X, Y, POINT3D_ID)")? {
                let x = parse(&line, g[0], "a 2D point's x")?;
                let y = parse(&line, g[1], "a 2D point's y")?;
                let id: i64 = parse(&line, g[2], "a 2D point's POINT3D_ID")?;
                let point3d_id = match id {
                    -1 => NO_POINT3D,
                    id => u64::try_from(id)
                        .map_err(|_| line.error(format!("POINT3D_ID {id} (not -1 nor an id)")))?,
                };
                points2d.push(ColmapPoint2D {
                    xy: Vector2::new(x, y),
                    point3d_id,
                });
            }
        }
        images.push(ColmapImage {
            image_id,
            name,
            camera_id,
            cam_from_world,
            points2d,
        });
    }
    Ok(images)
}

/// Parses `points3D.txt`; `path` names it in errors.
///
/// # Errors
/// [`ColmapError::Parse`] naming the line.
pub fn points_from_text(text: &str, path: &Path) -> Result<Vec<ColmapPoint3D>> {
    let mut points = Vec::new();
    for (number, l) in data_lines(text).filter(|(_, l)| !l.trim().is_empty()) {
        let mut line = Line::new(path, number, l);
        let point3d_id = line.value("the point id")?;
        let [x, y, z] = line.f64s::<3>("a coordinate")?;
        if ![x, y, z].iter().all(|v| v.is_finite()) {
            return Err(line.error(format!("3D point {point3d_id} is not finite")));
        }
        let color = [
            line.value("a colour")?,
            line.value("a colour")?,
            line.value("a colour")?,
        ];
        let error = line.value("the error")?;
        let mut track = Vec::new();
        for g in line.groups(2, "track elements (IMAGE_ID, POINT2D_IDX)")? {
            track.push((
                parse(&line, g[0], "a track's IMAGE_ID")?,
                parse(&line, g[1], "a track's POINT2D_IDX")?,
            ));
        }
        points.push(ColmapPoint3D {
            point3d_id,
            xyz: Point3::new(x, y, z),
            color,
            error,
            track,
        });
    }
    Ok(points)
}

/// Parses `rigs.txt`; `path` names it in errors.
///
/// # Errors
/// [`ColmapError::Parse`] naming the line.
pub fn rigs_from_text(text: &str, path: &Path) -> Result<Vec<ColmapRig>> {
    let mut rigs = Vec::new();
    for (number, l) in data_lines(text).filter(|(_, l)| !l.trim().is_empty()) {
        let mut line = Line::new(path, number, l);
        let rig_id = line.value("the rig id")?;
        let n: usize = line.value("the number of sensors")?;
        if n == 0 {
            return Err(line.error(format!("rig {rig_id} has no sensor")));
        }
        let ref_sensor = line.sensor()?;
        let mut sensors = Vec::new();
        for _ in 1..n {
            let sensor = line.sensor()?;
            let pose = match line.value::<u8>("HAS_POSE")? {
                0 => None,
                1 => Some(line.pose("sensor_from_rig")?),
                f => return Err(line.error(format!("HAS_POSE {f} (not 0 or 1)"))),
            };
            sensors.push((sensor, pose));
        }
        line.end()?;
        rigs.push(ColmapRig {
            rig_id,
            ref_sensor,
            sensors,
        });
    }
    Ok(rigs)
}

/// Parses `frames.txt`; `path` names it in errors.
///
/// # Errors
/// [`ColmapError::Parse`] naming the line.
pub fn frames_from_text(text: &str, path: &Path) -> Result<Vec<ColmapFrame>> {
    let mut frames = Vec::new();
    for (number, l) in data_lines(text).filter(|(_, l)| !l.trim().is_empty()) {
        let mut line = Line::new(path, number, l);
        let frame_id = line.value("the frame id")?;
        let rig_id = line.value("the rig id")?;
        let rig_from_world = line.pose("rig_from_world")?;
        let n: usize = line.value("the number of data ids")?;
        let mut data = Vec::new();
        for _ in 0..n {
            let sensor = line.sensor()?;
            data.push((sensor, line.value("a data id")?));
        }
        line.end()?;
        frames.push(ColmapFrame {
            frame_id,
            rig_id,
            rig_from_world,
            data,
        });
    }
    Ok(frames)
}

/// `{:?}` of an `f64` prints the shortest string that reads back to the same value.
fn num(out: &mut String, v: f64) {
    let _ = write!(out, " {v:?}");
}

fn pose_text(out: &mut String, p: &nalgebra::Isometry3<f64>) {
    for v in pose_values(p) {
        num(out, v);
    }
}

/// The five text files of a model: `(file name, content)`.
pub fn model_to_text(model: &ColmapModel) -> Vec<(&'static str, String)> {
    let mut cameras = String::from(
        "# Camera list with one line of data per camera:\n\
         #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let _ = writeln!(cameras, "# Number of cameras: {}", model.cameras.len());
    for c in &model.cameras {
        let _ = write!(
            cameras,
            "{} {} {} {}",
            c.camera_id,
            c.model.name(),
            c.width,
            c.height
        );
        for &p in &c.params {
            num(&mut cameras, p);
        }
        cameras.push('\n');
    }
    let mut images = String::from(
        "# Image list with two lines of data per image:\n\
         #   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n\
         #   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    let _ = writeln!(images, "# Number of images: {}", model.images.len());
    for i in &model.images {
        let _ = write!(images, "{}", i.image_id);
        pose_text(&mut images, &i.cam_from_world);
        let _ = writeln!(images, " {} {}", i.camera_id, i.name);
        let mut first = true;
        for p in &i.points2d {
            if !first {
                images.push(' ');
            }
            first = false;
            let _ = write!(images, "{:?} {:?}", p.xy.x, p.xy.y);
            if p.point3d_id == NO_POINT3D {
                images.push_str(" -1");
            } else {
                let _ = write!(images, " {}", p.point3d_id);
            }
        }
        images.push('\n');
    }
    let mut points = String::from(
        "# 3D point list with one line of data per point:\n\
         #   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
    );
    let _ = writeln!(points, "# Number of points: {}", model.points3d.len());
    for p in &model.points3d {
        let _ = write!(points, "{}", p.point3d_id);
        for v in [p.xyz.x, p.xyz.y, p.xyz.z] {
            num(&mut points, v);
        }
        let _ = write!(points, " {} {} {}", p.color[0], p.color[1], p.color[2]);
        num(&mut points, p.error);
        for (image, idx) in &p.track {
            let _ = write!(points, " {image} {idx}");
        }
        points.push('\n');
    }
    let mut rigs = String::from(
        "# Rig calib list with one line of data per calib:\n\
         #   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as (SENSOR_TYPE, \
         SENSOR_ID, HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])\n",
    );
    let _ = writeln!(rigs, "# Number of rigs: {}", model.rigs.len());
    for r in &model.rigs {
        let _ = write!(
            rigs,
            "{} {} {} {}",
            r.rig_id,
            r.sensors.len() + 1,
            r.ref_sensor.kind.name(),
            r.ref_sensor.id
        );
        for (s, p) in &r.sensors {
            let _ = write!(rigs, " {} {}", s.kind.name(), s.id);
            match p {
                Some(p) => {
                    rigs.push_str(" 1");
                    pose_text(&mut rigs, p);
                }
                None => rigs.push_str(" 0"),
            }
        }
        rigs.push('\n');
    }
    let mut frames = String::from(
        "# Frame list with one line of data per frame:\n\
         #   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, \
         DATA_IDS[] as (SENSOR_TYPE, SENSOR_ID, DATA_ID)\n",
    );
    let _ = writeln!(frames, "# Number of frames: {}", model.frames.len());
    for f in &model.frames {
        let _ = write!(frames, "{} {}", f.frame_id, f.rig_id);
        pose_text(&mut frames, &f.rig_from_world);
        let _ = write!(frames, " {}", f.data.len());
        for (s, id) in &f.data {
            let _ = write!(frames, " {} {} {id}", s.kind.name(), s.id);
        }
        frames.push('\n');
    }
    vec![
        ("cameras.txt", cameras),
        ("images.txt", images),
        ("points3D.txt", points),
        ("rigs.txt", rigs),
        ("frames.txt", frames),
    ]
}
