//! Feature descriptors: binary strings compared by Hamming distance and float vectors compared
//! by squared Euclidean distance, behind one sealed trait.
//!
//! - Binary `[u64; W]` (ORB and BRIEF-256: `W = 4`). Distance: the Hamming distance
//!   `popcount(a XOR b)`. Centroid of a cluster: the per-bit majority (a bit is set when more
//!   than half of the members have it set; a tie gives 0).
//! - Float `[f32; D]` (SURF-64: `D = 64`, SIFT-128: `D = 128`). Distance: the squared
//!   Euclidean distance, summed in eight interleaved lanes (element `i` goes to lane `i mod 8`,
//!   lanes reduced as `((l0+l4)+(l2+l6)) + ((l1+l5)+(l3+l7))`) so that the scalar and the AVX2
//!   paths give bit-identical results. Centroid: the mean, summed in `f64` in member order.
//!
//! OpenCV stores a binary descriptor as bytes; [`binary_from_bytes`] packs byte `i` into bits
//! `8 (i mod 8) ..` of word `i / 8` (little-endian), the layout used by the ORB-SLAM text
//! vocabulary import. Any packing works as long as vocabulary and images use the same one.

use std::fmt::Debug;

use crate::descent::{Quantized, TreeView};
use crate::simd::{self, Isa};

/// The two families of descriptors, as written in vocabulary files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DescriptorKind {
    /// Bit strings stored as `u64` words, compared by Hamming distance.
    Binary,
    /// `f32` vectors, compared by squared Euclidean distance.
    Float,
}

impl DescriptorKind {
    /// The byte that names the kind in every ibc file (vocabularies, maps, rig logs): 1 for
    /// binary, 2 for float.
    pub fn code(self) -> u8 {
        match self {
            Self::Binary => 1,
            Self::Float => 2,
        }
    }

    /// The kind with the given file code ([`code`](Self::code)), `None` for another byte.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            1 => Some(Self::Binary),
            2 => Some(Self::Float),
            _ => None,
        }
    }
}

pub(crate) mod sealed {
    use super::{Isa, Quantized, TreeView};

    /// The crate-internal operations of a descriptor type; users cannot implement or call it.
    pub trait Sealed: Sized {
        /// The distance value.
        type Dist: Copy + PartialOrd + Into<f64>;
        /// Running sums for a centroid.
        type Acc;
        /// The distance with the given instruction set (the result does not depend on it).
        fn distance_isa(isa: Isa, a: &Self, b: &Self) -> Self::Dist;
        /// Index and distance of the nearest candidate (lowest index on ties), `(0, MAX)` for
        /// no candidate.
        fn nearest_isa(isa: Isa, q: &Self, candidates: &[Self]) -> (usize, Self::Dist);
        /// Quantizes `descs` through the tree (see `descent::descend`).
        fn descend_isa(
            isa: Isa,
            tree: &TreeView<'_, Self>,
            descs: &[Self],
            target_depth: u32,
            out: &mut [Quantized],
        );
        /// The k-means++ sampling weight of a distance (the squared metric distance).
        fn seeding_weight(d: Self::Dist) -> f64;
        /// The metric distance (Hamming bits, or Euclidean distance) of a distance value.
        fn metric(d: Self::Dist) -> f64;
        /// The all-zero descriptor.
        fn zero() -> Self;
        /// Empty centroid sums.
        fn acc_zero() -> Self::Acc;
        /// Adds one member.
        fn acc_add(acc: &mut Self::Acc, x: &Self);
        /// The centroid of `count > 0` members.
        fn acc_finish(acc: &Self::Acc, count: u64) -> Self;
        /// Parses the descriptor tokens of a DBoW2 text vocabulary line.
        fn parse_dbow2(tokens: &mut dyn Iterator<Item = &str>) -> Result<Self, String>;
    }
}

/// A feature descriptor usable in a vocabulary tree.
///
/// Implemented for binary descriptors `[u64; W]` and float descriptors `[f32; D]` only (the
/// trait is sealed: the file format and the SIMD kernels know exactly these two families).
pub trait Descriptor: sealed::Sealed + Copy + Debug + PartialEq + Send + Sync + 'static {
    /// The distance type: `u32` Hamming distance for binary, `f32` squared Euclidean distance
    /// for float descriptors.
    type Distance: Copy + PartialOrd + Debug + Send + Sync + Into<f64>;
    /// Binary or float.
    const KIND: DescriptorKind;
    /// Number of elements: `u64` words for binary, `f32` values for float descriptors.
    const WIDTH: usize;
    /// The distance used to build and descend the tree (Hamming, or squared Euclidean),
    /// computed with the fastest instruction set this CPU has (the result does not depend on
    /// it).
    fn distance(&self, other: &Self) -> Self::Distance;
    /// The metric distance: Hamming distance in bits, or the (not squared) Euclidean distance.
    /// This is the distance the ratio test compares.
    fn metric_distance(&self, other: &Self) -> f64;

    /// Bytes of one element in files: 8 for a `u64` word, 4 for an `f32` value.
    const ELEMENT_BYTES: usize;
    /// Bytes of one descriptor in files, `WIDTH * ELEMENT_BYTES`.
    const BYTES: usize = Self::WIDTH * Self::ELEMENT_BYTES;

    /// Appends the descriptor's [`BYTES`](Self::BYTES) little-endian bytes: binary words as
    /// `u64`, float values as IEEE-754 `f32`. Every ibc file (vocabularies, maps, rig logs)
    /// stores descriptors so.
    fn write_le(&self, out: &mut Vec<u8>);
    /// The descriptor in `bytes`, which holds [`BYTES`](Self::BYTES) little-endian bytes
    /// (callers slice them; elements past a shorter slice read as zeros).
    fn read_le(bytes: &[u8]) -> Self;
    /// True when every element is finite (always for binary descriptors).
    fn is_finite(&self) -> bool;
}

/// Hamming distance, written so that it compiles to `popcnt` inside a function compiled with
/// that feature and to a bit-twiddling count elsewhere.
#[inline(always)]
pub(crate) fn hamming<const W: usize>(a: &[u64; W], b: &[u64; W]) -> u32 {
    let mut d = 0u32;
    for i in 0..W {
        d += (a[i] ^ b[i]).count_ones();
    }
    d
}

/// Nearest candidate by Hamming distance, lowest index on ties. Candidates go in pairs, the
/// pair's winner first, which halves the dependency chain of the running minimum.
#[inline(always)]
pub(crate) fn nearest_hamming<const W: usize>(q: &[u64; W], cands: &[[u64; W]]) -> (usize, u32) {
    let mut best = (0usize, u32::MAX);
    let mut pairs = cands.chunks_exact(2);
    let mut i = 0;
    for p in &mut pairs {
        let (d0, d1) = (hamming(q, &p[0]), hamming(q, &p[1]));
        let (j, d) = if d1 < d0 { (i + 1, d1) } else { (i, d0) };
        if d < best.1 {
            best = (j, d);
        }
        i += 2;
    }
    if let [c] = pairs.remainder() {
        let d = hamming(q, c);
        if d < best.1 {
            best = (i, d);
        }
    }
    best
}

/// Number of interleaved lanes of the float distance (one AVX register of `f32`).
pub(crate) const LANES: usize = 8;

/// Reduces the eight lane sums in the fixed order shared by every float path.
#[inline(always)]
pub(crate) fn reduce_lanes(l: &[f32; LANES]) -> f32 {
    let a = [l[0] + l[4], l[1] + l[5], l[2] + l[6], l[3] + l[7]];
    let b = [a[0] + a[2], a[1] + a[3]];
    b[0] + b[1]
}

/// Adds the elements past the last full chunk of eight to their lanes.
#[inline(always)]
pub(crate) fn add_tail<const D: usize>(a: &[f32; D], b: &[f32; D], lanes: &mut [f32; LANES]) {
    let full = D / LANES * LANES;
    for i in full..D {
        let d = a[i] - b[i];
        lanes[i - full] += d * d;
    }
}

/// Squared Euclidean distance in eight interleaved lanes (see the module docs).
#[inline(always)]
pub(crate) fn l2_squared<const D: usize>(a: &[f32; D], b: &[f32; D]) -> f32 {
    let mut lanes = [0f32; LANES];
    for c in 0..D / LANES {
        for (j, lane) in lanes.iter_mut().enumerate() {
            let d = a[c * LANES + j] - b[c * LANES + j];
            *lane += d * d;
        }
    }
    add_tail(a, b, &mut lanes);
    reduce_lanes(&lanes)
}

/// Nearest candidate by squared Euclidean distance, lowest index on ties.
#[inline(always)]
pub(crate) fn nearest_l2<const D: usize>(q: &[f32; D], cands: &[[f32; D]]) -> (usize, f32) {
    let mut best = (0usize, f32::INFINITY);
    for (i, c) in cands.iter().enumerate() {
        let d = l2_squared(q, c);
        if d < best.1 {
            best = (i, d);
        }
    }
    best
}

impl<const W: usize> sealed::Sealed for [u64; W] {
    type Dist = u32;
    type Acc = Vec<u64>;

    fn distance_isa(isa: Isa, a: &Self, b: &Self) -> u32 {
        simd::hamming_with(isa, a, b)
    }

    fn nearest_isa(isa: Isa, q: &Self, candidates: &[Self]) -> (usize, u32) {
        simd::nearest_hamming_with(isa, q, candidates)
    }

    fn descend_isa(
        isa: Isa,
        tree: &TreeView<'_, Self>,
        descs: &[Self],
        target_depth: u32,
        out: &mut [Quantized],
    ) {
        simd::descend_binary_with(isa, tree, descs, target_depth, out);
    }

    fn seeding_weight(d: u32) -> f64 {
        let d = f64::from(d);
        d * d
    }

    fn metric(d: u32) -> f64 {
        f64::from(d)
    }

    fn zero() -> Self {
        [0; W]
    }

    fn acc_zero() -> Vec<u64> {
        vec![0; 64 * W]
    }

    fn acc_add(acc: &mut Vec<u64>, x: &Self) {
        for (w, word) in x.iter().enumerate() {
            let counts = &mut acc[64 * w..64 * w + 64];
            for (bit, c) in counts.iter_mut().enumerate() {
                *c += (word >> bit) & 1;
            }
        }
    }

    fn acc_finish(acc: &Vec<u64>, count: u64) -> Self {
        let mut out = [0u64; W];
        for (w, word) in out.iter_mut().enumerate() {
            for bit in 0..64 {
                if 2 * acc[64 * w + bit] > count {
                    *word |= 1 << bit;
                }
            }
        }
        out
    }

    fn parse_dbow2(tokens: &mut dyn Iterator<Item = &str>) -> Result<Self, String> {
        let mut out = [0u64; W];
        for i in 0..8 * W {
            let tok = tokens
                .next()
                .ok_or_else(|| format!("expected {} descriptor bytes, found {i}", 8 * W))?;
            let byte: u8 = tok
                .parse()
                .map_err(|_| format!("descriptor byte `{tok}` is not an integer in 0..=255"))?;
            out[i / 8] |= u64::from(byte) << (8 * (i % 8));
        }
        Ok(out)
    }
}

impl<const W: usize> Descriptor for [u64; W] {
    type Distance = u32;
    const KIND: DescriptorKind = DescriptorKind::Binary;
    const WIDTH: usize = W;

    fn distance(&self, other: &Self) -> u32 {
        simd::hamming_with(Isa::detect(), self, other)
    }

    fn metric_distance(&self, other: &Self) -> f64 {
        f64::from(self.distance(other))
    }

    const ELEMENT_BYTES: usize = 8;

    fn is_finite(&self) -> bool {
        true
    }

    fn write_le(&self, out: &mut Vec<u8>) {
        for w in self {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }

    fn read_le(bytes: &[u8]) -> Self {
        let mut out = [0u64; W];
        for (w, chunk) in out.iter_mut().zip(bytes.chunks_exact(8)) {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            *w = u64::from_le_bytes(b);
        }
        out
    }
}

impl<const D: usize> sealed::Sealed for [f32; D] {
    type Dist = f32;
    type Acc = Vec<f64>;

    fn distance_isa(isa: Isa, a: &Self, b: &Self) -> f32 {
        simd::l2_squared_with(isa, a, b)
    }

    fn nearest_isa(isa: Isa, q: &Self, candidates: &[Self]) -> (usize, f32) {
        simd::nearest_l2_with(isa, q, candidates)
    }

    fn descend_isa(
        isa: Isa,
        tree: &TreeView<'_, Self>,
        descs: &[Self],
        target_depth: u32,
        out: &mut [Quantized],
    ) {
        simd::descend_float_with(isa, tree, descs, target_depth, out);
    }

    fn seeding_weight(d: f32) -> f64 {
        f64::from(d)
    }

    fn metric(d: f32) -> f64 {
        f64::from(d).sqrt()
    }

    fn zero() -> Self {
        [0.0; D]
    }

    fn acc_zero() -> Vec<f64> {
        vec![0.0; D]
    }

    fn acc_add(acc: &mut Vec<f64>, x: &Self) {
        for (a, v) in acc.iter_mut().zip(x) {
            *a += f64::from(*v);
        }
    }

    fn acc_finish(acc: &Vec<f64>, count: u64) -> Self {
        let mut out = [0f32; D];
        let n = count as f64;
        for (o, s) in out.iter_mut().zip(acc) {
            *o = (s / n) as f32;
        }
        out
    }

    fn parse_dbow2(tokens: &mut dyn Iterator<Item = &str>) -> Result<Self, String> {
        let mut out = [0f32; D];
        for (i, v) in out.iter_mut().enumerate() {
            let tok = tokens
                .next()
                .ok_or_else(|| format!("expected {D} descriptor values, found {i}"))?;
            *v = tok
                .parse()
                .map_err(|_| format!("descriptor value `{tok}` is not a number"))?;
            if !v.is_finite() {
                return Err(format!("descriptor value `{tok}` is not finite"));
            }
        }
        Ok(out)
    }
}

impl<const D: usize> Descriptor for [f32; D] {
    type Distance = f32;
    const KIND: DescriptorKind = DescriptorKind::Float;
    const WIDTH: usize = D;

    fn distance(&self, other: &Self) -> f32 {
        simd::l2_squared_with(Isa::detect(), self, other)
    }

    fn metric_distance(&self, other: &Self) -> f64 {
        f64::from(self.distance(other)).sqrt()
    }

    const ELEMENT_BYTES: usize = 4;

    fn is_finite(&self) -> bool {
        self.iter().all(|x| x.is_finite())
    }

    fn write_le(&self, out: &mut Vec<u8>) {
        for v in self {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }

    fn read_le(bytes: &[u8]) -> Self {
        let mut out = [0f32; D];
        for (v, chunk) in out.iter_mut().zip(bytes.chunks_exact(4)) {
            let mut b = [0u8; 4];
            b.copy_from_slice(chunk);
            *v = f32::from_le_bytes(b);
        }
        out
    }
}

/// Packs an OpenCV-style binary descriptor (`8 W` bytes) into `[u64; W]`: byte `i` goes to
/// bits `8 (i mod 8) .. 8 (i mod 8) + 8` of word `i / 8`. Returns `None` when `bytes` does not
/// hold exactly `8 W` bytes.
pub fn binary_from_bytes<const W: usize>(bytes: &[u8]) -> Option<[u64; W]> {
    if bytes.len() != 8 * W {
        return None;
    }
    Some(<[u64; W] as Descriptor>::read_le(bytes))
}

/// The inverse of [`binary_from_bytes`]: the `8 W` bytes of a binary descriptor.
pub fn binary_to_bytes<const W: usize>(descriptor: &[u64; W]) -> Vec<u8> {
    let mut out = Vec::with_capacity(8 * W);
    descriptor.write_le(&mut out);
    out
}
