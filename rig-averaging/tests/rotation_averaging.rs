//! Rotation averaging over viewing graphs (Chatterjee and Govindu, ICCV 2013 / TPAMI 2018):
//! 500 views of mean degree 20, 2 degrees of edge noise, 0 / 10 / 30 % outlier edges drawn as
//! uniformly random rotations. The robust solve on all edges must come within 10 % of the
//! chordal averaging of the inlier edges alone; the rig form must recover the extrinsics and
//! the rig rotations; bad input is a typed error.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{rng, rotation_noise, uniform_rotation};
use ibc_rig_averaging::{
    RigLayout, RigView, RotationAveragingOptions, RotationEdge, ViewingGraphError,
    largest_connected_component, quaternion_mean, rig_rotation_averaging, rotation_averaging,
};
use nalgebra::{Quaternion, UnitQuaternion};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

const VIEWS: usize = 500;
const EDGES: usize = 5000; // mean degree 20
/// Per-axis noise: 2 degrees RMS angle over the three axes.
const SIGMA_DEG: f64 = 2.0 / 1.732_050_807_568_877_2;

/// `count` distinct random pairs `(i, j)`, `i != j`, of `views` views.
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

/// Noisy edges between `camera_from_world` rotations; a fraction `outliers` of them (chosen at
/// random) replaced by uniform random rotations. Returns the edges and the outlier flags.
fn noisy_edges(
    r: &mut ChaCha8Rng,
    truth: &[UnitQuaternion<f64>],
    pairs: &[(usize, usize)],
    outliers: f64,
) -> (Vec<RotationEdge>, Vec<bool>) {
    let sigma = SIGMA_DEG.to_radians();
    let mut flags = Vec::with_capacity(pairs.len());
    let edges = pairs
        .iter()
        .map(|&(i, j)| {
            let outlier = r.random::<f64>() < outliers;
            flags.push(outlier);
            let j_from_i = if outlier {
                uniform_rotation(r)
            } else {
                rotation_noise(r, sigma) * truth[j] * truth[i].inverse()
            };
            RotationEdge::new(i, j, j_from_i)
        })
        .collect();
    (edges, flags)
}

/// Mean and largest angle between estimated and true `camera_from_world` after the best global
/// rotation of the world (the gauge): `estimate * G ~ truth`.
fn aligned_errors(
    estimate: &[Option<UnitQuaternion<f64>>],
    truth: &[UnitQuaternion<f64>],
) -> (f64, f64) {
    let pairs: Vec<_> = estimate
        .iter()
        .zip(truth)
        .filter_map(|(e, t)| e.map(|e| (e, *t)))
        .collect();
    let offsets: Vec<_> = pairs.iter().map(|(e, t)| e.inverse() * t).collect();
    let g = quaternion_mean(&offsets, None).unwrap().mean;
    let errors: Vec<f64> = pairs.iter().map(|(e, t)| (e * g).angle_to(t)).collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    (mean, errors.iter().copied().fold(0.0, f64::max))
}

fn chordal_only() -> RotationAveragingOptions {
    RotationAveragingOptions {
        l1_iterations: 0,
        irls_iterations: 0,
        ..Default::default()
    }
}

#[test]
fn robust_averaging_matches_chordal_on_inliers() {
    for (k, outliers) in [0.0, 0.1, 0.3].into_iter().enumerate() {
        let mut r = rng(100 + k as u64);
        let truth: Vec<_> = (0..VIEWS).map(|_| uniform_rotation(&mut r)).collect();
        let pairs = random_pairs(&mut r, VIEWS, EDGES);
        let (edges, flags) = noisy_edges(&mut r, &truth, &pairs, outliers);
        let start = std::time::Instant::now();
        let robust = rotation_averaging(VIEWS, &edges, &Default::default()).unwrap();
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        let inliers: Vec<_> = edges
            .iter()
            .zip(&flags)
            .filter(|(_, o)| !**o)
            .map(|(e, _)| *e)
            .collect();
        let baseline = rotation_averaging(VIEWS, &inliers, &chordal_only()).unwrap();
        let all_chordal = rotation_averaging(VIEWS, &edges, &chordal_only()).unwrap();
        assert!(robust.report.dropped_views.is_empty());
        let (mean, max) = aligned_errors(&robust.camera_from_world, &truth);
        let (base, _) = aligned_errors(&baseline.camera_from_world, &truth);
        let (chordal_all, _) = aligned_errors(&all_chordal.camera_from_world, &truth);
        // Outlier report: the true outliers far from their edge's truth are found; inliers
        // are not flagged.
        let reported: std::collections::HashSet<usize> =
            robust.report.outlier_edges.iter().copied().collect();
        let (mut far, mut found, mut false_alarms) = (0, 0, 0);
        for (e, (edge, &outlier)) in edges.iter().zip(&flags).enumerate() {
            let true_rel = truth[edge.j] * truth[edge.i].inverse();
            if outlier && edge.j_from_i.angle_to(&true_rel) > 15f64.to_radians() {
                far += 1;
                found += usize::from(reported.contains(&e));
            }
            if !outlier && reported.contains(&e) {
                false_alarms += 1;
            }
        }
        println!(
            "outliers {:>2.0}%: robust mean {:.4} deg (max {:.3}), chordal on inliers {:.4} deg \
             (ratio {:.3}), chordal on all {:.3} deg; {} outliers reported, {found}/{far} far \
             outliers found, {false_alarms} inliers flagged; scale {:.3} deg; {} iterations, {} \
             CG iterations, {elapsed:.1} ms",
            outliers * 100.0,
            mean.to_degrees(),
            max.to_degrees(),
            base.to_degrees(),
            mean / base,
            chordal_all.to_degrees(),
            reported.len(),
            robust.report.robust_scale.to_degrees(),
            robust.report.iterations,
            robust.report.linear_iterations,
        );
        assert!(mean <= 1.10 * base, "{outliers}: {mean} vs {base}");
        assert!(robust.report.converged && robust.report.linear_converged);
        assert_eq!(found, far);
        assert!(
            false_alarms <= EDGES / 1000,
            "{false_alarms} inliers flagged"
        );
        // The first view is the gauge.
        assert!(robust.camera_from_world[0].unwrap().angle() < 1e-12);
    }
}

#[test]
fn exact_edges_are_reproduced() {
    let mut r = rng(7);
    let truth: Vec<_> = (0..60).map(|_| uniform_rotation(&mut r)).collect();
    let pairs = random_pairs(&mut r, 60, 300);
    let (edges, _) = noisy_edges(&mut r, &truth, &pairs, 0.0);
    let exact: Vec<_> = edges
        .iter()
        .map(|e| RotationEdge::new(e.i, e.j, truth[e.j] * truth[e.i].inverse()))
        .collect();
    for options in [RotationAveragingOptions::default(), chordal_only()] {
        let result = rotation_averaging(60, &exact, &options).unwrap();
        let (mean, max) = aligned_errors(&result.camera_from_world, &truth);
        assert!(max < 1e-9, "{mean} {max}");
        assert!(result.report.outlier_edges.is_empty());
        assert!(result.report.residuals.iter().all(|r| r.unwrap() < 1e-9));
    }
}

/// A rig of `cameras` cameras at `times` times: random extrinsics and rig rotations, edges
/// between random pairs of views.
struct SyntheticRig {
    layout: RigLayout,
    world_from_rig: Vec<UnitQuaternion<f64>>,
    rig_from_camera: Vec<UnitQuaternion<f64>>,
}

impl SyntheticRig {
    fn new(r: &mut ChaCha8Rng, times: usize, cameras: usize) -> Self {
        let views = (0..times)
            .flat_map(|time| (0..cameras).map(move |camera| RigView { time, camera }))
            .collect();
        Self {
            layout: RigLayout::new(times, cameras, views).unwrap(),
            world_from_rig: (0..times).map(|_| uniform_rotation(r)).collect(),
            rig_from_camera: (0..cameras).map(|_| uniform_rotation(r)).collect(),
        }
    }

    fn camera_from_world(&self) -> Vec<UnitQuaternion<f64>> {
        self.layout
            .views()
            .iter()
            .map(|v| (self.world_from_rig[v.time] * self.rig_from_camera[v.camera]).inverse())
            .collect()
    }
}

/// Largest extrinsic error and mean rig rotation error in the gauge of the result (camera 0
/// the rig frame; world aligned by the best global rotation).
fn rig_errors(
    rig: &SyntheticRig,
    world_from_rig: &[Option<UnitQuaternion<f64>>],
    rig_from_camera: &[UnitQuaternion<f64>],
) -> (f64, f64) {
    let c0 = rig.rig_from_camera[0];
    let extrinsic = rig_from_camera
        .iter()
        .zip(&rig.rig_from_camera)
        .map(|(e, t)| e.angle_to(&(c0.inverse() * t)))
        .fold(0.0, f64::max);
    let truth: Vec<_> = rig.world_from_rig.iter().map(|w| w * c0).collect();
    let offsets: Vec<_> = world_from_rig
        .iter()
        .zip(&truth)
        .filter_map(|(e, t)| e.map(|e| t * e.inverse()))
        .collect();
    let g = quaternion_mean(&offsets, None).unwrap().mean;
    let errors: Vec<f64> = world_from_rig
        .iter()
        .zip(&truth)
        .filter_map(|(e, t)| e.map(|e| (g * e).angle_to(t)))
        .collect();
    (extrinsic, errors.iter().sum::<f64>() / errors.len() as f64)
}

#[test]
fn rig_form_recovers_extrinsics_and_rig_rotations() {
    let mut r = rng(31);
    let rig = SyntheticRig::new(&mut r, 125, 4);
    let truth = rig.camera_from_world();
    let pairs = random_pairs(&mut r, VIEWS, EDGES);
    // Exact edges: exact recovery.
    let exact: Vec<_> = pairs
        .iter()
        .map(|&(i, j)| RotationEdge::new(i, j, truth[j] * truth[i].inverse()))
        .collect();
    let result = rig_rotation_averaging(&rig.layout, &exact, &Default::default()).unwrap();
    let (extrinsic, rig_error) = rig_errors(&rig, &result.world_from_rig, &result.rig_from_camera);
    println!("rig, exact edges: extrinsics {extrinsic:.1e} rad, rig rotations {rig_error:.1e} rad");
    assert!(extrinsic < 1e-9 && rig_error < 1e-9);
    assert_eq!(result.rig_from_camera[0], UnitQuaternion::identity());
    // Noisy edges with 30 % outliers: the rig form pools four cameras per time.
    let (edges, _) = noisy_edges(&mut r, &truth, &pairs, 0.3);
    let result = rig_rotation_averaging(&rig.layout, &edges, &Default::default()).unwrap();
    let (extrinsic, rig_error) = rig_errors(&rig, &result.world_from_rig, &result.rig_from_camera);
    let per_view = rotation_averaging(VIEWS, &edges, &Default::default()).unwrap();
    let (view_error, _) = aligned_errors(&per_view.camera_from_world, &truth);
    let (rig_view_error, _) = aligned_errors(&result.camera_from_world, &truth);
    println!(
        "rig, 30% outliers: extrinsics max {:.4} deg, rig rotations mean {:.4} deg, views mean \
         {:.4} deg (per-view solve {:.4} deg); {} iterations, {} CG iterations",
        extrinsic.to_degrees(),
        rig_error.to_degrees(),
        rig_view_error.to_degrees(),
        view_error.to_degrees(),
        result.report.iterations,
        result.report.linear_iterations
    );
    assert!(extrinsic < 0.1f64.to_radians());
    assert!(rig_error < 0.75 * view_error);
    assert!(rig_view_error < 0.75 * view_error);
    assert!(result.report.converged);
    assert!(result.world_from_rig[0].unwrap().angle() < 1e-12);
}

#[test]
fn rig_without_shared_views_of_a_camera_is_an_error() {
    let mut r = rng(5);
    let rig = SyntheticRig::new(&mut r, 10, 3);
    let truth = rig.camera_from_world();
    // Edges only among cameras 0 and 1: camera 2's views have no edge.
    let views = rig.layout.views();
    let mut edges = Vec::new();
    for i in 0..views.len() {
        for j in i + 1..views.len() {
            if views[i].camera < 2 && views[j].camera < 2 {
                edges.push(RotationEdge::new(i, j, truth[j] * truth[i].inverse()));
            }
        }
    }
    let error = rig_rotation_averaging(&rig.layout, &edges, &Default::default()).unwrap_err();
    assert!(matches!(
        error,
        ViewingGraphError::UndeterminedCamera { camera: 2, .. }
    ));
    assert!(error.to_string().contains("camera 2"));
    // Camera 1 only seen together with itself: its views form their own component.
    let edges: Vec<_> = edges
        .into_iter()
        .filter(|e| views[e.i].camera == views[e.j].camera)
        .collect();
    let error = rig_rotation_averaging(&rig.layout, &edges, &Default::default()).unwrap_err();
    assert!(matches!(
        error,
        ViewingGraphError::UndeterminedCamera { camera: 1, .. }
    ));
}

#[test]
fn disconnected_graph_keeps_the_largest_component() {
    let mut r = rng(9);
    let truth: Vec<_> = (0..30).map(|_| uniform_rotation(&mut r)).collect();
    let mut edges = Vec::new();
    // Views 0..20 in a dense component, 20..27 in a smaller one, 27..30 isolated.
    for (lo, hi) in [(0, 20), (20, 27)] {
        for i in lo..hi {
            for j in i + 1..hi {
                edges.push(RotationEdge::new(i, j, truth[j] * truth[i].inverse()));
            }
        }
    }
    let result = rotation_averaging(30, &edges, &Default::default()).unwrap();
    assert_eq!(result.report.kept_views, (0..20).collect::<Vec<_>>());
    assert_eq!(result.report.dropped_views, (20..30).collect::<Vec<_>>());
    assert_eq!(result.report.dropped_edges.len(), 21);
    assert!(result.camera_from_world[20..].iter().all(Option::is_none));
    let (_, max) = aligned_errors(&result.camera_from_world[..20], &truth[..20]);
    assert!(max < 1e-9);
    let pairs: Vec<_> = edges.iter().map(|e| (e.i, e.j)).collect();
    let component = largest_connected_component(30, &pairs).unwrap();
    assert_eq!(component.views, result.report.kept_views);
}

#[test]
fn bad_input_is_a_typed_error() {
    let q = UnitQuaternion::identity();
    let options = RotationAveragingOptions::default();
    let edges = [RotationEdge::new(0, 1, q), RotationEdge::new(1, 2, q)];
    assert_eq!(
        rotation_averaging(3, &[], &options),
        Err(ViewingGraphError::NoEdges)
    );
    assert_eq!(
        rotation_averaging(0, &edges, &options),
        Err(ViewingGraphError::NoViews)
    );
    assert!(matches!(
        rotation_averaging(2, &edges, &options),
        Err(ViewingGraphError::ViewOutOfRange {
            edge: 1,
            view: 2,
            views: 2
        })
    ));
    assert!(matches!(
        rotation_averaging(3, &[RotationEdge::new(1, 1, q)], &options),
        Err(ViewingGraphError::SelfLoop { edge: 0, view: 1 })
    ));
    let nan = UnitQuaternion::new_unchecked(Quaternion::new(f64::NAN, 0.0, 0.0, 0.0));
    let long = UnitQuaternion::new_unchecked(Quaternion::new(2.0, 0.0, 0.0, 0.0));
    for bad in [nan, long] {
        assert!(matches!(
            rotation_averaging(3, &[edges[0], RotationEdge::new(1, 2, bad)], &options),
            Err(ViewingGraphError::NotUnitRotation { edge: 1, .. })
        ));
    }
    for weight in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            rotation_averaging(3, &[edges[0], edges[1].with_weight(weight)], &options),
            Err(ViewingGraphError::InvalidWeight { edge: 1, .. })
        ));
    }
    let bad_options = RotationAveragingOptions {
        robust_scale: Some(f64::NAN),
        ..Default::default()
    };
    assert!(matches!(
        rotation_averaging(3, &edges, &bad_options),
        Err(ViewingGraphError::InvalidOption {
            option: "robust_scale",
            ..
        })
    ));
    // Rig layouts.
    let view = |time, camera| RigView { time, camera };
    assert!(matches!(
        RigLayout::new(2, 2, vec![view(0, 0), view(2, 1)]),
        Err(ViewingGraphError::RigViewOutOfRange {
            view: 1,
            time: 2,
            ..
        })
    ));
    assert!(matches!(
        RigLayout::new(2, 2, vec![view(0, 0), view(0, 0)]),
        Err(ViewingGraphError::DuplicateRigView {
            first: 0,
            view: 1,
            ..
        })
    ));
    assert_eq!(
        RigLayout::new(2, 0, vec![]),
        Err(ViewingGraphError::NoCameras)
    );
    assert_eq!(
        RigLayout::new(2, 2, vec![]),
        Err(ViewingGraphError::NoViews)
    );
    let layout = RigLayout::new(2, 2, vec![view(0, 0), view(0, 1), view(1, 0)]).unwrap();
    assert!(matches!(
        rig_rotation_averaging(
            &layout,
            &edges,
            &RotationAveragingOptions {
                reference_camera: 2,
                ..Default::default()
            }
        ),
        Err(ViewingGraphError::InvalidOption {
            option: "reference_camera",
            ..
        })
    ));
    // Camera 1's only view has no edge.
    assert!(matches!(
        rig_rotation_averaging(&layout, &[RotationEdge::new(0, 2, q)], &options),
        Err(ViewingGraphError::UndeterminedCamera { camera: 1, .. })
    ));
    assert!(matches!(
        largest_connected_component(2, &[(0, 5)]),
        Err(ViewingGraphError::ViewOutOfRange {
            edge: 0,
            view: 5,
            views: 2
        })
    ));
}
