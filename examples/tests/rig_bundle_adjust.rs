//! Rig bundle adjustment with free points (`ibc_bundle_adjust::RigBundleAdjustment`) on the
//! pipeline's simulated garage world, the world COLMAP 4.2's figures of issue 16 were measured
//! on: the car's four 190-degree Kannala-Brandt fisheyes, 500 frames around the 295 m loop,
//! keypoint noise sigma 0.5 px. Observations: every log feature on a map point whose
//! keypoint's ray is within 85 degrees of the optical axis (COLMAP cannot use wider rays),
//! points seen at least twice.
//!
//! Start (seed 16): the extrinsics of the left, rear and right cameras turned 2 degrees about
//! a random axis and moved 10 cm in a random direction (the front camera, the reference,
//! exact); every point moved 5 cm in a random direction; the rig poses the truth turned
//! 0.1 degree about a random axis and moved 1 cm. The scale is fixed by the true front-rear
//! baseline. The last test does the same on TrimBot2020's pentagon (issue 17's bar there).
//!
//! With `IBC_LOG` set in the environment the solves print their iteration logs (Ceres's
//! format) to standard error.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::time::Instant;

use ibc_pipeline::ibc_bundle_adjust::{
    RigBundleAdjustment, RigBundleAdjustmentOptions, RigBundleAdjustmentResult, RobustLoss,
    ScaleGauge, SolverOptions,
};
use ibc_pipeline::ibc_camera_models::CameraModel;
use ibc_pipeline::nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use ibc_pipeline::sfm::extrinsic_errors;
use ibc_pipeline::sim::{Scenario, SimulatedWorld};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// COLMAP 4.2 on this world (issue 16): worst-camera extrinsic error with points free.
const COLMAP_DEG: f64 = 0.0021;
const COLMAP_MM: f64 = 0.54;
/// ... and with intrinsics free, plus its focal-length error.
const COLMAP_INTRINSICS_DEG: f64 = 0.013;
const COLMAP_INTRINSICS_MM: f64 = 0.61;
const FOCAL_PX: f64 = 0.05;

fn random_unit(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

fn perturb(pose: &Isometry3<f64>, deg: f64, m: f64, rng: &mut ChaCha8Rng) -> Isometry3<f64> {
    let turn = UnitQuaternion::from_scaled_axis(random_unit(rng) * deg.to_radians());
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + random_unit(rng) * m),
        pose.rotation * turn,
    )
}

struct Setup {
    problem: RigBundleAdjustment,
    truth_rig_from_camera: Vec<Isometry3<f64>>,
    truth_params: Vec<Vec<f64>>,
    baseline: f64,
    pixel_sigma: f64,
}

fn setup() -> Setup {
    setup_scaled(1.0)
}

fn setup_scaled(scale: f64) -> Setup {
    setup_seeded("garage", scale, 1)
}

/// Scenario `name` at `scale`, simulated with `seed`; the start drawn as above.
fn setup_seeded(name: &str, scale: f64, seed: u64) -> Setup {
    let scenario = Scenario::resolve(name)
        .unwrap()
        .with_seed(seed)
        .with_scale(scale);
    let world = SimulatedWorld::simulate(&scenario).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(16);
    let cameras: Vec<_> = world.rig.cameras.iter().map(|c| c.camera.clone()).collect();
    let (observations, kept) = world.free_point_observations(85f64.to_radians());
    let points = kept
        .iter()
        .map(|&id| world.true_map_points[id as usize].coords + random_unit(&mut rng) * 0.05)
        .collect();
    let truth = world.truth.rig_from_camera.clone();
    let rig_from_camera = truth
        .iter()
        .enumerate()
        .map(|(c, p)| {
            if c == 0 {
                *p
            } else {
                perturb(p, 2.0, 0.10, &mut rng)
            }
        })
        .collect();
    let world_from_rig = world
        .truth
        .world_from_rig
        .iter()
        .map(|p| perturb(p, 0.1, 0.01, &mut rng))
        .collect();
    Setup {
        pixel_sigma: scenario.noise.pixel_sigma_px,
        baseline: (truth[2].translation.vector - truth[0].translation.vector).norm(),
        truth_params: cameras.iter().map(|c| c.params().to_vec()).collect(),
        truth_rig_from_camera: truth,
        problem: RigBundleAdjustment {
            cameras,
            rig_from_camera,
            world_from_rig,
            points,
            observations,
        },
    }
}

/// Worst rotation (degrees) and translation (mm) error of `ref_from_camera` over cameras 1..
fn worst_error(truth: &[Isometry3<f64>], result: &RigBundleAdjustmentResult) -> (f64, f64) {
    let est = &result.rig_from_camera;
    let mut worst = (0.0f64, 0.0f64);
    for c in 1..truth.len() {
        let t = truth[0].inverse() * truth[c];
        let e = est[0].inverse() * est[c];
        let d = t.inverse() * e;
        worst.0 = worst.0.max(d.rotation.angle().to_degrees());
        worst.1 = worst
            .1
            .max((t.translation.vector - e.translation.vector).norm() * 1e3);
    }
    worst
}

fn options(s: &Setup) -> RigBundleAdjustmentOptions {
    RigBundleAdjustmentOptions {
        scale: ScaleGauge::Baseline {
            camera: 2,
            distance_m: s.baseline,
        },
        solver: SolverOptions {
            log_to_stderr: std::env::var("IBC_LOG").is_ok(),
            ..RigBundleAdjustmentOptions::default().solver
        },
        ..Default::default()
    }
}

/// The calling thread's user and system CPU seconds (Linux's `/proc/thread-self/stat`, in
/// its fixed 100 ticks a second; `None` elsewhere). The solves run on this thread, and on the
/// shared VM the system time (the kernel clearing fresh pages) varies from run to run.
fn thread_cpu() -> Option<(f64, f64)> {
    let stat = std::fs::read_to_string("/proc/thread-self/stat").ok()?;
    // Fields after the command name (which ends at the last ')'): utime and stime are the
    // 12th and 13th.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let ticks = |i: usize| fields.get(i)?.parse::<f64>().ok();
    Some((ticks(11)? / 100.0, ticks(12)? / 100.0))
}

/// "user U s, system S s" of the CPU time between two [`thread_cpu`] readings.
fn cpu_since(start: Option<(f64, f64)>) -> String {
    match (start, thread_cpu()) {
        (Some((u0, s0)), Some((u1, s1))) => {
            format!("user {:.2} s, system {:.2} s", u1 - u0, s1 - s0)
        }
        _ => "CPU time not available".into(),
    }
}

/// Points free, then points and intrinsics free (focal lengths starting 1 px off).
fn points_then_intrinsics(s: &Setup) -> ((f64, f64), (f64, f64, f64)) {
    let t = Instant::now();
    let cpu = thread_cpu();
    let r = s.problem.solve(&options(s)).unwrap();
    let seconds = t.elapsed().as_secs_f64();
    eprintln!("points free: {}", cpu_since(cpu));
    let points_free = worst_error(&s.truth_rig_from_camera, &r);
    eprintln!(
        "points free: {} observations, {} points; worst {:.5} deg / {:.3} mm; rms {:.3} -> {:.3} px; {} iterations, {}; {seconds:.2} s",
        s.problem.observations.len(),
        s.problem.points.len(),
        points_free.0,
        points_free.1,
        r.initial_rms,
        r.final_rms,
        r.summary.iterations,
        r.summary.termination
    );
    eprintln!(
        "points free: final cost {:.17e}; {:?}",
        r.summary.final_cost, r.summary.times
    );
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );

    let mut start = s.problem.clone();
    for c in &mut start.cameras {
        let mut p = c.params().to_vec();
        p[4] += 1.0;
        p[5] -= 1.0;
        c.set_params(&p).unwrap();
    }
    let t = Instant::now();
    let cpu = thread_cpu();
    let r = start
        .solve(&RigBundleAdjustmentOptions {
            optimize_intrinsics: true,
            ..options(s)
        })
        .unwrap();
    let seconds = t.elapsed().as_secs_f64();
    eprintln!("intrinsics free: {}", cpu_since(cpu));
    let (deg, mm) = worst_error(&s.truth_rig_from_camera, &r);
    let focal = r
        .cameras
        .iter()
        .zip(&s.truth_params)
        .map(|(c, t)| {
            (c.params()[4] - t[4])
                .abs()
                .max((c.params()[5] - t[5]).abs())
        })
        .fold(0.0, f64::max);
    eprintln!(
        "intrinsics free: worst {deg:.5} deg / {mm:.3} mm, focal {focal:.4} px; rms {:.3} -> {:.3} px; {} iterations, {}; {seconds:.2} s",
        r.initial_rms, r.final_rms, r.summary.iterations, r.summary.termination
    );
    eprintln!(
        "intrinsics free: final cost {:.17e}; {:?}",
        r.summary.final_cost, r.summary.times
    );
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );
    (points_free, (deg, mm, focal))
}

/// The garage at a fifth of its size (100 frames x 4 cameras, 275k observations): COLMAP's
/// full-size accuracy with points free already.
#[test]
fn fifth_of_the_garage_points_free_meets_colmap() {
    let s = setup_scaled(0.2);
    let options = RigBundleAdjustmentOptions {
        covariance: true,
        ..options(&s)
    };
    let r = s.problem.solve(&options).unwrap();
    assert!(
        r.summary.termination.is_converged(),
        "{}",
        r.summary.report()
    );
    let (deg, mm) = worst_error(&s.truth_rig_from_camera, &r);
    eprintln!(
        "fifth: worst {deg:.5} deg / {mm:.3} mm; {} iterations; final cost {:.17e}; {:?}",
        r.summary.iterations, r.summary.final_cost, r.summary.times
    );
    assert!(deg <= COLMAP_DEG && mm <= COLMAP_MM, "{deg} deg / {mm} mm");
    // The covariance at the simulator's 0.5 px: every extrinsic determined, and the largest
    // predicted rotation standard deviation of the order of the errors.
    let sigma = 0.5;
    let worst_std_deg = (1..4)
        .map(|c| {
            let cov = r.extrinsic_covariance[c].unwrap();
            (3..6)
                .map(|k| cov[(k, k)].sqrt() * sigma)
                .fold(0.0, f64::max)
                .to_degrees()
        })
        .fold(0.0, f64::max);
    eprintln!("fifth: largest predicted rotation std {worst_std_deg:.5} deg");
    assert!(
        r.observability
            .iter()
            .all(|p| p.observability > 0.0 && p.std_dev.is_finite())
    );
    assert!(deg < 10.0 * worst_std_deg && worst_std_deg < 10.0 * COLMAP_DEG);
}

/// The full garage (4 x 500, 1.8M observations), COLMAP's world: both bars of issue 16.
/// Minutes in release on a shared 2-core machine, hence ignored; run with
/// `cargo test -p ibc-pipeline --release --test rig_bundle_adjust -- --ignored full_garage --nocapture`.
#[test]
#[ignore]
fn full_garage_meets_colmap_points_free_and_intrinsics_free() {
    let s = setup();
    let ((deg, mm), (ideg, imm, focal)) = points_then_intrinsics(&s);
    assert!(deg <= COLMAP_DEG && mm <= COLMAP_MM, "{deg} deg / {mm} mm");
    assert!(
        ideg <= COLMAP_INTRINSICS_DEG && imm <= COLMAP_INTRINSICS_MM,
        "{ideg} deg / {imm} mm"
    );
    assert!(focal <= FOCAL_PX, "{focal} px");
}

/// Issue 17's pentagon bar (0.003 deg worst camera, after COLMAP's 0.0030 deg / 0.51 mm)
/// against what the data allows. TrimBot2020's pentagon (ten 82-degree pinholes) in the
/// garden, 100 frames, with perfect tracks (every log feature on a landmark: COLMAP's input),
/// solved by plain least squares, the maximum-likelihood estimate under the simulator's
/// Gaussian keypoint noise, on eight worlds of the scenario (seeds 1-8).
///
/// Asserted: the estimate is efficient, its errors those its covariance predicts: over the 72
/// (world, camera) pairs the rotation errors normalized by the reported covariance,
/// `φᵀ Σ_φφ⁻¹ φ`, average 3 (a χ² with three degrees of freedom) within sampling error, and
/// so do the translations (camera 2's, on the baseline's sphere, left out); the translations
/// meet the 0.5 mm. Measured 2026-12-03: normalized errors 2.99 (rotation) and 2.63
/// (translation); worst camera 0.0024-0.0070 deg, median 0.0036 deg, six of the eight worlds
/// above 0.003 deg; translations 0.28-0.48 mm after aligning the scale. So the 0.003 deg bar
/// lies below what the best estimator reaches on most worlds of this scenario, even with
/// perfect tracks (COLMAP's 0.0030 deg is one world's draw). On seed 1, the world of the
/// self-calibration's pentagon test (`selfcalib.rs`): 0.0037 deg / 0.38 mm here (0.0042 deg /
/// 0.46 mm with the Cauchy loss), against 0.0043 deg / 0.35 mm from the self-calibration's own
/// tracks, completed (0.0079 deg / 0.57 mm before the completion).
#[test]
fn pentagon_with_perfect_tracks_is_efficient_and_the_rotation_bar_below_its_spread() {
    let mut worst = Vec::new();
    let (mut rotation_chi2, mut translation_chi2) = (Vec::new(), Vec::new());
    for seed in 1..=8u64 {
        let s = setup_seeded("garden-pentagon", 1.0 / 3.0, seed);
        let r = s
            .problem
            .solve(&RigBundleAdjustmentOptions {
                covariance: true,
                loss: RobustLoss::Trivial,
                ..options(&s)
            })
            .unwrap();
        assert!(
            r.summary.termination.is_converged(),
            "{}",
            r.summary.report()
        );
        let sigma2 = s.pixel_sigma * s.pixel_sigma;
        // After aligning the scale, as COLMAP's figure and the self-calibration's bars.
        let errors = extrinsic_errors(&r.rig_from_camera, &s.truth_rig_from_camera, true);
        let deg = errors.iter().map(|e| e.0.to_degrees()).fold(0.0, f64::max);
        let mm = errors.iter().map(|e| e.1 * 1e3).fold(0.0, f64::max);
        eprintln!(
            "pentagon, perfect tracks, seed {seed}: {} observations of {} points; worst {deg:.5} deg / {mm:.3} mm",
            s.problem.observations.len(),
            s.problem.points.len(),
        );
        assert!(mm <= 0.5, "seed {seed}: {mm} mm");
        worst.push(deg);
        for c in 1..s.truth_rig_from_camera.len() {
            let truth = &s.truth_rig_from_camera[c];
            // The error in the solver's tangent coordinates: estimate = truth · Exp([ρ, φ]).
            let d = truth.inverse() * r.rig_from_camera[c];
            let phi = d.rotation.scaled_axis();
            let rho = d.translation.vector;
            let cov = r.extrinsic_covariance[c].unwrap() * sigma2;
            let chi2 = |e: Vector3<f64>, k: usize| {
                let block = cov.fixed_view::<3, 3>(k, k).into_owned();
                e.dot(&(block.try_inverse().unwrap() * e))
            };
            rotation_chi2.push(chi2(phi, 3));
            if c != 2 {
                translation_chi2.push(chi2(rho, 0));
            }
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    worst.sort_by(f64::total_cmp);
    let median = 0.5 * (worst[3] + worst[4]);
    let above = worst.iter().filter(|&&d| d > 0.003).count();
    eprintln!(
        "worst camera over the worlds {worst:.5?}, median {median:.5} deg, {above} of 8 above 0.003 deg; \
         normalized errors: rotation {:.2}, translation {:.2} (3 if efficient)",
        mean(&rotation_chi2),
        mean(&translation_chi2)
    );
    // Mean of n χ²(3) draws: 3 ± √(6/n) (0.29 for the 72 rotations, 0.31 for the 64
    // translations); ± 1.2 is about four of those, allowing for the cameras of one world
    // being correlated.
    for (what, v) in [
        ("rotation", &rotation_chi2),
        ("translation", &translation_chi2),
    ] {
        assert!((mean(v) - 3.0).abs() <= 1.2, "{what}: {}", mean(v));
    }
    assert!(median > 0.003, "median worst camera {median} deg");
}
