//! Benchmarks of `ibc-rig-averaging`: Markley averaging against same-run baselines (the naive
//! sign-unaligned normalized sum, the chordal SVD projection, and Markley's matrix solved by
//! nalgebra's `SymmetricEigen`), robust averaging, and rig initialization with 200 frame sets
//! of 4 cameras and 40,000 observations (against the same run on a one-thread pool and the
//! serial cost of scoring every hypothesis once).
//!
//! Run: `cargo bench -p ibc-benches --bench rig_averaging`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, criterion_group};
use ibc_benches::{bench_rng, thread_cpu_ns};
use ibc_rig_averaging::{
    ImageScorer, Observation, ObservationScorer, RigInitOptions, RobustOptions, initialize_rig,
    quaternion_mean, robust_quaternion_mean,
};
use nalgebra::{
    Isometry3, Matrix3, Matrix4, Point2, Point3, Quaternion, Rotation3, SymmetricEigen,
    UnitQuaternion, Vector3, Vector4,
};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

fn small_rotation(rng: &mut ChaCha8Rng, max: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(Vector3::new(
        rng.random_range(-max..max),
        rng.random_range(-max..max),
        rng.random_range(-max..max),
    ))
}

/// `n` rotations within 0.2 rad per axis of a random centre, with random quaternion signs.
fn rotations(n: usize, stream: u64) -> Vec<UnitQuaternion<f64>> {
    let mut rng = bench_rng(stream);
    let centre = small_rotation(&mut rng, 3.0);
    (0..n)
        .map(|_| {
            let q = centre * small_rotation(&mut rng, 0.2);
            if rng.random::<bool>() {
                UnitQuaternion::new_unchecked(-q.into_inner())
            } else {
                q
            }
        })
        .collect()
}

/// Baseline: normalize the plain sum of quaternions (wrong when signs differ).
fn naive_mean(rotations: &[UnitQuaternion<f64>]) -> UnitQuaternion<f64> {
    let sum = rotations
        .iter()
        .fold(Quaternion::new(0.0, 0.0, 0.0, 0.0), |acc, q| {
            acc + q.into_inner()
        });
    UnitQuaternion::from_quaternion(sum)
}

/// Baseline: project `sum R_i` onto SO(3) by SVD (the chordal mean; what CamOdoCal-style code
/// computes).
fn chordal_svd_mean(rotations: &[UnitQuaternion<f64>]) -> UnitQuaternion<f64> {
    let m = rotations.iter().fold(Matrix3::zeros(), |acc, q| {
        acc + q.to_rotation_matrix().into_inner()
    });
    let svd = m.svd(true, true);
    let (u, v_t) = (svd.u.unwrap(), svd.v_t.unwrap());
    let d = (u * v_t).determinant().signum();
    let r = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r))
}

/// Baseline: Markley's matrix solved by nalgebra's general symmetric eigen-solver.
fn markley_nalgebra(rotations: &[UnitQuaternion<f64>]) -> UnitQuaternion<f64> {
    let m = rotations.iter().fold(Matrix4::zeros(), |acc, q| {
        let v = Vector4::new(q.w, q.i, q.j, q.k);
        acc + v * v.transpose()
    });
    let eigen = SymmetricEigen::new(m);
    let top = eigen.eigenvalues.imax();
    let v = eigen.eigenvectors.column(top);
    let s = if v[0] < 0.0 { -1.0 } else { 1.0 };
    UnitQuaternion::from_quaternion(Quaternion::new(s * v[0], s * v[1], s * v[2], s * v[3]))
}

fn bench_quaternion_mean(c: &mut Criterion) {
    let mut group = c.benchmark_group("quaternion_mean");
    for n in [4usize, 10] {
        let qs = rotations(n, n as u64);
        group.bench_with_input(BenchmarkId::new("markley_jacobi", n), &qs, |b, qs| {
            b.iter(|| quaternion_mean(black_box(qs), None).unwrap())
        });
        group.bench_with_input(
            BenchmarkId::new("markley_nalgebra_eigen", n),
            &qs,
            |b, qs| b.iter(|| markley_nalgebra(black_box(qs))),
        );
        group.bench_with_input(BenchmarkId::new("chordal_svd", n), &qs, |b, qs| {
            b.iter(|| chordal_svd_mean(black_box(qs)))
        });
        group.bench_with_input(BenchmarkId::new("naive_sum", n), &qs, |b, qs| {
            b.iter(|| naive_mean(black_box(qs)))
        });
    }
    let mut qs = rotations(9, 100);
    qs.push(UnitQuaternion::from_euler_angles(1.0, 0.5, -0.5) * qs[0]);
    group.bench_function("robust_markley/10", |b| {
        b.iter(|| robust_quaternion_mean(black_box(&qs), None, &RobustOptions::default()).unwrap())
    });
    group.finish();
}

const SETS: usize = 200;
const CAMERAS: usize = 4;
const POINTS_PER_IMAGE: usize = 50;
const FOCAL: f64 = 400.0;

fn pinhole(_camera: usize, p: &Point3<f64>) -> Option<Point2<f64>> {
    (p.z > 1e-6).then(|| Point2::new(FOCAL * p.x / p.z + 320.0, FOCAL * p.y / p.z + 240.0))
}

type Projection = fn(usize, &Point3<f64>) -> Option<Point2<f64>>;

/// Per frame set, per camera, the localized `camera_from_world`.
type FrameSets = Vec<Vec<Option<Isometry3<f64>>>>;

/// 200 complete frame sets of a 4-camera rig (the most hypotheses: 200 + the average), camera
/// poses perturbed by up to 0.005 rad and 2 cm, 50 observations per image (40,000 in all).
fn rig_problem() -> (FrameSets, ObservationScorer<Projection>) {
    let mut rng = bench_rng(1000);
    let base = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(
        Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0),
    ));
    let rig_from_camera: Vec<Isometry3<f64>> = (0..CAMERAS)
        .map(|c| {
            let yaw = std::f64::consts::FRAC_PI_2 * c as f64;
            Isometry3::from_parts(
                Vector3::new(0.5 * yaw.cos(), 0.3 * yaw.sin(), 0.3).into(),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * base,
            )
        })
        .collect();
    let mut sets = Vec::with_capacity(SETS);
    let mut images = Vec::with_capacity(SETS);
    for s in 0..SETS {
        let t = s as f64;
        let world_from_rig = Isometry3::new(
            Vector3::new(0.8 * t, 3.0 * (0.1 * t).sin(), 0.0),
            Vector3::new(0.0, 0.0, 0.3 * (0.1 * t).cos()),
        );
        let mut set = Vec::with_capacity(CAMERAS);
        let mut set_images = Vec::with_capacity(CAMERAS);
        for e in &rig_from_camera {
            let world_from_camera = world_from_rig * e;
            let noise = Isometry3::from_parts(
                Vector3::new(
                    rng.random_range(-0.02..0.02),
                    rng.random_range(-0.02..0.02),
                    rng.random_range(-0.02..0.02),
                )
                .into(),
                small_rotation(&mut rng, 0.005),
            );
            set.push(Some(noise * world_from_camera.inverse()));
            set_images.push(
                (0..POINTS_PER_IMAGE)
                    .map(|_| {
                        let (u, v) = (rng.random_range(0.0..640.0), rng.random_range(0.0..480.0));
                        let depth = rng.random_range(2.0..20.0);
                        let p = Point3::new(
                            (u - 320.0) / FOCAL * depth,
                            (v - 240.0) / FOCAL * depth,
                            depth,
                        );
                        Observation {
                            point_in_world: world_from_camera * p,
                            pixel: Point2::new(u, v),
                        }
                    })
                    .collect::<Vec<_>>(),
            );
        }
        sets.push(set);
        images.push(set_images);
    }
    (sets, ObservationScorer::new(images, pinhole as Projection))
}

fn bench_rig_initialization(c: &mut Criterion) {
    let (sets, scorer) = rig_problem();
    assert_eq!(scorer.total_observations(), 40_000);
    let options = RigInitOptions::default();
    let mut group = c.benchmark_group("initialize_rig_200x4_40k");
    group.sample_size(10);
    group.bench_function("rayon_global_pool", |b| {
        b.iter(|| initialize_rig(black_box(&sets), &scorer, &options).unwrap())
    });
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    group.bench_function("rayon_one_thread", |b| {
        b.iter(|| {
            one_thread.install(|| initialize_rig(black_box(&sets), &scorer, &options).unwrap())
        })
    });
    // The floor: scoring all 800 images once per hypothesis (201 x 40,000 projections),
    // serially, at known poses; no averaging, no hypothesis bookkeeping.
    let poses: Vec<Vec<Isometry3<f64>>> = sets
        .iter()
        .map(|set| set.iter().map(|p| p.unwrap()).collect())
        .collect();
    group.bench_function("serial_scoring_floor", |b| {
        b.iter(|| {
            let mut total = 0.0;
            for _ in 0..=SETS {
                for (s, set) in poses.iter().enumerate() {
                    for (c, pose) in set.iter().enumerate() {
                        total += scorer.score_image(s, c, black_box(pose)).error_sum;
                    }
                }
            }
            total
        })
    });
    group.finish();
}

/// On the shared machines parallel builds inflate wall time several-fold, so before the
/// criterion runs this prints the *CPU time* of the benchmark thread over long spans: 2,000,000
/// Markley means, and three rig initializations on a one-thread pool. Runs only under
/// `cargo bench` (criterion's `--bench` flag), not when `cargo test` smoke-runs benches.
fn cpu_time_report() {
    if !std::env::args().any(|a| a == "--bench") || thread_cpu_ns().is_none() {
        return;
    }
    for n in [4usize, 10] {
        let qs = rotations(n, n as u64);
        let calls = 2_000_000;
        let (cpu0, wall0) = (thread_cpu_ns(), std::time::Instant::now());
        for _ in 0..calls {
            black_box(quaternion_mean(black_box(&qs), None).unwrap());
        }
        let cpu = (thread_cpu_ns().unwrap_or(0.0) - cpu0.unwrap_or(0.0)) / calls as f64;
        let wall = wall0.elapsed().as_nanos() as f64 / calls as f64;
        println!("cpu-time quaternion_mean/markley_jacobi/{n}: {cpu:.0} ns CPU, {wall:.0} ns wall");
    }
    let (sets, scorer) = rig_problem();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for _ in 0..3 {
        let (cpu, wall) = pool.install(|| {
            let (cpu0, wall0) = (thread_cpu_ns(), std::time::Instant::now());
            black_box(initialize_rig(&sets, &scorer, &RigInitOptions::default()).unwrap());
            let cpu = thread_cpu_ns().unwrap_or(0.0) - cpu0.unwrap_or(0.0);
            (cpu / 1e6, wall0.elapsed().as_secs_f64() * 1e3)
        });
        println!("cpu-time initialize_rig one thread: {cpu:.1} ms CPU, {wall:.1} ms wall");
    }
}

criterion_group!(benches, bench_quaternion_mean, bench_rig_initialization);

fn main() {
    cpu_time_report();
    benches();
    Criterion::default().configure_from_args().final_summary();
}
