//! An image database with an inverted index (for queries) and an optional direct index (for
//! matching), after Nister and Stewenius (CVPR 2006, section 4, inverted files) and
//! Galvez-Lopez and Tardos (T-RO 2012, section IV, direct index).
//!
//! The inverted index lists, for each word, the images that contain it and their weight. A
//! query touches only the lists of its own words and accumulates, per image, the scoring's
//! term for each common word ([`Scoring`](crate::Scoring)); images with no word in common are
//! not candidates. The scores are bit-identical to [`Scoring::score`](crate::Scoring::score)
//! on the two vectors.

use std::fmt;
use std::sync::Arc;

use crate::bow::{BowVector, FeatureVector};
use crate::descriptor::Descriptor;
use crate::error::{Result, VocabError};
use crate::simd::prefetch;
use crate::vocabulary::Vocabulary;

/// Index of an image in a [`Database`], in the order images were added from 0.
pub type ImageId = u32;

/// One entry of an inverted list.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Posting {
    image: ImageId,
    weight: f32,
}

/// Options of [`Database::query`].
pub struct QueryOptions<'a> {
    /// The most results returned, best first. Default 10: CamOdoCal localizes an image
    /// against its 10 most similar map images.
    pub max_results: usize,
    /// Keep only results at least this good: `score >= min_score`, or for KL (a divergence,
    /// lower is better) `score <= min_score`. Default: none.
    pub min_score: Option<f64>,
    /// Keep only the images for which this returns true (to leave out, say, the frames next
    /// to the query in time). Default: none.
    pub filter: Option<&'a (dyn Fn(ImageId) -> bool + Sync)>,
    /// Keeps the struct open to new fields: build it with `..Default::default()`.
    #[doc(hidden)]
    pub non_exhaustive: crate::NonExhaustive,
}

impl Default for QueryOptions<'_> {
    fn default() -> Self {
        Self {
            max_results: 10,
            min_score: None,
            filter: None,
            non_exhaustive: crate::NonExhaustive(()),
        }
    }
}

impl fmt::Debug for QueryOptions<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("QueryOptions")
            .field("max_results", &self.max_results)
            .field("min_score", &self.min_score)
            .field("filter", &self.filter.map(|_| "Fn(ImageId) -> bool"))
            .finish()
    }
}

impl<'a> QueryOptions<'a> {
    /// Sets the most results returned.
    pub fn with_max_results(mut self, max_results: usize) -> Self {
        self.max_results = max_results;
        self
    }

    /// Sets the score threshold.
    pub fn with_min_score(mut self, min_score: f64) -> Self {
        self.min_score = Some(min_score);
        self
    }

    /// Sets the image filter.
    pub fn with_filter(mut self, filter: &'a (dyn Fn(ImageId) -> bool + Sync)) -> Self {
        self.filter = Some(filter);
        self
    }
}

/// One result of a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryResult {
    /// The database image.
    pub image: ImageId,
    /// Its score against the query (see [`Scoring`](crate::Scoring) for the scale).
    pub score: f64,
}

/// A database of images described by bag-of-words vectors over one vocabulary.
///
/// `Send + Sync`; [`query`](Self::query) takes `&self`.
#[derive(Debug, Clone)]
pub struct Database<D: Descriptor> {
    vocabulary: Arc<Vocabulary<D>>,
    direct_index_levels: Option<u32>,
    inverted: Vec<Vec<Posting>>,
    direct: Vec<FeatureVector>,
    /// The scoring's constant of each image (`‖w‖²` for L2).
    constants: Vec<f64>,
    image_count: u32,
}

impl<D: Descriptor> Database<D> {
    /// An empty database. With `direct_index_levels = Some(l)` it also keeps, for every
    /// image, its feature vector at `l` levels above the leaves (see
    /// [`Vocabulary::transform_with_features`]); DBoW2's and ORB-SLAM's choice for a
    /// depth-6 tree is 4.
    pub fn new(vocabulary: Arc<Vocabulary<D>>, direct_index_levels: Option<u32>) -> Self {
        let words = vocabulary.word_count() as usize;
        Self {
            vocabulary,
            direct_index_levels,
            inverted: vec![Vec::new(); words],
            direct: Vec::new(),
            constants: Vec::new(),
            image_count: 0,
        }
    }

    /// The vocabulary.
    pub fn vocabulary(&self) -> &Arc<Vocabulary<D>> {
        &self.vocabulary
    }

    /// The levels above the leaves of the direct index, if the database keeps one.
    pub fn direct_index_levels(&self) -> Option<u32> {
        self.direct_index_levels
    }

    /// Number of images.
    pub fn len(&self) -> usize {
        self.image_count as usize
    }

    /// True when no image was added.
    pub fn is_empty(&self) -> bool {
        self.image_count == 0
    }

    /// Transforms an image's descriptors and adds the image; returns its id.
    pub fn add(&mut self, descriptors: &[D]) -> Result<ImageId> {
        match self.direct_index_levels {
            Some(levels) => {
                let (bow, fv) = self
                    .vocabulary
                    .transform_with_features(descriptors, levels)?;
                self.add_bow(&bow, Some(fv))
            }
            None => {
                let bow = self.vocabulary.transform(descriptors);
                self.add_bow(&bow, None)
            }
        }
    }

    /// Adds an image from its bag-of-words vector (made with this database's vocabulary) and,
    /// if the database keeps a direct index, its feature vector.
    pub fn add_bow(&mut self, bow: &BowVector, features: Option<FeatureVector>) -> Result<ImageId> {
        if self.image_count == u32::MAX {
            return Err(VocabError::DatabaseFull);
        }
        let word_count = self.vocabulary.word_count();
        if let Some((word, _)) = bow.iter().find(|&(w, _)| w >= word_count) {
            return Err(VocabError::WordOutOfRange { word, word_count });
        }
        if self.direct_index_levels.is_some() {
            let fv = features.ok_or(VocabError::MissingFeatureVector)?;
            let nodes = self.vocabulary.node_count();
            if let Some(&node) = fv.nodes().iter().find(|&&n| n >= nodes) {
                return Err(VocabError::InvalidFeatureVector(format!(
                    "node {node} is out of range: the vocabulary has {nodes} nodes"
                )));
            }
            self.direct.push(fv);
        }
        let image = self.image_count;
        self.constants.push(self.vocabulary.scoring().constant(bow));
        for (word, weight) in bow.iter() {
            self.inverted[word as usize].push(Posting { image, weight });
        }
        self.image_count += 1;
        Ok(image)
    }

    /// The feature vector of `image`, if the database keeps a direct index.
    pub fn features(&self, image: ImageId) -> Option<&FeatureVector> {
        self.direct.get(image as usize)
    }

    /// The images most similar to `query` (a vector made with this database's vocabulary),
    /// best first; ties are broken by increasing image id. Only images sharing at least one
    /// word with the query are candidates, so an empty query returns nothing.
    pub fn query(&self, query: &BowVector, options: &QueryOptions<'_>) -> Vec<QueryResult> {
        let scoring = self.vocabulary.scoring();
        let n = self.image_count as usize;
        let mut acc = vec![0f64; n];
        // Set without a branch: whether an image was touched is random, a poor bet for the
        // branch predictor.
        let mut hit = vec![false; n];
        let entries = query.entries();
        for (k, &(word, q)) in entries.iter().enumerate() {
            // Two-stage prefetch: the list header of the word 8 ahead, the list data of the
            // word 4 ahead (whose header arrived by now). Inverted lists are scattered over
            // the heap; this overlaps their cache misses.
            if let Some(l) = entries
                .get(k + 8)
                .and_then(|e| self.inverted.get(e.0 as usize))
            {
                prefetch(std::ptr::from_ref(l).cast::<u8>());
            }
            if let Some(l) = entries
                .get(k + 4)
                .and_then(|e| self.inverted.get(e.0 as usize))
            {
                prefetch(l.as_ptr().cast::<u8>());
            }
            let Some(list) = self.inverted.get(word as usize) else {
                continue;
            };
            for p in list {
                let i = p.image as usize;
                hit[i] = true;
                acc[i] += scoring.common_term(q, p.weight);
            }
        }
        let touched = hit
            .iter()
            .enumerate()
            .filter(|(_, h)| **h)
            .map(|(i, _)| i as ImageId);
        let constant = scoring.constant(query);
        let mut results: Vec<QueryResult> = touched
            .filter(|&image| options.filter.is_none_or(|f| f(image)))
            .map(|image| QueryResult {
                image,
                score: scoring.finish(
                    acc[image as usize],
                    constant,
                    self.constants.get(image as usize).copied().unwrap_or(0.0),
                ),
            })
            .filter(|r| {
                options
                    .min_score
                    .is_none_or(|m| r.score == m || scoring.better(r.score, m))
            })
            .collect();
        let order = |a: &QueryResult, b: &QueryResult| {
            let by_score = if scoring.higher_is_better() {
                b.score.total_cmp(&a.score)
            } else {
                a.score.total_cmp(&b.score)
            };
            by_score.then(a.image.cmp(&b.image))
        };
        if options.max_results == 0 {
            return Vec::new();
        }
        if results.len() > options.max_results {
            results.select_nth_unstable_by(options.max_results - 1, order);
            results.truncate(options.max_results);
        }
        results.sort_unstable_by(order);
        results
    }
}
