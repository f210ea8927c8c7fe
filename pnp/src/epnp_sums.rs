//! The O(n) parts of EPnP: the weighted sums that make up its normal equations, and the
//! bearing error that ranks its candidate poses.
//!
//! V. Lepetit, F. Moreno-Noguer and P. Fua, "EPnP: An Accurate O(n) Solution to the PnP
//! Problem", IJCV 81(2), 2009, section 3.2: the `3n x 12` matrix `M` is never formed; its
//! normal matrix `M^T M = sum_i (a_i a_i^T) ⊗ (I - f_i f_i^T)` (cross-product rows of unit
//! bearings) needs, per correspondence, the ten products `w_a w_b` of its control weights
//! `w = (1, alpha_1, alpha_2, alpha_3)` times the six distinct entries of `I - f f^T`.
//!
//! These two loops are the whole cost of EPnP that grows with `n`. The sums are held as six
//! rows (one per projector entry) of twelve products (ten, and two zeros of padding), so the
//! inner loop is a row of twelve: three 256-bit vectors with AVX; the bearing error takes
//! four correspondences per step, with their square roots and divisions in one instruction
//! each. The CPU is probed once (`is_x86_feature_detected!`, cached by `std`); with AVX the
//! loops run in `#[target_feature(enable = "avx")]` functions. Without fused multiply-adds
//! (not enabled) and with every sum taken in the same order, both paths give bit-identical
//! results (tested).

#![allow(unsafe_code)]

use nalgebra::{Matrix3, Point3, Vector3};

/// The index pairs `(a, b)`, `a <= b`, of the products of the four control weights, in the
/// order of the sums.
pub(crate) const PRODUCTS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

/// Products per row of the sums: the ten of [`PRODUCTS`] and two zeros (three 4-lane vectors).
const ROW: usize = 12;

/// The whitening of the world points: `alpha_k = scaled_axes[k] . (X - centroid)`.
pub(crate) struct WhitenedFrame {
    pub centroid: Vector3<f64>,
    /// Principal axes over their standard deviations; unused ones zero.
    pub scaled_axes: [Vector3<f64>; 3],
}

/// The sums `sum_i weight_i w_ia w_ib (I - f_i f_i^T)` and `sum_i weight_i w_ia f_i`.
pub(crate) struct NormalSums {
    /// `rows[j][k]`: entry `j` of `I - f f^T` (`xx, xy, xz, yy, yz, zz`) for product `k`.
    rows: [[f64; ROW]; 6],
    /// `bearings[a] = sum_i weight_i w_ia f_i`.
    bearings: [[f64; 3]; 4],
}

/// `(rotation, translation, scale)`: the weight of a point is `scale / |R X + t|^2` (EPnP
/// passes the mean squared depth as the scale).
pub(crate) type DepthWeighting<'a> = (&'a Matrix3<f64>, &'a Vector3<f64>, f64);

impl NormalSums {
    /// The sums over all correspondences, with weight 1 or the depth weighting.
    pub(crate) fn accumulate(
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        frame: &WhitenedFrame,
        weighting: Option<DepthWeighting<'_>>,
    ) -> Self {
        // One copy of the loops per weighting, so no point pays for the choice.
        match weighting {
            None => Self::accumulate_with(bearings, points, frame, |_| 1.0),
            Some(w) => Self::accumulate_with(bearings, points, frame, |x| depth_weight(&w, x)),
        }
    }

    /// The sums with the weight of each point given by `weight`, on the fastest path the CPU
    /// has.
    #[inline(always)]
    fn accumulate_with(
        bearings: &[Vector3<f64>],
        points: &[Point3<f64>],
        frame: &WhitenedFrame,
        weight: impl Fn(&Point3<f64>) -> f64,
    ) -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU supports AVX, checked just above.
            return unsafe { accumulate_avx(bearings, points, frame, weight) };
        }
        accumulate_portable(bearings, points, frame, weight)
    }

    /// The six distinct entries (`xx, xy, xz, yy, yz, zz`) of the sum for product `k` of
    /// [`PRODUCTS`].
    pub(crate) fn projector_entries(&self, k: usize) -> [f64; 6] {
        self.rows.map(|row| row[k])
    }

    /// `sum_i weight_i w_ia f_i` for `a = 0..4`.
    pub(crate) fn bearing_sums(&self) -> [Vector3<f64>; 4] {
        self.bearings.map(Vector3::from)
    }
}

/// The sums with AVX intrinsics. The twelve products of a correspondence are three 4-lane
/// vectors (`W = (1, w1, w2, w3)` itself, then two lane-wise products), and each projector
/// entry is broadcast against them. Eighteen 4-lane accumulators do not fit the sixteen
/// vector registers, so the rows go in two passes of three (nine accumulators each, kept in
/// registers); the second pass also sums the bearings (three more accumulators, lane `a`
/// holding `w_a weight f`). The per-correspondence set-up (whitening, projector entries,
/// products) runs four correspondences to a vector, one per lane, and a 4 x 4 transpose turns
/// the products into the per-correspondence vectors of the sweeps. Every lane computes the
/// same products and sums them in the same order as the portable loop.
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn accumulate_avx(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    frame: &WhitenedFrame,
    weight: impl Fn(&Point3<f64>) -> f64,
) -> NormalSums {
    use core::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_broadcast_sd, _mm256_mul_pd, _mm256_setzero_pd,
        _mm256_storeu_pd,
    };
    let zero = _mm256_setzero_pd();
    let mut acc: [[__m256d; 3]; 6] = [[zero; 3]; 6];
    // bearing[j] lane a: sum_i (w_ia weight_i) f_ij.
    let mut bearing: [__m256d; 3] = [zero; 3];
    // Per chunk of correspondences: their product vectors, projector entries (by entry),
    // bearing coordinates (by coordinate), weights and `W weight`, computed once and then
    // swept twice.
    let mut products = [[zero; 3]; CHUNK];
    let mut entries = [[0.0; CHUNK]; 6];
    let mut coordinates = [[0.0; CHUNK]; 3];
    let mut weights = [0.0; CHUNK];
    let mut scales = [zero; CHUNK];
    for (chunk_f, chunk_x) in bearings.chunks(CHUNK).zip(points.chunks(CHUNK)) {
        let len = chunk_f.len().min(chunk_x.len());
        for (w, x) in weights.iter_mut().zip(chunk_x) {
            *w = weight(x);
        }
        let mut chunk = Chunk {
            products: &mut products,
            entries: &mut entries,
            coordinates: &mut coordinates,
            scales: &mut scales,
        };
        // SAFETY: the CPU supports AVX (the caller's guarantee).
        unsafe {
            if len == CHUNK {
                prepare_chunk::<false>(chunk_f, chunk_x, frame, &weights, &mut chunk);
            } else {
                prepare_chunk::<true>(
                    &chunk_f[..len],
                    &chunk_x[..len],
                    frame,
                    &weights,
                    &mut chunk,
                );
            }
        }
        // Two sweeps of three rows: nine accumulators each, held in registers.
        for half in 0..2 {
            let mut rows: [[__m256d; 3]; 3] = [acc[3 * half], acc[3 * half + 1], acc[3 * half + 2]];
            for i in 0..len {
                let [p0, p1, p2] = products[i];
                for (row, entry) in rows.iter_mut().zip(&entries[3 * half..]) {
                    let e = _mm256_broadcast_sd(&entry[i]);
                    row[0] = _mm256_add_pd(row[0], _mm256_mul_pd(p0, e));
                    row[1] = _mm256_add_pd(row[1], _mm256_mul_pd(p1, e));
                    row[2] = _mm256_add_pd(row[2], _mm256_mul_pd(p2, e));
                }
            }
            acc[3 * half..3 * half + 3].copy_from_slice(&rows);
        }
        for i in 0..len {
            for (sum, coordinate) in bearing.iter_mut().zip(&coordinates) {
                *sum = _mm256_add_pd(
                    *sum,
                    _mm256_mul_pd(_mm256_broadcast_sd(&coordinate[i]), scales[i]),
                );
            }
        }
    }
    let mut rows = [[0.0; ROW]; 6];
    for (row, vectors) in rows.iter_mut().zip(&acc) {
        for (chunk, v) in row.chunks_exact_mut(4).zip(vectors) {
            // SAFETY: `chunk` holds four f64, the unaligned store writes exactly those.
            unsafe { _mm256_storeu_pd(chunk.as_mut_ptr(), *v) };
        }
    }
    let mut by_coordinate = [[0.0; 4]; 3];
    for (lanes, v) in by_coordinate.iter_mut().zip(&bearing) {
        // SAFETY: `lanes` holds four f64, the unaligned store writes exactly those.
        unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), *v) };
    }
    let bearing_sums: [[f64; 3]; 4] = core::array::from_fn(|a| {
        [
            by_coordinate[0][a],
            by_coordinate[1][a],
            by_coordinate[2][a],
        ]
    });
    NormalSums {
        rows,
        bearings: bearing_sums,
    }
}

/// The per-chunk arrays of [`accumulate_avx`]: product vectors, projector entries (by
/// entry), bearing coordinates (by coordinate) and `W weight`, by correspondence.
#[cfg(target_arch = "x86_64")]
struct Chunk<'a> {
    products: &'a mut [[core::arch::x86_64::__m256d; 3]; CHUNK],
    entries: &'a mut [[f64; CHUNK]; 6],
    coordinates: &'a mut [[f64; CHUNK]; 3],
    scales: &'a mut [core::arch::x86_64::__m256d; CHUNK],
}

/// The set-up of one chunk of [`accumulate_avx`] (whitening, projector entries, products),
/// four correspondences to a vector, one per lane; a 4 x 4 transpose turns the products into
/// the per-correspondence vectors of the sweeps. Kept out of line so that its constants do
/// not take the accumulators' registers in the sweeps.
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline(never)]
unsafe fn prepare_chunk<const SHORT: bool>(
    block_f: &[Vector3<f64>],
    block_x: &[Point3<f64>],
    frame: &WhitenedFrame,
    weights: &[f64; CHUNK],
    chunk: &mut Chunk<'_>,
) {
    use core::arch::x86_64::{
        _mm256_add_pd, _mm256_broadcast_sd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set_pd,
        _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd, _mm256_xor_pd,
    };
    let c = frame.centroid;
    let centre = [c.x, c.y, c.z].map(|v| _mm256_set1_pd(v));
    let mut axes = [[_mm256_setzero_pd(); 3]; 3];
    for (lanes, axis) in axes.iter_mut().zip(&frame.scaled_axes) {
        for (lane, v) in lanes.iter_mut().zip(axis.iter()) {
            *lane = _mm256_set1_pd(*v);
        }
    }
    let zero = _mm256_setzero_pd();
    let one = _mm256_set1_pd(1.0);
    // Flips the sign bit only: exact negation, as `-x` in the portable path.
    let sign = _mm256_set1_pd(-0.0);
    let len = if SHORT {
        block_f.len().min(block_x.len()).min(CHUNK)
    } else {
        CHUNK
    };
    let (block_f, block_x) = (&block_f[..len], &block_x[..len]);
    let last = len.saturating_sub(1);
    for base in (0..len).step_by(4) {
        // In a short chunk, lanes past the end repeat the last correspondence (with a stale
        // weight): computed, never summed.
        let index = if SHORT {
            [
                base,
                (base + 1).min(last),
                (base + 2).min(last),
                (base + 3).min(last),
            ]
        } else {
            [base, base + 1, base + 2, base + 3]
        };
        macro_rules! lanes {
            ($block:ident . $field:ident) => {
                _mm256_set_pd(
                    $block[index[3]].$field,
                    $block[index[2]].$field,
                    $block[index[1]].$field,
                    $block[index[0]].$field,
                )
            };
        }
        // Whitened coordinates w_k = (a_k0 lx + a_k1 ly) + a_k2 lz, as `whitened`.
        let local = [
            _mm256_sub_pd(lanes!(block_x.x), centre[0]),
            _mm256_sub_pd(lanes!(block_x.y), centre[1]),
            _mm256_sub_pd(lanes!(block_x.z), centre[2]),
        ];
        let mut w = [zero; 3];
        for (wk, a) in w.iter_mut().zip(&axes) {
            *wk = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(a[0], local[0]), _mm256_mul_pd(a[1], local[1])),
                _mm256_mul_pd(a[2], local[2]),
            );
        }
        // Projector entries, as `weighted_projector`.
        let (fx, fy, fz) = (lanes!(block_f.x), lanes!(block_f.y), lanes!(block_f.z));
        // SAFETY: `base + 4 <= CHUNK`: four f64 to read.
        let wt = unsafe { _mm256_loadu_pd(weights.as_ptr().add(base)) };
        let (minus_fx, minus_fy) = (_mm256_xor_pd(fx, sign), _mm256_xor_pd(fy, sign));
        let projector = [
            _mm256_mul_pd(_mm256_sub_pd(one, _mm256_mul_pd(fx, fx)), wt),
            _mm256_mul_pd(_mm256_mul_pd(minus_fx, fy), wt),
            _mm256_mul_pd(_mm256_mul_pd(minus_fx, fz), wt),
            _mm256_mul_pd(_mm256_sub_pd(one, _mm256_mul_pd(fy, fy)), wt),
            _mm256_mul_pd(_mm256_mul_pd(minus_fy, fz), wt),
            _mm256_mul_pd(_mm256_sub_pd(one, _mm256_mul_pd(fz, fz)), wt),
        ];
        for (row, v) in chunk.entries.iter_mut().zip(&projector) {
            // SAFETY: `base + 4 <= CHUNK`: four f64 to write.
            unsafe { _mm256_storeu_pd(row.as_mut_ptr().add(base), *v) };
        }
        for (row, v) in chunk.coordinates.iter_mut().zip([fx, fy, fz]) {
            // SAFETY: `base + 4 <= CHUNK`: four f64 to write.
            unsafe { _mm256_storeu_pd(row.as_mut_ptr().add(base), v) };
        }
        // The products by correspondence. Lanes low to high: (0,0) (0,1) (0,2) (0,3) |
        // (1,1) (1,2) (1,3) (2,2) | (2,3) (3,3) 0 0; w0 = 1, so the first four are W
        // itself (1 * w_b = w_b).
        let [w1, w2, w3] = w;
        let p0 = transpose(one, w1, w2, w3);
        let p1 = transpose(
            _mm256_mul_pd(w1, w1),
            _mm256_mul_pd(w1, w2),
            _mm256_mul_pd(w1, w3),
            _mm256_mul_pd(w2, w2),
        );
        let p2 = transpose(_mm256_mul_pd(w2, w3), _mm256_mul_pd(w3, w3), zero, zero);
        for lane in 0..4 {
            chunk.products[base + lane] = [p0[lane], p1[lane], p2[lane]];
            // Lane a: w_a * weight.
            chunk.scales[base + lane] =
                _mm256_mul_pd(p0[lane], _mm256_broadcast_sd(&weights[base + lane]));
        }
    }
}

/// The 4 x 4 transpose: lane `l` of result `k` is lane `k` of argument `l`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
#[inline]
fn transpose(
    r0: core::arch::x86_64::__m256d,
    r1: core::arch::x86_64::__m256d,
    r2: core::arch::x86_64::__m256d,
    r3: core::arch::x86_64::__m256d,
) -> [core::arch::x86_64::__m256d; 4] {
    use core::arch::x86_64::{_mm256_permute2f128_pd, _mm256_unpackhi_pd, _mm256_unpacklo_pd};
    // (r0_0, r1_0, r0_2, r1_2), (r0_1, r1_1, r0_3, r1_3), and the same of r2, r3.
    let t0 = _mm256_unpacklo_pd(r0, r1);
    let t1 = _mm256_unpackhi_pd(r0, r1);
    let t2 = _mm256_unpacklo_pd(r2, r3);
    let t3 = _mm256_unpackhi_pd(r2, r3);
    [
        _mm256_permute2f128_pd::<0x20>(t0, t2),
        _mm256_permute2f128_pd::<0x20>(t1, t3),
        _mm256_permute2f128_pd::<0x31>(t0, t2),
        _mm256_permute2f128_pd::<0x31>(t1, t3),
    ]
}

/// Correspondences per chunk of the AVX sums (a multiple of the four lanes): 3.3 KB of stack;
/// reloading the accumulators costs little per sixteen. Sixteen rather than eight also keeps
/// the compiler from unrolling the sweeps completely, which would spill their accumulators.
#[cfg(target_arch = "x86_64")]
const CHUNK: usize = 16;

/// `scale / |R X + t|^2`, written out (nalgebra's generic product does not unroll here).
#[inline(always)]
fn depth_weight(weighting: &DepthWeighting<'_>, x: &Point3<f64>) -> f64 {
    let (r, t, scale) = *weighting;
    let [px, py, pz] = transform(r, t, x);
    scale / (px * px + py * py + pz * pz)
}

/// The whitened coordinates `(w1, w2, w3)` of `x` (`w0 = 1`), with the axes as plain arrays
/// (nalgebra's generic dot products do not unroll in these loops). The AVX path evaluates the
/// same expression, in the same order, four correspondences at a time.
#[inline(always)]
fn whitened(c: &Vector3<f64>, axes: &[[f64; 3]; 3], x: &Point3<f64>) -> [f64; 3] {
    let (lx, ly, lz) = (x.x - c.x, x.y - c.y, x.z - c.z);
    axes.map(|a| a[0] * lx + a[1] * ly + a[2] * lz)
}

/// The six distinct entries (`xx, xy, xz, yy, yz, zz`) of `weight (I - f f^T)`. The AVX path
/// evaluates the same expressions, in the same order, four correspondences at a time.
#[inline(always)]
fn weighted_projector(f: &Vector3<f64>, weight: f64) -> [f64; 6] {
    let (fx, fy, fz) = (f.x, f.y, f.z);
    [
        (1.0 - fx * fx) * weight,
        -fx * fy * weight,
        -fx * fz * weight,
        (1.0 - fy * fy) * weight,
        -fy * fz * weight,
        (1.0 - fz * fz) * weight,
    ]
}

/// The sums in plain scalar code: the reference the AVX path must match bit for bit.
fn accumulate_portable(
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
    frame: &WhitenedFrame,
    weight: impl Fn(&Point3<f64>) -> f64,
) -> NormalSums {
    let mut rows = [[0.0; ROW]; 6];
    let mut bearing_sums = [[0.0; 3]; 4];
    let c = frame.centroid;
    let axes = frame.scaled_axes.map(|a| [a.x, a.y, a.z]);
    for (f, x) in bearings.iter().zip(points) {
        let weight = weight(x);
        let [w1, w2, w3] = whitened(&c, &axes, x);
        let w = [1.0, w1, w2, w3];
        let mut products = [0.0; ROW];
        for (p, &(a, b)) in products.iter_mut().zip(&PRODUCTS) {
            *p = w[a] * w[b];
        }
        let projector = weighted_projector(f, weight);
        for (row, entry) in rows.iter_mut().zip(&projector) {
            for (s, p) in row.iter_mut().zip(&products) {
                *s += p * entry;
            }
        }
        for (sum, wa) in bearing_sums.iter_mut().zip(&w) {
            let scale = wa * weight;
            sum[0] += f.x * scale;
            sum[1] += f.y * scale;
            sum[2] += f.z * scale;
        }
    }
    NormalSums {
        rows,
        bearings: bearing_sums,
    }
}

/// Sum over all correspondences of the squared chord error of a pose,
/// `|p / |p| - f|^2 = 2 - 2 cos(angle)` with `p = R X + t` (4 for a point at the centre, NaN
/// for a non-finite pose, so a broken pose never scores well).
pub(crate) fn total_chord_error(
    rotation: &Matrix3<f64>,
    translation: &Vector3<f64>,
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX, checked just above.
        return unsafe { chord_error_avx(rotation, translation, bearings, points) };
    }
    chord_error_portable(rotation, translation, bearings, points)
}

/// `R X + t`, each coordinate summed left to right (both paths use this order).
#[inline(always)]
fn transform(r: &Matrix3<f64>, t: &Vector3<f64>, x: &Point3<f64>) -> [f64; 3] {
    [
        r[(0, 0)] * x.x + r[(0, 1)] * x.y + r[(0, 2)] * x.z + t.x,
        r[(1, 0)] * x.x + r[(1, 1)] * x.y + r[(1, 2)] * x.z + t.y,
        r[(2, 0)] * x.x + r[(2, 1)] * x.y + r[(2, 2)] * x.z + t.z,
    ]
}

/// The squared chord of one correspondence, as the AVX lanes compute it: one division for
/// the reciprocal norm (within an ulp of three quotients).
#[inline(always)]
fn chord(f: &Vector3<f64>, p: [f64; 3]) -> f64 {
    let norm = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let inverse = 1.0 / norm;
    let (dx, dy, dz) = (
        p[0] * inverse - f.x,
        p[1] * inverse - f.y,
        p[2] * inverse - f.z,
    );
    let chord = dx * dx + dy * dy + dz * dz;
    if norm == 0.0 { 4.0 } else { chord }
}

fn chord_error_portable(
    rotation: &Matrix3<f64>,
    translation: &Vector3<f64>,
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
) -> f64 {
    let mut sum = 0.0;
    for (f, x) in bearings.iter().zip(points) {
        sum += chord(f, transform(rotation, translation, x));
    }
    sum
}

/// [`chord_error_portable`] four correspondences at a time, the lanes added to the sum in
/// order.
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn chord_error_avx(
    rotation: &Matrix3<f64>,
    translation: &Vector3<f64>,
    bearings: &[Vector3<f64>],
    points: &[Point3<f64>],
) -> f64 {
    use core::arch::x86_64::{
        __m256d, _CMP_EQ_OQ, _mm256_add_pd, _mm256_blendv_pd, _mm256_cmp_pd, _mm256_div_pd,
        _mm256_mul_pd, _mm256_set_pd, _mm256_set1_pd, _mm256_setzero_pd, _mm256_sqrt_pd,
        _mm256_storeu_pd, _mm256_sub_pd,
    };
    let r = |i: usize, j: usize| _mm256_set1_pd(rotation[(i, j)]);
    let rows = [
        [r(0, 0), r(0, 1), r(0, 2)],
        [r(1, 0), r(1, 1), r(1, 2)],
        [r(2, 0), r(2, 1), r(2, 2)],
    ];
    let t = [
        _mm256_set1_pd(translation.x),
        _mm256_set1_pd(translation.y),
        _mm256_set1_pd(translation.z),
    ];
    let one = _mm256_set1_pd(1.0);
    let four = _mm256_set1_pd(4.0);
    let zero = _mm256_setzero_pd();
    let lanes = |v: [f64; 12], k: usize| _mm256_set_pd(v[9 + k], v[6 + k], v[3 + k], v[k]);
    let mut sum = 0.0;
    let mut quads_f = bearings.chunks_exact(4);
    let mut quads_x = points.chunks_exact(4);
    for (fq, xq) in (&mut quads_f).zip(&mut quads_x) {
        // Coordinates of the four as lanes.
        let xs: [f64; 12] = core::array::from_fn(|i| xq[i / 3][i % 3]);
        let fs: [f64; 12] = core::array::from_fn(|i| fq[i / 3][i % 3]);
        let x = [lanes(xs, 0), lanes(xs, 1), lanes(xs, 2)];
        let p: [__m256d; 3] = core::array::from_fn(|i| {
            let row = &rows[i];
            let sum = _mm256_add_pd(_mm256_mul_pd(row[0], x[0]), _mm256_mul_pd(row[1], x[1]));
            _mm256_add_pd(_mm256_add_pd(sum, _mm256_mul_pd(row[2], x[2])), t[i])
        });
        let squared = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(p[0], p[0]), _mm256_mul_pd(p[1], p[1])),
            _mm256_mul_pd(p[2], p[2]),
        );
        let norm = _mm256_sqrt_pd(squared);
        let inverse = _mm256_div_pd(one, norm);
        let d: [__m256d; 3] =
            core::array::from_fn(|i| _mm256_sub_pd(_mm256_mul_pd(p[i], inverse), lanes(fs, i)));
        let chords = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(d[0], d[0]), _mm256_mul_pd(d[1], d[1])),
            _mm256_mul_pd(d[2], d[2]),
        );
        let chords = _mm256_blendv_pd(chords, four, _mm256_cmp_pd::<_CMP_EQ_OQ>(norm, zero));
        let mut out = [0.0; 4];
        // SAFETY: `out` holds four f64, the unaligned store writes exactly those.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), chords) };
        for c in out {
            sum += c;
        }
    }
    for (f, x) in quads_f.remainder().iter().zip(quads_x.remainder()) {
        sum += chord(f, transform(rotation, translation, x));
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Every compiled path gives exactly the portable path's bearing error, also with points
    /// at the centre and non-finite poses.
    #[test]
    fn avx_and_portable_chord_errors_are_bit_identical() {
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for n in [1usize, 4, 7, 100] {
            let bearings: Vec<Vector3<f64>> = (0..n)
                .map(|_| Vector3::from_fn(|_, _| rng.random_range(-1.0..1.0)).normalize())
                .collect();
            let mut points: Vec<Point3<f64>> = (0..n)
                .map(|_| Point3::from(Vector3::from_fn(|_, _| rng.random_range(-3.0..3.0))))
                .collect();
            let rotation = nalgebra::Rotation3::new(Vector3::new(0.3, -0.2, 0.1)).into_inner();
            let translation = Vector3::new(0.5, 0.0, 4.0);
            // A point mapped to the centre scores 4.
            points[0] = Point3::from(-(rotation.transpose() * translation));
            let reference = chord_error_portable(&rotation, &translation, &bearings, &points);
            assert_eq!(
                reference,
                total_chord_error(&rotation, &translation, &bearings, &points)
            );
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx") {
                // SAFETY: AVX is supported (checked).
                let avx = unsafe { chord_error_avx(&rotation, &translation, &bearings, &points) };
                assert_eq!(reference, avx);
                let broken = Vector3::new(f64::NAN, 0.0, 0.0);
                // SAFETY: AVX is supported (checked).
                let nan = unsafe { chord_error_avx(&rotation, &broken, &bearings, &points) };
                assert!(nan.is_nan());
            }
        }
    }

    /// Every compiled path gives exactly the portable path's sums.
    #[test]
    fn avx_and_portable_sums_are_bit_identical() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for n in [4usize, 7, 16, 17, 100] {
            let bearings: Vec<Vector3<f64>> = (0..n)
                .map(|_| {
                    Vector3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        1.0,
                    )
                    .normalize()
                })
                .collect();
            let points: Vec<Point3<f64>> = (0..n)
                .map(|_| Point3::from(Vector3::from_fn(|_, _| rng.random_range(-3.0..3.0))))
                .collect();
            let frame = WhitenedFrame {
                centroid: Vector3::new(0.1, -0.2, 0.3),
                scaled_axes: [
                    Vector3::new(0.5, 0.1, 0.0),
                    Vector3::y(),
                    Vector3::z() * 2.0,
                ],
            };
            let rotation = Matrix3::identity();
            let translation = Vector3::new(0.0, 0.0, 10.0);
            for weighting in [None, Some((&rotation, &translation, 49.0))] {
                let weight = |x: &Point3<f64>| weighting.map_or(1.0, |w| depth_weight(&w, x));
                let reference = accumulate_portable(&bearings, &points, &frame, weight);
                let dispatched = NormalSums::accumulate(&bearings, &points, &frame, weighting);
                assert_eq!(reference.rows, dispatched.rows);
                assert_eq!(reference.bearings, dispatched.bearings);
                #[cfg(target_arch = "x86_64")]
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: AVX is supported (checked).
                    let avx = unsafe { accumulate_avx(&bearings, &points, &frame, weight) };
                    assert_eq!(reference.rows, avx.rows);
                    assert_eq!(reference.bearings, avx.bearings);
                }
            }
        }
    }
}
