//! Built-in rigs: the paper's car with four fisheye cameras, the TrimBot2020 ten-camera
//! pentagon rig, and a handheld 6-DoF rig with a pose tracker.
//!
//! A rig is given in the simulator's vehicle (body) frame: x forward, y left, z up (REP-103),
//! origin on the ground below the vehicle's centre (for the handheld rig, at the rig's centre).
//! Camera frames have z along the optical axis, x right, y down. These are the configurations
//! that build the map; a scenario's camera changes move cameras away from them.

use std::f64::consts::PI;

use ibc_camera_models::{Camera, KannalaBrandt, PinholeRadtan, Rig, RigCamera};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

use super::error::SimError;

/// A rig as the simulator uses it: the cameras (intrinsics and `rig_from_camera` in the
/// vehicle frame), the odometry mount and each lens's field of view.
#[derive(Clone, Debug, PartialEq)]
pub struct SimRig {
    /// The cameras, with their extrinsics in the vehicle frame.
    pub rig: Rig,
    /// Maps odometry-frame coordinates into the vehicle frame.
    pub rig_from_odometry: Isometry3<f64>,
    /// Per camera, the largest angle from the optical axis at which the lens images anything
    /// (radians; half the lens's field of view). A fisheye's image circle ends there even
    /// where the model would still give a pixel inside the sensor.
    pub max_incidence_rad: Vec<f64>,
}

/// The built-in rigs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuiltinRig {
    /// The paper's car: four Kannala-Brandt fisheyes (front, left, rear, right), 1280x960,
    /// 190-degree lenses, mounted in the grille, under the side mirrors and on the tailgate.
    CarFisheye,
    /// The TrimBot2020 pentagon rig on a garden robot: five stereo pairs of 752x480
    /// pinhole-radtan cameras, 82 degrees of horizontal field of view, 30 mm baselines, pairs
    /// 72 degrees apart.
    Pentagon,
    /// A handheld rig: three 848x800 Kannala-Brandt fisheyes (165-degree lenses) 120 degrees
    /// apart, with a 6-DoF pose tracker mounted upside down and turned.
    Handheld,
    /// A TUM-VI-like stereo pair: two forward-looking 512x512 Kannala-Brandt fisheyes with
    /// 195-degree lenses, 10 cm apart, with a 6-DoF pose tracker; the image corners see rays
    /// up to 97.5 degrees from the optical axis.
    FisheyePair,
}

impl BuiltinRig {
    /// Every built-in rig.
    pub const ALL: [Self; 4] = [
        Self::CarFisheye,
        Self::Pentagon,
        Self::Handheld,
        Self::FisheyePair,
    ];

    /// Its name in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            Self::CarFisheye => "car-fisheye",
            Self::Pentagon => "pentagon",
            Self::Handheld => "handheld",
            Self::FisheyePair => "fisheye-pair",
        }
    }

    /// The rig of a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The rig.
    ///
    /// # Errors
    /// Never in practice: the parameters are constants the camera models accept; an error
    /// would name the camera whose parameters were refused.
    pub fn build(self) -> Result<SimRig, SimError> {
        match self {
            Self::CarFisheye => car_fisheye(),
            Self::Pentagon => pentagon(),
            Self::Handheld => handheld(),
            Self::FisheyePair => fisheye_pair(),
        }
    }
}

/// The rotation of a camera looking along the vehicle's x-axis, level: camera z = vehicle x,
/// camera x = -vehicle y (right), camera y = -vehicle z (down).
fn forward_camera() -> Rotation3<f64> {
    Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, //
        -1.0, 0.0, 0.0, //
        0.0, -1.0, 0.0,
    ))
}

/// `rig_from_camera` of a camera at `position` (vehicle frame) looking at azimuth `yaw_deg`
/// (counter-clockwise from forward), tilted down by `pitch_down_deg` and rolled about its
/// optical axis by `roll_deg`.
pub fn mount(
    position: Vector3<f64>,
    yaw_deg: f64,
    pitch_down_deg: f64,
    roll_deg: f64,
) -> Isometry3<f64> {
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_deg.to_radians())
        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch_down_deg.to_radians())
        * forward_camera()
        * Rotation3::from_axis_angle(&Vector3::z_axis(), roll_deg.to_radians());
    Isometry3::from_parts(
        Translation3::from(position),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

fn kb(name: &str, width: u32, height: u32, params: [f64; 8]) -> Result<Camera, SimError> {
    KannalaBrandt::new(width, height, params)
        .map(Camera::from)
        .map_err(|source| SimError::BuiltinCamera {
            name: name.to_owned(),
            source,
        })
}

fn pinhole(name: &str, params: [f64; 8]) -> Result<Camera, SimError> {
    PinholeRadtan::new(752, 480, params)
        .map(Camera::from)
        .map_err(|source| SimError::BuiltinCamera {
            name: name.to_owned(),
            source,
        })
}

/// The car: cameras named `front`, `left`, `rear`, `right`, in that order.
///
/// Vehicle 4.7 m long and 1.85 m wide, frame origin on the ground below its centre. The
/// front camera sits in the grille 0.65 m up, the side cameras under the mirrors 1.0 m up and
/// tilted 30 degrees down, the rear camera on the tailgate 0.9 m up; each has a small
/// mounting error of a fraction of a degree, as a real car does. The wheel-odometry frame is
/// the rear axle's centre on the ground, 1.4 m behind the origin.
fn car_fisheye() -> Result<SimRig, SimError> {
    let k = [-0.012, 0.0025, -0.0007, 0.00005];
    let cams = [
        // name, position, yaw, pitch down, roll, mu, mv, u0, v0
        (
            "front",
            Vector3::new(2.30, 0.00, 0.65),
            0.6,
            14.0,
            -0.4,
            396.2,
            395.8,
            642.1,
            478.3,
        ),
        (
            "left",
            Vector3::new(0.95, 0.98, 1.00),
            90.8,
            30.0,
            0.7,
            394.9,
            395.1,
            637.6,
            481.9,
        ),
        (
            "rear",
            Vector3::new(-2.30, 0.02, 0.90),
            179.4,
            22.0,
            0.3,
            395.5,
            395.3,
            640.8,
            476.4,
        ),
        (
            "right",
            Vector3::new(0.95, -0.98, 1.00),
            -89.6,
            30.5,
            -0.6,
            396.8,
            396.5,
            643.2,
            482.7,
        ),
    ];
    let mut cameras = Vec::with_capacity(cams.len());
    for (i, (name, p, yaw, pitch, roll, mu, mv, u0, v0)) in cams.into_iter().enumerate() {
        // Slightly different lenses, as four real ones are.
        let s = 1.0 + 0.01 * i as f64;
        let params = [k[0] * s, k[1] * s, k[2], k[3], mu, mv, u0, v0];
        let camera = kb(name, 1280, 960, params)?;
        cameras.push(RigCamera::new(name, camera, mount(p, yaw, pitch, roll)));
    }
    Ok(SimRig {
        rig: named_topics(Rig::new(cameras)),
        rig_from_odometry: Isometry3::translation(-1.4, 0.0, 0.0),
        max_incidence_rad: vec![95f64.to_radians(); 4],
    })
}

/// The pentagon rig: pairs `pair0` (forward) to `pair4` counter-clockwise 72 degrees apart,
/// cameras `pairN-left` and `pairN-right` 30 mm apart with parallel optical axes, 0.1 m from
/// the rig's axis, 0.6 m above the ground, tilted 5 degrees down. The robot's wheel-odometry
/// frame is its axle centre on the ground, 0.15 m behind the rig's axis.
fn pentagon() -> Result<SimRig, SimError> {
    // fx = 376 / tan(41 deg): an 82-degree horizontal field of view before distortion.
    let f = 376.0 / (41f64.to_radians()).tan();
    let mut cameras = Vec::with_capacity(10);
    for pair in 0..5 {
        let yaw = 72.0 * f64::from(pair);
        let a = yaw.to_radians();
        let ahead = Vector3::new(a.cos(), a.sin(), 0.0);
        let left = Vector3::new(-a.sin(), a.cos(), 0.0);
        let centre = ahead * 0.10 + Vector3::new(0.0, 0.0, 0.60);
        for (side, offset) in [("left", 0.015), ("right", -0.015)] {
            let name = format!("pair{pair}-{side}");
            let i = f64::from(pair) * 2.0 + if side == "left" { 0.0 } else { 1.0 };
            let params = [
                -0.05 + 0.002 * i,
                0.004,
                0.0002,
                -0.0001,
                f + 0.4 * i,
                f - 0.3 * i,
                375.5 + 1.1 * (i - 4.5),
                239.5 - 0.7 * (i - 4.5),
            ];
            let camera = pinhole(&name, params)?;
            let pose = mount(
                centre + left * offset,
                yaw + 0.03 * (i - 4.5),
                5.0,
                0.05 * i,
            );
            cameras.push(RigCamera::new(name, camera, pose));
        }
    }
    Ok(SimRig {
        rig: named_topics(Rig::new(cameras)),
        rig_from_odometry: Isometry3::translation(-0.15, 0.0, 0.0),
        max_incidence_rad: vec![PI / 2.0; 10],
    })
}

/// The handheld rig: cameras `front`, `back-left`, `back-right` 0.08 m from the rig's centre,
/// 120 degrees apart and level. The pose tracker is mounted 7 cm below the centre, upside down
/// and turned 90 degrees, so `rig_from_odometry` is a general rotation.
fn handheld() -> Result<SimRig, SimError> {
    let cams = [("front", 0.0), ("back-left", 120.0), ("back-right", -120.0)];
    let mut cameras = Vec::with_capacity(3);
    for (i, (name, yaw)) in cams.into_iter().enumerate() {
        let a = f64::to_radians(yaw);
        let p = Vector3::new(a.cos(), a.sin(), 0.0) * 0.08;
        let s = i as f64;
        let params = [
            -0.004,
            0.0386,
            -0.0362,
            0.0061,
            285.7 + s,
            285.9 - s,
            424.3 + s,
            400.6 - s,
        ];
        let camera = kb(name, 848, 800, params)?;
        cameras.push(RigCamera::new(name, camera, mount(p, yaw, 0.0, 0.2 * s)));
    }
    let tracker = UnitQuaternion::from_euler_angles(PI, 0.0, PI / 2.0)
        * UnitQuaternion::from_euler_angles(0.02, -0.03, 0.01);
    Ok(SimRig {
        rig: named_topics(Rig::new(cameras)),
        rig_from_odometry: Isometry3::from_parts(Translation3::new(0.03, -0.02, -0.07), tracker),
        max_incidence_rad: vec![82.5f64.to_radians(); 3],
    })
}

/// The TUM-VI-like pair: cameras `cam0` (left) and `cam1` (right), 10 cm apart, both
/// looking forward (the rig's x-axis), with mounting errors of a fraction of a degree. The
/// intrinsics are close to the published calibration of the TUM-VI dataset's cameras
/// (Schubert et al., "The TUM VI Benchmark for Evaluating Visual-Inertial Odometry", IROS
/// 2018: 512x512, f about 191 px, Kannala-Brandt), so r(90 deg) is about 297 px and the image
/// circle of the 195-degree lens (318 px) reaches into the corners. The pose tracker sits
/// 5 cm behind the pair, turned.
fn fisheye_pair() -> Result<SimRig, SimError> {
    let cams = [("cam0", 0.05, 0.0), ("cam1", -0.05, 1.0)];
    let mut cameras = Vec::with_capacity(2);
    for (name, y, s) in cams {
        let params = [
            0.0035,
            0.0007,
            -0.0021,
            0.0002,
            190.97 + 0.3 * s,
            190.98 - 0.2 * s,
            254.93 + 0.9 * s,
            256.90 - 0.6 * s,
        ];
        let camera = kb(name, 512, 512, params)?;
        let pose = mount(
            Vector3::new(0.0, y, 0.0),
            0.3 - 0.5 * s,
            0.2 * s,
            -0.4 + 0.6 * s,
        );
        cameras.push(RigCamera::new(name, camera, pose));
    }
    let tracker = UnitQuaternion::from_euler_angles(PI / 2.0, 0.0, -PI / 2.0)
        * UnitQuaternion::from_euler_angles(0.01, 0.02, -0.015);
    Ok(SimRig {
        rig: named_topics(Rig::new(cameras)),
        rig_from_odometry: Isometry3::from_parts(Translation3::new(-0.05, 0.01, 0.02), tracker),
        max_incidence_rad: vec![97.5f64.to_radians(); 2],
    })
}

/// Sets each camera's Kalibr `rostopic` to `/<name>/image_raw`, so the names survive a
/// camchain (which stores cameras as `cam0`, `cam1`, ...).
fn named_topics(mut rig: Rig) -> Rig {
    for c in &mut rig.cameras {
        c.topic = Some(format!("/{}/image_raw", c.name));
    }
    rig
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn mount_points_the_optical_axis_where_asked() {
        // Looking left (yaw 90), tilted 30 degrees down.
        let pose = mount(Vector3::zeros(), 90.0, 30.0, 0.0);
        let axis = pose.rotation * Vector3::z();
        let c = 30f64.to_radians().cos();
        let s = 30f64.to_radians().sin();
        assert_abs_diff_eq!(axis, Vector3::new(0.0, c, -s), epsilon = 1e-12);
        // Image x points right of the view: for a camera looking left, that is forward.
        assert_abs_diff_eq!(
            pose.rotation * Vector3::x(),
            Vector3::new(1.0, 0.0, 0.0),
            epsilon = 1e-12
        );
    }

    #[test]
    fn pentagon_pairs_have_30_mm_baselines_72_degrees_apart() {
        let rig = pentagon().unwrap().rig;
        assert_eq!(rig.cameras.len(), 10);
        for pair in 0..5 {
            let l = &rig.cameras[2 * pair].rig_from_camera;
            let r = &rig.cameras[2 * pair + 1].rig_from_camera;
            assert_abs_diff_eq!(
                (l.translation.vector - r.translation.vector).norm(),
                0.030,
                epsilon = 1e-12
            );
            let next = &rig.cameras[(2 * pair + 2) % 10].rig_from_camera;
            // Azimuths of the optical axes (each pair is tilted 5 degrees down).
            let azimuth = |p: &Isometry3<f64>| {
                let a = p.rotation * Vector3::z();
                a.y.atan2(a.x).to_degrees()
            };
            let step = (azimuth(next) - azimuth(l)).rem_euclid(360.0);
            assert_abs_diff_eq!(step, 72.0, epsilon = 0.3);
        }
    }
}
