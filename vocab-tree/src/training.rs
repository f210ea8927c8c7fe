//! Vocabulary training by hierarchical k-means (Nister and Stewenius, "Scalable recognition
//! with a vocabulary tree", CVPR 2006, section 3) with IDF word weights (Galvez-Lopez and
//! Tardos, T-RO 2012, section IV).
//!
//! The training descriptors are clustered into `k` groups ([`crate::kmeans`]), each group
//! again into `k`, down to depth `L`; the leaves are the words. The tree is grown level by
//! level, so nodes come out in breadth-first order. A node with a single distinct descriptor
//! (or a single descriptor) is not split further and becomes a word above depth `L`.
//!
//! Each node's clustering draws from its own ChaCha8 stream, seeded from the training seed and
//! the node id, and no sum depends on how work is split between threads: the vocabulary for a
//! given seed is the same whatever the thread count.
//!
//! Word weights: with `N` the number of training images (empty ones included) and `N_i` the
//! number of training images with at least one descriptor quantized to word `i`, the weight is
//! `idf_i = ln(N / N_i)` (0 for a word no image reaches).

use crate::descriptor::Descriptor;
use crate::error::{Result, VocabError};
use crate::kmeans::{kmeans, map_items};
use crate::scoring::Scoring;
use crate::simd::Isa;
use crate::vocabulary::{MAX_DEPTH, Vocabulary, VocabularyParts};
use crate::weighting::Weighting;

/// Options of [`Vocabulary::train`].
///
/// The defaults are DBoW2's and ORB-SLAM's: branching 10, depth 6 (up to a million words),
/// TF-IDF weighting and L1 scoring; at most 10 Lloyd iterations per node (DBoW2 iterates until
/// convergence without a bound, which can loop on float descriptors).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingOptions {
    /// Branching factor `k` (`2 ..= 65536`).
    pub branching: u32,
    /// Depth `L` (`1 ..= 32`).
    pub depth: u32,
    /// How words are weighted.
    pub weighting: Weighting,
    /// How vectors are compared.
    pub scoring: Scoring,
    /// The most Lloyd iterations per node; the loop stops earlier when no assignment changes.
    pub max_iterations: u32,
    /// Seed of the random number streams.
    pub seed: u64,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for TrainingOptions {
    fn default() -> Self {
        Self {
            branching: 10,
            depth: 6,
            weighting: Weighting::TfIdf,
            scoring: Scoring::L1,
            max_iterations: 10,
            seed: 0,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

impl TrainingOptions {
    /// Sets the branching factor and the depth.
    pub fn with_shape(mut self, branching: u32, depth: u32) -> Self {
        self.branching = branching;
        self.depth = depth;
        self
    }

    /// Sets the seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Sets the most Lloyd iterations per node.
    pub fn with_max_iterations(mut self, max_iterations: u32) -> Self {
        self.max_iterations = max_iterations;
        self
    }

    /// Sets the weighting.
    pub fn with_weighting(mut self, weighting: Weighting) -> Self {
        self.weighting = weighting;
        self
    }

    /// Sets the scoring.
    pub fn with_scoring(mut self, scoring: Scoring) -> Self {
        self.scoring = scoring;
        self
    }
}

/// SplitMix64 (Steele, Lea and Flood, OOPSLA 2014): mixes the seed and a node id into the
/// seed of that node's stream.
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A node waiting to be split, with the training descriptors that reached it.
struct Pending {
    node: u32,
    members: Vec<u32>,
}

impl<D: Descriptor> Vocabulary<D> {
    /// Trains a vocabulary on the descriptors of a set of images (one slice per image; the
    /// grouping gives the IDF weights `ln(N / N_i)`).
    ///
    /// Fails when there is no descriptor, a float descriptor is not finite, or an option is
    /// outside its domain. Fewer distinct descriptors than clusters is fine: such nodes get
    /// fewer children.
    pub fn train<I: AsRef<[D]> + Sync>(images: &[I], options: &TrainingOptions) -> Result<Self> {
        check_options(options)?;
        let mut points: Vec<D> = Vec::new();
        for (image, descs) in images.iter().enumerate() {
            let descs = descs.as_ref();
            if let Some(index) = descs.iter().position(|d| !d.is_finite()) {
                return Err(VocabError::NonFiniteDescriptor { image, index });
            }
            points.extend_from_slice(descs);
        }
        if points.is_empty() {
            return Err(VocabError::NoTrainingData);
        }
        let n_points = u32::try_from(points.len()).map_err(|_| VocabError::InvalidOption {
            name: "images",
            reason: format!(
                "{} descriptors; at most u32::MAX can be trained on",
                points.len()
            ),
        })?;
        let bound = 1 + u64::from(options.depth) * u64::from(n_points);
        if bound >= u64::from(u32::MAX) {
            return Err(VocabError::TooManyNodes { nodes: bound });
        }
        let isa = Isa::detect();
        let k = options.branching as usize;

        let mut centroids = vec![D::zero()];
        let mut child_start: Vec<u32> = Vec::new();
        let mut level = vec![Pending {
            node: 0,
            members: (0..n_points).collect(),
        }];
        for _ in 0..options.depth {
            let clusters = map_items(&level, |p| {
                if p.members.len() < 2 && p.node != 0 {
                    return Vec::new();
                }
                let seed = splitmix64(options.seed ^ splitmix64(u64::from(p.node)));
                let c = kmeans(isa, &points, &p.members, k, options.max_iterations, seed);
                // A single cluster is one distinct descriptor: a word, unless at the root.
                if c.len() < 2 && p.node != 0 {
                    Vec::new()
                } else {
                    c
                }
            });
            let mut next = Vec::new();
            for (p, children) in level.into_iter().zip(clusters) {
                debug_assert_eq!(child_start.len(), p.node as usize);
                child_start.push(centroids.len() as u32);
                for (centroid, members) in children {
                    next.push(Pending {
                        node: centroids.len() as u32,
                        members,
                    });
                    centroids.push(centroid);
                }
            }
            level = next;
        }
        let n = centroids.len() as u32;
        child_start.resize(centroids.len() + 1, n);
        let word_node: Vec<u32> = (1..n)
            .filter(|&i| child_start[i as usize] == child_start[i as usize + 1])
            .collect();
        let words = word_node.len();
        let vocabulary = Self::from_parts(VocabularyParts {
            branching: options.branching,
            depth: options.depth,
            weighting: options.weighting,
            scoring: options.scoring,
            child_start,
            centroids,
            word_node,
            word_weights: vec![0.0; words],
        })?;
        Ok(vocabulary.with_idf(images))
    }

    /// Sets every word weight to `ln(N / N_i)` over the given images.
    fn with_idf<I: AsRef<[D]> + Sync>(mut self, images: &[I]) -> Self {
        let words = self.word_weights.len();
        let per_image = map_items(images, |descs| {
            let mut w = self.quantize(descs.as_ref());
            w.sort_unstable();
            w.dedup();
            w
        });
        let mut seen = vec![0u32; words];
        for w in per_image.iter().flatten() {
            seen[*w as usize] += 1;
        }
        let n = images.len() as f64;
        self.word_weights = seen
            .iter()
            .map(|&ni| {
                if ni == 0 {
                    0.0
                } else {
                    (n / f64::from(ni)).ln() as f32
                }
            })
            .collect();
        self
    }
}

fn check_options(o: &TrainingOptions) -> Result<()> {
    if !(2..=65_536).contains(&o.branching) {
        return Err(VocabError::InvalidOption {
            name: "branching",
            reason: format!("{} is outside 2..=65536", o.branching),
        });
    }
    if !(1..=MAX_DEPTH).contains(&o.depth) {
        return Err(VocabError::InvalidOption {
            name: "depth",
            reason: format!("{} is outside 1..={MAX_DEPTH}", o.depth),
        });
    }
    Ok(())
}
