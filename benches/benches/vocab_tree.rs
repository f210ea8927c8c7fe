//! Benchmarks of `ibc-vocab-tree` on synthetic trees of the shape: branching 10,
//! depth 6 (10^6 words), built directly from random centroids (training a million words is
//! not what is measured here).
//!
//! - `transform_binary`: quantizing 1000 ORB (256-bit) descriptors, one thread, with the flat
//!   layout (AVX2, POPCNT and portable paths) against a pointer-per-node tree of the same
//!   centroids measured in the same run (the same-run baseline; see `PtrNode`).
//! - `transform_surf64`: the same for SURF-64 float descriptors (AVX2 and portable paths).
//! - `query`: a 1000-feature image against 20,000 database images.
//! - `load`: reading the million-word binary vocabulary from disk, against reading the same
//!   file's bytes with `std::fs::read` (same-run baseline).
//!
//! Run with `cargo bench -p ibc-benches --bench vocab_tree`; figures in BENCHMARKS.md.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use ibc_benches::bench_rng;
use ibc_vocab_tree::{
    BowVector, Database, Descriptor, Isa, OrbDescriptor, QueryOptions, Scoring, Surf64Descriptor,
    Vocabulary, VocabularyParts, Weighting,
};
use rand::{Rng, RngExt};

const BRANCHING: u32 = 10;
const DEPTH: u32 = 6;
/// Descriptors per transformed image.
const FEATURES: usize = 1000;
/// Images in the query benchmark's database.
const DATABASE_IMAGES: usize = 20_000;

/// The shortest of `runs` timings of `f`: on a shared machine the mean moves with the other
/// jobs' load while the best run stays close to the code's own speed. Printed next to
/// criterion's mean.
fn best_of<R>(label: &str, per: usize, runs: usize, mut f: impl FnMut() -> R) {
    let mut best = Duration::MAX;
    for _ in 0..runs {
        let t = Instant::now();
        black_box(f());
        best = best.min(t.elapsed());
    }
    let each = best.as_secs_f64() / per as f64;
    eprintln!("best of {runs}: {label}: {:.3} us each", each * 1e6);
}

/// Nodes below the root of a complete tree of branching 10 and depth 6.
fn centroid_count() -> usize {
    (1..=DEPTH).map(|l| 10usize.pow(l)).sum()
}

fn random_orb(rng: &mut impl Rng) -> OrbDescriptor {
    [
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
        rng.next_u64(),
    ]
}

fn random_surf(rng: &mut impl Rng) -> Surf64Descriptor {
    let mut d = [0f32; 64];
    for x in &mut d {
        *x = rng.random::<f32>() - 0.5;
    }
    d
}

fn binary_vocabulary() -> Vocabulary<OrbDescriptor> {
    let mut rng = bench_rng(1);
    let centroids = (0..centroid_count())
        .map(|_| random_orb(&mut rng))
        .collect();
    let parts =
        VocabularyParts::complete(BRANCHING, DEPTH, centroids, Weighting::TfIdf, Scoring::L1)
            .unwrap();
    Vocabulary::from_parts(parts).unwrap()
}

/// The same-run baseline: a pointer-per-node tree (each node its own heap allocation holding
/// its centroid and a vector of boxed children), built depth first as a recursive k-means
/// would build it, descended one descriptor at a time.
struct PtrNode<D> {
    centroid: D,
    word: u32,
    children: Vec<Box<PtrNode<D>>>,
}

impl<D: Descriptor> PtrNode<D> {
    fn from_vocabulary(v: &Vocabulary<D>, node: u32) -> Box<Self> {
        Box::new(Self {
            centroid: *v.centroid(node).unwrap(),
            word: v.node_word(node).unwrap_or(u32::MAX),
            children: v
                .children(node)
                .map(|c| Self::from_vocabulary(v, c))
                .collect(),
        })
    }

    fn word(&self, q: &D, distance: impl Fn(&D, &D) -> u32) -> u32 {
        let mut node = self;
        while !node.children.is_empty() {
            let mut best = (0, u32::MAX);
            for (i, c) in node.children.iter().enumerate() {
                let d = distance(q, &c.centroid);
                if d < best.1 {
                    best = (i, d);
                }
            }
            node = &node.children[best.0];
        }
        node.word
    }
}

/// Hamming distance as a plain Rust loop compiles for the default `x86_64` target (no
/// POPCNT): the portable kernel, for the layout-only comparison.
fn hamming_portable(a: &OrbDescriptor, b: &OrbDescriptor) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

fn bench_transform_binary(c: &mut Criterion) {
    let vocabulary = binary_vocabulary();
    let mut rng = bench_rng(2);
    let queries: Vec<OrbDescriptor> = (0..FEATURES).map(|_| random_orb(&mut rng)).collect();
    let pointer_tree = PtrNode::from_vocabulary(&vocabulary, 0);
    // Both layouts must agree before their times are compared.
    let flat = vocabulary.quantize(&queries);
    let ptr: Vec<u32> = queries
        .iter()
        .map(|q| pointer_tree.word(q, |a, b| a.distance(b)))
        .collect();
    assert_eq!(flat, ptr);

    let mut group = c.benchmark_group("transform_binary_k10_l6");
    group.throughput(Throughput::Elements(FEATURES as u64));
    for isa in Isa::supported() {
        group.bench_function(format!("flat_{isa:?}"), |b| {
            b.iter(|| {
                vocabulary
                    .quantize_with_isa(isa, black_box(&queries))
                    .unwrap()
            })
        });
    }
    group.bench_function("flat_transform_bow", |b| {
        b.iter(|| vocabulary.transform(black_box(&queries)))
    });
    group.bench_function("pointer_per_node_dispatched", |b| {
        b.iter(|| {
            black_box(&queries)
                .iter()
                .map(|q| pointer_tree.word(q, |a, b| a.distance(b)))
                .collect::<Vec<_>>()
        })
    });
    group.bench_function("pointer_per_node_portable", |b| {
        b.iter(|| {
            black_box(&queries)
                .iter()
                .map(|q| pointer_tree.word(q, hamming_portable))
                .collect::<Vec<_>>()
        })
    });
    group.finish();
    for isa in Isa::supported() {
        best_of(&format!("binary flat {isa:?}"), FEATURES, 50, || {
            vocabulary.quantize_with_isa(isa, &queries).unwrap()
        });
    }
    best_of("binary pointer-per-node dispatched", FEATURES, 50, || {
        queries
            .iter()
            .map(|q| pointer_tree.word(q, |a, b| a.distance(b)))
            .collect::<Vec<_>>()
    });
    best_of("binary pointer-per-node portable", FEATURES, 50, || {
        queries
            .iter()
            .map(|q| pointer_tree.word(q, hamming_portable))
            .collect::<Vec<_>>()
    });

    let mut group = c.benchmark_group("load_binary_k10_l6");
    let dir = std::env::temp_dir().join(format!("ibc-vocab-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("k10l6.ibcvoc");
    vocabulary.save(&path).unwrap();
    group.bench_function("load", |b| {
        b.iter(|| Vocabulary::<OrbDescriptor>::load(black_box(&path)).unwrap())
    });
    // Same-run baseline: reading the file's bytes into memory, with no parsing or checking.
    group.bench_function("fs_read_baseline", |b| {
        b.iter(|| std::fs::read(black_box(&path)).unwrap())
    });
    group.finish();
    best_of("load", 1, 10, || {
        Vocabulary::<OrbDescriptor>::load(&path).unwrap()
    });
    best_of("fs_read_baseline", 1, 10, || std::fs::read(&path).unwrap());
    std::fs::remove_dir_all(&dir).ok();

    drop(pointer_tree);
    bench_query(c, vocabulary);
}

fn bench_transform_surf(c: &mut Criterion) {
    let mut rng = bench_rng(3);
    let centroids = (0..centroid_count())
        .map(|_| random_surf(&mut rng))
        .collect();
    let parts =
        VocabularyParts::complete(BRANCHING, DEPTH, centroids, Weighting::TfIdf, Scoring::L1)
            .unwrap();
    let vocabulary = Vocabulary::<Surf64Descriptor>::from_parts(parts).unwrap();
    let queries: Vec<Surf64Descriptor> = (0..FEATURES).map(|_| random_surf(&mut rng)).collect();
    let mut group = c.benchmark_group("transform_surf64_k10_l6");
    group.throughput(Throughput::Elements(FEATURES as u64));
    for isa in Isa::supported().into_iter().filter(|i| *i != Isa::Popcnt) {
        group.bench_function(format!("flat_{isa:?}"), |b| {
            b.iter(|| {
                vocabulary
                    .quantize_with_isa(isa, black_box(&queries))
                    .unwrap()
            })
        });
    }
    group.finish();
    for isa in Isa::supported().into_iter().filter(|i| *i != Isa::Popcnt) {
        best_of(&format!("surf64 flat {isa:?}"), FEATURES, 50, || {
            vocabulary.quantize_with_isa(isa, &queries).unwrap()
        });
    }
}

/// A random image vector of `FEATURES` words drawn with density `∝ 1/√w` over the words
/// (word `⌊W u²⌋`, `u` uniform): popular words have long inverted lists, as in real data.
fn random_bow(rng: &mut impl Rng, vocabulary: &Vocabulary<OrbDescriptor>) -> Vec<u32> {
    let words = f64::from(vocabulary.word_count());
    let mut w: Vec<u32> = (0..FEATURES)
        .map(|_| {
            let u = rng.random::<f64>();
            ((words * u * u) as u32).min(vocabulary.word_count() - 1)
        })
        .collect();
    w.sort_unstable();
    w
}

fn bow_of(words: &[u32]) -> BowVector {
    let mut entries: Vec<(u32, f32)> = Vec::new();
    for &w in words {
        match entries.last_mut() {
            Some(e) if e.0 == w => e.1 += 1.0,
            _ => entries.push((w, 1.0)),
        }
    }
    let total = words.len() as f32;
    for e in &mut entries {
        e.1 /= total;
    }
    BowVector::from_entries(entries).unwrap()
}

fn bench_query(c: &mut Criterion, vocabulary: Vocabulary<OrbDescriptor>) {
    let vocabulary = Arc::new(vocabulary);
    let mut database = Database::new(Arc::clone(&vocabulary), None);
    let mut rng = bench_rng(4);
    for _ in 0..DATABASE_IMAGES {
        let bow = bow_of(&random_bow(&mut rng, &vocabulary));
        database.add_bow(&bow, None).unwrap();
    }
    let queries: Vec<BowVector> = (0..16)
        .map(|_| bow_of(&random_bow(&mut rng, &vocabulary)))
        .collect();
    let mut group = c.benchmark_group("query_20000_images");
    let options = QueryOptions::default();
    let mut i = 0;
    group.bench_function("query_1000_features", |b| {
        b.iter_batched(
            || {
                i = (i + 1) % queries.len();
                &queries[i]
            },
            |q| database.query(q, &options),
            BatchSize::SmallInput,
        )
    });
    group.finish();
    let mut i = 0;
    best_of("query", 1, 64, || {
        i = (i + 1) % queries.len();
        database.query(&queries[i], &options)
    });
}

fn config() -> Criterion {
    Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(4))
}

criterion_group! {
    name = benches;
    config = config();
    targets = bench_transform_binary, bench_transform_surf
}
criterion_main!(benches);
