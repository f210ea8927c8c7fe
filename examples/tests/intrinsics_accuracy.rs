//! Accuracy of `calibrate_intrinsics` on simulated boards (issue 9): 20 views, 0.2 px noise.
//!
//! The bars: `mu, mv, u0, v0` (or `fx, fy, cx, cy`) within 0.1 px of the truth; the
//! reprojection RMS within 10% of the noise-only figure; the initialization alone gives the
//! focal length within 5%.
//!
//! The noise-only figure is what a perfect estimator leaves: with `m` residual coordinates of
//! i.i.d. noise `sigma` and `n = 8 + 6 * views` unknowns fitted, the expected RMS per
//! coordinate of the least-squares residuals is `sigma * sqrt(1 - n / m)`.
//!
//! With 54 corners a view (a 9x6 board) the parameter standard deviations are 0.06 to 0.09 px
//! for the fisheye and 0.12 to 0.18 px for the pinhole, so 0.1 px is only one or two standard
//! deviations there: a test of it would pass or fail by the luck of the seed. The 0.1 px bar is
//! therefore tested on denser boards (20 x 25 and 30 x 40 corners) where it is at least 2.5
//! standard deviations, on several seeds; on the 9x6 board the errors are tested against the
//! refinement's own standard deviations (within 4 of them), which also checks the covariance.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod intrinsics_common;

use ibc_camera_models::CameraModel;
use ibc_pipeline::intrinsics::kb_init::KbInitOptions;
use ibc_pipeline::intrinsics::simulate::{BoardSimulationOptions, SimulatedBoards};
use ibc_pipeline::intrinsics::{
    Initialization, IntrinsicCalibration, IntrinsicModel, IntrinsicsOptions, calibrate_intrinsics,
};
use intrinsics_common::{max_projection_difference, simulated, simulated_with};

/// The noise, pixels per coordinate.
const SIGMA: f64 = 0.2;

/// Calibrates simulated boards with the default options.
fn calibrate(sim: &SimulatedBoards, model: IntrinsicModel) -> IntrinsicCalibration {
    calibrate_intrinsics(
        &sim.corners,
        &sim.target,
        model,
        &IntrinsicsOptions::default(),
    )
    .unwrap()
}

/// `sigma * sqrt(1 - n / m)`: the RMS per coordinate that noise alone leaves after fitting.
fn noise_only_rms(sim: &SimulatedBoards) -> f64 {
    let m = 2.0 * sim.corners.num_corners() as f64;
    let n = (sim.camera.params().len() + 6 * sim.corners.images.len()) as f64;
    SIGMA * (1.0 - n / m).sqrt()
}

/// Errors of the parameters against the truth.
fn errors(cal: &IntrinsicCalibration, sim: &SimulatedBoards) -> Vec<f64> {
    let (est, truth) = (cal.camera.params(), sim.camera.params());
    est.iter().zip(truth).map(|(e, t)| e - t).collect()
}

/// The index of the horizontal focal length (`mu`, `fx` or `gamma1`): every model keeps
/// `[.., fx, fy, cx, cy]` last.
fn focal_index(sim: &SimulatedBoards) -> usize {
    sim.camera.params().len() - 4
}

/// The focal length after the initialization, relative to the true `mu` (or `fx`, `gamma1`).
fn initial_focal_error(cal: &IntrinsicCalibration, sim: &SimulatedBoards) -> f64 {
    let i = focal_index(sim);
    cal.initial_camera.params()[i] / sim.camera.params()[i] - 1.0
}

/// The bars every calibration must meet whatever the board: RMS within 10% of the noise-only
/// figure, every parameter within 4 of its standard deviations, and the initial focal length
/// within 5%.
fn assert_consistent(cal: &IntrinsicCalibration, sim: &SimulatedBoards, what: &str) {
    let expected = noise_only_rms(sim);
    let ratio = cal.rms_px / expected;
    assert!(
        (ratio - 1.0).abs() < 0.1,
        "{what}: RMS {:.4} px vs noise-only {expected:.4} px",
        cal.rms_px
    );
    // The estimated noise is the same figure scaled back by sqrt(m / (m - n)).
    assert!((cal.noise_sigma_px / SIGMA - 1.0).abs() < 0.1, "{what}");
    for (i, e) in errors(cal, sim).iter().enumerate() {
        let sd = cal.std_devs[i];
        assert!(sd > 0.0 && sd.is_finite(), "{what}: parameter {i} sd {sd}");
        assert!(
            e.abs() < 4.0 * sd,
            "{what}: parameter {i} off by {e:.3e}, {:.1} standard deviations",
            e / sd
        );
    }
    let f0 = initial_focal_error(cal, sim);
    assert!(
        f0.abs() < 0.05,
        "{what}: initial focal length off by {:.2}%",
        100.0 * f0
    );
}

/// The bar on the projection parameters: within 0.1 px, with standard deviations
/// small enough that the bar means at least 2.5 of them.
fn assert_projection_within(cal: &IntrinsicCalibration, sim: &SimulatedBoards, what: &str) {
    let e = errors(cal, sim);
    for (i, (err, sd)) in e
        .iter()
        .zip(&cal.std_devs)
        .enumerate()
        .skip(focal_index(sim))
    {
        assert!(err.abs() < 0.1, "{what}: parameter {i} off by {err:.4} px");
        assert!(*sd < 0.04, "{what}: parameter {i} sd {sd}");
    }
}

#[test]
fn kannala_brandt_190_degree_lens_within_a_tenth_of_a_pixel() {
    for seed in 0..3 {
        let sim = simulated(IntrinsicModel::KannalaBrandt, 20, 25, seed);
        let cal = calibrate(&sim, IntrinsicModel::KannalaBrandt);
        let what = format!("kb 20x25 seed {seed}");
        assert_consistent(&cal, &sim, &what);
        assert_projection_within(&cal, &sim, &what);
        assert!(matches!(
            cal.initialization,
            Initialization::VanishingPoints { .. }
        ));
    }
}

#[test]
fn kannala_brandt_on_the_9x6_board() {
    for seed in 0..4 {
        let sim = simulated(IntrinsicModel::KannalaBrandt, 6, 9, seed);
        let cal = calibrate(&sim, IntrinsicModel::KannalaBrandt);
        assert_consistent(&cal, &sim, &format!("kb 9x6 seed {seed}"));
    }
}

#[test]
fn vanishing_point_initialization_alone_gives_the_focal_length_within_5_percent() {
    // The paper's initialization (rows only) on the 9x6 board, and with a tenth of the corners
    // missing: the hypothesis kept is within 5% of the true mu, and so is every hypothesis
    // whose image saw enough of the board to score well.
    for (missing, use_columns) in [(0.0, false), (0.1, true)] {
        let options = BoardSimulationOptions {
            missing_fraction: missing,
            seed: 7,
            ..BoardSimulationOptions::for_model(IntrinsicModel::KannalaBrandt)
        };
        let sim = simulated_with(IntrinsicModel::KannalaBrandt, 6, 9, &options);
        let calib_options = IntrinsicsOptions {
            kb_init: KbInitOptions {
                use_columns,
                ..Default::default()
            },
            ..Default::default()
        };
        let cal = calibrate_intrinsics(
            &sim.corners,
            &sim.target,
            IntrinsicModel::KannalaBrandt,
            &calib_options,
        )
        .unwrap();
        let Initialization::VanishingPoints { hypotheses, chosen } = &cal.initialization else {
            panic!("not the vanishing-point initialization");
        };
        let truth = sim.camera.params()[4];
        let kept = hypotheses[*chosen].focal;
        assert!(
            (kept / truth - 1.0).abs() < 0.05,
            "missing {missing}: f = {kept:.2} px, truth {truth:.2} px"
        );
        assert!(hypotheses.len() >= sim.corners.images.len() / 2);
        // The initial camera is the paper's equidistant one with that focal length.
        let p = cal.initial_camera.params();
        assert_eq!(&p[..4], &[0.0; 4]);
        assert_eq!((p[4], p[5]), (kept, kept));
        assert_consistent(&cal, &sim, &format!("kb 9x6 missing {missing}"));
    }
}

#[test]
fn pinhole_radtan_within_a_tenth_of_a_pixel() {
    for seed in 0..2 {
        let sim = simulated(IntrinsicModel::PinholeRadtan, 30, 40, seed);
        let cal = calibrate(&sim, IntrinsicModel::PinholeRadtan);
        let what = format!("pinhole 30x40 seed {seed}");
        assert_consistent(&cal, &sim, &what);
        assert_projection_within(&cal, &sim, &what);
        let Initialization::Zhang(z) = cal.initialization else {
            panic!("not Zhang's initialization");
        };
        let truth = sim.camera.params();
        assert!((z.fx / truth[4] - 1.0).abs() < 0.05 && (z.fy / truth[5] - 1.0).abs() < 0.05);
    }
}

#[test]
fn pinhole_radtan_on_the_9x6_board() {
    for seed in 0..3 {
        let sim = simulated(IntrinsicModel::PinholeRadtan, 6, 9, seed);
        let cal = calibrate(&sim, IntrinsicModel::PinholeRadtan);
        assert_consistent(&cal, &sim, &format!("pinhole 9x6 seed {seed}"));
    }
}

/// The unified model's generalized focal lengths are strongly correlated with `xi` (here a
/// standard deviation of about 0.8 px against 0.02 px for the principal point), so 0.1 px on
/// `gamma1, gamma2` is not what the data determine: the bar is on what they do determine,
/// the projection, within 0.1 px over the simulated field, with the principal point within
/// 0.1 px and every parameter within 4 of its standard deviations (`assert_consistent`).
#[test]
fn unified_190_degree_lens_projects_within_a_tenth_of_a_pixel() {
    for seed in 0..3 {
        let sim = simulated(IntrinsicModel::Unified, 20, 25, seed);
        let cal = calibrate(&sim, IntrinsicModel::Unified);
        let what = format!("mei 20x25 seed {seed}");
        assert_consistent(&cal, &sim, &what);
        let e = errors(&cal, &sim);
        let centre = focal_index(&sim) + 2;
        assert!(
            e[centre].abs() < 0.1 && e[centre + 1].abs() < 0.1,
            "{what}: principal point off by {:.3}, {:.3} px",
            e[centre],
            e[centre + 1]
        );
        let field = max_projection_difference(&sim.camera, &cal.camera, 95.0);
        println!(
            "{what}: xi {:.4} (truth {:.4}, sd {:.4}), gamma1 off by {:.3} px (sd {:.3}), \
             projection within {field:.4} px",
            cal.camera.params()[0],
            sim.camera.params()[0],
            cal.std_devs[0],
            e[5],
            cal.std_devs[5]
        );
        assert!(field < 0.1, "{what}: projection differs by {field} px");
        assert!(matches!(
            cal.initialization,
            Initialization::LineConics { .. }
        ));
    }
}

#[test]
fn unified_on_the_9x6_board() {
    for seed in 0..4 {
        let sim = simulated(IntrinsicModel::Unified, 6, 9, seed);
        let cal = calibrate(&sim, IntrinsicModel::Unified);
        assert_consistent(&cal, &sim, &format!("mei 9x6 seed {seed}"));
    }
}
