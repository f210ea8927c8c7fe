#![doc = include_str!("../README.md")]

mod bow;
mod database;
pub mod dbow2_text;
mod descent;
mod descriptor;
mod error;
pub mod file_format;
mod kmeans;
mod matching;
mod scoring;
mod simd;
mod training;
mod vocabulary;
mod weighting;

pub use bow::{BowVector, FeatureVector, NodeId, WordId};
pub use database::{Database, ImageId, QueryOptions, QueryResult};
pub use descriptor::{Descriptor, DescriptorKind, binary_from_bytes, binary_to_bytes};
pub use error::{Result, VocabError, VocabFileError};
pub use matching::{
    Match, MatchOptions, MatchScratch, match_brute_force, match_by_nodes, match_sets,
};
pub use scoring::{LOG_EPS, Norm, Scoring};
pub use simd::Isa;
pub use training::TrainingOptions;
pub use vocabulary::{MAX_DEPTH, Vocabulary, VocabularyParts};
pub use weighting::Weighting;

/// An ORB / BRIEF-256 binary descriptor: 256 bits in four `u64` words.
pub type OrbDescriptor = [u64; 4];
/// A SURF-64 float descriptor.
pub type Surf64Descriptor = [f32; 64];
/// A SIFT-128 float descriptor.
pub type Sift128Descriptor = [f32; 128];

#[cfg(test)]
mod send_sync {
    /// `Vocabulary` and `Database` can be shared between threads.
    #[test]
    fn vocabulary_and_database_are_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<crate::Vocabulary<crate::OrbDescriptor>>();
        check::<crate::Database<crate::Surf64Descriptor>>();
    }
}

/// Marks an options struct as open to new fields: outside this crate it can only be built
/// with `..Default::default()` (`MatchOptions { ratio: 0.8, ..Default::default() }`), so
/// adding a field is not a breaking change (faer's pattern).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[doc(hidden)]
pub struct NonExhaustive(pub(crate) ());
