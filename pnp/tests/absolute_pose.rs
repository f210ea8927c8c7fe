//! Robust PnP from a camera and pixels: pixels beyond a fisheye's fold count as outliers, the
//! inliers index the caller's slices, the result is that of unprojecting and calling
//! `robust_pose` by hand, and bad input is a typed error.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

mod common;

use common::*;
use ibc_camera_models::{CameraModel, KannalaBrandt};
use ibc_pnp::{
    AbsolutePoseOptions, PnpError, RansacOptions, absolute_pose, angle_from_pixels_at, robust_pose,
};
use nalgebra::{Isometry3, Point3, Vector2, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// An equidistant-like fisheye whose polynomial folds at about 148 degrees
/// (`r(theta) = theta - 0.05 theta^3`, `r' = 0` at `theta = sqrt(1 / 0.15)`): the image
/// corners lie beyond the fold and cannot be unprojected.
fn folding_fisheye() -> KannalaBrandt {
    KannalaBrandt::new(
        1280,
        1280,
        [-0.05, 0.0, 0.0, 0.0, 385.0, 385.0, 639.5, 639.5],
    )
    .unwrap()
}

/// A correspondence set seen by `camera`: the first `wrong` pixels are random pixels the
/// camera can unproject (wrong matches), the next `beyond` are image pixels beyond the fold,
/// the rest are the projections of their points (rays up to 100 degrees off the axis) with
/// `sigma_px` of noise.
struct PixelScene {
    pixels: Vec<Vector2<f64>>,
    points: Vec<Point3<f64>>,
    camera_from_world: Isometry3<f64>,
}

fn pixel_scene(
    rng: &mut ChaCha8Rng,
    camera: &KannalaBrandt,
    n: usize,
    wrong: usize,
    beyond: usize,
    sigma_px: f64,
) -> PixelScene {
    let camera_from_world = random_pose(rng);
    let world_from_camera = camera_from_world.inverse();
    let noise = Normal::new(0.0, sigma_px.max(f64::MIN_POSITIVE)).unwrap();
    let centre = camera.principal_point();
    let fold_px = camera.max_radius() * camera.mu();
    let mut pixels = Vec::with_capacity(n);
    let mut points = Vec::with_capacity(n);
    for i in 0..n {
        let ray = direction_in_cap(rng, 100f64.to_radians());
        let p = ray * rng.random_range(2.0..10.0);
        points.push(world_from_camera * Point3::from(p));
        let pixel = if i < wrong {
            loop {
                let q = Vector2::new(rng.random_range(0.0..1279.0), rng.random_range(0.0..1279.0));
                if (q - centre).norm() < 0.95 * fold_px {
                    break q;
                }
            }
        } else if i < wrong + beyond {
            // A pixel in one of the image corners, past the fold.
            loop {
                let q = Vector2::new(rng.random_range(0.0..1279.0), rng.random_range(0.0..1279.0));
                if (q - centre).norm() > 1.02 * fold_px {
                    break q;
                }
            }
        } else {
            camera.project(&p).unwrap() + Vector2::new(noise.sample(rng), noise.sample(rng))
        };
        pixels.push(pixel);
    }
    PixelScene {
        pixels,
        points,
        camera_from_world,
    }
}

/// The angle between the ray of `pixel` and the direction of `point` under `pose`, or `None`
/// if the pixel has no ray.
fn angle_under(
    camera: &KannalaBrandt,
    pose: &Isometry3<f64>,
    pixel: &Vector2<f64>,
    point: &Point3<f64>,
) -> Option<f64> {
    let ray = camera.unproject(pixel).ok()?;
    let p = (pose * point).coords;
    Some(ray.cross(&p).norm().atan2(ray.dot(&p)))
}

#[test]
fn pixels_beyond_the_fold_are_outliers_and_inliers_index_the_callers_slices() {
    let camera = folding_fisheye();
    assert!(camera.has_fold());
    let mut rng = ChaCha8Rng::seed_from_u64(60);
    let (n, wrong, beyond) = (300, 90, 30);
    for trial in 0..20 {
        let mut s = pixel_scene(&mut rng, &camera, n, wrong, beyond, 0.3);
        // Shuffle, so that the planted outliers are spread over the caller's indices.
        let mut order: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            order.swap(i, rng.random_range(0..=i));
        }
        let planted: Vec<bool> = order.iter().map(|&k| k < wrong + beyond).collect();
        s.pixels = order.iter().map(|&k| s.pixels[k]).collect();
        s.points = order.iter().map(|&k| s.points[k]).collect();
        for (i, pixel) in s.pixels.iter().enumerate() {
            // The planted corner pixels are exactly the ones without a ray.
            let unprojectable = camera.unproject(pixel).is_err();
            assert_eq!(
                unprojectable,
                order[i] >= wrong && order[i] < wrong + beyond
            );
        }
        let options = AbsolutePoseOptions {
            ransac: RansacOptions {
                seed: trial,
                ..Default::default()
            },
            ..Default::default()
        };
        let pose = absolute_pose(&camera, &s.pixels, &s.points, &options).unwrap();
        assert_eq!(pose.unprojection_failures, beyond);
        let error = rotation_error_deg(&pose.camera_from_world, &s.camera_from_world);
        assert!(error < 0.1, "trial {trial}: {error} degrees");
        assert!(pose.inliers.windows(2).all(|w| w[0] < w[1]));
        for &i in &pose.inliers {
            assert!(
                !planted[i],
                "trial {trial}: planted outlier {i} among the inliers"
            );
            // A true inlier under the true pose: within the threshold (with a margin for the
            // noise the estimated pose absorbs).
            let angle = angle_under(&camera, &s.camera_from_world, &s.pixels[i], &s.points[i])
                .expect("an inlier has a ray");
            assert!(
                angle <= 1.5 * pose.threshold,
                "trial {trial}: {i} at {angle}"
            );
        }
        let clean = n - wrong - beyond;
        assert!(
            pose.inliers.len() as f64 >= 0.95 * clean as f64,
            "trial {trial}: {} of {clean} inliers",
            pose.inliers.len()
        );
        let backward = pose
            .inliers
            .iter()
            .filter(|&&i| (s.camera_from_world * s.points[i]).z < 0.0)
            .count();
        assert!(backward > 0, "rays beyond 90 degrees are inliers too");
    }
}

#[test]
fn same_as_unprojecting_and_calling_robust_pose_by_hand() {
    let camera = folding_fisheye();
    let mut rng = ChaCha8Rng::seed_from_u64(61);
    let s = pixel_scene(&mut rng, &camera, 200, 60, 20, 0.5);
    let options = AbsolutePoseOptions {
        max_error_px: 1.5,
        ..Default::default()
    };
    let pose = absolute_pose(&camera, &s.pixels, &s.points, &options).unwrap();

    // The eleven lines it replaces.
    let threshold =
        angle_from_pixels_at(&camera, &camera.principal_point(), options.max_error_px).unwrap();
    let mut bearings: Vec<Vector3<f64>> = Vec::new();
    let mut points = Vec::new();
    let mut used = Vec::new();
    for (i, (pixel, point)) in s.pixels.iter().zip(&s.points).enumerate() {
        if let Ok(ray) = camera.unproject_fast(pixel) {
            bearings.push(ray.into_inner());
            points.push(*point);
            used.push(i);
        }
    }
    let ransac = RansacOptions {
        threshold,
        ..Default::default()
    };
    let by_hand = robust_pose(&bearings, &points, &ransac).unwrap();

    assert_eq!(pose.threshold, threshold);
    assert_eq!(pose.camera_from_world, by_hand.camera_from_world);
    assert_eq!(pose.iterations, by_hand.iterations);
    assert_eq!(pose.inlier_rms, by_hand.inlier_rms);
    let mapped: Vec<usize> = by_hand.inliers.iter().map(|&k| used[k]).collect();
    assert_eq!(pose.inliers, mapped);
    assert_eq!(pose.unprojection_failures, 20);
}

#[test]
fn bad_input_is_a_typed_error_naming_the_culprit() {
    let camera = folding_fisheye();
    let mut rng = ChaCha8Rng::seed_from_u64(62);
    let s = pixel_scene(&mut rng, &camera, 40, 0, 0, 0.0);
    let options = AbsolutePoseOptions::default();
    let solve = |pixels: &[Vector2<f64>], points: &[Point3<f64>], options: &AbsolutePoseOptions| {
        absolute_pose(&camera, pixels, points, options)
    };
    assert!(solve(&s.pixels, &s.points, &options).is_ok());
    assert_eq!(
        solve(&s.pixels, &s.points[..39], &options).unwrap_err(),
        PnpError::PixelLengthMismatch {
            pixels: 40,
            points: 39
        }
    );
    assert!(matches!(
        solve(&s.pixels[..2], &s.points[..2], &options),
        Err(PnpError::NotEnoughPoints {
            needed: 3,
            got: 2,
            ..
        })
    ));
    for value in [f64::NAN, f64::INFINITY] {
        let mut pixels = s.pixels.clone();
        pixels[17].y = value;
        assert_eq!(
            solve(&pixels, &s.points, &options).unwrap_err(),
            PnpError::NonFinitePixel { index: 17 }
        );
        let mut points = s.points.clone();
        points[23].x = value;
        assert_eq!(
            solve(&s.pixels, &points, &options).unwrap_err(),
            PnpError::NonFinitePoint { index: 23 }
        );
    }
    // All but two pixels beyond the fold.
    let mut pixels = s.pixels.clone();
    for p in pixels.iter_mut().skip(2) {
        *p = Vector2::new(5.0, 5.0);
    }
    assert_eq!(
        solve(&pixels, &s.points, &options).unwrap_err(),
        PnpError::TooFewUnprojected {
            unprojected: 2,
            needed: 3,
            total: 40
        }
    );
    // Too few inliers: the count is over the caller's pixels.
    let mut pixels = s.pixels.clone();
    for p in pixels.iter_mut().skip(10).take(20) {
        *p = Vector2::new(5.0, 5.0);
    }
    match solve(&pixels, &s.points, &options) {
        Err(PnpError::TooFewInliers {
            found,
            required,
            total,
        }) => {
            assert_eq!((found, required, total), (20, 25, 40));
        }
        other => panic!("expected TooFewInliers, got {other:?}"),
    }
    for max_error_px in [0.0, -1.0, f64::NAN, 1e4] {
        let options = AbsolutePoseOptions {
            max_error_px,
            ..Default::default()
        };
        assert!(matches!(
            solve(&s.pixels, &s.points, &options),
            Err(PnpError::InvalidOption {
                name: "max_error_px",
                ..
            })
        ));
    }
    let options = AbsolutePoseOptions {
        ransac: RansacOptions {
            refine: ibc_pnp::RefineOptions {
                loss: ibc_pnp::RobustLoss::Huber { scale: -1.0 },
                ..Default::default()
            },
            ..Default::default()
        },
        ..Default::default()
    };
    assert!(options.validate().is_err());
    assert_eq!(
        solve(&s.pixels, &s.points, &options).unwrap_err(),
        PnpError::InvalidLossScale { scale: -1.0 }
    );
}
