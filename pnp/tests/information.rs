//! The information matrix of a bearing under pixel noise, for every camera model: against
//! the pseudo-inverse of a finite-difference covariance and a Monte-Carlo covariance of
//! unprojected noisy pixels, equal to the pinhole helper for a pinhole, typed errors.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use ibc_camera_models::{CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use ibc_pnp::{PnpError, bearing_information, pinhole_information};
use nalgebra::{Matrix2, Matrix3, Matrix3x2, Vector2, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A unit ray at `theta` radians from the optical axis, azimuth `phi`.
fn ray(theta: f64, phi: f64) -> Vector3<f64> {
    Vector3::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

/// An orthonormal basis (3 x 2) of the plane orthogonal to the unit vector `f`.
fn tangent_basis(f: &Vector3<f64>) -> Matrix3x2<f64> {
    let helper = if f.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = f.cross(&helper).normalize();
    let e2 = f.cross(&e1);
    Matrix3x2::from_columns(&[e1, e2])
}

/// Relative Frobenius distance.
fn relative(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (a - b).norm() / b.norm()
}

/// `d ray / d pixel` by central differences of `unproject`, step `h` pixels.
fn finite_difference_jacobian(
    camera: &dyn CameraModel,
    pixel: &Vector2<f64>,
    h: f64,
) -> Matrix3x2<f64> {
    let column = |d: Vector2<f64>| {
        let plus = camera.unproject(&(pixel + d)).unwrap().into_inner();
        let minus = camera.unproject(&(pixel - d)).unwrap().into_inner();
        (plus - minus) / (2.0 * h)
    };
    Matrix3x2::from_columns(&[column(Vector2::new(h, 0.0)), column(Vector2::new(0.0, h))])
}

/// Checks the information at `pixel` against (1) the pseudo-inverse of `J J^T sigma^2` with a
/// finite-difference `J`, and (2) the covariance of the rays of `samples` noisy pixels, in
/// the tangent plane: `W C` must be the identity, `W` the information and `C` the sample
/// covariance, both in a tangent basis. Also: the information annihilates the ray.
fn check_model(camera: &dyn CameraModel, pixel: &Vector2<f64>, seed: u64) {
    let sigma = 0.05;
    let information = bearing_information(camera, pixel, sigma).unwrap();
    let f = camera.unproject(pixel).unwrap().into_inner();
    assert!(
        (information * f).norm() <= 1e-9 * information.norm(),
        "{}: the information must vanish along the ray",
        camera.model_name()
    );
    assert!(relative(&information, &information.transpose()) <= 1e-12);

    // (1) Finite differences.
    // A step of 0.01 px: truncation error about (h / f)^2, round-off of a 1e-12 rad
    // unprojection about 1e-10 / |J|, both far below the tolerance.
    let j = finite_difference_jacobian(camera, pixel, 1e-2);
    let covariance = j * j.transpose() * (sigma * sigma);
    // Rank 2: the third singular value is round-off, zeroed.
    let pseudo_inverse = covariance.pseudo_inverse(1e-8 * covariance.norm()).unwrap();
    let fd = relative(&information, &pseudo_inverse);
    assert!(
        fd <= 1e-6,
        "{} at {pixel:?}: finite-difference pseudo-inverse differs by {fd:e}",
        camera.model_name()
    );

    // (2) Monte-Carlo.
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma).unwrap();
    let samples = 40_000;
    let basis = tangent_basis(&f);
    let mut sum = Vector2::zeros();
    let mut sum_sq = Matrix2::zeros();
    for _ in 0..samples {
        let noisy = pixel + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng));
        let d = basis.transpose() * (camera.unproject(&noisy).unwrap().into_inner() - f);
        sum += d;
        sum_sq += d * d.transpose();
    }
    let n = f64::from(samples);
    let mean = sum / n;
    let sample_covariance = (sum_sq - mean * mean.transpose() * n) / (n - 1.0);
    let whitened = basis.transpose() * information * basis * sample_covariance;
    // The sample covariance of 40 000 draws is within about sqrt(2 / 40 000) = 0.7 % of the
    // truth per entry: 5 % is beyond six standard deviations.
    let error = (whitened - Matrix2::identity()).abs().max();
    assert!(
        error <= 0.05,
        "{} at {pixel:?}: information times Monte-Carlo covariance is {whitened}",
        camera.model_name()
    );
}

#[test]
fn kannala_brandt_beyond_ninety_degrees() {
    let camera = KannalaBrandt::new(
        1280,
        1280,
        [-0.01, 0.002, 0.0003, -0.0001, 385.0, 384.0, 639.5, 641.0],
    )
    .unwrap();
    for (k, (theta_deg, phi)) in [
        (0.0, 0.0),
        (30.0, 0.4),
        (70.0, 2.0),
        (95.0, -1.1),
        (100.0, 3.0),
    ]
    .into_iter()
    .enumerate()
    {
        let f = ray(f64::to_radians(theta_deg), phi);
        let pixel = camera.project(&f).unwrap();
        if theta_deg > 90.0 {
            assert!(camera.unproject(&pixel).unwrap().z < 0.0);
        }
        check_model(&camera, &pixel, 70 + k as u64);
    }
}

#[test]
fn pinhole_radtan() {
    let camera = PinholeRadtan::new(
        752,
        480,
        [-0.28, 0.07, 0.0002, 0.00002, 458.0, 457.0, 367.0, 248.0],
    )
    .unwrap();
    for (k, pixel) in [
        Vector2::new(367.0, 248.0),
        Vector2::new(100.0, 50.0),
        Vector2::new(700.0, 420.0),
        Vector2::new(500.0, 200.0),
    ]
    .iter()
    .enumerate()
    {
        check_model(&camera, pixel, 80 + k as u64);
    }
}

#[test]
fn unified_beyond_ninety_degrees() {
    let camera = Unified::new(
        1280,
        1024,
        [0.9, -0.1, 0.02, 0.0005, -0.0003, 700.0, 698.0, 640.0, 512.0],
    )
    .unwrap();
    for (k, (theta_deg, phi)) in [(0.0, 0.0), (45.0, 1.0), (80.0, -2.5), (100.0, 0.7)]
        .into_iter()
        .enumerate()
    {
        let f = ray(f64::to_radians(theta_deg), phi);
        let pixel = camera.project(&f).unwrap();
        check_model(&camera, &pixel, 90 + k as u64);
    }
}

#[test]
fn pinhole_agrees_with_the_pinhole_helper() {
    let focal = 800.0;
    let camera =
        PinholeRadtan::new(640, 480, [0.0, 0.0, 0.0, 0.0, focal, focal, 320.0, 240.0]).unwrap();
    for pixel in [
        Vector2::new(320.0, 240.0),
        Vector2::new(0.0, 0.0),
        Vector2::new(639.0, 17.0),
        Vector2::new(400.0, 470.0),
    ] {
        let f = camera.unproject(&pixel).unwrap().into_inner();
        let helper = pinhole_information(&f, focal);
        // The helper is J^T J for the projection Jacobian J = d pixel / d bearing; check that
        // closed form too.
        let z = f.z;
        let projection =
            nalgebra::Matrix2x3::new(1.0 / z, 0.0, -f.x / (z * z), 0.0, 1.0 / z, -f.y / (z * z))
                * focal;
        let closed_form = projection.transpose() * projection;
        assert!(relative(&helper, &closed_form) <= 1e-12, "{pixel:?}");
        for sigma in [1.0, 0.5, 2.0] {
            let general = bearing_information(&camera, &pixel, sigma).unwrap();
            let expected = helper / (sigma * sigma);
            assert!(
                relative(&general, &expected) <= 1e-10,
                "{pixel:?}, sigma {sigma}: {general} vs {expected}"
            );
        }
    }
    // A bearing a pinhole cannot see, and a bad focal length, give zero.
    assert_eq!(
        pinhole_information(&Vector3::new(0.0, 0.6, -0.8), focal),
        Matrix3::zeros()
    );
    assert_eq!(
        pinhole_information(&Vector3::z(), f64::NAN),
        Matrix3::zeros()
    );
}

#[test]
fn bad_arguments_are_typed_errors() {
    let camera = KannalaBrandt::new(
        1280,
        1280,
        [-0.05, 0.0, 0.0, 0.0, 385.0, 385.0, 639.5, 639.5],
    )
    .unwrap();
    let centre = camera.principal_point();
    for sigma in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            bearing_information(&camera, &centre, sigma),
            Err(PnpError::InvalidOption {
                name: "sigma_px",
                ..
            })
        ));
    }
    assert!(matches!(
        bearing_information(&camera, &Vector2::new(f64::NAN, 3.0), 1.0),
        Err(PnpError::Unprojection(_))
    ));
    // An image corner, beyond the polynomial's fold.
    assert!(matches!(
        bearing_information(&camera, &Vector2::new(0.0, 0.0), 1.0),
        Err(PnpError::Unprojection(
            ibc_camera_models::UnprojectionError::BeyondFold { .. }
        ))
    ));
}

#[test]
fn weighted_refinement_is_the_fisheye_maximum_likelihood() {
    // With the information of one-pixel noise the weighted cost is the squared pixel error to
    // first order, at every incidence: at the optimum its mean is that of a chi-square with
    // 2 n - 6 degrees of freedom, here 94, also for a fisheye with rays beyond 90 degrees.
    use ibc_pnp::{RefineOptions, epnp, refine_pose_weighted};
    use nalgebra::{Isometry3, Point3};
    use rand::RngExt;
    let camera = KannalaBrandt::new(
        1280,
        1280,
        [-0.01, 0.002, 0.0003, -0.0001, 385.0, 384.0, 639.5, 641.0],
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(100);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let mut costs = Vec::new();
    for _ in 0..300 {
        let camera_from_world = Isometry3::new(
            Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)),
            Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)),
        );
        let world_from_camera = camera_from_world.inverse();
        let (mut bearings, mut points, mut information) = (vec![], vec![], vec![]);
        while bearings.len() < 50 {
            let f = ray(
                rng.random_range(0.0..100f64.to_radians()),
                rng.random_range(0.0..std::f64::consts::TAU),
            );
            let pixel = camera.project(&f).unwrap()
                + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng));
            bearings.push(camera.unproject(&pixel).unwrap().into_inner());
            information.push(bearing_information(&camera, &pixel, 1.0).unwrap());
            points.push(world_from_camera * Point3::from(f * rng.random_range(2.0..8.0)));
        }
        let start = epnp(&bearings, &points).unwrap();
        let refined = refine_pose_weighted(
            &bearings,
            &points,
            &information,
            &start,
            &RefineOptions::default(),
        )
        .unwrap();
        costs.push(refined.final_cost);
    }
    let mean = costs.iter().sum::<f64>() / costs.len() as f64;
    println!("mean weighted cost {mean:.2} (expected 94)");
    assert!((mean - 94.0).abs() < 3.0, "{mean}");
}
