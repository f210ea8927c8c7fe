//! XXH64, the 64-bit xxHash (Yann Collet, "xxHash fast digest algorithm", specification
//! v0.1.1), the checksum of map and rig-log files: several GB/s, so checking a 100 MB log
//! costs a few tens of milliseconds, and a user can check a file with `xxhsum -H1` (over every
//! byte but the last eight).

/// The XXH64 digest (seed 0) of `data`: the checksum stored in the last eight bytes of map and
/// rig-log files, over every byte before it (what `xxhsum -H1`, or python-xxhash's
/// `xxh64_intdigest`, gives for the file without its last eight bytes).
pub fn xxh64(data: &[u8]) -> u64 {
    xxhash_rust::xxh64::xxh64(data, 0)
}

#[cfg(test)]
mod tests {
    use super::xxh64;

    /// Reference digests of the reference C implementation (`xxhsum -H1`, seed 0), as
    /// published with xxHash's test vectors and reproduced by python-xxhash.
    #[test]
    fn matches_reference_digests() {
        let long: Vec<u8> = (0..768).map(|i| (i % 256) as u8).collect();
        let cases: [(&[u8], u64); 5] = [
            (b"", 0xef46_db37_51d8_e999),
            (b"a", 0xd24e_c4f1_a98c_6e5b),
            (b"abc", 0x44bc_2cf5_ad77_0999),
            (&long, 0x8e03_c838_c596_036f),
            (b"0123456789abcdef0123456789abcdef!", 0x8aff_f4da_ac4e_677e),
        ];
        for (data, expected) in cases {
            assert_eq!(xxh64(data), expected, "input of {} bytes", data.len());
        }
    }
}
