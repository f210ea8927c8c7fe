//! Localization of each image of the rig log against the map (the paper's section IV-A).
//!
//! For one image:
//! 1. its bag-of-words vector and direct-index feature vector (the map's vocabulary);
//! 2. the [`candidates`](LocalizationOptions::candidates) most similar map images from the
//!    database (inverted index);
//! 3. ratio-test matching (with the mutual check) of the image's features against the map
//!    points the candidates observe, restricted to features under the same vocabulary node
//!    (the direct index, as DBoW2 matches; see [`match_to_map`]): each match is a 2D-3D
//!    correspondence;
//! 4. each map point and each feature are kept at most once: the correspondences of all
//!    nodes are sorted by descriptor distance (then feature and point index) and taken
//!    greedily;
//! 5. `ibc_pnp::absolute_pose` on the keypoints and the map points
//!    ([`pose`](LocalizationOptions::pose)): the keypoints become unit bearings
//!    (`unproject_fast`; one the camera cannot unproject is an outlier), the pixel threshold
//!    an angle at the camera's principal point, and RANSAC with P3P and a final refit gives
//!    `camera_from_world`;
//! 6. fewer than the pose options' `min_inliers` correspondences or inliers leave the image
//!    unlocalized.
//!
//! Images are localized in parallel (rayon); each has its own RANSAC seed derived from the
//! options' seed and its frame and camera, so the result does not depend on the thread count.

use std::sync::Arc;

use ibc_camera_models::Camera;
use ibc_pnp::{AbsolutePoseOptions, PnpError, RansacOptions, absolute_pose};
use ibc_vocab_tree::{
    Descriptor, MatchOptions, MatchScratch, QueryOptions, VocabError, match_sets,
};
use nalgebra::{Isometry3, Point3, Vector2};
use rayon::prelude::*;

use super::error::CalibrationError;
use super::map_index::{MapIndex, NodeGroups};
use super::options::LocalizationOptions;
use super::progress::Progress;
use crate::data::{ImageFeatures, Map, PointId, RigLog};

/// An inlier 2D-3D correspondence of a localized image: its feature `feature` observes map
/// point `point`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Correspondence {
    /// Index of the feature in the image.
    pub feature: u32,
    /// The map point.
    pub point: PointId,
}

/// A localized image.
#[derive(Clone, Debug, PartialEq)]
pub struct LocalizedImage {
    /// The camera's pose.
    pub camera_from_world: Isometry3<f64>,
    /// The RANSAC inliers, by increasing feature index.
    pub inliers: Vec<Correspondence>,
    /// Every correspondence RANSAC was given, inliers or not (for re-selecting the inliers
    /// under refined intrinsics: see [`crate::calib::refinement`]).
    pub correspondences: Vec<Correspondence>,
    /// Correspondences before RANSAC (one per map point).
    pub matches: usize,
}

/// Why an image was not localized.
#[derive(Clone, Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LocalizationFailure {
    /// The image has no feature.
    #[error("the image has no feature")]
    NoFeatures,
    /// No map image shares a word with it.
    #[error("no similar map image")]
    NoCandidates,
    /// Too few 2D-3D correspondences to try.
    #[error("{found} correspondences, fewer than the {required} required")]
    TooFewMatches {
        /// Correspondences found.
        found: usize,
        /// The `min_inliers` option.
        required: usize,
    },
    /// RANSAC found too few inliers.
    #[error("{found} inliers, fewer than the {required} required")]
    TooFewInliers {
        /// Inliers of the best pose.
        found: usize,
        /// The `min_inliers` option.
        required: usize,
    },
    /// The pose solver refused the correspondences (degenerate geometry, a threshold the
    /// camera cannot turn into an angle).
    #[error("pose: {0}")]
    Pose(#[source] PnpError),
    /// The matching options are outside their domain.
    #[error("matching: {0}")]
    InvalidOption(#[source] Arc<VocabError>),
    /// The vocabulary could not describe the image (a direct-index level past the tree's
    /// depth).
    #[error("vocabulary: {0}")]
    Vocabulary(#[source] Arc<VocabError>),
}

/// What happened to one image.
pub type ImageLocalization = Result<LocalizedImage, LocalizationFailure>;

/// The localization of every image of a log, `images[frame][camera]`.
#[derive(Clone, Debug)]
pub struct Localizations {
    /// One entry per frame and camera.
    pub images: Vec<Vec<ImageLocalization>>,
}

impl Localizations {
    /// The localized image (`frame`, `camera`), if it was localized.
    pub fn get(&self, frame: usize, camera: usize) -> Option<&LocalizedImage> {
        self.images.get(frame)?.get(camera)?.as_ref().ok()
    }

    /// Number of images tried.
    pub fn image_count(&self) -> usize {
        self.images.iter().map(Vec::len).sum()
    }

    /// Number of localized images.
    pub fn localized_count(&self) -> usize {
        self.images.iter().flatten().filter(|r| r.is_ok()).count()
    }

    /// Localized images per camera.
    pub fn localized_per_camera(&self) -> Vec<usize> {
        let cameras = self.images.first().map_or(0, Vec::len);
        (0..cameras)
            .map(|c| {
                self.images
                    .iter()
                    .filter(|f| f.get(c).is_some_and(Result::is_ok))
                    .count()
            })
            .collect()
    }
}

/// SplitMix64 of a value (Steele, Lea and Flood, OOPSLA 2014): decorrelates per-image seeds.
pub(crate) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The RANSAC seed of image (`frame`, `camera`).
fn image_seed(seed: u64, frame: usize, camera: usize) -> u64 {
    mix(mix(seed ^ mix(frame as u64)) ^ camera as u64)
}

/// The vocabulary crate's matching options for `options` (ratio and mutual check).
fn match_options(options: &LocalizationOptions) -> MatchOptions {
    MatchOptions::default()
        .with_ratio(options.ratio)
        .with_mutual_check(options.mutual_check)
}

/// The 2D-3D correspondences of an image (steps 1 to 4 of the module docs), sorted by
/// feature.
///
/// Within each node of the direct index, the image's features are matched against the map
/// points that the candidate images' features under the same node observe, each map point
/// once (with the descriptor of the best-ranked candidate image that has it there): the two
/// nearest points of each feature pass the ratio test on their metric distances, and the
/// mutual check keeps a match only when the feature is also the point's nearest among the
/// node's features. Map features without a map point are not candidates. Matching against
/// the candidates' points rather than each candidate image in turn compares each feature with
/// each point once, however many candidates see it.
///
/// # Errors
/// [`LocalizationFailure::NoFeatures`], [`LocalizationFailure::NoCandidates`], and
/// [`LocalizationFailure::InvalidOption`] for a ratio outside `(0, 1]`.
pub fn match_to_map<D: Descriptor>(
    index: &MapIndex<D>,
    map: &Map<D>,
    features: &ImageFeatures<D>,
    options: &LocalizationOptions,
) -> Result<Vec<Correspondence>, LocalizationFailure> {
    let matching = match_options(options);
    matching
        .validate()
        .map_err(|e| LocalizationFailure::InvalidOption(Arc::new(e)))?;
    if features.is_empty() {
        return Err(LocalizationFailure::NoFeatures);
    }
    let (bow, feature_vector) = index
        .vocabulary
        .transform_with_features(&features.descriptors, index.direct_index_levels)
        .map_err(|e| LocalizationFailure::Vocabulary(Arc::new(e)))?;
    let results = index.database.query(
        &bow,
        &QueryOptions::default().with_max_results(options.candidates),
    );
    let candidates: Vec<&NodeGroups<D>> = results
        .iter()
        .filter_map(|r| index.groups.get(r.image as usize))
        .collect();
    if candidates.is_empty() {
        return Err(LocalizationFailure::NoCandidates);
    }
    // Per node: the pool of (point, descriptor), each point once (`stamp` marks the points
    // already in the current node's pool). The candidates' groups are sorted by node, like
    // the query's feature vector, so one cursor per candidate walks them in step.
    let mut stamp = vec![u32::MAX; map.points.len()];
    let mut pool_points: Vec<PointId> = Vec::new();
    let mut pool: Vec<&D> = Vec::new();
    let mut query_features: Vec<u32> = Vec::new();
    let mut query: Vec<&D> = Vec::new();
    let mut scratch = MatchScratch::default();
    let mut cursors: Vec<_> = candidates.iter().map(|g| g.iter().peekable()).collect();
    // (distance, feature, point)
    let mut pairs: Vec<(f64, u32, PointId)> = Vec::new();
    for (node_index, (node, query_group)) in feature_vector.iter().enumerate() {
        pool_points.clear();
        pool.clear();
        for cursor in &mut cursors {
            while cursor.next_if(|(n, _, _)| *n < node).is_some() {}
            let Some((_, points, descriptors)) = cursor.next_if(|(n, _, _)| *n == node) else {
                continue;
            };
            for (point, descriptor) in points.iter().zip(descriptors) {
                if let Some(s) = stamp.get_mut(*point as usize)
                    && *s != node_index as u32
                {
                    *s = node_index as u32;
                    pool_points.push(*point);
                    pool.push(descriptor);
                }
            }
        }
        if pool.is_empty() {
            continue;
        }
        query_features.clear();
        query.clear();
        for &q in query_group {
            if let Some(descriptor) = features.descriptors.get(q as usize) {
                query_features.push(q);
                query.push(descriptor);
            }
        }
        let found = |r: usize, c: usize, distance: f64| {
            pairs.push((distance, query_features[r], pool_points[c]));
        };
        match_sets(&query, &pool, &matching, &mut scratch, found)
            .map_err(|e| LocalizationFailure::InvalidOption(Arc::new(e)))?;
    }
    pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let mut feature_used = vec![false; features.len()];
    let mut point_used = std::collections::HashSet::with_capacity(pairs.len());
    let mut kept = Vec::with_capacity(pairs.len());
    for (_, feature, point) in pairs {
        let f = feature as usize;
        if f < feature_used.len() && !feature_used[f] && point_used.insert(point) {
            feature_used[f] = true;
            kept.push(Correspondence { feature, point });
        }
    }
    kept.sort_unstable_by_key(|c| c.feature);
    Ok(kept)
}

/// Localizes one image (see the module docs); `seed` seeds its RANSAC.
pub fn localize_image<D: Descriptor>(
    index: &MapIndex<D>,
    map: &Map<D>,
    camera: &Camera,
    features: &ImageFeatures<D>,
    options: &LocalizationOptions,
    seed: u64,
) -> ImageLocalization {
    let correspondences = match_to_map(index, map, features, options)?;
    let mut pixels: Vec<Vector2<f64>> = Vec::with_capacity(correspondences.len());
    let mut points: Vec<Point3<f64>> = Vec::with_capacity(correspondences.len());
    let mut used: Vec<Correspondence> = Vec::with_capacity(correspondences.len());
    for c in &correspondences {
        if let (Some(pixel), Some(point)) = (
            features.keypoints.get(c.feature as usize),
            map.points.get(c.point as usize),
        ) {
            pixels.push(*pixel);
            points.push(*point);
            used.push(*c);
        }
    }
    let required = options.pose.ransac.min_inliers;
    if pixels.len() < required {
        return Err(LocalizationFailure::TooFewMatches {
            found: pixels.len(),
            required,
        });
    }
    let pose = AbsolutePoseOptions {
        ransac: RansacOptions {
            seed,
            ..options.pose.ransac.clone()
        },
        ..options.pose.clone()
    };
    match absolute_pose(camera, &pixels, &points, &pose) {
        Ok(pose) => Ok(LocalizedImage {
            camera_from_world: pose.camera_from_world,
            inliers: pose.inliers.iter().map(|&i| used[i]).collect(),
            matches: used.len() - pose.unprojection_failures,
            correspondences: used,
        }),
        Err(PnpError::TooFewInliers { found, .. }) => {
            Err(LocalizationFailure::TooFewInliers { found, required })
        }
        // Fewer correspondences (that the camera can unproject) than inliers are required.
        Err(
            PnpError::TooFewUnprojected {
                unprojected: found, ..
            }
            | PnpError::NotEnoughPoints { got: found, .. },
        ) => Err(LocalizationFailure::TooFewMatches { found, required }),
        Err(e) => Err(LocalizationFailure::Pose(e)),
    }
}

/// Localizes every image of the log in parallel (see the module docs).
///
/// # Errors
/// [`CalibrationError::CameraCountMismatch`] if `cameras` and the log disagree,
/// [`CalibrationError::InvalidInput`] for a frame with another number of images,
/// [`CalibrationError::InvalidOption`] for a threshold that does not fit a camera.
pub fn localize_log<D: Descriptor>(
    index: &MapIndex<D>,
    map: &Map<D>,
    cameras: &[Camera],
    log: &RigLog<D>,
    options: &LocalizationOptions,
    progress: &dyn Progress,
) -> Result<Localizations, CalibrationError> {
    let k = cameras.len();
    if log.camera_names.len() != k {
        return Err(CalibrationError::CameraCountMismatch {
            cameras: k,
            log_cameras: log.camera_names.len(),
        });
    }
    if let Some((i, f)) = log
        .frames
        .iter()
        .enumerate()
        .find(|(_, f)| f.images.len() != k)
    {
        return Err(CalibrationError::InvalidInput(format!(
            "frame {i} of the log has {} images for {k} cameras",
            f.images.len()
        )));
    }
    let flat: Vec<ImageLocalization> = (0..log.frames.len() * k)
        .into_par_iter()
        .map(|i| {
            let (frame, camera) = (i / k, i % k);
            let result = localize_image(
                index,
                map,
                &cameras[camera],
                &log.frames[frame].images[camera],
                options,
                image_seed(options.pose.ransac.seed, frame, camera),
            );
            progress.advance(1);
            result
        })
        .collect();
    let mut images = Vec::with_capacity(log.frames.len());
    let mut it = flat.into_iter();
    for _ in 0..log.frames.len() {
        images.push(it.by_ref().take(k).collect());
    }
    Ok(Localizations { images })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_seeds_differ_by_frame_and_camera() {
        let a = image_seed(0, 1, 0);
        assert_ne!(a, image_seed(0, 0, 1));
        assert_ne!(a, image_seed(1, 1, 0));
        assert_eq!(a, image_seed(0, 1, 0));
    }
}
