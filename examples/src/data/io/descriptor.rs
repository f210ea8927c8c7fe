//! How descriptors are stored in map and rig-log files: binary descriptors as little-endian
//! `u64` words, float descriptors as little-endian IEEE-754 `f32` values, with the kind and
//! the width recorded in the file header.

use ibc_vocab_tree::DescriptorKind;

use super::error::DescriptorLayout;

mod sealed {
    /// Only `[u64; W]` and `[f32; D]` are file descriptors.
    pub trait Sealed {}
    impl<const W: usize> Sealed for [u64; W] {}
    impl<const D: usize> Sealed for [f32; D] {}
}

/// A descriptor type that map and rig-log files can hold: binary `[u64; W]` (ORB and
/// BRIEF-256 are `[u64; 4]`) or float `[f32; D]` (SURF-64 is `[f32; 64]`). Sealed: the file
/// format knows exactly these two families, as the vocabulary tree does.
pub trait FileDescriptor: sealed::Sealed + Copy + Send + Sync + 'static {
    /// Binary or float.
    const KIND: DescriptorKind;
    /// Number of elements (`u64` words or `f32` values).
    const WIDTH: usize;
    /// Bytes of one element (8 or 4).
    const ELEMENT_BYTES: usize;

    /// Bytes of one descriptor in a file.
    const BYTES: usize = Self::WIDTH * Self::ELEMENT_BYTES;

    /// Appends the descriptor's little-endian bytes.
    fn write_le(&self, out: &mut Vec<u8>);

    /// The descriptor in `bytes`, which holds exactly [`BYTES`](Self::BYTES) bytes (callers
    /// slice them; a shorter slice reads as zeros).
    fn read_le(bytes: &[u8]) -> Self;

    /// True when every element is finite (always for binary descriptors).
    fn is_finite(&self) -> bool;

    /// The layout recorded in file headers.
    fn layout() -> DescriptorLayout {
        DescriptorLayout {
            kind: Self::KIND,
            // Widths are small constants (4, 64, 128); a width past u32 is not a descriptor.
            width: u32::try_from(Self::WIDTH).unwrap_or(u32::MAX),
        }
    }
}

impl<const W: usize> FileDescriptor for [u64; W] {
    const KIND: DescriptorKind = DescriptorKind::Binary;
    const WIDTH: usize = W;
    const ELEMENT_BYTES: usize = 8;

    fn write_le(&self, out: &mut Vec<u8>) {
        for w in self {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }

    fn read_le(bytes: &[u8]) -> Self {
        let mut d = [0u64; W];
        for (w, chunk) in d.iter_mut().zip(bytes.chunks_exact(8)) {
            let mut a = [0u8; 8];
            a.copy_from_slice(chunk);
            *w = u64::from_le_bytes(a);
        }
        d
    }

    fn is_finite(&self) -> bool {
        true
    }
}

impl<const D: usize> FileDescriptor for [f32; D] {
    const KIND: DescriptorKind = DescriptorKind::Float;
    const WIDTH: usize = D;
    const ELEMENT_BYTES: usize = 4;

    fn write_le(&self, out: &mut Vec<u8>) {
        for v in self {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }

    fn read_le(bytes: &[u8]) -> Self {
        let mut d = [0f32; D];
        for (v, chunk) in d.iter_mut().zip(bytes.chunks_exact(4)) {
            *v = f32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        }
        d
    }

    fn is_finite(&self) -> bool {
        self.iter().all(|v| v.is_finite())
    }
}

/// The header code of a descriptor kind (the vocabulary file's codes).
pub(crate) fn kind_code(kind: DescriptorKind) -> u8 {
    match kind {
        DescriptorKind::Binary => 1,
        DescriptorKind::Float => 2,
    }
}

/// The descriptor kind of a header code.
pub(crate) fn kind_from_code(code: u8) -> Option<DescriptorKind> {
    match code {
        1 => Some(DescriptorKind::Binary),
        2 => Some(DescriptorKind::Float),
        _ => None,
    }
}
