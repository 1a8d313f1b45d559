//! Child references: the word a wide node keeps per child, saying whether the slot is empty,
//! a node, a leaf of packed triangle blocks or a range leaf, and where that child is.

use std::ops::Range;

/// What one child slot of a [`super::WideNode`] holds, in one word:
///
/// | bits | child |
/// |---|---|
/// | all set ([`ChildRef::EMPTY`]) | none: an unused slot |
/// | bit 31 clear | a node: bits 0..31 its index in [`super::WideBvh::nodes`] |
/// | bits 31 and 30 set | a packed leaf: bits 26..30 its block count - 1, bits 0..26 its first [`super::Tri4`] block in [`super::WideBvh::blocks`] |
/// | bit 31 set, bit 30 clear | a range leaf: bits 0..30 its index in [`super::WideBvh::ranges`] |
///
/// The accessors read their field without checking the kind, as the traversals know it when
/// they ask (an empty slot reads as a packed leaf): each is the bit arithmetic it names, no
/// more, and the type is a `u32` in memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(transparent)]
pub struct ChildRef(u32);

impl ChildRef {
    /// An unused slot.
    pub const EMPTY: ChildRef = ChildRef(u32::MAX);
    /// The root node, where every traversal starts.
    pub const ROOT: ChildRef = ChildRef(0);
    /// Most blocks one packed leaf holds (4 bits of count - 1); larger leaves use ranges.
    pub const MAX_BLOCKS: u32 = 16;
    /// Bits of a packed leaf reference that hold its first block: blocks from
    /// `1 << BLOCK_BITS` on can only be reached through ranges.
    pub const BLOCK_BITS: u32 = 26;
    /// Set on a leaf.
    const LEAF_BIT: u32 = 1 << 31;
    /// Set, with [`ChildRef::LEAF_BIT`], on a leaf of packed triangles.
    const PACKED_BIT: u32 = 1 << 30;

    /// The reference to node `index` of [`super::WideBvh::nodes`].
    #[inline(always)]
    pub fn node(index: u32) -> ChildRef {
        debug_assert!(index & Self::LEAF_BIT == 0);
        ChildRef(index)
    }

    /// The reference to a packed leaf of blocks `first..first + count` in
    /// [`super::WideBvh::blocks`] (`count` in `1..=MAX_BLOCKS`, `first` below
    /// `2^BLOCK_BITS`).
    #[inline]
    pub fn packed(first: u32, count: u32) -> ChildRef {
        debug_assert!((1..=Self::MAX_BLOCKS).contains(&count) && first < 1 << Self::BLOCK_BITS);
        ChildRef(Self::LEAF_BIT | Self::PACKED_BIT | ((count - 1) << Self::BLOCK_BITS) | first)
    }

    /// The reference to range leaf `index` of [`super::WideBvh::ranges`].
    #[inline]
    pub fn range(index: u32) -> ChildRef {
        debug_assert!(index & (Self::LEAF_BIT | Self::PACKED_BIT) == 0);
        ChildRef(Self::LEAF_BIT | index)
    }

    /// Whether the reference is a leaf (or the empty slot's, which reads as one).
    #[inline(always)]
    pub fn is_leaf(self) -> bool {
        self.0 & Self::LEAF_BIT != 0
    }

    /// Whether the reference is a packed leaf (or the empty slot's, which reads as one).
    #[inline(always)]
    pub fn is_packed(self) -> bool {
        self.0 & (Self::LEAF_BIT | Self::PACKED_BIT) == Self::LEAF_BIT | Self::PACKED_BIT
    }

    /// The index of a node reference in [`super::WideBvh::nodes`].
    #[inline(always)]
    pub fn node_index(self) -> u32 {
        self.0
    }

    /// A node reference's index, or a leaf's low bits: an index in range for nodes, which the
    /// branchless prefetch computes for any reference before it knows which it has.
    #[inline(always)]
    pub fn index_bits(self) -> usize {
        (self.0 & !(Self::LEAF_BIT | Self::PACKED_BIT)) as usize
    }

    /// The first block of a packed leaf reference (the reference's low bits, whatever else it
    /// is).
    #[inline(always)]
    pub fn first_block(self) -> usize {
        (self.0 & ((1 << Self::BLOCK_BITS) - 1)) as usize
    }

    /// The blocks of a packed leaf reference: `first..first + count` in
    /// [`super::WideBvh::blocks`].
    #[inline(always)]
    pub fn packed_blocks(self) -> Range<usize> {
        let first = self.first_block();
        first..first + ((self.0 >> Self::BLOCK_BITS) & 0xf) as usize + 1
    }

    /// The index in [`super::WideBvh::ranges`] of a range leaf reference.
    #[inline(always)]
    pub fn range_index(self) -> usize {
        (self.0 & !Self::LEAF_BIT) as usize
    }

    /// The reference as its word, for error reports.
    pub fn to_bits(self) -> u32 {
        self.0
    }
}
