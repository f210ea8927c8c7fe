//! Feature tracks of a rig log without a map: candidate image pairs, descriptor matching,
//! geometric verification on bearings, and tracks by union-find.
//!
//! Method (TrimBot2020 D3.1 §3.3.3; the candidate retrieval of Nister and Stewenius, "Scalable
//! Recognition with a Vocabulary Tree", CVPR 2006, and DBoW2's direct index, Galvez-Lopez and
//! Tardos, T-RO 2012; union-find tracks as in Moulon and Monasse, "Unordered feature tracking
//! made fast and easy", CVMP 2012):
//! 1. every keypoint is unprojected to a unit bearing (a keypoint its camera cannot unproject is
//!    left out);
//! 2. candidate pairs: each camera's image with the same camera's next `sequential_window`
//!    images, every pair of cameras of one frame, and the `retrieved` most similar images (bag of
//!    words over a vocabulary trained on the log itself) within `retrieval_window` frames, of any
//!    camera: this is what links cameras that never see the same place at the same time;
//! 3. matching under the same node of the direct index, ratio test and mutual check;
//! 4. geometric verification by [`ibc_pnp::relative_pose`] on the bearings (LO-RANSAC, the
//!    five-point essential matrix, a homography or a pure rotation chosen by GRIC), which keeps
//!    the inlier matches and the relative pose: its rotation always, its translation direction
//!    when the pair has parallax (an essential or planar model); with the rig's extrinsics
//!    known ([`build_tracks_with_rig`], a map being built), two cameras of one frame need no
//!    search: their relative pose is the rig's, and [`ibc_pnp::relative_pose_inliers`] keeps
//!    the matches consistent with it;
//! 5. tracks: the connected components of the verified matches; a component with two keypoints
//!    in one image is a wrong match somewhere and is dropped whole.

use std::sync::Arc;

use ibc_camera_models::{Camera, CameraModel};
use ibc_pnp::{
    RansacOptions, RelativePoseError, RelativePoseOptions, TwoViewModel, relative_pose,
    relative_pose_inliers,
};
use ibc_vocab_tree::{
    Database, Descriptor, FeatureVector, MatchOptions, QueryOptions, TrainingOptions, Vocabulary,
    match_by_nodes,
};
use nalgebra::{Isometry3, Translation3, Vector3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::error::SelfCalibrationError;
use crate::NonExhaustive;
use crate::calib::localization::mix;
use crate::data::RigLog;

/// An image's keypoints as unit bearings (`None` where the camera cannot unproject).
type Bearings = [Option<Vector3<f64>>];

/// Options of [`build_tracks`].
#[derive(Clone, Debug, PartialEq)]
pub struct TrackOptions {
    /// Each image is matched with the same camera's images of the next this many frames.
    /// Default 3.
    pub sequential_window: usize,
    /// The most similar images (bag of words) each image is matched with. Default 16: on the
    /// garage (100 frames), 8 found 553 pairs between different cameras and a worst camera of
    /// 0.55 mm, 16 found 1345 and 0.42 mm, 24 found 2518 and 0.35 mm for 12 % more time.
    pub retrieved: usize,
    /// Retrieved images must be within this many frames. Default 60: at the garage's 0.6 m a
    /// frame, a place seen ahead by the front camera is seen by the side and rear cameras well
    /// within it.
    pub retrieval_window: usize,
    /// Ratio test of the descriptor matching. Default 0.8 (Lowe's).
    pub ratio: f64,
    /// Fewest verified matches for a pair to count. Default 30.
    pub min_inliers: usize,
    /// Options of the geometric verification; its seed is mixed with each pair's images. With
    /// [`RelativePoseOptions::progressive`] the matches are passed best first (smallest
    /// descriptor distance) and sampled progressively (PROSAC), as
    /// [`super::MapOptions::default`] does. Default [`RelativePoseOptions::default`] with at
    /// most 2000 iterations.
    pub relative_pose: RelativePoseOptions,
    /// Descriptors that train the vocabulary (a seeded sample, the same number from every
    /// image). Default 50,000.
    pub training_descriptors: usize,
    /// Seed of the vocabulary and of the verification. Default 0.
    pub seed: u64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: NonExhaustive,
}

impl Default for TrackOptions {
    fn default() -> Self {
        Self {
            sequential_window: 3,
            retrieved: 16,
            retrieval_window: 60,
            ratio: 0.8,
            min_inliers: 30,
            relative_pose: RelativePoseOptions {
                ransac: RansacOptions {
                    max_iterations: 2000,
                    ..RelativePoseOptions::default().ransac
                },
                ..Default::default()
            },
            training_descriptors: 50_000,
            seed: 0,
            non_exhaustive: NonExhaustive(()),
        }
    }
}

/// One image of the log: camera `camera` of frame `frame`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImageId {
    /// The frame.
    pub frame: usize,
    /// The camera.
    pub camera: usize,
}

/// A verified image pair: the relative pose and the inlier matches.
#[derive(Clone, Debug, PartialEq)]
pub struct VerifiedPair {
    /// The first image (index into [`Tracks::images`]).
    pub a: usize,
    /// The second image.
    pub b: usize,
    /// `b_from_a`, translation of unit length (or zero where the direction is not determined:
    /// a pure rotation or too little parallax).
    pub b_from_a: Isometry3<f64>,
    /// Whether the translation direction is determined (an essential or planar model with
    /// parallax); a pure rotation or too little parallax gives the rotation only.
    pub has_direction: bool,
    /// Inlier matches: (keypoint in a, keypoint in b), in keypoint order.
    pub matches: Vec<(u32, u32)>,
}

/// One track: the keypoints that observe one scene point, at most one per image.
#[derive(Clone, Debug, PartialEq)]
pub struct Track {
    /// (image index into [`Tracks::images`], keypoint index in that image).
    pub observations: Vec<(usize, u32)>,
}

/// What [`build_tracks`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracks {
    /// The images, frame by frame, camera by camera (those with at least one keypoint).
    pub images: Vec<ImageId>,
    /// Every image's keypoints as unit bearings (`None` where the camera cannot unproject).
    pub bearings: Vec<Vec<Option<Vector3<f64>>>>,
    /// The verified pairs.
    pub pairs: Vec<VerifiedPair>,
    /// The tracks of at least two images.
    pub tracks: Vec<Track>,
    /// Candidate pairs that were matched.
    pub candidate_pairs: usize,
    /// Candidate pairs that failed the verification (too few matches or inliers, degenerate).
    pub rejected_pairs: usize,
    /// Components dropped for holding two keypoints of one image.
    pub inconsistent_tracks: usize,
}

/// Every image's keypoints as bearings, seeded training sample, vocabulary and database, and
/// the candidate pairs (see the module documentation); then matching, verification and tracks.
///
/// # Errors
/// [`SelfCalibrationError::CameraCount`] when `cameras` and the log disagree,
/// [`SelfCalibrationError::InvalidOption`] for an option out of its domain,
/// [`SelfCalibrationError::Vocabulary`] when the vocabulary cannot be trained (no descriptor).
pub fn build_tracks<D: Descriptor>(
    log: &RigLog<D>,
    cameras: &[Camera],
    options: &TrackOptions,
) -> Result<Tracks, SelfCalibrationError> {
    build_tracks_with_rig(log, cameras, None, options)
}

/// As [`build_tracks`], with the rig's extrinsics `rig_from_camera` (one per camera, any
/// common rig frame) known when given: a pair of two cameras of one frame is then verified
/// against their known relative pose instead of by a search (see the module documentation).
///
/// # Errors
/// As [`build_tracks`], and [`SelfCalibrationError::CameraCount`] when `rig_from_camera` does
/// not have one pose per camera.
pub fn build_tracks_with_rig<D: Descriptor>(
    log: &RigLog<D>,
    cameras: &[Camera],
    rig_from_camera: Option<&[Isometry3<f64>]>,
    options: &TrackOptions,
) -> Result<Tracks, SelfCalibrationError> {
    if let Some(known) = rig_from_camera
        && known.len() != cameras.len()
    {
        return Err(SelfCalibrationError::CameraCount {
            cameras: known.len(),
            log: cameras.len(),
        });
    }
    if cameras.len() != log.camera_names.len() {
        return Err(SelfCalibrationError::CameraCount {
            cameras: cameras.len(),
            log: log.camera_names.len(),
        });
    }
    if !(options.ratio > 0.0 && options.ratio <= 1.0) {
        return Err(SelfCalibrationError::InvalidOption {
            option: "ratio",
            reason: format!("must be in (0, 1], got {}", options.ratio),
        });
    }
    options
        .relative_pose
        .validate()
        .map_err(|e| SelfCalibrationError::InvalidOption {
            option: "relative_pose",
            reason: e.to_string(),
        })?;
    let mut images = Vec::new();
    for (frame, f) in log.frames.iter().enumerate() {
        if f.images.len() != cameras.len() {
            return Err(SelfCalibrationError::FrameImages {
                frame,
                images: f.images.len(),
                cameras: cameras.len(),
            });
        }
        for (camera, image) in f.images.iter().enumerate() {
            if !image.is_empty() {
                images.push(ImageId { frame, camera });
            }
        }
    }
    let features = |id: &ImageId| &log.frames[id.frame].images[id.camera];
    let bearings: Vec<Vec<Option<Vector3<f64>>>> = images
        .par_iter()
        .map(|id| {
            features(id)
                .keypoints
                .iter()
                .map(|p| cameras[id.camera].unproject(p).ok().map(|b| b.into_inner()))
                .collect()
        })
        .collect();

    // Vocabulary on a seeded sample of the log's own descriptors.
    let per_image = options
        .training_descriptors
        .div_ceil(images.len().max(1))
        .max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let sample: Vec<Vec<D>> = images
        .iter()
        .map(|id| {
            let d = &features(id).descriptors;
            if d.len() <= per_image {
                return d.clone();
            }
            let mut order: Vec<usize> = (0..d.len()).collect();
            for i in 0..per_image {
                let j = rng.random_range(i..order.len());
                order.swap(i, j);
            }
            order[..per_image].iter().map(|&k| d[k]).collect()
        })
        .collect();
    if sample.iter().all(Vec::is_empty) {
        return Err(SelfCalibrationError::NoFeatures);
    }
    let training = TrainingOptions::default()
        .with_shape(10, 5)
        .with_seed(options.seed);
    let vocabulary =
        Arc::new(Vocabulary::train(&sample, &training).map_err(SelfCalibrationError::Vocabulary)?);
    const LEVELS_UP: u32 = 2;
    let transformed: Vec<_> = images
        .par_iter()
        .map(|id| vocabulary.transform_with_features(&features(id).descriptors, LEVELS_UP))
        .collect::<Result<_, _>>()
        .map_err(SelfCalibrationError::Vocabulary)?;
    let mut database = Database::new(Arc::clone(&vocabulary), Some(LEVELS_UP));
    for (bow, fv) in &transformed {
        database
            .add_bow(bow, Some(fv.clone()))
            .map_err(SelfCalibrationError::Vocabulary)?;
    }

    // Candidate pairs (a < b), deterministic order.
    let index_of =
        |frame: usize, camera: usize| images.binary_search(&ImageId { frame, camera }).ok();
    let mut candidates: Vec<(usize, usize)> = Vec::new();
    for (a, id) in images.iter().enumerate() {
        for k in 1..=options.sequential_window {
            if let Some(b) = index_of(id.frame + k, id.camera) {
                candidates.push((a, b));
            }
        }
        for camera in id.camera + 1..cameras.len() {
            if let Some(b) = index_of(id.frame, camera) {
                candidates.push((a, b));
            }
        }
    }
    let window = options.retrieval_window;
    let retrieved: Vec<Vec<usize>> = images
        .par_iter()
        .enumerate()
        .map(|(a, id)| {
            let filter = |image: u32| {
                let other = images[image as usize];
                image as usize != a && other.frame.abs_diff(id.frame) <= window
            };
            database
                .query(
                    &transformed[a].0,
                    &QueryOptions::default()
                        .with_max_results(options.retrieved)
                        .with_filter(&filter),
                )
                .iter()
                .map(|r| r.image as usize)
                .collect()
        })
        .collect();
    for (a, found) in retrieved.iter().enumerate() {
        for &b in found {
            candidates.push((a.min(b), a.max(b)));
        }
    }
    candidates.sort_unstable();
    candidates.dedup();

    let matching = MatchOptions::default()
        .with_ratio(options.ratio)
        .with_mutual_check(true);
    let verified: Vec<Option<VerifiedPair>> = candidates
        .par_iter()
        .map(|&(a, b)| {
            let (ia, ib) = (images[a], images[b]);
            let known = rig_from_camera
                .filter(|_| ia.frame == ib.frame)
                .map(|rig| rig[ib.camera].inverse() * rig[ia.camera]);
            verify_pair(
                (a, b),
                known,
                (&features(&images[a]).descriptors, &transformed[a].1),
                (&features(&images[b]).descriptors, &transformed[b].1),
                (&bearings[a], &bearings[b]),
                &matching,
                options,
            )
        })
        .collect();
    let candidate_pairs = candidates.len();
    let pairs: Vec<VerifiedPair> = verified.into_iter().flatten().collect();
    let rejected_pairs = candidate_pairs - pairs.len();
    let (tracks, inconsistent_tracks) = union_tracks(&bearings, &pairs);
    Ok(Tracks {
        images,
        bearings,
        pairs,
        tracks,
        candidate_pairs,
        rejected_pairs,
        inconsistent_tracks,
    })
}

/// Matches and verifies one candidate pair; `None` when it does not hold.
fn verify_pair<D: Descriptor>(
    (a, b): (usize, usize),
    known: Option<Isometry3<f64>>,
    (desc_a, fv_a): (&[D], &FeatureVector),
    (desc_b, fv_b): (&[D], &FeatureVector),
    (bear_a, bear_b): (&Bearings, &Bearings),
    matching: &MatchOptions,
    options: &TrackOptions,
) -> Option<VerifiedPair> {
    let mut found = match_by_nodes(desc_a, fv_a, desc_b, fv_b, matching).ok()?;
    if options.relative_pose.progressive {
        // Best first, for the progressive sampling (ties by keypoint: deterministic).
        found.sort_by(|x, y| {
            x.distance
                .total_cmp(&y.distance)
                .then(x.query.cmp(&y.query))
                .then(x.train.cmp(&y.train))
        });
    }
    let mut keypoints = Vec::with_capacity(found.len());
    let (mut xa, mut xb) = (Vec::new(), Vec::new());
    for m in &found {
        if let (Some(Some(p)), Some(Some(q))) =
            (bear_a.get(m.query as usize), bear_b.get(m.train as usize))
        {
            keypoints.push((m.query, m.train));
            xa.push(*p);
            xb.push(*q);
        }
    }
    if keypoints.len() < options.min_inliers {
        return None;
    }
    if let Some(b_from_a) = known {
        // Two cameras of one frame of a known rig: their relative pose is the rig's.
        let inliers =
            relative_pose_inliers(&xa, &xb, &b_from_a, options.relative_pose.ransac.threshold)
                .ok()?;
        if inliers.len() < options.min_inliers {
            return None;
        }
        let mut matches: Vec<(u32, u32)> = inliers.iter().map(|&k| keypoints[k]).collect();
        matches.sort_unstable();
        let length = b_from_a.translation.vector.norm();
        return Some(VerifiedPair {
            a,
            b,
            b_from_a: Isometry3::from_parts(
                Translation3::from(if length > 0.0 {
                    b_from_a.translation.vector / length
                } else {
                    Vector3::zeros()
                }),
                b_from_a.rotation,
            ),
            has_direction: length > 0.0,
            matches,
        });
    }
    let mut pose_options = options.relative_pose.clone();
    pose_options.ransac.seed = mix(mix(options.seed ^ mix(a as u64)) ^ b as u64);
    pose_options.ransac.min_inliers = options.min_inliers.max(pose_options.ransac.min_inliers);
    // Too little parallax still gives a rotation and its inliers (the parallax is checked
    // after the search, so they are those a search without the check would find).
    let (b_from_a, inliers, has_direction) = match relative_pose(&xa, &xb, &pose_options) {
        Ok(p) => {
            let direction = !matches!(p.model, TwoViewModel::PureRotation);
            (p.b_from_a, p.inliers, direction)
        }
        Err(RelativePoseError::InsufficientParallax {
            rotation, inliers, ..
        }) => (
            Isometry3::from_parts(Translation3::identity(), rotation),
            inliers,
            false,
        ),
        Err(_) => return None,
    };
    if inliers.len() < options.min_inliers {
        return None;
    }
    let mut matches: Vec<(u32, u32)> = inliers.iter().map(|&k| keypoints[k]).collect();
    matches.sort_unstable();
    Some(VerifiedPair {
        a,
        b,
        b_from_a,
        has_direction,
        matches,
    })
}

/// The connected components of the verified matches (union-find over all keypoints), without
/// those holding two keypoints of one image; with the count of those dropped.
fn union_tracks(
    bearings: &[Vec<Option<Vector3<f64>>>],
    pairs: &[VerifiedPair],
) -> (Vec<Track>, usize) {
    let mut offset = Vec::with_capacity(bearings.len() + 1);
    offset.push(0usize);
    for b in bearings {
        offset.push(offset[offset.len() - 1] + b.len());
    }
    let total = offset[bearings.len()];
    let mut parent: Vec<usize> = (0..total).collect();
    fn find(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    let mut linked = vec![false; total];
    for p in pairs {
        for &(ka, kb) in &p.matches {
            let (x, y) = (offset[p.a] + ka as usize, offset[p.b] + kb as usize);
            linked[x] = true;
            linked[y] = true;
            let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
            if rx != ry {
                // The smaller root wins: the same tracks whatever the pair order.
                let (lo, hi) = (rx.min(ry), rx.max(ry));
                parent[hi] = lo;
            }
        }
    }
    let mut members: Vec<(usize, usize, u32)> = Vec::new();
    for (image, b) in bearings.iter().enumerate() {
        for k in 0..b.len() {
            let x = offset[image] + k;
            if linked[x] {
                members.push((find(&mut parent, x), image, k as u32));
            }
        }
    }
    members.sort_unstable();
    let mut tracks = Vec::new();
    let mut inconsistent = 0;
    for group in members.chunk_by(|x, y| x.0 == y.0) {
        if group.len() < 2 {
            continue;
        }
        if group.windows(2).any(|w| w[0].1 == w[1].1) {
            inconsistent += 1;
            continue;
        }
        tracks.push(Track {
            observations: group.iter().map(|&(_, image, k)| (image, k)).collect(),
        });
    }
    (tracks, inconsistent)
}
