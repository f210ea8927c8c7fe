//! The vocabulary tree in a flat, breadth-first layout, and the transform of an image's
//! descriptors into a bag-of-words vector (Nister and Stewenius, CVPR 2006; Galvez-Lopez and
//! Tardos, T-RO 2012).
//!
//! Layout: node 0 is the root; nodes are numbered breadth first, so the children of node `n`
//! are the contiguous nodes `child_start[n] .. child_start[n + 1]` and their centroids sit
//! side by side in one array. Leaves are the words; `node_word[n]` is the word of leaf `n`.
//! Depth counts from the root (depth 0); a full tree of branching `k` and depth `L` has `k^L`
//! words at depth `L`, but leaves may be shallower (a cluster with a single distinct
//! descriptor is not split further).

use crate::bow::{BowVector, FeatureVector, NodeId, WordId};
use crate::descent::{Quantized, TreeView};
use crate::descriptor::Descriptor;
use crate::error::{Result, VocabError};
use crate::scoring::Scoring;
use crate::simd::Isa;
use crate::weighting::{Weighting, bow_from_sorted_words};

/// Marks a node that is not a leaf in `node_word`.
pub(crate) const NO_WORD: u32 = u32::MAX;

/// The deepest tree a vocabulary may declare (DBoW2 allows 10 levels; 32 leaves room).
pub const MAX_DEPTH: u32 = 32;

/// Batches at least this large are descended in parallel (with the `rayon` feature).
#[cfg(feature = "rayon")]
const PARALLEL_BATCH: usize = 8192;

/// The raw arrays of a vocabulary, for building one directly (for example with centroids
/// learned elsewhere) through [`Vocabulary::from_parts`], which checks them.
#[derive(Debug, Clone, PartialEq)]
pub struct VocabularyParts<D> {
    /// The branching factor `k`: no node may have more children.
    pub branching: u32,
    /// The depth `L`: no leaf may be deeper (the root has depth 0).
    pub depth: u32,
    /// How words are weighted.
    pub weighting: Weighting,
    /// How vectors are compared.
    pub scoring: Scoring,
    /// `node_count + 1` offsets: the children of node `n` are `child_start[n]..child_start[n + 1]`
    /// (breadth-first numbering, so `child_start[0] = 1` and `child_start[node_count] =
    /// node_count`).
    pub child_start: Vec<u32>,
    /// One centroid per node, root included (its centroid is never used).
    pub centroids: Vec<D>,
    /// The leaf node of each word; every leaf must have exactly one word.
    pub word_node: Vec<u32>,
    /// The inverse document frequency `ln(N / N_i)` of each word (finite, `>= 0`).
    pub word_weights: Vec<f32>,
}

impl<D: Descriptor> VocabularyParts<D> {
    /// The parts of a complete tree: every internal node has exactly `branching` children and
    /// every leaf is at `depth`. `centroids` holds the `k + k² + … + k^L` centroids of the
    /// nodes below the root in breadth-first order; word `w` is the `w`-th leaf and every word
    /// weight is 1.
    pub fn complete(
        branching: u32,
        depth: u32,
        centroids: Vec<D>,
        weighting: Weighting,
        scoring: Scoring,
    ) -> Result<Self> {
        if branching < 2 || depth == 0 || depth > MAX_DEPTH {
            return Err(VocabError::InvalidTree(format!(
                "a complete tree needs branching >= 2 and 1 <= depth <= {MAX_DEPTH}, got \
                 branching {branching}, depth {depth}"
            )));
        }
        let k = u64::from(branching);
        let mut level_size = 1u64;
        let mut total = 1u64;
        for _ in 0..depth {
            level_size = level_size.saturating_mul(k);
            total = total.saturating_add(level_size);
        }
        if total >= u64::from(u32::MAX) {
            return Err(VocabError::TooManyNodes { nodes: total });
        }
        if centroids.len() as u64 != total - 1 {
            return Err(VocabError::InvalidTree(format!(
                "a complete tree of branching {branching} and depth {depth} has {} centroids \
                 below the root, got {}",
                total - 1,
                centroids.len()
            )));
        }
        let n = total as u32;
        let internal = n - level_size as u32;
        let mut child_start = Vec::with_capacity(n as usize + 1);
        for node in 0..=n {
            child_start.push(if node < internal {
                1 + node * branching
            } else {
                n
            });
        }
        let mut all = Vec::with_capacity(n as usize);
        all.push(D::zero());
        all.extend(centroids);
        Ok(Self {
            branching,
            depth,
            weighting,
            scoring,
            child_start,
            centroids: all,
            word_node: (internal..n).collect(),
            word_weights: vec![1.0; level_size as usize],
        })
    }
}

/// A vocabulary tree: hierarchical k-means centroids in a flat layout, word weights, and the
/// weighting and scoring used with it.
///
/// `Send + Sync`; [`transform`](Self::transform) takes `&self`, so one vocabulary serves every
/// thread.
#[derive(Debug, Clone, PartialEq)]
pub struct Vocabulary<D: Descriptor> {
    pub(crate) branching: u32,
    pub(crate) depth: u32,
    pub(crate) weighting: Weighting,
    pub(crate) scoring: Scoring,
    pub(crate) child_start: Vec<u32>,
    pub(crate) centroids: Vec<D>,
    /// The word of each leaf, [`NO_WORD`] for internal nodes.
    pub(crate) node_word: Vec<u32>,
    pub(crate) word_weights: Vec<f32>,
}

impl<D: Descriptor> Vocabulary<D> {
    /// Builds a vocabulary from raw arrays after checking that they form a valid tree: every
    /// child index in range and after its parent, every node with one parent, no node with more
    /// than `branching` children or deeper than `depth`, each leaf with exactly one word,
    /// finite non-negative word weights and finite centroids.
    pub fn from_parts(parts: VocabularyParts<D>) -> Result<Self> {
        let n = parts.centroids.len();
        check_tree(parts.branching, parts.depth, &parts.child_start, n)?;
        let words = parts.word_node.len();
        if parts.word_weights.len() != words {
            return Err(VocabError::InvalidTree(format!(
                "{} word weights for {words} words",
                parts.word_weights.len()
            )));
        }
        if words >= NO_WORD as usize {
            return Err(VocabError::InvalidTree(format!(
                "{words} words: word ids are u32"
            )));
        }
        let mut node_word = vec![NO_WORD; n];
        for (w, &leaf) in parts.word_node.iter().enumerate() {
            let l = leaf as usize;
            if l >= n || l == 0 || parts.child_start[l] != parts.child_start[l + 1] {
                return Err(VocabError::InvalidTree(format!(
                    "word {w} names node {leaf}, which is not a leaf of the {n}-node tree"
                )));
            }
            if node_word[l] != NO_WORD {
                return Err(VocabError::InvalidTree(format!(
                    "node {leaf} carries two words, {} and {w}",
                    node_word[l]
                )));
            }
            node_word[l] = w as u32;
        }
        Self::from_checked_tree(
            parts.branching,
            parts.depth,
            parts.weighting,
            parts.scoring,
            parts.child_start,
            parts.centroids,
            node_word,
            parts.word_weights,
        )
    }

    /// Finishes building a vocabulary whose tree passed [`check_tree`]: checks that the
    /// leaves carry exactly the words `0 .. word_weights.len()`, once each, that the weights
    /// are finite and `>= 0` and that the centroids are finite.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn from_checked_tree(
        branching: u32,
        depth: u32,
        weighting: Weighting,
        scoring: Scoring,
        child_start: Vec<u32>,
        centroids: Vec<D>,
        node_word: Vec<u32>,
        word_weights: Vec<f32>,
    ) -> Result<Self> {
        let bad = |msg: String| Err(VocabError::InvalidTree(msg));
        let words = word_weights.len();
        let mut seen = vec![0u64; words.div_ceil(64)];
        let mut leaves = 0usize;
        for (node, &w) in node_word.iter().enumerate() {
            let leaf = child_start[node] == child_start[node + 1];
            if !leaf {
                if w != NO_WORD {
                    return bad(format!("internal node {node} carries word {w}"));
                }
                continue;
            }
            if w as usize >= words {
                return bad(format!(
                    "leaf {node} carries word {w}, but there are {words} words"
                ));
            }
            let (i, bit) = (w as usize / 64, 1u64 << (w % 64));
            if seen[i] & bit != 0 {
                return bad(format!("word {w} is carried by two leaves"));
            }
            seen[i] |= bit;
            leaves += 1;
        }
        if leaves != words {
            return bad(format!("{leaves} leaves for {words} words"));
        }
        if let Some((w, x)) = word_weights
            .iter()
            .enumerate()
            .find(|(_, x)| !(x.is_finite() && **x >= 0.0))
        {
            return bad(format!(
                "word {w} has weight {x}; weights must be finite and >= 0"
            ));
        }
        if let Some(node) = centroids.iter().position(|c| !c.is_finite()) {
            return bad(format!("the centroid of node {node} is not finite"));
        }
        Ok(Self {
            branching,
            depth,
            weighting,
            scoring,
            child_start,
            centroids,
            node_word,
            word_weights,
        })
    }

    /// The raw arrays (the inverse of [`from_parts`](Self::from_parts)).
    pub fn into_parts(self) -> VocabularyParts<D> {
        let mut word_node = vec![0u32; self.word_weights.len()];
        for (node, &w) in self.node_word.iter().enumerate() {
            if let Some(slot) = word_node.get_mut(w as usize) {
                *slot = node as u32;
            }
        }
        VocabularyParts {
            branching: self.branching,
            depth: self.depth,
            weighting: self.weighting,
            scoring: self.scoring,
            child_start: self.child_start,
            centroids: self.centroids,
            word_node,
            word_weights: self.word_weights,
        }
    }

    /// The branching factor `k`.
    pub fn branching(&self) -> u32 {
        self.branching
    }

    /// The depth `L` (the root has depth 0).
    pub fn depth(&self) -> u32 {
        self.depth
    }

    /// Number of words (leaves).
    pub fn word_count(&self) -> u32 {
        self.word_weights.len() as u32
    }

    /// Number of nodes, root included.
    pub fn node_count(&self) -> u32 {
        self.centroids.len() as u32
    }

    /// How words are weighted.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }

    /// How vectors are compared.
    pub fn scoring(&self) -> Scoring {
        self.scoring
    }

    /// The same vocabulary with another weighting (the stored inverse document frequencies
    /// are kept, so any weighting can be chosen after training).
    pub fn with_weighting(mut self, weighting: Weighting) -> Self {
        self.weighting = weighting;
        self
    }

    /// The same vocabulary with another scoring (vectors made before must be made again: the
    /// normalization may differ).
    pub fn with_scoring(mut self, scoring: Scoring) -> Self {
        self.scoring = scoring;
        self
    }

    /// The inverse document frequency `ln(N / N_i)` of `word`.
    pub fn word_weight(&self, word: WordId) -> Option<f32> {
        self.word_weights.get(word as usize).copied()
    }

    /// The centroid of `node` (the root's is meaningless).
    pub fn centroid(&self, node: NodeId) -> Option<&D> {
        self.centroids.get(node as usize)
    }

    /// The children of `node` (empty for a leaf).
    pub fn children(&self, node: NodeId) -> std::ops::Range<NodeId> {
        let (s, e) = self.view().children(node);
        s..e
    }

    /// The word of `node`, if it is a leaf.
    pub fn node_word(&self, node: NodeId) -> Option<WordId> {
        self.node_word
            .get(node as usize)
            .copied()
            .filter(|&w| w != NO_WORD)
    }

    pub(crate) fn view(&self) -> TreeView<'_, D> {
        TreeView {
            centroids: &self.centroids,
            child_start: &self.child_start,
        }
    }

    /// Descends every descriptor with the given instruction set.
    fn descend(&self, isa: Isa, descriptors: &[D], target_depth: u32) -> Vec<Quantized> {
        let mut out = vec![Quantized::default(); descriptors.len()];
        let view = self.view();
        #[cfg(feature = "rayon")]
        if descriptors.len() >= PARALLEL_BATCH {
            use rayon::prelude::*;
            const CHUNK: usize = 1024;
            out.par_chunks_mut(CHUNK)
                .zip(descriptors.par_chunks(CHUNK))
                .for_each(|(o, d)| D::descend_isa(isa, &view, d, target_depth, o));
            return out;
        }
        D::descend_isa(isa, &view, descriptors, target_depth, &mut out);
        out
    }

    fn word_of_leaf(&self, leaf: u32) -> WordId {
        // Validation guarantees that every descent ends on a leaf with a word.
        self.node_word.get(leaf as usize).copied().unwrap_or(0)
    }

    /// The word of one descriptor.
    pub fn word(&self, descriptor: &D) -> WordId {
        self.quantize(std::slice::from_ref(descriptor))
            .first()
            .copied()
            .unwrap_or(0)
    }

    /// The word of each descriptor (greedy descent, nearest centroid at each level, lowest
    /// child index on ties).
    ///
    /// A float descriptor holding NaN compares false with every distance and so follows the
    /// first child at every level: garbage in, a deterministic word out, never a panic.
    pub fn quantize(&self, descriptors: &[D]) -> Vec<WordId> {
        self.quantize_impl(Isa::detect(), descriptors)
    }

    /// [`quantize`](Self::quantize) with a chosen instruction set, to compare the SIMD paths
    /// with the scalar path (they give the same words). Fails when the CPU lacks `isa`.
    pub fn quantize_with_isa(&self, isa: Isa, descriptors: &[D]) -> Result<Vec<WordId>> {
        if !isa.is_supported() {
            return Err(VocabError::UnsupportedIsa(isa));
        }
        Ok(self.quantize_impl(isa, descriptors))
    }

    fn quantize_impl(&self, isa: Isa, descriptors: &[D]) -> Vec<WordId> {
        self.descend(isa, descriptors, self.depth)
            .into_iter()
            .map(|q| self.word_of_leaf(q.leaf))
            .collect()
    }

    /// The bag-of-words vector of an image's descriptors, weighted and normalized as this
    /// vocabulary says. An empty image gives an empty vector.
    pub fn transform(&self, descriptors: &[D]) -> BowVector {
        let mut words = self.quantize(descriptors);
        words.sort_unstable();
        self.bow_from_words(&words, descriptors.len())
    }

    fn bow_from_words(&self, sorted_words: &[WordId], total: usize) -> BowVector {
        bow_from_sorted_words(
            sorted_words.iter().copied(),
            total,
            self.weighting,
            &self.word_weights,
            self.scoring,
        )
    }

    /// The bag-of-words vector and the feature vector (direct index) of an image.
    ///
    /// The feature vector groups the features by the node their descent crossed
    /// `levels_up` levels above the leaves, that is at depth `max(0, L − levels_up)` (or
    /// at the leaf itself when the leaf is shallower). `levels_up = 0` groups by word;
    /// `levels_up >= L` puts every feature under the root.
    pub fn transform_with_features(
        &self,
        descriptors: &[D],
        levels_up: u32,
    ) -> Result<(BowVector, FeatureVector)> {
        let n = u32::try_from(descriptors.len()).map_err(|_| {
            VocabError::InvalidFeatureVector(format!(
                "{} features: feature indices are u32",
                descriptors.len()
            ))
        })?;
        let target = self.depth.saturating_sub(levels_up);
        let q = self.descend(Isa::detect(), descriptors, target);
        let mut words: Vec<WordId> = q.iter().map(|x| self.word_of_leaf(x.leaf)).collect();
        words.sort_unstable();
        let bow = self.bow_from_words(&words, descriptors.len());
        let mut pairs: Vec<(NodeId, u32)> = q.iter().map(|x| x.ancestor).zip(0..n).collect();
        pairs.sort_unstable();
        Ok((bow, FeatureVector::from_sorted_pairs(&pairs)))
    }

    /// The score of `a` (the query) against `b` with this vocabulary's scoring.
    pub fn score(&self, a: &BowVector, b: &BowVector) -> f64 {
        self.scoring.score(a, b)
    }
}

/// Checks that `child_start` describes a tree of `n` nodes numbered breadth first: node 0
/// has children, the children of each node are a contiguous range after it, the ranges
/// partition `1 .. n` in order, no node has more than `branching` children and no node is
/// deeper than `depth`. Runs in `O(n)` without allocating.
pub(crate) fn check_tree(branching: u32, depth: u32, child_start: &[u32], n: usize) -> Result<()> {
    let bad = |msg: String| Err(VocabError::InvalidTree(msg));
    if branching == 0 {
        return bad("branching must be >= 1".into());
    }
    if depth == 0 || depth > MAX_DEPTH {
        return bad(format!("depth {depth} is outside 1..={MAX_DEPTH}"));
    }
    if n < 2 || n >= u32::MAX as usize {
        return bad(format!(
            "{n} nodes: a tree needs a root and at least one word, and fewer than 2^32 nodes"
        ));
    }
    if child_start.len() != n + 1 {
        return bad(format!(
            "child_start has {} entries, {} expected (node count + 1)",
            child_start.len(),
            n + 1
        ));
    }
    if child_start[0] != 1 || child_start[n] as usize != n {
        return bad(format!(
            "child_start must begin at 1 and end at the node count {n}, got {} and {}",
            child_start[0], child_start[n]
        ));
    }
    for node in 0..n {
        let (s, e) = (child_start[node] as usize, child_start[node + 1] as usize);
        if e < s {
            return bad(format!("child_start decreases after node {node}"));
        }
        if s < e && s <= node {
            return bad(format!(
                "node {node} has child {s}: children must come after their parent"
            ));
        }
        if e - s > branching as usize {
            return bad(format!(
                "node {node} has {} children, more than the branching {branching}",
                e - s
            ));
        }
    }
    if child_start[1] == child_start[0] {
        return bad("the root has no children".into());
    }
    // With contiguous, ordered child ranges the nodes of depth d + 1 are the children of the
    // nodes of depth d: walk the levels.
    let (mut s, mut e, mut d) = (0usize, 1usize, 0u32);
    while s < e {
        if d > depth {
            return bad(format!(
                "node {s} is at depth {d}, deeper than the declared depth {depth}"
            ));
        }
        (s, e) = (child_start[s] as usize, child_start[e] as usize);
        d += 1;
    }
    Ok(())
}
