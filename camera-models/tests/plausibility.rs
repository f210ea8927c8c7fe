//! Plausibility of cameras: every legitimate camera of the repository passes, and each
//! absurd value fails on its check with the parameter named.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::f64::consts::TAU;

use ibc_camera_models::plausibility::{
    MAX_ANGLE_RATIO, MAX_ASPECT_RATIO, MAX_FOCAL_PER_SIDE, MIN_ANGLE_RATIO, MIN_EDGE_ANGLE_DEG,
    MIN_FOCAL_PER_SIDE, ROUND_TRIP_TOLERANCE_PX,
};
use ibc_camera_models::{
    Camera, CameraModel, KannalaBrandt, PinholeRadtan, PlausibilityError, Rig, Unified,
};
use nalgebra::Vector2;

/// The repository's example rigs (`examples/scenarios/rigs`).
const SCENARIO_RIGS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/scenarios/rigs");

/// The TrimBot2020 camchain (`tests/data/README.md`).
const TRIMBOT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/data/trimbot-camchain.yaml"
);

/// The built-in simulated rigs of `examples/src/sim/rigs.rs`, their parameters copied here.
fn simulated_rigs() -> Vec<(String, Camera)> {
    let mut out = Vec::new();
    // The car: four Kannala-Brandt fisheyes, 1280 x 960, k1 and k2 scaled by 1 + 0.01 i.
    let k = [-0.012, 0.0025, -0.0007, 0.00005];
    let car = [
        ("front", 396.2, 395.8, 642.1, 478.3),
        ("left", 394.9, 395.1, 637.6, 481.9),
        ("rear", 395.5, 395.3, 640.8, 476.4),
        ("right", 396.8, 396.5, 643.2, 482.7),
    ];
    for (i, (name, mu, mv, u0, v0)) in car.into_iter().enumerate() {
        let s = 1.0 + 0.01 * i as f64;
        let params = [k[0] * s, k[1] * s, k[2], k[3], mu, mv, u0, v0];
        out.push((
            format!("car-fisheye {name}"),
            KannalaBrandt::new(1280, 960, params).unwrap().into(),
        ));
    }
    // The pentagon: ten pinhole-radtan cameras, 752 x 480, fx = 376 / tan(41 deg).
    let f = 376.0 / 41f64.to_radians().tan();
    for i in 0..10 {
        let i = f64::from(i);
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
        out.push((
            format!("pentagon {i}"),
            PinholeRadtan::new(752, 480, params).unwrap().into(),
        ));
    }
    // The handheld rig: three Kannala-Brandt fisheyes, 848 x 800.
    for s in [0.0, 1.0, 2.0] {
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
        out.push((
            format!("handheld {s}"),
            KannalaBrandt::new(848, 800, params).unwrap().into(),
        ));
    }
    // `examples/src/intrinsics/simulate.rs`: the 190-degree fisheye (the EuRoC pinhole is
    // among the fixtures).
    out.push((
        "intrinsics fisheye_190".to_owned(),
        KannalaBrandt::new(
            1280,
            960,
            [
                0.0123, -0.0046, 0.00071, -0.000041, 301.7, 301.2, 643.4, 478.1,
            ],
        )
        .unwrap()
        .into(),
    ));
    out
}

/// Every legitimate camera: the test fixtures, the TrimBot camchain, the example rigs' files
/// and the simulated rigs.
fn legitimate_cameras() -> Vec<(String, Camera)> {
    let mut out: Vec<(String, Camera)> = common::all_cameras()
        .into_iter()
        .map(|(n, c)| (n.to_owned(), c))
        .collect();
    let rigs = [
        ("trimbot", Rig::read_kalibr(TRIMBOT).unwrap()),
        (
            "stereo-rear",
            Rig::read_kalibr(format!("{SCENARIO_RIGS}/stereo-rear-camchain.yaml")).unwrap(),
        ),
        (
            "camodocal-car",
            Rig::read_camodocal_dir(format!("{SCENARIO_RIGS}/camodocal-car")).unwrap(),
        ),
    ];
    for (rig_name, rig) in rigs {
        for c in rig.cameras {
            out.push((format!("{rig_name} {}", c.name), c.camera));
        }
    }
    out.extend(simulated_rigs());
    out
}

/// The figures each check compares with its threshold.
#[derive(Debug)]
struct Figures {
    /// Shortest and longest paraxial focal length over the larger side.
    focal_per_side: (f64, f64),
    /// Larger focal over the smaller.
    aspect: f64,
    /// Smallest and largest angle ratio on the largest circle.
    angle_ratio: (f64, f64),
    /// Smallest angle of incidence on the largest circle (degrees).
    edge_angle_deg: f64,
    /// Largest round-trip error (pixels).
    round_trip_px: f64,
}

fn figures(camera: &Camera) -> Figures {
    let (w, h) = (f64::from(camera.width()), f64::from(camera.height()));
    let p = camera.params();
    let (fx, fy) = match camera {
        Camera::KannalaBrandt(_) | Camera::PinholeRadtan(_) => (p[4], p[5]),
        Camera::Unified(_) => (p[5] / (1.0 + p[0]), p[6] / (1.0 + p[0])),
        _ => unreachable!(),
    };
    let pp = camera.principal_point();
    let radius = (pp.x + 0.5)
        .min(w - 0.5 - pp.x)
        .min(pp.y + 0.5)
        .min(h - 0.5 - pp.y);
    let mut f = Figures {
        focal_per_side: (fx.min(fy) / w.max(h), fx.max(fy) / w.max(h)),
        aspect: fx.max(fy) / fx.min(fy),
        angle_ratio: (f64::INFINITY, 0.0),
        edge_angle_deg: f64::INFINITY,
        round_trip_px: 0.0,
    };
    for fraction in [0.25, 0.5, 0.75, 1.0] {
        for i in 0..32 {
            let phi = TAU * f64::from(i) / 32.0;
            let offset = Vector2::new(phi.cos(), phi.sin()) * radius * fraction;
            let ray = camera.unproject(&(pp + offset)).unwrap();
            let back = camera.project(&ray).unwrap();
            f.round_trip_px = f.round_trip_px.max((back - pp - offset).norm());
            if fraction == 1.0 {
                let angle = ray.x.hypot(ray.y).atan2(ray.z);
                let ratio = angle / (offset.x / fx).hypot(offset.y / fy);
                f.angle_ratio = (f.angle_ratio.0.min(ratio), f.angle_ratio.1.max(ratio));
                f.edge_angle_deg = f.edge_angle_deg.min(angle.to_degrees());
            }
        }
    }
    f
}

#[test]
fn every_legitimate_camera_is_plausible_with_a_margin() {
    let cameras = legitimate_cameras();
    assert!(cameras.len() == 35, "{}", cameras.len());
    let mut worst = Figures {
        focal_per_side: (f64::INFINITY, 0.0),
        aspect: 1.0,
        angle_ratio: (f64::INFINITY, 0.0),
        edge_angle_deg: f64::INFINITY,
        round_trip_px: 0.0,
    };
    for (name, camera) in &cameras {
        camera
            .check_plausible()
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let f = figures(camera);
        worst.focal_per_side.0 = worst.focal_per_side.0.min(f.focal_per_side.0);
        worst.focal_per_side.1 = worst.focal_per_side.1.max(f.focal_per_side.1);
        worst.aspect = worst.aspect.max(f.aspect);
        worst.angle_ratio.0 = worst.angle_ratio.0.min(f.angle_ratio.0);
        worst.angle_ratio.1 = worst.angle_ratio.1.max(f.angle_ratio.1);
        worst.edge_angle_deg = worst.edge_angle_deg.min(f.edge_angle_deg);
        worst.round_trip_px = worst.round_trip_px.max(f.round_trip_px);
    }
    // The figures the thresholds' documentation quotes (measured: focal 0.235 to 0.951 of the
    // larger side, aspect 1.015, angle ratio 0.921 to 1.083, edge angle 19.1 deg, round trip
    // 9.2e-13 px), each with a margin of more than 4 to its threshold.
    eprintln!("widest figures of the legitimate cameras: {worst:?}");
    assert!(worst.focal_per_side.0 > 4.0 * MIN_FOCAL_PER_SIDE);
    assert!(worst.focal_per_side.1 < MAX_FOCAL_PER_SIDE / 4.0);
    assert!(4.0 * (worst.aspect - 1.0) < MAX_ASPECT_RATIO - 1.0);
    assert!(worst.angle_ratio.0 > 4.0 * MIN_ANGLE_RATIO);
    assert!(worst.angle_ratio.1 < MAX_ANGLE_RATIO / 4.0);
    assert!(worst.edge_angle_deg > 4.0 * MIN_EDGE_ANGLE_DEG);
    assert!(worst.round_trip_px < ROUND_TRIP_TOLERANCE_PX / 1e4);
}

/// EuRoC cam0 with parameter `i` replaced.
fn euroc_with(i: usize, value: f64) -> Camera {
    let mut p: [f64; 8] = common::euroc_cam0().params().try_into().unwrap();
    p[i] = value;
    PinholeRadtan::new(752, 480, p).unwrap().into()
}

/// CamOdoCal's KB test camera with parameter `i` replaced.
fn kb_with(i: usize, value: f64) -> Camera {
    let mut p: [f64; 8] = common::camodocal_kb().params().try_into().unwrap();
    p[i] = value;
    KannalaBrandt::new(1280, 800, p).unwrap().into()
}

/// CamOdoCal's Mei test camera with parameter `i` replaced.
fn mei_with(i: usize, value: f64) -> Camera {
    let mut p: [f64; 9] = common::camodocal_mei().params().try_into().unwrap();
    p[i] = value;
    Unified::new(1280, 800, p).unwrap().into()
}

fn refused(camera: &Camera) -> PlausibilityError {
    camera.check_plausible().expect_err("an implausible camera")
}

#[test]
fn absurd_focal_lengths_are_refused_naming_the_focal_parameter() {
    // fu = 3.4e38 (the largest f32) and fu = 4.3e9 (a u32 overflow), as in the files seen.
    for fu in [3.4e38, 4.3e9] {
        let e = refused(&euroc_with(4, fu));
        assert!(
            matches!(e, PlausibilityError::FocalLength { name: "fx", .. }),
            "{e}"
        );
        assert_eq!(e.value(), fu);
        let e = refused(&kb_with(4, fu));
        assert_eq!(e.parameter(), "mu", "{e}");
    }
    // Too short: 10 px on a 1280-px image (a 360-degree lens needs 204).
    let e = refused(&kb_with(5, 10.0));
    assert!(
        matches!(e, PlausibilityError::FocalLength { name: "mv", max_px, .. } if max_px == 128_000.0),
        "{e}"
    );
    // The unified model's paraxial focal length is gamma / (1 + xi): gamma2 = 1e6 with
    // xi = 0.895 is 5.3e5 px, over 100 x 1280.
    let e = refused(&mei_with(6, 1e6));
    assert!(
        matches!(e, PlausibilityError::FocalLength { name: "gamma2", focal_px, .. }
            if (focal_px - 1e6 / 1.894975).abs() < 1e-6),
        "{e}"
    );
    assert!(e.to_string().contains("gamma2 = 1000000"), "{e}");
}

#[test]
fn a_squeezed_pixel_aspect_is_refused_naming_the_longer_focal() {
    let e = refused(&euroc_with(5, 458.654 * 3.5));
    assert!(
        matches!(e, PlausibilityError::AspectRatio { name: "fy", other_name: "fx", ratio, .. }
            if (ratio - 3.5).abs() < 1e-12),
        "{e}"
    );
}

#[test]
fn a_principal_point_outside_the_image_is_refused_naming_it() {
    // v0 = -476 px, as in the file seen.
    let e = refused(&kb_with(7, -476.0));
    assert!(
        matches!(e, PlausibilityError::PrincipalPoint { name: "v0", value: -476.0, max, .. }
            if max == 799.5),
        "{e}"
    );
    let e = refused(&euroc_with(6, 752.0));
    assert_eq!(e.parameter(), "cx", "{e}");
    // 0.1 px inside the edge is inside (it fails later, for its 0.1-px circle).
    let e = refused(&euroc_with(6, 751.4));
    assert!(
        matches!(e, PlausibilityError::NarrowField { name: "cx", .. }),
        "{e}"
    );
}

#[test]
fn k2_of_4e9_squeezes_the_image_and_is_named() {
    // k2 = 4.3e9 (a u32 overflow): the whole image within about half a degree.
    for camera in [euroc_with(1, 4.3e9), kb_with(1, 4.3e9), mei_with(2, 4.3e9)] {
        let e = refused(&camera);
        assert!(
            matches!(e, PlausibilityError::AngleRatio { name: "k2", ratio, .. } if ratio < 0.05),
            "{}: {e}",
            camera.model_name()
        );
        assert_eq!(e.value(), 4.3e9);
    }
}

#[test]
fn a_model_that_folds_inside_the_image_is_refused_naming_the_term() {
    // Kannala-Brandt with k1 = -0.3 folds at 60 degrees, r = 0.70: 295 px from the centre.
    let e = refused(&kb_with(0, -0.3));
    assert!(
        matches!(
            e,
            PlausibilityError::NoRay {
                name: "k1",
                reason: ibc_camera_models::UnprojectionError::BeyondFold { .. },
                ..
            }
        ),
        "{e}"
    );
    // Radial-tangential k1 = -0.5 is injective up to r = 0.82, whose image is 218 px from
    // the centre of a 640 x 480 image.
    let folding = PinholeRadtan::new(640, 480, [-0.5, 0.0, 0.0, 0.0, 400.0, 400.0, 319.5, 239.5])
        .unwrap()
        .check_plausible()
        .unwrap_err();
    assert!(
        matches!(folding, PlausibilityError::NoRay { name: "k1", .. }),
        "{folding}"
    );
    // Unified with xi = 1.5 and gamma = 200 lifts only r <= 0.89, 179 px: xi is at fault.
    let mei = Unified::new(
        640,
        480,
        [1.5, 0.0, 0.0, 0.0, 0.0, 200.0, 200.0, 319.5, 239.5],
    )
    .unwrap()
    .check_plausible()
    .unwrap_err();
    assert!(
        matches!(
            mei,
            PlausibilityError::NoRay {
                name: "xi",
                reason: ibc_camera_models::UnprojectionError::OutsideMeiDomain { .. },
                ..
            }
        ),
        "{mei}"
    );
}

#[test]
fn a_narrow_field_names_the_principal_point_or_the_focal_length() {
    // The principal point 0.1 px from the left edge: the largest circle is 0.1 px.
    let e = refused(&euroc_with(6, -0.4));
    assert!(
        matches!(e, PlausibilityError::NarrowField { name: "cx", radius_px, .. }
            if (radius_px - 0.1).abs() < 1e-9),
        "{e}"
    );
    // A 1000 x 40 strip behind a 95 000-px telephoto: 20 px is 0.012 degrees.
    let strip = PinholeRadtan::new(1000, 40, [0.0, 0.0, 0.0, 0.0, 95e3, 95e3, 499.5, 19.5])
        .unwrap()
        .check_plausible()
        .unwrap_err();
    assert!(
        matches!(strip, PlausibilityError::NarrowField { name: "fx", angle_deg, .. }
            if angle_deg < 0.02),
        "{strip}"
    );
}

#[test]
fn messages_read_plainly() {
    for camera in [
        euroc_with(4, 3.4e38),
        euroc_with(5, 458.654 * 3.5),
        kb_with(7, -476.0),
        euroc_with(1, 4.3e9),
        kb_with(0, -0.3),
        euroc_with(6, -0.4),
    ] {
        eprintln!("{}", refused(&camera));
    }
}

#[test]
fn each_model_checks_itself_as_the_enum_does() {
    let kb = common::camodocal_kb();
    assert_eq!(kb.check_plausible(), Camera::from(kb).check_plausible());
    assert!(common::euroc_cam0().check_plausible().is_ok());
    assert!(common::mei_xi_182().check_plausible().is_ok());
}
