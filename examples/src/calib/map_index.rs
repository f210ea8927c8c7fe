//! The map database: a vocabulary tree over the map images' descriptors and an image database
//! with an inverted index (retrieval) and a direct index (matching).
//!
//! D. Galvez-Lopez and J. D. Tardos, "Bags of Binary Words for Fast Place Recognition in
//! Image Sequences", IEEE T-RO 28(5), 2012 (the database and its direct index); D. Nister and
//! H. Stewenius, "Scalable Recognition with a Vocabulary Tree", CVPR 2006 (the tree).
//!
//! The vocabulary is trained on a seeded subsample of the map's own descriptors (the same
//! number from every map image, so the IDF weights `ln(N / N_i)` count every image), or given
//! by the caller. Database image `i` is map image `i`.

use std::sync::Arc;

use ibc_vocab_tree::{Database, Descriptor, FeatureVector, NodeId, TrainingOptions, Vocabulary};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::error::CalibrationError;
use super::options::VocabularyOptions;
use crate::data::{Map, MapImage, PointId};

/// One map image's features that observe a map point, grouped by their direct-index node:
/// the features of node `nodes[i]` are `offsets[i]..offsets[i + 1]` of `points` and
/// `descriptors`. Contiguous, so matching reads them in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NodeGroups<D> {
    /// The nodes, increasing.
    pub nodes: Vec<NodeId>,
    /// `nodes.len() + 1` offsets.
    pub offsets: Vec<u32>,
    /// The map point of each feature.
    pub points: Vec<PointId>,
    /// The descriptor of each feature.
    pub descriptors: Vec<D>,
}

impl<D: Copy> NodeGroups<D> {
    /// Groups `image`'s features that observe a map point by the nodes of `features`.
    fn new(image: &MapImage<D>, features: &FeatureVector) -> Self {
        let mut g = Self {
            nodes: Vec::with_capacity(features.len()),
            offsets: Vec::with_capacity(features.len() + 1),
            points: Vec::new(),
            descriptors: Vec::new(),
        };
        g.offsets.push(0);
        for (node, group) in features.iter() {
            for &f in group {
                let f = f as usize;
                if let (Some(Some(p)), Some(d)) =
                    (image.point_ids.get(f), image.features.descriptors.get(f))
                {
                    g.points.push(*p);
                    g.descriptors.push(*d);
                }
            }
            if g.points.len() as u32 > g.offsets[g.offsets.len() - 1] {
                g.nodes.push(node);
                g.offsets.push(g.points.len() as u32);
            }
        }
        g
    }

    /// The `(node, points, descriptors)` groups, by increasing node.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, &[PointId], &[D])> + '_ {
        self.nodes
            .iter()
            .zip(self.offsets.windows(2))
            .map(|(&n, w)| {
                let (a, b) = (w[0] as usize, w[1] as usize);
                (n, &self.points[a..b], &self.descriptors[a..b])
            })
    }
}

/// The map's vocabulary and database.
#[derive(Clone, Debug)]
pub struct MapIndex<D: Descriptor> {
    /// The vocabulary tree.
    pub vocabulary: Arc<Vocabulary<D>>,
    /// The database of map images (image id = map image index), with a direct index at
    /// [`direct_index_levels`](Self::direct_index_levels) above the leaves.
    pub database: Database<D>,
    /// Levels above the leaves of the direct index.
    pub direct_index_levels: u32,
    /// Per map image, its features with a map point grouped by direct-index node.
    pub groups: Vec<NodeGroups<D>>,
}

/// Every map image's descriptors, subsampled to about `budget` in all: the same number from
/// each image (all of an image's when it has fewer), chosen by a seeded partial shuffle.
fn training_sample<D: Descriptor>(map: &Map<D>, budget: usize, seed: u64) -> Vec<Vec<D>> {
    let images = map.images.len().max(1);
    let per_image = budget.div_ceil(images).max(1);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    map.images
        .iter()
        .map(|image| {
            let descriptors = &image.features.descriptors;
            if descriptors.len() <= per_image {
                return descriptors.clone();
            }
            let mut order: Vec<u32> = (0..descriptors.len() as u32).collect();
            for i in 0..per_image {
                let j = rng.random_range(i..order.len());
                order.swap(i, j);
            }
            order[..per_image]
                .iter()
                .map(|&k| descriptors[k as usize])
                .collect()
        })
        .collect()
}

/// Trains a vocabulary on a subsample of the map's descriptors (see the module docs).
///
/// # Errors
/// [`CalibrationError::EmptyMap`] if the map has no descriptor, [`CalibrationError::Vocabulary`]
/// if training fails (an option out of range, a non-finite float descriptor).
pub fn train_vocabulary<D: Descriptor>(
    map: &Map<D>,
    options: &VocabularyOptions,
) -> Result<Vocabulary<D>, CalibrationError> {
    let sample = training_sample(map, options.training_descriptors, options.seed);
    if sample.iter().all(Vec::is_empty) {
        return Err(CalibrationError::EmptyMap {
            what: "no map image has a descriptor",
        });
    }
    let training = TrainingOptions::default()
        .with_shape(options.branching, options.depth)
        .with_max_iterations(options.max_iterations)
        .with_seed(options.seed);
    Ok(Vocabulary::train(&sample, &training)?)
}

impl<D: Descriptor> MapIndex<D> {
    /// Indexes every map image with `vocabulary` (image `i` of the database is map image `i`).
    ///
    /// # Errors
    /// [`CalibrationError::Vocabulary`] if the vocabulary cannot transform the descriptors.
    pub fn build(
        map: &Map<D>,
        vocabulary: Arc<Vocabulary<D>>,
        direct_index_levels: u32,
    ) -> Result<Self, CalibrationError> {
        use rayon::prelude::*;
        let transformed: Vec<_> = map
            .images
            .par_iter()
            .map(|image| {
                vocabulary.transform_with_features(&image.features.descriptors, direct_index_levels)
            })
            .collect::<Result<_, _>>()?;
        let groups = map
            .images
            .par_iter()
            .zip(&transformed)
            .map(|(image, (_, features))| NodeGroups::new(image, features))
            .collect();
        let mut database = Database::new(Arc::clone(&vocabulary), Some(direct_index_levels));
        for (bow, features) in transformed {
            database.add_bow(&bow, Some(features))?;
        }
        Ok(Self {
            vocabulary,
            database,
            direct_index_levels,
            groups,
        })
    }

    /// Trains a vocabulary on the map (see [`train_vocabulary`]) and indexes the map with it.
    ///
    /// # Errors
    /// As [`train_vocabulary`] and [`build`](Self::build).
    pub fn train(map: &Map<D>, options: &VocabularyOptions) -> Result<Self, CalibrationError> {
        let vocabulary = Arc::new(train_vocabulary(map, options)?);
        Self::build(map, vocabulary, options.direct_index_levels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::{ImageFeatures, MapImage};

    fn map(images: usize, features: usize) -> Map<[u64; 4]> {
        let mut state = 1u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state
        };
        Map {
            points: Vec::new(),
            images: (0..images)
                .map(|_| MapImage {
                    camera_from_world: None,
                    features: ImageFeatures {
                        keypoints: vec![nalgebra::Vector2::zeros(); features],
                        descriptors: (0..features)
                            .map(|_| [next(), next(), next(), next()])
                            .collect(),
                    },
                    point_ids: vec![None; features],
                })
                .collect(),
        }
    }

    #[test]
    fn subsample_takes_the_same_number_from_each_image_and_is_seeded() {
        let m = map(4, 50);
        let a = training_sample(&m, 40, 3);
        assert!(a.iter().all(|s| s.len() == 10));
        assert_eq!(a, training_sample(&m, 40, 3));
        assert_ne!(a, training_sample(&m, 40, 4));
        // A sampled descriptor comes from its own image.
        assert!(
            a[2].iter()
                .all(|d| m.images[2].features.descriptors.contains(d))
        );
        // A budget above the map's size takes everything.
        let all = training_sample(&m, 1000, 3);
        assert_eq!(all[1], m.images[1].features.descriptors);
    }

    #[test]
    fn an_empty_map_is_an_error() {
        let e = MapIndex::train(&map(3, 0), &VocabularyOptions::default()).unwrap_err();
        assert!(matches!(e, CalibrationError::EmptyMap { .. }), "{e}");
    }
}
