//! Sparse bag-of-words vectors and feature vectors (the direct index of one image).

use crate::error::{Result, VocabError};

/// Index of a word (a leaf of the vocabulary tree), `0 .. word_count`.
pub type WordId = u32;
/// Index of a node of the vocabulary tree in breadth-first order; the root is node 0.
pub type NodeId = u32;

/// A sparse bag-of-words vector: word ids in strictly increasing order with positive, finite
/// weights (words of weight zero are not stored).
///
/// Vectors made by [`Vocabulary::transform`](crate::Vocabulary::transform) are already
/// normalized as the vocabulary's [`Scoring`](crate::Scoring) requires.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BowVector {
    entries: Vec<(WordId, f32)>,
}

impl BowVector {
    /// The empty vector (an image with no feature).
    pub fn new() -> Self {
        Self::default()
    }

    /// A vector from `(word, weight)` pairs, which must be sorted by strictly increasing word
    /// id with finite weights `> 0`.
    pub fn from_entries(entries: Vec<(WordId, f32)>) -> Result<Self> {
        for (i, &(word, weight)) in entries.iter().enumerate() {
            if !(weight.is_finite() && weight > 0.0) {
                return Err(VocabError::InvalidBowVector(format!(
                    "word {word} has weight {weight}; weights must be finite and > 0"
                )));
            }
            if i > 0 && entries[i - 1].0 >= word {
                return Err(VocabError::InvalidBowVector(format!(
                    "word ids must increase strictly, but {} is followed by {word}",
                    entries[i - 1].0
                )));
            }
        }
        Ok(Self { entries })
    }

    /// Builds from entries the crate already sorted and checked.
    pub(crate) fn from_sorted(entries: Vec<(WordId, f32)>) -> Self {
        Self { entries }
    }

    /// The `(word, weight)` pairs, by increasing word id.
    pub fn entries(&self) -> &[(WordId, f32)] {
        &self.entries
    }

    /// Iterates over the `(word, weight)` pairs by increasing word id.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (WordId, f32)> + '_ {
        self.entries.iter().copied()
    }

    /// Number of distinct words.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True for an image with no (weighted) word.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The weight of `word`, if the vector holds it.
    pub fn get(&self, word: WordId) -> Option<f32> {
        self.entries
            .binary_search_by_key(&word, |e| e.0)
            .ok()
            .map(|i| self.entries[i].1)
    }
}

/// The direct index of one image: for each tree node (at the level chosen when it was built),
/// the indices of the image's features whose descent crossed that node.
///
/// Nodes are sorted by increasing id; the feature indices of a node increase too.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FeatureVector {
    nodes: Vec<NodeId>,
    /// `nodes.len() + 1` offsets into `features`.
    offsets: Vec<u32>,
    features: Vec<u32>,
}

impl Default for FeatureVector {
    fn default() -> Self {
        Self::new()
    }
}

impl FeatureVector {
    /// The empty feature vector.
    pub fn new() -> Self {
        Self {
            nodes: Vec::new(),
            offsets: vec![0],
            features: Vec::new(),
        }
    }

    /// Builds the feature vector of an image whose feature `i` belongs to node `node_of[i]`.
    ///
    /// Fails when the image has more than `u32::MAX` features.
    pub fn from_nodes(node_of: &[NodeId]) -> Result<Self> {
        let n = u32::try_from(node_of.len()).map_err(|_| {
            VocabError::InvalidFeatureVector(format!(
                "{} features: feature indices are u32",
                node_of.len()
            ))
        })?;
        let mut pairs: Vec<(NodeId, u32)> = node_of.iter().copied().zip(0..n).collect();
        pairs.sort_unstable();
        Ok(Self::from_sorted_pairs(&pairs))
    }

    /// Builds from `(node, feature)` pairs sorted by node, then feature.
    pub(crate) fn from_sorted_pairs(pairs: &[(NodeId, u32)]) -> Self {
        let mut fv = Self {
            nodes: Vec::new(),
            offsets: Vec::with_capacity(pairs.len() + 1),
            features: Vec::with_capacity(pairs.len()),
        };
        for &(node, feature) in pairs {
            if fv.nodes.last() != Some(&node) {
                fv.nodes.push(node);
                fv.offsets.push(fv.features.len() as u32);
            }
            fv.features.push(feature);
        }
        fv.offsets.push(fv.features.len() as u32);
        fv
    }

    /// Number of distinct nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True when no feature is indexed.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Total number of indexed features.
    pub fn feature_count(&self) -> usize {
        self.features.len()
    }

    /// The node ids, increasing.
    pub fn nodes(&self) -> &[NodeId] {
        &self.nodes
    }

    /// The features of the `i`-th node (by position, not by id).
    fn features_at(&self, i: usize) -> &[u32] {
        match (self.offsets.get(i), self.offsets.get(i + 1)) {
            (Some(&s), Some(&e)) => self.features.get(s as usize..e as usize).unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Iterates over `(node, feature indices)` by increasing node id.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = (NodeId, &[u32])> + '_ {
        self.nodes
            .iter()
            .enumerate()
            .map(|(i, &n)| (n, self.features_at(i)))
    }

    /// The features of `node`, if any.
    pub fn get(&self, node: NodeId) -> Option<&[u32]> {
        self.nodes
            .binary_search(&node)
            .ok()
            .map(|i| self.features_at(i))
    }

    /// The largest feature index plus one (0 when empty).
    pub(crate) fn feature_bound(&self) -> usize {
        self.features.iter().max().map_or(0, |&m| m as usize + 1)
    }
}
