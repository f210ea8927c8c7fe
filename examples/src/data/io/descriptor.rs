//! How descriptors are stored in map and rig-log files: as `ibc-vocab-tree` stores them in
//! vocabularies ([`Descriptor::write_le`], [`Descriptor::read_le`]): binary descriptors as
//! little-endian `u64` words, float descriptors as little-endian IEEE-754 `f32` values, with
//! the kind ([`DescriptorKind::code`](ibc_vocab_tree::DescriptorKind::code)) and the width
//! recorded in the file header.

use ibc_vocab_tree::Descriptor;

use super::error::DescriptorLayout;

/// The layout that file headers record for descriptors of type `D`.
pub fn descriptor_layout<D: Descriptor>() -> DescriptorLayout {
    DescriptorLayout {
        kind: D::KIND,
        // Widths are small constants (4, 64, 128); a width past u32 is not a descriptor.
        width: u32::try_from(D::WIDTH).unwrap_or(u32::MAX),
    }
}
