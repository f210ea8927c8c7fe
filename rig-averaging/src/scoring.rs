//! Scoring a candidate camera pose by reprojection error, without knowing the camera model.
//!
//! Rig initialization (see [`initialize_rig`](crate::initialize_rig)) ranks hypotheses by the
//! mean reprojection error over all images, as in Heng et al., ICRA 2014, section IV-C. This
//! crate does not know the camera models or the localization pipeline, so the caller supplies
//! the scoring: either any [`ImageScorer`] (a closure
//! `Fn(set, camera, &camera_from_world) -> ImageScore` is one), or an [`ObservationScorer`]
//! built from 2D-3D observations and a projection function.

use nalgebra::{Isometry3, Point2, Point3};

/// The reprojection error of one image under a candidate pose: the sum of per-observation
/// errors (pixels) and the number of observations.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImageScore {
    /// Sum of the per-observation reprojection errors, pixels.
    pub error_sum: f64,
    /// Number of observations summed.
    pub observations: usize,
}

impl ImageScore {
    /// An image score from an error sum and an observation count.
    pub fn new(error_sum: f64, observations: usize) -> Self {
        Self {
            error_sum,
            observations,
        }
    }
}

/// Gives the reprojection error of image (`set`, `camera`) when that camera is placed at
/// `camera_from_world`.
///
/// Called from several threads at once (hence `Sync`), once per image per hypothesis, so the
/// total work is linear in hypotheses x observations. It is called for every camera slot of
/// every set, also for cameras that were not localized in that set: return
/// `ImageScore::default()` for an image without observations. Return a NaN or infinite
/// `error_sum` to disqualify the hypothesis.
pub trait ImageScorer: Sync {
    /// The score of image (`set`, `camera`) at the candidate `camera_from_world`.
    fn score_image(
        &self,
        set: usize,
        camera: usize,
        camera_from_world: &Isometry3<f64>,
    ) -> ImageScore;
}

impl<F> ImageScorer for F
where
    F: Fn(usize, usize, &Isometry3<f64>) -> ImageScore + Sync,
{
    fn score_image(
        &self,
        set: usize,
        camera: usize,
        camera_from_world: &Isometry3<f64>,
    ) -> ImageScore {
        self(set, camera, camera_from_world)
    }
}

/// One 2D-3D observation: a world point and the pixel where it was seen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// The observed point, world frame, metres.
    pub point_in_world: Point3<f64>,
    /// The measured pixel (pixel centres at integer coordinates).
    pub pixel: Point2<f64>,
}

/// Pixel error counted for an observation the projection function cannot project (it returned
/// `None` or a non-finite pixel), for example a point behind the candidate camera: 1000 px,
/// larger than any reprojection error of a usable hypothesis, so a hypothesis that puts map
/// points behind a camera ranks below those that do not, yet stays finite and comparable.
pub const DEFAULT_FAILURE_PENALTY_PX: f64 = 1000.0;

/// An [`ImageScorer`] from observations: the error of an observation is the Euclidean distance
/// in pixels between its measured pixel and `project(camera, camera_from_world * point)`.
///
/// `project(camera, point_in_camera)` is the caller's camera model (for example a
/// `ibc-camera-models` camera): it returns `None` where the point cannot be projected.
///
/// ```
/// use ibc_rig_averaging::{ImageScorer, Observation, ObservationScorer};
/// use nalgebra::{Isometry3, Point2, Point3};
///
/// // One set, one camera, one point 2 m ahead seen at the principal point of a pinhole camera.
/// let images = vec![vec![vec![Observation {
///     point_in_world: Point3::new(0.0, 0.0, 2.0),
///     pixel: Point2::new(320.0, 240.0),
/// }]]];
/// let pinhole = |_camera: usize, p: &Point3<f64>| {
///     (p.z > 0.0).then(|| Point2::new(500.0 * p.x / p.z + 320.0, 500.0 * p.y / p.z + 240.0))
/// };
/// let scorer = ObservationScorer::new(images, pinhole);
/// let shifted = Isometry3::translation(0.01, 0.0, 0.0);
/// let score = scorer.score_image(0, 0, &shifted);
/// assert_eq!(score.observations, 1);
/// assert!((score.error_sum - 2.5).abs() < 1e-12); // 500 px * 0.01 m / 2 m
/// ```
#[derive(Clone, Debug)]
pub struct ObservationScorer<P> {
    images: Vec<Vec<Vec<Observation>>>,
    project: P,
    failure_penalty: f64,
}

impl<P> ObservationScorer<P>
where
    P: Fn(usize, &Point3<f64>) -> Option<Point2<f64>> + Sync,
{
    /// A scorer over `images[set][camera]` (a missing set or camera has no observations),
    /// with [`DEFAULT_FAILURE_PENALTY_PX`].
    pub fn new(images: Vec<Vec<Vec<Observation>>>, project: P) -> Self {
        Self {
            images,
            project,
            failure_penalty: DEFAULT_FAILURE_PENALTY_PX,
        }
    }

    /// Sets the pixel error counted for an observation that cannot be projected. A NaN or
    /// infinite penalty disqualifies every hypothesis that meets such an observation.
    pub fn with_failure_penalty(mut self, pixels: f64) -> Self {
        self.failure_penalty = pixels;
        self
    }

    /// The observations of image (`set`, `camera`), empty when there are none.
    pub fn observations(&self, set: usize, camera: usize) -> &[Observation] {
        self.images
            .get(set)
            .and_then(|s| s.get(camera))
            .map_or(&[], Vec::as_slice)
    }

    /// Total number of observations over all images.
    pub fn total_observations(&self) -> usize {
        self.images.iter().flatten().map(Vec::len).sum()
    }
}

impl<P> ImageScorer for ObservationScorer<P>
where
    P: Fn(usize, &Point3<f64>) -> Option<Point2<f64>> + Sync,
{
    fn score_image(
        &self,
        set: usize,
        camera: usize,
        camera_from_world: &Isometry3<f64>,
    ) -> ImageScore {
        let observations = self.observations(set, camera);
        if observations.is_empty() {
            return ImageScore::default();
        }
        // One rotation matrix per image: 9 multiply-adds per point instead of a quaternion
        // sandwich product.
        let rotation = camera_from_world.rotation.to_rotation_matrix();
        let r = rotation.matrix();
        let t = camera_from_world.translation.vector;
        let mut error_sum = 0.0;
        for obs in observations {
            let point_in_camera = Point3::from(r * obs.point_in_world.coords + t);
            let error = match (self.project)(camera, &point_in_camera) {
                Some(pixel) => (pixel - obs.pixel).norm(),
                None => self.failure_penalty,
            };
            error_sum += if error.is_finite() {
                error
            } else {
                self.failure_penalty
            };
        }
        ImageScore::new(error_sum, observations.len())
    }
}
