//! Bad input gives typed errors, never a panic and never a silently wrong value.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use ibc_camera_models::{
    Camera, CameraModel, KannalaBrandt, ParameterError, PinholeRadtan, ProjectionError, Unified,
    UnprojectionError,
};
use nalgebra::{Vector2, Vector3};

#[test]
fn non_finite_and_zero_points_and_pixels() {
    for (name, camera) in common::all_cameras() {
        for p in [
            Vector3::new(f64::NAN, 0.0, 1.0),
            Vector3::new(0.0, f64::INFINITY, 1.0),
            Vector3::new(0.0, 0.0, f64::NEG_INFINITY),
        ] {
            assert_eq!(
                camera.project(&p),
                Err(ProjectionError::NonFinitePoint),
                "{name}"
            );
            assert_eq!(
                camera.project_with_jacobians(&p).err(),
                Some(ProjectionError::NonFinitePoint)
            );
        }
        assert_eq!(
            camera.project(&Vector3::zeros()),
            Err(ProjectionError::ZeroPoint)
        );
        for px in [
            Vector2::new(f64::NAN, 1.0),
            Vector2::new(1.0, f64::INFINITY),
        ] {
            assert_eq!(
                camera.unproject(&px),
                Err(UnprojectionError::NonFinitePixel),
                "{name}"
            );
            assert_eq!(
                camera.unproject_fast(&px),
                Err(UnprojectionError::NonFinitePixel)
            );
            assert_eq!(
                camera.unproject_with_jacobians(&px).err(),
                Some(UnprojectionError::NonFinitePixel)
            );
            assert!(camera.radians_per_pixel(&px).is_err());
            assert!(!camera.in_image(&px));
        }
        // Absurd pixels: an error or a valid unit ray, never a panic or a NaN.
        for px in [
            Vector2::new(1e300, -1e300),
            Vector2::new(-1e9, 3.0),
            Vector2::new(1e6, 1e6),
        ] {
            if let Ok(ray) = camera.unproject(&px) {
                assert!((ray.norm() - 1.0).abs() < 1e-12 && ray.iter().all(|v| v.is_finite()));
            }
        }
        // Tiny and huge (but finite) points still project or fail cleanly.
        for p in [
            Vector3::new(1e-300, 1e-300, 1e-300),
            Vector3::new(1e300, 1e300, 1e300),
        ] {
            if let Ok(px) = camera.project(&p) {
                assert!(px.iter().all(|v| v.is_finite()), "{name}: {p:?}");
            }
        }
    }
}

#[test]
fn points_outside_each_domain() {
    let pin = common::euroc_cam0();
    assert!(matches!(
        pin.project(&Vector3::new(0.1, 0.0, -1.0)),
        Err(ProjectionError::BehindCamera { .. })
    ));
    assert!(matches!(
        pin.project(&Vector3::new(1.0, 0.0, 0.0)),
        Err(ProjectionError::BehindCamera { .. })
    ));
    // Beyond the fold: CamOdoCal's KB test camera folds at about 112 degrees.
    let kb = common::camodocal_kb();
    let beyond = common::direction(kb.theta_max() + 1e-6, 0.5);
    assert!(matches!(
        kb.project(&beyond),
        Err(ProjectionError::BeyondFold { .. })
    ));
    assert!(matches!(
        kb.project_with_jacobians(&beyond),
        Err(ProjectionError::BeyondFold { .. })
    ));
    // The negative optical axis of a lens with no fold: its image is a circle.
    let tum = common::tum_kb();
    assert_eq!(
        tum.project(&Vector3::new(0.0, 0.0, -1.0)),
        Err(ProjectionError::OnNegativeAxis)
    );
    // A KB with a fold refuses the negative axis as beyond the fold.
    assert!(matches!(
        kb.project(&Vector3::new(0.0, 0.0, -1.0)),
        Err(ProjectionError::BeyondFold { .. })
    ));
    // Mei: z <= -w |P|.
    for mei in [
        common::camodocal_mei(),
        common::mei_xi_145(),
        common::mei_xi_182(),
    ] {
        let limit = mei.cos_theta_limit();
        let outside = common::direction(limit.acos() + 1e-6, 1.0);
        assert!(
            matches!(
                mei.project(&outside),
                Err(ProjectionError::OutsideMeiDomain { .. })
            ),
            "xi {}",
            mei.xi()
        );
    }
    // Mei with xi > 1: a pixel whose undistorted radius is past 1 / sqrt(xi^2 - 1).
    let plain = Unified::new(
        640,
        480,
        [1.5, 0.0, 0.0, 0.0, 0.0, 500.0, 500.0, 320.0, 240.0],
    )
    .unwrap();
    let r_max = 1.0 / (1.5f64 * 1.5 - 1.0).sqrt();
    let px = Vector2::new(320.0 + 500.0 * r_max * 1.01, 240.0);
    assert!(matches!(
        plain.unproject(&px),
        Err(UnprojectionError::OutsideMeiDomain { .. })
    ));
    let inside = Vector2::new(320.0 + 500.0 * r_max * 0.99, 240.0);
    assert!(
        plain.unproject(&inside).unwrap().z < 0.0,
        "a ray behind the image plane"
    );
    // Radial-tangential beyond the injective radius.
    let folding =
        PinholeRadtan::new(640, 480, [-0.5, 0.0, 0.0, 0.0, 400.0, 400.0, 320.0, 240.0]).unwrap();
    let r_inj = folding.injective_radius();
    assert!((r_inj - (1.0f64 / 1.5).sqrt()).abs() < 1e-8);
    assert!(matches!(
        folding.project(&Vector3::new(r_inj * 1.01, 0.0, 1.0)),
        Err(ProjectionError::BeyondInjectiveRadius { .. })
    ));
    // Pixels past the image of the fold have no ray inside the radius.
    let px = Vector2::new(320.0 + 400.0 * 0.6, 240.0);
    assert!(folding.unproject(&px).is_err());
}

#[test]
fn invalid_parameters_are_refused_and_leave_the_camera_unchanged() {
    assert!(matches!(
        KannalaBrandt::new(0, 480, [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0]),
        Err(ParameterError::EmptyImage { .. })
    ));
    let mut kb = common::camodocal_kb();
    let before = kb.clone();
    let p = kb.params().to_vec();
    assert!(matches!(
        kb.set_params(&p[..7]),
        Err(ParameterError::WrongCount { got: 7, .. })
    ));
    let mut bad = p.clone();
    bad[2] = f64::NAN;
    assert!(matches!(
        kb.set_params(&bad),
        Err(ParameterError::NonFinite { name: "k3", .. })
    ));
    let mut bad = p.clone();
    bad[4] = 0.0;
    assert!(matches!(
        kb.set_params(&bad),
        Err(ParameterError::NotPositive { name: "mu", .. })
    ));
    assert_eq!(kb, before);
    let mut mei = Camera::from(common::camodocal_mei());
    let mut bad = mei.params().to_vec();
    bad[0] = -0.1;
    assert!(matches!(
        mei.set_params(&bad),
        Err(ParameterError::Negative { name: "xi", .. })
    ));
    let mut pin = Camera::from(common::euroc_cam0());
    let mut bad = pin.params().to_vec();
    bad[5] = -458.0;
    assert!(matches!(
        pin.set_params(&bad),
        Err(ParameterError::NotPositive { name: "fy", .. })
    ));
    // A valid change is applied, with the derived limits recomputed.
    let mut kb = common::tum_kb();
    let mut q = kb.params().to_vec();
    q[0] = -0.2; // a strong negative k1 creates a fold
    kb.set_params(&q).unwrap();
    assert!(kb.has_fold() && kb.theta_max() < 2.0);
}

#[test]
fn kb_fallback_is_flagged_for_pixels_beyond_the_fold() {
    let kb = common::camodocal_kb();
    let far = Vector2::new(-300.0, -300.0);
    assert!(matches!(
        kb.unproject(&far),
        Err(UnprojectionError::BeyondFold { .. })
    ));
    assert!(kb.backproject_with_fallback(&far).unwrap().fallback);
    assert!(
        kb.backproject_with_fallback(&Vector2::new(f64::NAN, 0.0))
            .is_err()
    );
}

#[test]
fn kb_subnormal_coefficient_neither_hangs_nor_misleads() {
    // With k4 = +-1e-310 the companion matrix holds -c_i / k4 = infinity; balancing such a
    // matrix used to loop forever (in `new`, through the fold's quartic, and per pixel).
    for k4 in [1e-310, -1e-310, 5e-324] {
        let kb = KannalaBrandt::new(1000, 1000, [0.0, 0.0, 0.0, k4, 500.0, 500.0, 500.0, 500.0])
            .unwrap();
        // r(theta) = theta to within 1e-300: no fold before pi.
        assert_eq!(kb.theta_max(), std::f64::consts::PI);
        let px = Vector2::new(900.0, 500.0);
        let fast = kb.unproject_fast(&px).unwrap();
        // The equidistant ray: theta = d = 0.8.
        assert!((fast.z - 0.8_f64.cos()).abs() < 1e-15, "{k4:e}");
        // The companion path either agrees or says why it cannot, never a wrong ray.
        match kb.unproject(&px) {
            Ok(ray) => assert!(ray.angle(&fast) <= 1e-12, "{k4:e}"),
            Err(e) => assert!(
                matches!(
                    e,
                    UnprojectionError::EigenvalueIterationLimit { .. }
                        | UnprojectionError::NoRealRoot
                ),
                "{k4:e}: {e}"
            ),
        }
    }
}
