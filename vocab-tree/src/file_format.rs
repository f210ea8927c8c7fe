//! The vocabulary file format (version 1). All integers and floats are little-endian.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 8 | magic `IBCVOCAB` |
//! | 8 | 4 | format version, `u32` = 1 |
//! | 12 | 1 | descriptor kind: 1 binary (`u64` words), 2 float (`f32`) |
//! | 13 | 1 | weighting, DBoW2's code (0 TF-IDF, 1 TF, 2 IDF, 3 binary) |
//! | 14 | 1 | scoring, DBoW2's code (0 L1, 1 L2, 2 χ², 3 KL, 4 Bhattacharyya, 5 dot product) |
//! | 15 | 1 | reserved, 0 |
//! | 16 | 4 | descriptor width `W` (`u64` words or `f32` values), `u32` |
//! | 20 | 4 | branching `k`, `u32` |
//! | 24 | 4 | depth `L`, `u32` |
//! | 28 | 4 | node count `n` (root included), `u32` |
//! | 32 | 4 | word count `w`, `u32` |
//! | 36 | 4 | reserved, 0 |
//! | 40 | `4 (n + 1)` | `child_start`, `u32` |
//! | … | `4 n` | `node_word`: the word of each leaf, `0xFFFF_FFFF` for internal nodes, `u32` |
//! | … | `4 w` | word weights (IDF), `f32` |
//! | … | `n W e` | centroids in node order (`e` = 8 binary, 4 float) |
//! | end − 8 | 8 | XXH64 (seed 0) of every byte before it, `u64` |
//!
//! Loading checks, in order: magic, version, header codes, descriptor kind and width against
//! the type asked for, the exact length, the checksum, and then the whole tree (every child
//! index in range and after its parent, depths, words on leaves, finite weights and
//! centroids) before any traversal. The file is streamed through a small buffer straight into
//! the final arrays (hashed on the way): one allocation per array, none per node, no copy of
//! the whole file. Files are written atomically (a temporary file in the same folder, then a
//! rename).

use std::io::Read;
use std::path::Path;

use ibc_camera_models::io::{IoError, open_regular, write_atomically};

use crate::descriptor::{Descriptor, DescriptorKind};
use crate::error::{Result, VocabError, VocabFileError};
use crate::scoring::Scoring;
use crate::vocabulary::{Vocabulary, check_tree};
use crate::weighting::Weighting;
use xxhash_rust::xxh64::Xxh64;

/// The magic bytes that open a vocabulary file.
pub const MAGIC: [u8; 8] = *b"IBCVOCAB";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;
const HEADER_LEN: usize = 40;
const CHECKSUM_LEN: usize = 8;
/// Bytes read at a time while loading (fits the L2 cache, so hashing and decoding read it
/// hot).
const READ_CHUNK: usize = 256 * 1024;

/// The checksum stored in the last 8 bytes of a file: XXH64 with seed 0 of every byte before
/// it (the value `xxhsum -H64` prints for the file without its last 8 bytes).
pub fn checksum(body: &[u8]) -> u64 {
    xxhash_rust::xxh64::xxh64(body, 0)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn io_error(path: &Path, source: std::io::Error) -> VocabError {
    IoError::os(path, source).into()
}

/// Streams the file body through a small buffer, hashing every byte read.
struct Reader<R> {
    inner: R,
    hash: Xxh64,
    buffer: Vec<u8>,
    path: std::path::PathBuf,
}

impl<R: Read> Reader<R> {
    /// Reads `count` items of `size` bytes, decoding each with `decode`, into one vector.
    fn array<T>(
        &mut self,
        count: usize,
        size: usize,
        decode: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>> {
        let mut out = Vec::with_capacity(count);
        let per_chunk = (READ_CHUNK / size.max(1)).max(1);
        let mut left = count;
        while left > 0 {
            let items = left.min(per_chunk);
            let bytes = &mut self.buffer[..items * size];
            self.inner
                .read_exact(bytes)
                .map_err(|e| io_error(&self.path, e))?;
            self.hash.update(bytes);
            out.extend(bytes.chunks_exact(size.max(1)).map(&decode));
            left -= items;
        }
        Ok(out)
    }
}

fn decode_u32(c: &[u8]) -> u32 {
    u32::from_le_bytes([c[0], c[1], c[2], c[3]])
}

fn decode_f32(c: &[u8]) -> f32 {
    f32::from_le_bytes([c[0], c[1], c[2], c[3]])
}

impl<D: Descriptor> Vocabulary<D> {
    /// The vocabulary in the file format (see the [module docs](crate::file_format)).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.centroids.len();
        let w = self.word_weights.len();
        let len = HEADER_LEN
            + 4 * (n + 1)
            + 4 * n
            + 4 * w
            + n * D::WIDTH * D::ELEMENT_BYTES
            + CHECKSUM_LEN;
        let mut out = Vec::with_capacity(len);
        out.extend_from_slice(&MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&[
            D::KIND.code(),
            self.weighting.code(),
            self.scoring.code(),
            0,
        ]);
        for x in [
            D::WIDTH as u32,
            self.branching,
            self.depth,
            n as u32,
            w as u32,
            0,
        ] {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for x in self.child_start.iter().chain(&self.node_word) {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for x in &self.word_weights {
            out.extend_from_slice(&x.to_le_bytes());
        }
        for c in &self.centroids {
            c.write_le(&mut out);
        }
        let sum = checksum(&out);
        out.extend_from_slice(&sum.to_le_bytes());
        out
    }

    /// Reads a vocabulary from the bytes of a file, checking everything (see the
    /// [module docs](crate::file_format)); every kind of damage is a typed
    /// [`VocabFileError`] or an [`VocabError::InvalidTree`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        Self::read_from(bytes, bytes.len() as u64, Path::new("<bytes>"))
    }

    /// Reads a vocabulary from `source`, which holds exactly `len` bytes.
    fn read_from(mut source: impl Read, len: u64, path: &Path) -> Result<Self> {
        let mut header = [0u8; HEADER_LEN];
        let got = read_up_to(&mut source, &mut header).map_err(|e| io_error(path, e))?;
        if got < MAGIC.len() || header[..MAGIC.len()] != MAGIC {
            return Err(VocabFileError::BadMagic.into());
        }
        if got < HEADER_LEN {
            return Err(VocabFileError::Truncated {
                expected: (HEADER_LEN + CHECKSUM_LEN) as u64,
                found: len,
            }
            .into());
        }
        let version = u32_at(&header, 8);
        if version != FORMAT_VERSION {
            return Err(VocabFileError::UnsupportedVersion {
                found: version,
                supported: FORMAT_VERSION,
            }
            .into());
        }
        let field =
            |field: &'static str, value: u64| VocabFileError::InvalidHeader { field, value };
        let kind = DescriptorKind::from_code(header[12])
            .ok_or_else(|| field("descriptor kind", header[12].into()))?;
        let weighting = Weighting::from_code(header[13])
            .ok_or_else(|| field("weighting", header[13].into()))?;
        let scoring =
            Scoring::from_code(header[14]).ok_or_else(|| field("scoring", header[14].into()))?;
        if header[15] != 0 {
            return Err(field("reserved byte 15", header[15].into()).into());
        }
        let width = u32_at(&header, 16);
        let (branching, depth) = (u32_at(&header, 20), u32_at(&header, 24));
        let (n, w) = (u32_at(&header, 28), u32_at(&header, 32));
        if u32_at(&header, 36) != 0 {
            return Err(field("reserved word 36", u32_at(&header, 36).into()).into());
        }
        if kind != D::KIND || width as usize != D::WIDTH {
            return Err(VocabFileError::DescriptorMismatch {
                expected_kind: D::KIND,
                expected_width: D::WIDTH as u32,
                found_kind: kind,
                found_width: width,
            }
            .into());
        }
        let desc_bytes = D::WIDTH * D::ELEMENT_BYTES;
        let (n64, w64) = (u64::from(n), u64::from(w));
        let expected = (HEADER_LEN + CHECKSUM_LEN) as u64
            + 4 * (n64 + 1)
            + 4 * n64
            + 4 * w64
            + n64 * desc_bytes as u64;
        if len < expected {
            return Err(VocabFileError::Truncated {
                expected,
                found: len,
            }
            .into());
        }
        if len > expected {
            return Err(VocabFileError::TrailingBytes {
                extra: len - expected,
            }
            .into());
        }
        let mut hash = Xxh64::new(0);
        hash.update(&header);
        let mut reader = Reader {
            inner: source,
            hash,
            buffer: vec![0u8; READ_CHUNK.max(desc_bytes)],
            path: path.to_path_buf(),
        };
        let (n, w) = (n as usize, w as usize);
        let child_start = reader.array(n + 1, 4, decode_u32)?;
        let node_word = reader.array(n, 4, decode_u32)?;
        let word_weights = reader.array(w, 4, decode_f32)?;
        let centroids = reader.array(n, desc_bytes, D::read_le)?;
        let mut stored = [0u8; CHECKSUM_LEN];
        reader
            .inner
            .read_exact(&mut stored)
            .map_err(|e| io_error(path, e))?;
        let stored = u64::from_le_bytes(stored);
        let computed = reader.hash.digest();
        if stored != computed {
            return Err(VocabFileError::ChecksumMismatch { stored, computed }.into());
        }
        check_tree(branching, depth, &child_start, n)?;
        Self::from_checked_tree(
            branching,
            depth,
            weighting,
            scoring,
            child_start,
            centroids,
            node_word,
            word_weights,
        )
    }

    /// Writes the vocabulary to `path` atomically (a temporary file in the same folder, then a
    /// rename), so a reader never sees a half-written file.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        Ok(write_atomically(path.as_ref(), &self.to_bytes())?)
    }

    /// Reads a vocabulary written by [`save`](Self::save) (see
    /// [`from_bytes`](Self::from_bytes) for the checks).
    ///
    /// Only regular files are read (a FIFO would block, a device never end); an invalid file's
    /// error names it ([`VocabError::InvalidFile`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let (file, len) = open_regular(path)?;
        Self::read_from(file, len, path).map_err(|e| e.in_file(path))
    }
}

/// Reads until `buf` is full or the source ends; returns the bytes read.
fn read_up_to(source: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match source.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

#[cfg(test)]
mod checksum_tests {
    use super::checksum;

    /// The documented checksum is XXH64 with seed 0: reference digests of the reference C
    /// implementation (`xxhsum -H1`), as reproduced by python-xxhash.
    #[test]
    fn checksum_is_the_reference_xxh64() {
        let long: Vec<u8> = (0..768).map(|i| (i % 256) as u8).collect();
        let cases: [(&[u8], u64); 4] = [
            (b"", 0xef46_db37_51d8_e999),
            (b"abc", 0x44bc_2cf5_ad77_0999),
            (&long, 0x8e03_c838_c596_036f),
            (b"0123456789abcdef0123456789abcdef!", 0x8aff_f4da_ac4e_677e),
        ];
        for (data, expected) in cases {
            assert_eq!(checksum(data), expected, "input of {} bytes", data.len());
        }
    }
}
