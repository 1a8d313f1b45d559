//! Child references: the word a wide node keeps per child, saying whether the slot is empty,
//! a node, a leaf of packed triangle blocks or a range leaf, and where that child is.

/// Set on a child reference that is a leaf.
pub(super) const LEAF_BIT: u32 = 1 << 31;
/// Set, with [`LEAF_BIT`], on a leaf of packed triangles ([`super::Tri4`] blocks).
pub(super) const PACKED_BIT: u32 = 1 << 30;
/// Bits of a packed leaf reference that hold its first block.
pub(super) const BLOCK_BITS: u32 = 26;
/// Most blocks one packed leaf holds (4 bits of count - 1); larger leaves use ranges.
pub(super) const MAX_BLOCKS: u32 = 16;

/// The reference to a packed leaf of blocks `first..first + count` in [`super::WideBvh::blocks`]
/// (`count` in `1..=MAX_BLOCKS`, `first` below `2^BLOCK_BITS`); [`packed_blocks`] reads it.
#[inline]
pub(super) fn packed_ref(first: u32, count: u32) -> u32 {
    debug_assert!((1..=MAX_BLOCKS).contains(&count) && first < 1 << BLOCK_BITS);
    LEAF_BIT | PACKED_BIT | ((count - 1) << BLOCK_BITS) | first
}

/// The first block of a packed leaf reference (the reference's low bits, whatever else it is).
#[inline(always)]
pub(super) fn first_block(child: u32) -> usize {
    (child & ((1 << BLOCK_BITS) - 1)) as usize
}

/// The blocks of a packed leaf reference: `first..first + count` in [`super::WideBvh::blocks`].
#[inline(always)]
pub(super) fn packed_blocks(child: u32) -> std::ops::Range<usize> {
    let first = first_block(child);
    first..first + ((child >> BLOCK_BITS) & 0xf) as usize + 1
}

/// The reference to range leaf `index` of [`super::WideBvh::ranges`]; [`range_index`] reads it.
#[inline]
pub(super) fn range_ref(index: u32) -> u32 {
    debug_assert!(index & (LEAF_BIT | PACKED_BIT) == 0);
    LEAF_BIT | index
}

/// The index in [`super::WideBvh::ranges`] of a range leaf reference.
#[inline(always)]
pub(super) fn range_index(child: u32) -> usize {
    (child & !LEAF_BIT) as usize
}

/// Whether a child reference is a packed leaf.
#[inline(always)]
pub(super) fn is_packed(child: u32) -> bool {
    child & (LEAF_BIT | PACKED_BIT) == LEAF_BIT | PACKED_BIT
}
