//! Greedy descent of the flat tree (Nister and Stewenius, "Scalable recognition with a
//! vocabulary tree", CVPR 2006, section 3): at each level a descriptor moves to the child whose
//! centroid is nearest, until it reaches a leaf (a word).
//!
//! The tree is stored breadth first: the children of node `n` are the contiguous nodes
//! `child_start[n] .. child_start[n + 1]`, and their centroids are contiguous too, so one level
//! reads one short run of memory. Descriptors are descended in groups of [`GROUP`] in lock
//! step; after each step the next children block of every descriptor is prefetched, so the
//! cache misses of a large tree overlap instead of adding up.

use crate::descriptor::sealed::Sealed;
use crate::simd::prefetch;

/// Number of descriptors descended in lock step.
pub(crate) const GROUP: usize = 16;

/// A read-only view of the flat tree.
#[derive(Clone, Copy)]
pub struct TreeView<'a, D> {
    /// One centroid per node, in breadth-first order (the root's is unused).
    pub centroids: &'a [D],
    /// `node_count + 1` offsets: the children of `n` are `child_start[n]..child_start[n + 1]`.
    pub child_start: &'a [u32],
}

impl<D> TreeView<'_, D> {
    /// The children range of `node` (empty for a leaf or an out-of-range node).
    #[inline(always)]
    pub fn children(&self, node: u32) -> (u32, u32) {
        let n = node as usize;
        match (self.child_start.get(n), self.child_start.get(n + 1)) {
            (Some(&s), Some(&e)) => (s, e),
            _ => (0, 0),
        }
    }

    /// Prefetches the centroids and child offsets of the children `s..e`.
    #[inline(always)]
    fn prefetch_children(&self, s: u32, e: u32) {
        if let Some(block) = self.centroids.get(s as usize..e as usize) {
            let bytes = size_of_val(block);
            let base = block.as_ptr().cast::<u8>();
            let mut off = 0;
            while off < bytes {
                prefetch(base.wrapping_add(off));
                off += 64;
            }
        }
        if let Some(x) = self.child_start.get(s as usize) {
            prefetch(std::ptr::from_ref(x).cast::<u8>());
        }
    }
}

/// Where one descriptor ended: its leaf and the node it crossed at the target depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Quantized {
    /// The leaf (word) node.
    pub leaf: u32,
    /// The node at the target depth on the path (the leaf itself when the leaf is shallower).
    pub ancestor: u32,
}

/// A "nearest centroid among contiguous candidates" kernel.
pub(crate) trait Nearest<D: Sealed> {
    /// Index of the nearest candidate, lowest index on ties (0 when there is none).
    fn nearest(q: &D, candidates: &[D]) -> usize;
}

/// Descends every descriptor of `descs` and writes where it ended into `out` (same length).
///
/// `target_depth` is the depth whose node is recorded as [`Quantized::ancestor`] (0 is the
/// root). The function is `inline(always)` so that each instruction-set wrapper compiles its
/// own copy with its own target features.
#[inline(always)]
pub(crate) fn descend<D: Sealed, N: Nearest<D>>(
    tree: &TreeView<'_, D>,
    descs: &[D],
    target_depth: u32,
    out: &mut [Quantized],
) {
    let (s0, e0) = tree.children(0);
    for (qs, os) in descs.chunks(GROUP).zip(out.chunks_mut(GROUP)) {
        let mut start = [s0; GROUP];
        let mut end = [e0; GROUP];
        let mut node = [0u32; GROUP];
        let mut ancestor = [if target_depth == 0 { 0 } else { u32::MAX }; GROUP];
        let mut depth = 0u32;
        loop {
            depth += 1;
            let mut active = false;
            for (g, q) in qs.iter().enumerate() {
                if start[g] >= end[g] {
                    continue;
                }
                let cands = tree
                    .centroids
                    .get(start[g] as usize..end[g] as usize)
                    .unwrap_or(&[]);
                let m = start[g] + N::nearest(q, cands) as u32;
                node[g] = m;
                if depth == target_depth {
                    ancestor[g] = m;
                }
                let (s, e) = tree.children(m);
                start[g] = s;
                end[g] = e;
                if s < e {
                    tree.prefetch_children(s, e);
                    active = true;
                }
            }
            if !active {
                break;
            }
        }
        for (g, o) in os.iter_mut().enumerate() {
            *o = Quantized {
                leaf: node[g],
                ancestor: if ancestor[g] == u32::MAX {
                    node[g]
                } else {
                    ancestor[g]
                },
            };
        }
    }
}
