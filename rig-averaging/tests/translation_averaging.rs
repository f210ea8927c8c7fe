//! Translation averaging from relative directions (BATA, Zhuang, Cheong and Lee, CVPR 2018):
//! 500 views of mean degree 20, 2 degrees of direction noise, 0 / 10 / 30 % outlier edges drawn
//! as uniformly random directions. After the similarity gauge is fixed (scale and translation;
//! the world's orientation is that of the directions), the robust solve on all edges must come
//! within 10 % of the least-squares solve on the inlier edges alone; the rig form must recover
//! the lever arms; bad input is a typed error.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{rng, uniform_rotation};
use ibc_rig_averaging::{
    DirectionEdge, RigLayout, RigView, ScaleGauge, TimeDistance, TranslationAveragingOptions,
    ViewingGraphError, rig_translation_averaging, rig_translation_averaging_with_distances,
    translation_averaging,
};
use nalgebra::{UnitQuaternion, Vector3};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, UnitSphere};

const VIEWS: usize = 500;
const EDGES: usize = 5000; // mean degree 20
/// Per-axis noise: 2 degrees RMS angle over the two axes across the direction.
const SIGMA_DEG: f64 = 2.0 / std::f64::consts::SQRT_2;

fn random_pairs(r: &mut ChaCha8Rng, views: usize, count: usize) -> Vec<(usize, usize)> {
    let mut seen = std::collections::HashSet::new();
    let mut pairs = Vec::with_capacity(count);
    while pairs.len() < count {
        let (i, j) = (r.random_range(0..views), r.random_range(0..views));
        if i != j && seen.insert((i.min(j), i.max(j))) {
            pairs.push((i, j));
        }
    }
    pairs
}

fn unit(r: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::from(UnitSphere.sample(r))
}

/// Noisy directions between `positions`; a fraction `outliers` replaced by uniformly random
/// unit vectors. Returns the edges and the outlier flags.
fn noisy_edges(
    r: &mut ChaCha8Rng,
    positions: &[Vector3<f64>],
    pairs: &[(usize, usize)],
    outliers: f64,
) -> (Vec<DirectionEdge>, Vec<bool>) {
    let n = Normal::new(0.0, SIGMA_DEG.to_radians()).unwrap();
    let mut flags = Vec::new();
    let edges = pairs
        .iter()
        .map(|&(i, j)| {
            let outlier = r.random::<f64>() < outliers;
            flags.push(outlier);
            let v = if outlier {
                unit(r)
            } else {
                let noise = Vector3::new(n.sample(r), n.sample(r), n.sample(r));
                ((positions[j] - positions[i]).normalize() + noise).normalize()
            };
            DirectionEdge::new(i, j, v)
        })
        .collect();
    (edges, flags)
}

/// The scale `s` and translation `t` minimizing `sum |s e_k + t - p_k|^2`, and the mean and
/// largest error after that alignment.
fn aligned_errors(estimate: &[Option<Vector3<f64>>], truth: &[Vector3<f64>]) -> (f64, f64, f64) {
    let pairs: Vec<_> = estimate
        .iter()
        .zip(truth)
        .filter_map(|(e, t)| e.map(|e| (e, *t)))
        .collect();
    let n = pairs.len() as f64;
    let ce = pairs.iter().map(|(e, _)| e).sum::<Vector3<f64>>() / n;
    let ct = pairs.iter().map(|(_, t)| t).sum::<Vector3<f64>>() / n;
    let (num, den) = pairs.iter().fold((0.0, 0.0), |(a, b), (e, t)| {
        (a + (e - ce).dot(&(t - ct)), b + (e - ce).norm_squared())
    });
    let s = num / den;
    let errors: Vec<f64> = pairs
        .iter()
        .map(|(e, t)| (s * (e - ce) - (t - ct)).norm())
        .collect();
    (
        errors.iter().sum::<f64>() / n,
        errors.iter().copied().fold(0.0, f64::max),
        s,
    )
}

fn least_squares() -> TranslationAveragingOptions {
    TranslationAveragingOptions {
        robust: false,
        irls_iterations: 200,
        ..Default::default()
    }
}

#[test]
fn robust_averaging_matches_least_squares_on_inliers() {
    for (k, outliers) in [0.0, 0.1, 0.3].into_iter().enumerate() {
        let mut r = rng(200 + k as u64);
        let truth: Vec<_> = (0..VIEWS)
            .map(|_| Vector3::new(r.random(), r.random(), r.random()) * 20.0)
            .collect();
        let pairs = random_pairs(&mut r, VIEWS, EDGES);
        let (edges, flags) = noisy_edges(&mut r, &truth, &pairs, outliers);
        let start = std::time::Instant::now();
        let robust = translation_averaging(VIEWS, &edges, &Default::default()).unwrap();
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        let inliers: Vec<_> = edges
            .iter()
            .zip(&flags)
            .filter(|(_, o)| !**o)
            .map(|(e, _)| *e)
            .collect();
        let baseline = translation_averaging(VIEWS, &inliers, &least_squares()).unwrap();
        assert!(robust.report.dropped_views.is_empty());
        let (mean, max, _) = aligned_errors(&robust.positions, &truth);
        let (base, _, _) = aligned_errors(&baseline.positions, &truth);
        let reported: std::collections::HashSet<usize> =
            robust.report.outlier_edges.iter().copied().collect();
        let (mut far, mut found, mut false_alarms) = (0, 0, 0);
        for (e, (edge, &outlier)) in edges.iter().zip(&flags).enumerate() {
            let true_dir = (truth[edge.j] - truth[edge.i]).normalize();
            if outlier && edge.direction.angle(&true_dir) > 15f64.to_radians() {
                far += 1;
                found += usize::from(reported.contains(&e));
            }
            if !outlier && reported.contains(&e) {
                false_alarms += 1;
            }
        }
        println!(
            "outliers {:>2.0}%: robust mean {mean:.4} m (max {max:.3}), least squares on inliers \
             {base:.4} m (ratio {:.3}, {} iterations); {} outliers reported, {found}/{far} far \
             outliers found, {false_alarms} inliers flagged; scale {:.3} deg; {} iterations, {} \
             CG iterations, converged {}, {elapsed:.1} ms",
            outliers * 100.0,
            mean / base,
            baseline.report.iterations,
            reported.len(),
            robust.report.robust_scale.to_degrees(),
            robust.report.iterations,
            robust.report.linear_iterations,
            robust.report.converged,
        );
        assert!(baseline.report.converged);
        assert!(mean <= 1.10 * base, "{outliers}: {mean} vs {base}");
        // A view with few edges and several outliers can keep an outlier that agrees with it.
        assert!(found * 100 >= far * 99, "{found}/{far} far outliers found");
        assert!(
            false_alarms <= EDGES / 1000,
            "{false_alarms} inliers flagged"
        );
        assert!(robust.positions[0].unwrap().norm() < 1e-12);
    }
}

#[test]
fn exact_directions_are_reproduced_and_scaled() {
    let mut r = rng(17);
    let truth: Vec<_> = (0..40)
        .map(|_| Vector3::new(r.random(), r.random(), r.random()) * 10.0)
        .collect();
    let pairs = random_pairs(&mut r, 40, 200);
    let (edges, _) = noisy_edges(&mut r, &truth, &pairs, 0.0);
    let exact: Vec<_> = edges
        .iter()
        .map(|e| DirectionEdge::new(e.i, e.j, (truth[e.j] - truth[e.i]).normalize()))
        .collect();
    let distance = (truth[3] - truth[5]).norm();
    let options = TranslationAveragingOptions {
        scale: ScaleGauge::ViewDistance {
            from: 3,
            to: 5,
            distance,
        },
        ..Default::default()
    };
    let result = translation_averaging(40, &exact, &options).unwrap();
    let (mean, max, s) = aligned_errors(&result.positions, &truth);
    println!("exact: mean {mean:.1e} max {max:.1e} scale {s}");
    assert!(max < 1e-7 && (s - 1.0).abs() < 1e-9);
    assert!(result.report.outlier_edges.is_empty());
    // The default gauge: mean inlier baseline 1.
    let result = translation_averaging(40, &exact, &Default::default()).unwrap();
    let mean_length = exact
        .iter()
        .map(|e| (result.positions[e.j].unwrap() - result.positions[e.i].unwrap()).norm())
        .sum::<f64>()
        / exact.len() as f64;
    assert!((mean_length - 1.0).abs() < 1e-12);
}

#[test]
fn rig_form_recovers_lever_arms() {
    let mut r = rng(41);
    let (times, cameras) = (125, 4);
    let views: Vec<RigView> = (0..times)
        .flat_map(|time| (0..cameras).map(move |camera| RigView { time, camera }))
        .collect();
    let layout = RigLayout::new(times, cameras, views.clone()).unwrap();
    let world_from_rig: Vec<UnitQuaternion<f64>> =
        (0..times).map(|_| uniform_rotation(&mut r)).collect();
    // Camera 0 is the rig frame; the others 0.3 to 0.7 m away.
    let lever_arms: Vec<Vector3<f64>> = (0..cameras)
        .map(|c| {
            if c == 0 {
                Vector3::zeros()
            } else {
                unit(&mut r) * r.random_range(0.3..0.7)
            }
        })
        .collect();
    let mut rig_positions = vec![Vector3::zeros()];
    for _ in 1..times {
        let last = *rig_positions.last().unwrap();
        rig_positions.push(last + unit(&mut r) * 2.0);
    }
    let truth: Vec<_> = views
        .iter()
        .map(|v| rig_positions[v.time] + world_from_rig[v.time] * lever_arms[v.camera])
        .collect();
    let pairs = random_pairs(&mut r, views.len(), EDGES);
    let rotations: Vec<_> = world_from_rig.iter().copied().map(Some).collect();
    for outliers in [0.0, 0.3] {
        let (edges, _) = noisy_edges(&mut r, &truth, &pairs, outliers);
        let result =
            rig_translation_averaging(&layout, &rotations, &edges, &Default::default()).unwrap();
        let per_view = translation_averaging(views.len(), &edges, &Default::default()).unwrap();
        let (mean, _, s) = aligned_errors(&result.positions, &truth);
        let (view_mean, _, _) = aligned_errors(&per_view.positions, &truth);
        let lever_error = result
            .lever_arms
            .iter()
            .zip(&lever_arms)
            .map(|(e, t)| (s * e - t).norm())
            .fold(0.0, f64::max);
        println!(
            "rig, {:.0}% outliers: lever arms max error {lever_error:.4} m, views mean {mean:.4} \
             m (per-view solve {view_mean:.4} m), {} iterations",
            outliers * 100.0,
            result.report.iterations
        );
        assert!(lever_error < 0.05, "{lever_error}");
        assert!(mean < view_mean);
        assert_eq!(result.lever_arms[0], Vector3::zeros());
    }
    // Exact directions: exact lever arms.
    let exact: Vec<_> = pairs
        .iter()
        .map(|&(i, j)| DirectionEdge::new(i, j, (truth[j] - truth[i]).normalize()))
        .collect();
    let result =
        rig_translation_averaging(&layout, &rotations, &exact, &Default::default()).unwrap();
    let (mean, _, s) = aligned_errors(&result.positions, &truth);
    let lever_error = result
        .lever_arms
        .iter()
        .zip(&lever_arms)
        .map(|(e, t)| (s * e - t).norm())
        .fold(0.0, f64::max);
    println!("rig, exact: lever arms {lever_error:.1e} m, views {mean:.1e} m");
    assert!(lever_error < 1e-7 && mean < 1e-7);
    // A time without a rotation drops its views.
    let mut partial = rotations.clone();
    partial[7] = None;
    let result = rig_translation_averaging(&layout, &partial, &exact, &Default::default()).unwrap();
    assert_eq!(result.report.dropped_times, vec![7]);
    assert_eq!(result.report.dropped_views, vec![28, 29, 30, 31]);
    assert!(result.rig_positions[7].is_none());
}

/// A straight drive (the survey's straights): every direction between frames is along the
/// road whatever their spacing, so directions alone leave the spacing to the lever arms'
/// weak geometry; the distances the odometry travelled (1 % noise) fix it, and the scale.
/// Two cameras 1.5 m apart (one 0.5 m to the side), frames 0.4-0.8 m apart, edges between the
/// images of each camera up to five frames apart and across the cameras from every tenth
/// frame, 0.1 degree of direction noise. Measured: directions only 0.41 m mean / 1.66 m
/// largest error after a similarity alignment; with the distances 8 mm / 21 mm, scale 0.9993.
#[test]
fn measured_distances_fix_the_spacing_of_a_straight_drive() {
    let mut r = rng(43);
    let (times, cameras) = (60, 2);
    let views: Vec<RigView> = (0..times)
        .flat_map(|time| (0..cameras).map(move |camera| RigView { time, camera }))
        .collect();
    let layout = RigLayout::new(times, cameras, views.clone()).unwrap();
    let heading = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3);
    let rotations = vec![Some(heading); times];
    let lever_arms = [Vector3::zeros(), Vector3::new(-1.4, 0.5, 0.1)];
    let mut rig_positions = vec![Vector3::zeros()];
    for _ in 1..times {
        let last = *rig_positions.last().unwrap();
        rig_positions.push(last + heading * Vector3::x() * r.random_range(0.4..0.8));
    }
    let truth: Vec<_> = views
        .iter()
        .map(|v| rig_positions[v.time] + heading * lever_arms[v.camera])
        .collect();
    let noise = Normal::new(0.0, 0.1_f64.to_radians()).unwrap();
    let mut edges = Vec::new();
    for (i, a) in views.iter().enumerate() {
        for (j, b) in views.iter().enumerate().skip(i + 1) {
            // Each camera with its own images; the two cameras linked at every tenth frame
            // only (a rig whose cameras do not overlap).
            let linked = a.camera == b.camera || a.time % 10 == 0;
            if b.time - a.time <= 5 && b.time != a.time && linked {
                let d = (truth[j] - truth[i]).normalize();
                let n = Vector3::new(
                    noise.sample(&mut r),
                    noise.sample(&mut r),
                    noise.sample(&mut r),
                );
                edges.push(DirectionEdge::new(i, j, (d + n).normalize()));
            }
        }
    }
    let odometry = Normal::new(0.0, 0.01).unwrap();
    let distances: Vec<TimeDistance> = (1..times)
        .map(|t| {
            let length = (rig_positions[t] - rig_positions[t - 1]).norm();
            let measured = length * (1.0 + odometry.sample(&mut r));
            TimeDistance::new(t - 1, t, measured, 0.01 * measured)
        })
        .collect();
    let options = TranslationAveragingOptions::default();
    let without = rig_translation_averaging(&layout, &rotations, &edges, &options).unwrap();
    let with =
        rig_translation_averaging_with_distances(&layout, &rotations, &edges, &distances, &options)
            .unwrap();
    assert_eq!(with.distances_used, times - 1);
    let (mean_without, max_without, _) = aligned_errors(&without.positions, &truth);
    let (mean_with, max_with, s) = aligned_errors(&with.positions, &truth);
    println!(
        "straight drive: directions only {mean_without:.3} m mean / {max_without:.3} m max after \
         a similarity; with distances {mean_with:.4} / {max_with:.4} m, scale {s:.4}"
    );
    assert!(
        mean_with < 0.02 && max_with < 0.05,
        "{mean_with} {max_with}"
    );
    assert!(mean_with < 0.2 * mean_without, "{mean_with} {mean_without}");
    // The distances fixed the scale: metres within their noise.
    assert!((s - 1.0).abs() < 0.01, "{s}");
    // A distance naming a time the graph does not keep is not used.
    let mut partial = rotations.clone();
    partial[0] = None;
    let some =
        rig_translation_averaging_with_distances(&layout, &partial, &edges, &distances, &options)
            .unwrap();
    assert_eq!(some.distances_used, times - 2);
    // Bad distances are typed errors naming the distance.
    for (bad, reason) in [
        (TimeDistance::new(0, times, 1.0, 0.01), "no such time"),
        (
            TimeDistance::new(3, 3, 1.0, 0.01),
            "the two times are the same",
        ),
        (
            TimeDistance::new(0, 1, f64::NAN, 0.01),
            "the distance must be finite and positive",
        ),
        (
            TimeDistance::new(0, 1, 1.0, 0.0),
            "the standard deviation must be finite and positive",
        ),
    ] {
        let mut list = distances.clone();
        list.insert(2, bad);
        assert_eq!(
            rig_translation_averaging_with_distances(&layout, &rotations, &edges, &list, &options),
            Err(ViewingGraphError::InvalidDistance { index: 2, reason })
        );
    }
    // Distances fix the scale: another gauge with them is refused.
    let gauge = TranslationAveragingOptions {
        scale: ScaleGauge::ViewDistance {
            from: 0,
            to: 1,
            distance: 1.0,
        },
        ..Default::default()
    };
    assert!(matches!(
        rig_translation_averaging_with_distances(&layout, &rotations, &edges, &distances, &gauge),
        Err(ViewingGraphError::InvalidOption {
            option: "scale",
            ..
        })
    ));
}

#[test]
fn bad_input_is_a_typed_error() {
    let x = Vector3::x();
    let y = Vector3::y();
    let options = TranslationAveragingOptions::default();
    let edges = [
        DirectionEdge::new(0, 1, x),
        DirectionEdge::new(1, 2, y),
        DirectionEdge::new(0, 2, (x + y).normalize()),
    ];
    assert_eq!(
        translation_averaging(3, &[], &options),
        Err(ViewingGraphError::NoEdges)
    );
    assert_eq!(
        translation_averaging(0, &edges, &options),
        Err(ViewingGraphError::NoViews)
    );
    assert!(matches!(
        translation_averaging(2, &edges, &options),
        Err(ViewingGraphError::ViewOutOfRange {
            edge: 1,
            view: 2,
            views: 2
        })
    ));
    for bad in [x * 2.0, Vector3::new(f64::NAN, 0.0, 0.0), Vector3::zeros()] {
        assert!(matches!(
            translation_averaging(3, &[edges[0], DirectionEdge::new(1, 2, bad)], &options),
            Err(ViewingGraphError::NotUnitDirection { edge: 1, .. })
        ));
    }
    assert!(matches!(
        translation_averaging(3, &[edges[0], edges[1].with_weight(f64::NAN)], &options),
        Err(ViewingGraphError::InvalidWeight { edge: 1, .. })
    ));
    // One edge: neither view has two edges, so nothing can be solved.
    assert_eq!(
        translation_averaging(2, &edges[..1], &options),
        Err(ViewingGraphError::NoSolvableViews)
    );
    // A triangle is solved; a pendant view is dropped.
    let mut with_pendant = edges.to_vec();
    with_pendant.push(DirectionEdge::new(2, 3, x));
    let result = translation_averaging(4, &with_pendant, &options).unwrap();
    assert_eq!(result.report.dropped_views, vec![3]);
    assert_eq!(result.report.dropped_edges, vec![3]);
    assert!(result.positions[3].is_none());
    // Scale gauges.
    let gauge = |from, to, distance| TranslationAveragingOptions {
        scale: ScaleGauge::ViewDistance { from, to, distance },
        ..Default::default()
    };
    assert!(matches!(
        translation_averaging(4, &with_pendant, &gauge(0, 3, 1.0)),
        Err(ViewingGraphError::InvalidScaleGauge { view: 3, .. })
    ));
    assert!(matches!(
        translation_averaging(4, &with_pendant, &gauge(1, 1, 1.0)),
        Err(ViewingGraphError::InvalidScaleGauge { view: 1, .. })
    ));
    assert!(matches!(
        translation_averaging(4, &with_pendant, &gauge(0, 9, 1.0)),
        Err(ViewingGraphError::InvalidScaleGauge { view: 9, .. })
    ));
    assert!(matches!(
        translation_averaging(4, &with_pendant, &gauge(0, 1, -1.0)),
        Err(ViewingGraphError::InvalidOption {
            option: "scale",
            ..
        })
    ));
    let result = translation_averaging(4, &with_pendant, &gauge(0, 1, 2.0)).unwrap();
    assert!((result.positions[1].unwrap() - 2.0 * x).norm() < 1e-9);
    // Rig form: rotation count and validity, undetermined cameras.
    let view = |time, camera| RigView { time, camera };
    let layout =
        RigLayout::new(3, 2, vec![view(0, 0), view(1, 0), view(2, 0), view(0, 1)]).unwrap();
    let q = Some(UnitQuaternion::identity());
    assert!(matches!(
        rig_translation_averaging(&layout, &[q, q], &edges, &options),
        Err(ViewingGraphError::RotationCountMismatch {
            expected: 3,
            found: 2
        })
    ));
    let nan = Some(UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
        f64::NAN,
        0.0,
        0.0,
        0.0,
    )));
    assert!(matches!(
        rig_translation_averaging(&layout, &[q, nan, q], &edges, &options),
        Err(ViewingGraphError::InvalidRotation { index: 1, .. })
    ));
    assert!(matches!(
        rig_translation_averaging(&layout, &[q, q, q], &edges, &options),
        Err(ViewingGraphError::UndeterminedCamera { camera: 1, .. })
    ));
    assert!(matches!(
        rig_translation_averaging(
            &layout,
            &[q, q, q],
            &edges,
            &TranslationAveragingOptions {
                reference_camera: 5,
                ..Default::default()
            }
        ),
        Err(ViewingGraphError::InvalidOption {
            option: "reference_camera",
            ..
        })
    ));
    let none_rotations = [None, None, None];
    assert_eq!(
        rig_translation_averaging(&layout, &none_rotations, &edges, &options),
        Err(ViewingGraphError::NoSolvableViews)
    );
}
