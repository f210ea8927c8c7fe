//! XXH64, the 64-bit xxHash (Yann Collet, "xxHash fast digest algorithm", specification
//! v0.1.1), used as the checksum of vocabulary files: fast enough (several GB/s) that checking
//! a million-word vocabulary costs a few milliseconds, and checkable with `xxhsum -H1`.

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;
const P4: u64 = 0x85EB_CA77_C2B2_AE63;
const P5: u64 = 0x27D4_EB2F_1656_67C5;

#[inline(always)]
fn read64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

#[inline(always)]
fn round(acc: u64, lane: u64) -> u64 {
    acc.wrapping_add(lane.wrapping_mul(P2))
        .rotate_left(31)
        .wrapping_mul(P1)
}

#[inline(always)]
fn merge(acc: u64, v: u64) -> u64 {
    (acc ^ round(0, v)).wrapping_mul(P1).wrapping_add(P4)
}

/// A streaming XXH64 state: feed bytes in any pieces, the digest is the same.
#[derive(Clone)]
pub(crate) struct Xxh64 {
    seed: u64,
    lanes: [u64; 4],
    total: u64,
    buffer: [u8; 32],
    buffered: usize,
}

impl Xxh64 {
    pub(crate) fn new(seed: u64) -> Self {
        Self {
            seed,
            lanes: [
                seed.wrapping_add(P1).wrapping_add(P2),
                seed.wrapping_add(P2),
                seed,
                seed.wrapping_sub(P1),
            ],
            total: 0,
            buffer: [0; 32],
            buffered: 0,
        }
    }

    #[inline(always)]
    fn stripe(&mut self, s: &[u8]) {
        for (i, lane) in self.lanes.iter_mut().enumerate() {
            *lane = round(*lane, read64(&s[8 * i..]));
        }
    }

    pub(crate) fn update(&mut self, mut data: &[u8]) {
        self.total += data.len() as u64;
        if self.buffered > 0 {
            let take = (32 - self.buffered).min(data.len());
            self.buffer[self.buffered..self.buffered + take].copy_from_slice(&data[..take]);
            self.buffered += take;
            data = &data[take..];
            if self.buffered < 32 {
                return;
            }
            let b = self.buffer;
            self.stripe(&b);
            self.buffered = 0;
        }
        let stripes = data.chunks_exact(32);
        let rest = stripes.remainder();
        for s in stripes {
            self.stripe(s);
        }
        self.buffer[..rest.len()].copy_from_slice(rest);
        self.buffered = rest.len();
    }

    pub(crate) fn digest(&self) -> u64 {
        let mut h = if self.total >= 32 {
            let v = self.lanes;
            let mut h = v[0]
                .rotate_left(1)
                .wrapping_add(v[1].rotate_left(7))
                .wrapping_add(v[2].rotate_left(12))
                .wrapping_add(v[3].rotate_left(18));
            for lane in v {
                h = merge(h, lane);
            }
            h
        } else {
            self.seed.wrapping_add(P5)
        };
        h = h.wrapping_add(self.total);
        let mut words = self.buffer[..self.buffered].chunks_exact(8);
        for w in &mut words {
            h ^= round(0, read64(w));
            h = h.rotate_left(27).wrapping_mul(P1).wrapping_add(P4);
        }
        let mut rest = words.remainder();
        if rest.len() >= 4 {
            let x = u32::from_le_bytes([rest[0], rest[1], rest[2], rest[3]]);
            h ^= u64::from(x).wrapping_mul(P1);
            h = h.rotate_left(23).wrapping_mul(P2).wrapping_add(P3);
            rest = &rest[4..];
        }
        for &b in rest {
            h ^= u64::from(b).wrapping_mul(P5);
            h = h.rotate_left(11).wrapping_mul(P1);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^= h >> 29;
        h = h.wrapping_mul(P3);
        h ^ (h >> 32)
    }
}

/// The XXH64 digest of `data` with `seed`.
pub(crate) fn xxh64(data: &[u8], seed: u64) -> u64 {
    let mut h = Xxh64::new(seed);
    h.update(data);
    h.digest()
}

#[cfg(test)]
mod tests {
    use super::{Xxh64, xxh64};

    /// Reference digests computed with the `xxhash` Python package (python-xxhash 3.x, which
    /// wraps the reference C implementation).
    #[test]
    fn matches_reference_digests() {
        let long: Vec<u8> = (0..768).map(|i| (i % 256) as u8).collect();
        let cases: [(&[u8], u64, u64); 6] = [
            (b"", 0, 0xef46_db37_51d8_e999),
            (b"a", 0, 0xd24e_c4f1_a98c_6e5b),
            (b"abc", 0, 0x44bc_2cf5_ad77_0999),
            (&long, 0, 0x8e03_c838_c596_036f),
            (
                b"0123456789abcdef0123456789abcdef!",
                0,
                0x8aff_f4da_ac4e_677e,
            ),
            (b"abc", 0x9E37_79B1_85EB_CA87, 0xa7cb_2aac_405e_36c7),
        ];
        for (data, seed, expected) in cases {
            assert_eq!(xxh64(data, seed), expected, "input of {} bytes", data.len());
        }
    }

    /// Feeding the bytes in pieces of any sizes gives the one-shot digest.
    #[test]
    fn streaming_equals_one_shot() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let whole = xxh64(&data, 0);
        for piece in [1, 3, 8, 31, 32, 33, 100, 999] {
            let mut h = Xxh64::new(0);
            for chunk in data.chunks(piece) {
                h.update(chunk);
            }
            assert_eq!(h.digest(), whole, "pieces of {piece} bytes");
        }
    }
}
