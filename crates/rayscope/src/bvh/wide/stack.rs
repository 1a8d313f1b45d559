//! The traversals' fixed-capacity stack, and whether a tree's depth fits it.

use super::WideBvh;
use super::kernels::{Lanes, NodeWidth};

/// Deepest traversal stack: `W - 1` pushes per level of a tree at most [`crate::bvh::MAX_DEPTH`]
/// deep, for the 8-wide tree (whose depth is at most the binary tree's). A 16-wide tree is
/// used only where its own depth fits ([`WideBvh::fits_stack`]; every course mesh's does,
/// with room to spare): a stack sized for the worst 16-wide tree was a page more per query.
const STACK: usize = 7 * crate::bvh::MAX_DEPTH + 8;

/// A fixed-capacity stack on the machine stack. Its storage is left uninitialised: zeroing
/// a few KiB per ray showed up in profiles as a few percent of render time.
pub(super) struct Stack<T: Copy> {
    items: [std::mem::MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        Stack { items: [const { std::mem::MaybeUninit::uninit() }; STACK], len: 0 }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, v: T) {
        // Cannot overflow: the tree is at most MAX_DEPTH levels deep and each level pushes
        // at most W - 1 entries; the bounds check stays as a guard.
        self.items[self.len].write(v);
        self.len += 1;
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W>,
{
    /// Whether the traversals' fixed stack holds every entry this tree can need: `W - 1` per
    /// level. Always so up to eight children a node (the depth is at most the binary tree's).
    pub fn fits_stack(&self) -> bool {
        (W - 1) * self.depth() + W <= STACK
    }
}
