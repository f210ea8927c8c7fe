//! Instruction-set detection and the SIMD kernels.
//!
//! The default `x86_64` target has no `popcnt`, so a plain Hamming loop compiles to a
//! bit-twiddling count. The CPU is probed once ([`Isa::detect`], cached); each kernel is then
//! compiled a second time inside a `#[target_feature]` function:
//!
//! - binary descriptors with `popcnt`: the whole tree descent, recompiled with the
//!   instruction;
//! - binary descriptors with AVX2 (widths that are a multiple of 256 bits): eight candidates
//!   at a time, a nibble-table popcount per 256 bits, the distances packed as 16-bit values
//!   and the nearest picked by `phminposuw` (lowest index on ties, as the scalar loop);
//! - float descriptors with AVX2: the squared Euclidean distance with 256-bit vectors, eight
//!   lanes that are exactly the eight lanes of the scalar code, with no fused multiply-add, so
//!   the result is bit-identical to the scalar path.
//!
//! Every path is tested to give exactly the scalar path's output.

#![allow(unsafe_code)]

use std::sync::OnceLock;

use crate::descent::{self, Nearest, Quantized, TreeView};
use crate::descriptor::{hamming, l2_squared, nearest_hamming, nearest_l2};

/// An instruction-set level of the kernels.
///
/// Levels are ordered: a CPU that supports a level supports the ones below it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// Portable code (on `x86_64`, SSE2 only).
    Scalar,
    /// `x86_64` with the `popcnt` instruction (Hamming distance).
    Popcnt,
    /// `x86_64` with `popcnt` and AVX2 (binary and float kernels in 256-bit vectors).
    Avx2,
}

impl Isa {
    /// The best level this CPU supports, probed on the first call and cached.
    pub fn detect() -> Isa {
        static DETECTED: OnceLock<Isa> = OnceLock::new();
        *DETECTED.get_or_init(probe)
    }

    /// True when this CPU supports the level.
    pub fn is_supported(self) -> bool {
        self <= Isa::detect()
    }

    /// Every level this CPU supports, lowest first.
    pub fn supported() -> Vec<Isa> {
        [Isa::Scalar, Isa::Popcnt, Isa::Avx2]
            .into_iter()
            .filter(|i| i.is_supported())
            .collect()
    }
}

#[cfg(target_arch = "x86_64")]
fn probe() -> Isa {
    if !std::arch::is_x86_feature_detected!("popcnt") {
        Isa::Scalar
    } else if std::arch::is_x86_feature_detected!("avx2") {
        Isa::Avx2
    } else {
        Isa::Popcnt
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn probe() -> Isa {
    Isa::Scalar
}

/// Asks the CPU to bring the cache line holding `p` into the cache. A hint only: it never
/// faults and does nothing on other architectures.
#[inline(always)]
pub(crate) fn prefetch(p: *const u8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `prefetcht0` is a hint that never faults, whatever the address; SSE is part of
    // the `x86_64` baseline.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// The portable Hamming kernel (also the `popcnt` kernel, once compiled with that feature).
struct Hamming;

impl<const W: usize> Nearest<[u64; W]> for Hamming {
    #[inline(always)]
    fn nearest(q: &[u64; W], candidates: &[[u64; W]]) -> usize {
        nearest_hamming(q, candidates).0
    }
}

/// The portable squared-Euclidean kernel.
struct L2;

impl<const D: usize> Nearest<[f32; D]> for L2 {
    #[inline(always)]
    fn nearest(q: &[f32; D], candidates: &[[f32; D]]) -> usize {
        nearest_l2(q, candidates).0
    }
}

/// Hamming distance at the given level.
pub(crate) fn hamming_with<const W: usize>(isa: Isa, a: &[u64; W], b: &[u64; W]) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Popcnt && Isa::Popcnt.is_supported() {
        // SAFETY: `popcnt` support was just checked.
        return unsafe { x86::hamming_popcnt(a, b) };
    }
    let _ = isa;
    hamming(a, b)
}

/// Nearest candidate by Hamming distance at the given level.
pub(crate) fn nearest_hamming_with<const W: usize>(
    isa: Isa,
    q: &[u64; W],
    candidates: &[[u64; W]],
) -> (usize, u32) {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && Isa::Avx2.is_supported() {
        // SAFETY: AVX2 and `popcnt` support was just checked.
        return unsafe { x86::nearest_hamming_avx2(q, candidates) };
    }
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Popcnt && Isa::Popcnt.is_supported() {
        // SAFETY: `popcnt` support was just checked.
        return unsafe { x86::nearest_hamming_popcnt(q, candidates) };
    }
    let _ = isa;
    nearest_hamming(q, candidates)
}

/// Tree descent of binary descriptors at the given level.
pub(crate) fn descend_binary_with<const W: usize>(
    isa: Isa,
    tree: &TreeView<'_, [u64; W]>,
    descs: &[[u64; W]],
    target_depth: u32,
    out: &mut [Quantized],
) {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && Isa::Avx2.is_supported() {
        // SAFETY: AVX2 and `popcnt` support was just checked.
        return unsafe { x86::descend_binary_avx2(tree, descs, target_depth, out) };
    }
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Popcnt && Isa::Popcnt.is_supported() {
        // SAFETY: `popcnt` support was just checked.
        return unsafe { x86::descend_binary_popcnt(tree, descs, target_depth, out) };
    }
    let _ = isa;
    descent::descend::<_, Hamming>(tree, descs, target_depth, out);
}

/// Squared Euclidean distance at the given level.
pub(crate) fn l2_squared_with<const D: usize>(isa: Isa, a: &[f32; D], b: &[f32; D]) -> f32 {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && Isa::Avx2.is_supported() {
        // SAFETY: AVX2 support was just checked.
        return unsafe { x86::l2_squared_avx2(a, b) };
    }
    let _ = isa;
    l2_squared(a, b)
}

/// Nearest candidate by squared Euclidean distance at the given level.
pub(crate) fn nearest_l2_with<const D: usize>(
    isa: Isa,
    q: &[f32; D],
    candidates: &[[f32; D]],
) -> (usize, f32) {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && Isa::Avx2.is_supported() {
        // SAFETY: AVX2 support was just checked.
        return unsafe { x86::nearest_l2_avx2(q, candidates) };
    }
    let _ = isa;
    nearest_l2(q, candidates)
}

/// Tree descent of float descriptors at the given level.
pub(crate) fn descend_float_with<const D: usize>(
    isa: Isa,
    tree: &TreeView<'_, [f32; D]>,
    descs: &[[f32; D]],
    target_depth: u32,
    out: &mut [Quantized],
) {
    #[cfg(target_arch = "x86_64")]
    if isa >= Isa::Avx2 && Isa::Avx2.is_supported() {
        // SAFETY: AVX2 support was just checked.
        return unsafe { x86::descend_float_avx2(tree, descs, target_depth, out) };
    }
    let _ = isa;
    descent::descend::<_, L2>(tree, descs, target_depth, out);
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::{
        __m128i, __m256, __m256i, _mm_add_epi16, _mm_cmpgt_epi16, _mm_cvtsi128_si32,
        _mm_minpos_epu16, _mm_or_si128, _mm_set1_epi16, _mm_setr_epi16, _mm_unpackhi_epi64,
        _mm_unpacklo_epi64, _mm256_add_epi8, _mm256_add_epi64, _mm256_add_ps, _mm256_and_si256,
        _mm256_castsi256_si128, _mm256_extracti128_si256, _mm256_loadu_ps, _mm256_loadu_si256,
        _mm256_mul_ps, _mm256_or_si256, _mm256_sad_epu8, _mm256_set1_epi8, _mm256_setr_epi8,
        _mm256_setzero_ps, _mm256_setzero_si256, _mm256_shuffle_epi8, _mm256_slli_epi64,
        _mm256_srli_epi16, _mm256_storeu_ps, _mm256_sub_ps, _mm256_xor_si256,
    };

    use super::Hamming;
    use crate::descent::{self, Nearest, Quantized, TreeView};
    use crate::descriptor::{LANES, add_tail, hamming, nearest_hamming, reduce_lanes};

    #[target_feature(enable = "popcnt")]
    pub(super) fn hamming_popcnt<const W: usize>(a: &[u64; W], b: &[u64; W]) -> u32 {
        hamming(a, b)
    }

    #[target_feature(enable = "popcnt")]
    pub(super) fn nearest_hamming_popcnt<const W: usize>(
        q: &[u64; W],
        candidates: &[[u64; W]],
    ) -> (usize, u32) {
        nearest_hamming(q, candidates)
    }

    #[target_feature(enable = "popcnt")]
    pub(super) fn descend_binary_popcnt<const W: usize>(
        tree: &TreeView<'_, [u64; W]>,
        descs: &[[u64; W]],
        target_depth: u32,
        out: &mut [Quantized],
    ) {
        descent::descend::<_, Hamming>(tree, descs, target_depth, out);
    }

    /// The widest binary descriptor (in `u64` words) of the AVX2 kernel: its distances must
    /// fit in 16 bits (`64 W <= 65535`).
    const AVX2_MAX_WORDS: usize = 1020;

    /// Per-64-bit-lane popcounts of `q XOR c` (four partial sums per 256-bit chunk), by the
    /// nibble lookup of Mula, Kurz and Lemire ("Faster population counts using AVX2
    /// instructions", The Computer Journal 2018) and `vpsadbw`. `W` is a multiple of 4.
    #[target_feature(enable = "avx2,popcnt")]
    #[inline]
    fn lane_popcounts<const W: usize>(q: &[u64; W], c: &[u64; W]) -> __m256i {
        let lut = _mm256_setr_epi8(
            0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2,
            3, 3, 4,
        );
        let low = _mm256_set1_epi8(0x0f);
        let mut sums = _mm256_setzero_si256();
        for k in 0..W / 4 {
            // SAFETY: `4 k + 4 <= W`, so both 32-byte loads are inside the arrays; `loadu`
            // has no alignment requirement.
            let (a, b) = unsafe {
                (
                    _mm256_loadu_si256(q.as_ptr().add(4 * k).cast::<__m256i>()),
                    _mm256_loadu_si256(c.as_ptr().add(4 * k).cast::<__m256i>()),
                )
            };
            let x = _mm256_xor_si256(a, b);
            let lo = _mm256_and_si256(x, low);
            let hi = _mm256_and_si256(_mm256_srli_epi16::<4>(x), low);
            let bytes = _mm256_add_epi8(_mm256_shuffle_epi8(lut, lo), _mm256_shuffle_epi8(lut, hi));
            sums = _mm256_add_epi64(sums, _mm256_sad_epu8(bytes, _mm256_setzero_si256()));
        }
        sums
    }

    /// Nearest candidate by Hamming distance, eight candidates at a time: their lane sums are
    /// packed as 16-bit values, reduced to eight distances in one register, and
    /// `phminposuw` returns the smallest with its lowest index (the scalar tie rule).
    #[target_feature(enable = "avx2,popcnt")]
    #[inline]
    pub(super) fn nearest_hamming_avx2<const W: usize>(
        q: &[u64; W],
        candidates: &[[u64; W]],
    ) -> (usize, u32) {
        if !W.is_multiple_of(4) || W > AVX2_MAX_WORDS {
            return nearest_hamming(q, candidates);
        }
        let index = _mm_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7);
        let mut best = (0usize, u32::MAX);
        for (b, block) in candidates.chunks(8).enumerate() {
            let mut packed = [_mm256_setzero_si256(); 2];
            for (j, c) in block.iter().enumerate() {
                let s = lane_popcounts(q, c);
                let s = match j % 4 {
                    0 => s,
                    1 => _mm256_slli_epi64::<16>(s),
                    2 => _mm256_slli_epi64::<32>(s),
                    _ => _mm256_slli_epi64::<48>(s),
                };
                packed[j / 4] = _mm256_or_si256(packed[j / 4], s);
            }
            let half = |p: __m256i| -> __m128i {
                _mm_add_epi16(_mm256_castsi256_si128(p), _mm256_extracti128_si256::<1>(p))
            };
            let (r0, r1) = (half(packed[0]), half(packed[1]));
            let totals = _mm_add_epi16(_mm_unpacklo_epi64(r0, r1), _mm_unpackhi_epi64(r0, r1));
            // Lanes past the block's end read 0xFFFF, above any distance of <= 1020 words.
            let pad = _mm_cmpgt_epi16(index, _mm_set1_epi16(block.len() as i16 - 1));
            let m = _mm_cvtsi128_si32(_mm_minpos_epu16(_mm_or_si128(totals, pad))) as u32;
            let (value, lane) = (m & 0xffff, (m >> 16) & 7);
            if value < best.1 {
                best = (8 * b + lane as usize, value);
            }
        }
        best
    }

    /// The AVX2 binary kernel of the descent; reached only through [`descend_binary_avx2`].
    struct HammingAvx2;

    impl<const W: usize> Nearest<[u64; W]> for HammingAvx2 {
        #[inline(always)]
        fn nearest(q: &[u64; W], candidates: &[[u64; W]]) -> usize {
            // SAFETY: this kernel is only instantiated inside `descend_binary_avx2`, which is
            // only called after AVX2 and `popcnt` support was checked.
            unsafe { nearest_hamming_avx2(q, candidates).0 }
        }
    }

    #[target_feature(enable = "avx2,popcnt")]
    pub(super) fn descend_binary_avx2<const W: usize>(
        tree: &TreeView<'_, [u64; W]>,
        descs: &[[u64; W]],
        target_depth: u32,
        out: &mut [Quantized],
    ) {
        descent::descend::<_, HammingAvx2>(tree, descs, target_depth, out);
    }

    /// Squared Euclidean distance with the eight lanes in one AVX register: lane `j` sums the
    /// elements `8 c + j` in the same order as the scalar code, then the same tail and the
    /// same reduction run on the stored lanes.
    #[target_feature(enable = "avx2,popcnt")]
    #[inline]
    pub(super) fn l2_squared_avx2<const D: usize>(a: &[f32; D], b: &[f32; D]) -> f32 {
        let mut acc: __m256 = _mm256_setzero_ps();
        for c in 0..D / LANES {
            // SAFETY: `c * LANES + LANES <= D`, so both eight-float loads are inside the
            // arrays; `loadu` has no alignment requirement.
            let (va, vb) = unsafe {
                (
                    _mm256_loadu_ps(a.as_ptr().add(c * LANES)),
                    _mm256_loadu_ps(b.as_ptr().add(c * LANES)),
                )
            };
            let d = _mm256_sub_ps(va, vb);
            acc = _mm256_add_ps(acc, _mm256_mul_ps(d, d));
        }
        let mut lanes = [0f32; LANES];
        // SAFETY: `lanes` holds exactly eight floats; `storeu` has no alignment requirement.
        unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), acc) };
        add_tail(a, b, &mut lanes);
        reduce_lanes(&lanes)
    }

    #[target_feature(enable = "avx2,popcnt")]
    #[inline]
    pub(super) fn nearest_l2_avx2<const D: usize>(
        q: &[f32; D],
        candidates: &[[f32; D]],
    ) -> (usize, f32) {
        let mut best = (0usize, f32::INFINITY);
        for (i, c) in candidates.iter().enumerate() {
            let d = l2_squared_avx2(q, c);
            if d < best.1 {
                best = (i, d);
            }
        }
        best
    }

    /// The AVX2 kernel of the descent. Private to this module and only reached through
    /// [`descend_float_avx2`], which runs only after AVX2 support was checked.
    struct L2Avx2;

    impl<const D: usize> Nearest<[f32; D]> for L2Avx2 {
        #[inline(always)]
        fn nearest(q: &[f32; D], candidates: &[[f32; D]]) -> usize {
            // SAFETY: this kernel is only instantiated inside `descend_float_avx2`, which is
            // only called after AVX2 support was checked.
            unsafe { nearest_l2_avx2(q, candidates).0 }
        }
    }

    #[target_feature(enable = "avx2,popcnt")]
    pub(super) fn descend_float_avx2<const D: usize>(
        tree: &TreeView<'_, [f32; D]>,
        descs: &[[f32; D]],
        target_depth: u32,
        out: &mut [Quantized],
    ) {
        descent::descend::<_, L2Avx2>(tree, descs, target_depth, out);
    }
}
