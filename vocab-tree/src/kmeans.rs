//! One level of the hierarchical k-means: k-means++ seeding (Arthur and Vassilvitskii,
//! "k-means++: the advantages of careful seeding", SODA 2007) and a bounded number of Lloyd
//! iterations.
//!
//! - Seeding picks the first centre uniformly, then each next centre with probability
//!   proportional to `D(x)²`, the squared distance to the nearest centre picked so far. A point
//!   equal to a centre has weight 0 and is never picked, so the seeds are distinct; when every
//!   remaining weight is 0 there are fewer distinct points than clusters, and the clustering
//!   has fewer clusters (more clusters than points is not an error).
//! - Lloyd: assign every point to its nearest centre (lowest index on ties), recompute the
//!   centroids, repeat until no assignment changes or `max_iterations` is reached; the final
//!   assignment is always the nearest-centre assignment of the final centres, so a point's
//!   cluster is the child a descent would take.
//! - An empty cluster is re-seeded with the point farthest from its centre (lowest index on
//!   ties); when every point sits on a centre, the empty cluster is dropped.
//!
//! Distances are computed over fixed chunks and centroids sum each cluster's members in
//! member order, so the result for a seed does not depend on the number of threads.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::descriptor::Descriptor;
use crate::simd::Isa;

/// Points per chunk of the (possibly parallel) loops; fixed, so sums do not depend on the
/// thread count.
const CHUNK: usize = 2048;

/// Maps `f` over fixed chunks of `0..len` (in parallel with the `rayon` feature) and returns
/// the results in chunk order.
pub(crate) fn map_chunks<R: Send>(
    len: usize,
    f: impl Fn(std::ops::Range<usize>) -> R + Sync + Send,
) -> Vec<R> {
    let chunks = len.div_ceil(CHUNK);
    let range = move |c: usize| c * CHUNK..((c + 1) * CHUNK).min(len);
    #[cfg(feature = "rayon")]
    {
        use rayon::prelude::*;
        if chunks > 1 {
            return (0..chunks).into_par_iter().map(|c| f(range(c))).collect();
        }
    }
    (0..chunks).map(|c| f(range(c))).collect()
}

/// Index and distance of the nearest centre of every member.
fn assign<D: Descriptor>(
    isa: Isa,
    points: &[D],
    members: &[u32],
    centres: &[D],
) -> Vec<(u32, f64)> {
    map_chunks(members.len(), |r| {
        members[r]
            .iter()
            .map(|&m| {
                let (i, d) = D::nearest_isa(isa, &points[m as usize], centres);
                (i as u32, D::seeding_weight(d))
            })
            .collect::<Vec<_>>()
    })
    .concat()
}

/// k-means++ seeds: up to `k` distinct members.
fn seed<D: Descriptor>(
    isa: Isa,
    points: &[D],
    members: &[u32],
    k: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<D> {
    let first = members[rng.random_range(0..members.len())];
    let mut centres = vec![points[first as usize]];
    let weight_to = |c: &D| {
        map_chunks(members.len(), |r| {
            members[r]
                .iter()
                .map(|&m| D::seeding_weight(D::distance_isa(isa, &points[m as usize], c)))
                .collect::<Vec<_>>()
        })
        .concat()
    };
    let mut weights = weight_to(&centres[0]);
    while centres.len() < k {
        let total: f64 = weights.iter().sum();
        if total.is_nan() || total <= 0.0 {
            break;
        }
        let target = rng.random::<f64>() * total;
        let mut cumulative = 0.0;
        let mut pick = None;
        for (i, &w) in weights.iter().enumerate() {
            if w > 0.0 {
                pick = Some(i);
                cumulative += w;
                if cumulative > target {
                    break;
                }
            }
        }
        let Some(pick) = pick else { break };
        let c = points[members[pick] as usize];
        let new = weight_to(&c);
        for (w, n) in weights.iter_mut().zip(new) {
            if n < *w {
                *w = n;
            }
        }
        centres.push(c);
    }
    centres
}

/// Maps `f` over `items` in order (in parallel with the `rayon` feature).
pub(crate) fn map_items<T: Sync, R: Send>(
    items: &[T],
    f: impl Fn(&T) -> R + Sync + Send,
) -> Vec<R> {
    #[cfg(feature = "rayon")]
    {
        use rayon::prelude::*;
        items.par_iter().map(f).collect()
    }
    #[cfg(not(feature = "rayon"))]
    {
        items.iter().map(f).collect()
    }
}

/// The centroid of each cluster (`None` for an empty one). Each cluster sums its own members
/// in member order, so the result does not depend on the thread count, and only one set of
/// sums per cluster is ever allocated.
fn centroids<D: Descriptor>(
    points: &[D],
    members: &[u32],
    labels: &[(u32, f64)],
    k: usize,
) -> Vec<Option<D>> {
    let mut groups: Vec<Vec<u32>> = vec![Vec::new(); k];
    for (&m, l) in members.iter().zip(labels) {
        groups[l.0 as usize].push(m);
    }
    map_items(&groups, |group| {
        if group.is_empty() {
            return None;
        }
        let mut acc = D::acc_zero();
        for &m in group {
            D::acc_add(&mut acc, &points[m as usize]);
        }
        Some(D::acc_finish(&acc, group.len() as u64))
    })
}

/// Clusters `members` (indices into `points`) into at most `k` non-empty clusters and returns
/// each cluster's centroid and members, members in their original order.
pub(crate) fn kmeans<D: Descriptor>(
    isa: Isa,
    points: &[D],
    members: &[u32],
    k: usize,
    max_iterations: u32,
    seed_value: u64,
) -> Vec<(D, Vec<u32>)> {
    if members.is_empty() || k == 0 {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed_value);
    let mut centres = seed(isa, points, members, k, &mut rng);
    let mut labels = assign(isa, points, members, &centres);
    for _ in 0..max_iterations {
        let mut next: Vec<Option<D>> = centroids(points, members, &labels, centres.len());
        if next.iter().any(Option::is_none) {
            // Re-seed empty clusters with the farthest points.
            let mut far: Vec<(f64, usize)> =
                labels.iter().enumerate().map(|(i, l)| (l.1, i)).collect();
            far.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            let mut far = far.into_iter().filter(|f| f.0 > 0.0);
            for c in next.iter_mut().filter(|c| c.is_none()) {
                *c = far.next().map(|(_, i)| points[members[i] as usize]);
            }
        }
        let next: Vec<D> = next.into_iter().flatten().collect();
        let next_labels = assign(isa, points, members, &next);
        let converged =
            next.len() == centres.len() && next_labels.iter().zip(&labels).all(|(a, b)| a.0 == b.0);
        centres = next;
        labels = next_labels;
        if converged {
            break;
        }
    }
    let mut groups: Vec<Vec<u32>> = vec![Vec::new(); centres.len()];
    for (&m, l) in members.iter().zip(&labels) {
        groups[l.0 as usize].push(m);
    }
    centres
        .into_iter()
        .zip(groups)
        .filter(|(_, g)| !g.is_empty())
        .collect()
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::kmeans;
    use crate::descriptor::Descriptor;
    use crate::simd::Isa;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        /// On any data (with many duplicates), the clusters are non-empty, partition the
        /// members, number at most `k` and at most the distinct points, and every member's
        /// nearest centre is its own cluster's (the assignment a descent would make).
        #[test]
        fn clusters_partition_and_are_consistent(
            raw in proptest::collection::vec(0u64..40, 1..120),
            k in 1usize..12,
            iterations in 0u32..6,
            seed in any::<u64>(),
        ) {
            // Small values spread over two words give many ties and duplicates.
            let points: Vec<[u64; 2]> = raw.iter().map(|&x| [x * 0x0101, x >> 3]).collect();
            let members: Vec<u32> = (0..points.len() as u32).rev().collect();
            let clusters = kmeans(Isa::detect(), &points, &members, k, iterations, seed);
            let mut distinct = points.clone();
            distinct.sort_unstable();
            distinct.dedup();
            prop_assert!(!clusters.is_empty());
            prop_assert!(clusters.len() <= k.min(distinct.len()));
            let mut seen: Vec<u32> = clusters.iter().flat_map(|c| c.1.iter().copied()).collect();
            seen.sort_unstable();
            prop_assert_eq!(seen, (0..points.len() as u32).collect::<Vec<_>>());
            let centres: Vec<[u64; 2]> = clusters.iter().map(|c| c.0).collect();
            for (i, (_, group)) in clusters.iter().enumerate() {
                prop_assert!(!group.is_empty());
                for &m in group {
                    let p = &points[m as usize];
                    let nearest = centres
                        .iter()
                        .enumerate()
                        .min_by_key(|(j, c)| (p.distance(c), *j))
                        .map(|(j, _)| j);
                    prop_assert_eq!(nearest, Some(i));
                }
            }
        }
    }
}
