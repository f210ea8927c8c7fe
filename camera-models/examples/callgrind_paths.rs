//! Runs the per-point paths of the camera-models benches a fixed number of times, one
//! `#[inline(never)]` function per path, so that `valgrind --tool=callgrind` can count the
//! instructions of each path exactly (a count that does not depend on the machine's load):
//!
//! ```text
//! cargo build --release -p ibc-camera-models --example callgrind_paths
//! valgrind --tool=callgrind --callgrind-out-file=/tmp/cg.out \
//!     target/release/examples/callgrind_paths 20
//! callgrind_annotate --inclusive=yes --threshold=100 /tmp/cg.out | grep run_
//! ```
//!
//! Each `run_*` function processes the same 1024 points or pixels as the criterion bench
//! (`benches/benches/camera_models.rs`) `reps` times (argument, default 20); the instructions
//! per point are the function's inclusive count divided by `1024 * reps`. The program prints a
//! checksum so nothing is optimized away.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use ibc_camera_models::{CameraModel, KannalaBrandt, PinholeRadtan, Unified};
use nalgebra::{Vector2, Vector3};

// The cameras of the tests (CamOdoCal's Kannala-Brandt and Mei test cameras, EuRoC cam0, a
// 195-degree TUM-VI-like fisheye).
#[path = "../tests/common/mod.rs"]
mod common;

const N: usize = 1024;

/// The bench's samples: N pixels on a grid over the image that have rays, and their rays
/// scaled to points.
fn samples<C: CameraModel>(camera: &C) -> (Vec<Vector2<f64>>, Vec<Vector3<f64>>) {
    let (w, h) = (f64::from(camera.width()), f64::from(camera.height()));
    let mut pixels = Vec::with_capacity(N);
    let mut points = Vec::with_capacity(N);
    let mut i = 0usize;
    while pixels.len() < N {
        let px = Vector2::new(
            (i % 41) as f64 * w / 41.0,
            ((i / 41) % 29) as f64 * h / 29.0,
        );
        i += 1;
        if let Ok(ray) = camera.unproject(&px) {
            pixels.push(px);
            points.push(ray.into_inner() * (1.0 + (i % 7) as f64));
        }
    }
    (pixels, points)
}

/// One `#[inline(never)]` function per path and camera, so callgrind reports each separately:
/// `name(camera type, input type): |camera, input| value to sum`.
macro_rules! paths {
    ($($name:ident($camera:ty, $input:ty): |$c:ident, $x:ident| $call:expr;)*) => {
        $(
            #[inline(never)]
            fn $name($c: &$camera, data: &[$input], reps: usize) -> f64 {
                let mut sum = 0.0;
                for _ in 0..reps {
                    for $x in data {
                        let $x = black_box($x);
                        sum += black_box($call);
                    }
                }
                sum
            }
        )*
    };
}

paths! {
    run_kb_project(KannalaBrandt, Vector3<f64>): |c, p| c.project(p).map_or(0.0, |v| v.x);
    run_kb_project_jacobians(KannalaBrandt, Vector3<f64>): |c, p| c
        .project_with_jacobians(p)
        .map_or(0.0, |j| j.d_pixel_d_point[(0, 0)]);
    run_radtan_project(PinholeRadtan, Vector3<f64>): |c, p| c.project(p).map_or(0.0, |v| v.x);
    run_radtan_project_jacobians(PinholeRadtan, Vector3<f64>): |c, p| c
        .project_with_jacobians(p)
        .map_or(0.0, |j| j.d_pixel_d_point[(0, 0)]);
    run_mei_project(Unified, Vector3<f64>): |c, p| c.project(p).map_or(0.0, |v| v.x);
    run_mei_project_jacobians(Unified, Vector3<f64>): |c, p| c
        .project_with_jacobians(p)
        .map_or(0.0, |j| j.d_pixel_d_point[(0, 0)]);
    run_kb_unproject_fast(KannalaBrandt, Vector2<f64>): |c, px| c
        .unproject_fast(px)
        .map_or(0.0, |r| r.z);
    run_kb_unproject_companion(KannalaBrandt, Vector2<f64>): |c, px| c
        .unproject(px)
        .map_or(0.0, |r| r.z);
    // (Sums y, not z, so that the linker does not fold it into the function above.)
    run_tum_unproject_companion(KannalaBrandt, Vector2<f64>): |c, px| c
        .unproject(px)
        .map_or(0.0, |r| r.y);
    run_kb_unproject_jacobians(KannalaBrandt, Vector2<f64>): |c, px| c
        .unproject_with_jacobians(px)
        .map_or(0.0, |j| j.d_ray_d_pixel[(0, 0)]);
    run_radtan_unproject(PinholeRadtan, Vector2<f64>): |c, px| c
        .unproject(px)
        .map_or(0.0, |r| r.z);
    run_mei_unproject(Unified, Vector2<f64>): |c, px| c.unproject(px).map_or(0.0, |r| r.z);
}

fn main() {
    let reps: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let (kb, tum) = (common::camodocal_kb(), common::tum_kb());
    let (euroc, mei) = (common::euroc_cam0(), common::camodocal_mei());
    let (kb_pixels, kb_points) = samples(&kb);
    let (tum_pixels, _) = samples(&tum);
    let (pin_pixels, pin_points) = samples(&euroc);
    let (mei_pixels, mei_points) = samples(&mei);
    let mut sum = 0.0;
    sum += run_kb_project(&kb, &kb_points, reps);
    sum += run_kb_project_jacobians(&kb, &kb_points, reps);
    sum += run_radtan_project(&euroc, &pin_points, reps);
    sum += run_radtan_project_jacobians(&euroc, &pin_points, reps);
    sum += run_mei_project(&mei, &mei_points, reps);
    sum += run_mei_project_jacobians(&mei, &mei_points, reps);
    sum += run_kb_unproject_fast(&kb, &kb_pixels, reps);
    sum += run_kb_unproject_companion(&kb, &kb_pixels, reps);
    sum += run_tum_unproject_companion(&tum, &tum_pixels, reps);
    sum += run_kb_unproject_jacobians(&kb, &kb_pixels, reps);
    sum += run_radtan_unproject(&euroc, &pin_pixels, reps);
    sum += run_mei_unproject(&mei, &mei_pixels, reps);
    println!("checksum {sum}");
}
