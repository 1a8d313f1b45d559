//! What a wide tree stores: its nodes (`W` child boxes as structure-of-arrays and `W` child
//! references), the blocks of four packed triangles its leaves of static triangles hold, and
//! the slot ranges of its other leaves. Sizes are checked at compile time.

use super::ChildRef;
use crate::geometry::{Aabb, Triangle};
use crate::math::Vec3A;

/// Marks an unused lane of a [`Tri4`] block (in its `slot`).
pub const EMPTY: u32 = u32::MAX;

/// Rows of [`WideNode::bounds`]: lower x, y, z, then upper x, y, z.
const ROWS: usize = 6;

/// One node: `W` child boxes and `W` child references; 128 bytes (two cache lines) at
/// `W = 4`, 256 bytes (four) at `W = 8`, 448 bytes (seven) at `W = 16`.
///
/// | field | bytes (W = 4 / 8 / 16) | meaning |
/// |---|---|---|
/// | `bounds[0..3]` | 0..48 / 0..96 / 0..192 | lower x, y, z corners of the `W` child boxes, one row per axis |
/// | `bounds[3..6]` | 48..96 / 96..192 / 192..384 | upper x, y, z corners |
/// | `child` | 96..112 / 192..224 / 384..448 | per child, a [`ChildRef`]: an empty slot, a node, a leaf of packed [`Tri4`] blocks or a range leaf (its bits are documented there) |
/// | padding | 112..128 / 224..256 / none | keeps nodes aligned to cache lines |
///
/// A box row per axis and side lets the slab test load, for each axis, just the plane the
/// ray enters by and the one it leaves by. Empty slots have boxes at `+inf` that no ray with
/// a finite `t_max` can hit.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode<const W: usize> {
    /// Lower x, y, z and upper x, y, z of the `W` children, by row.
    pub bounds: [[f32; W]; ROWS],
    /// Child references (see the table).
    pub child: [ChildRef; W],
}

const _: () = assert!(std::mem::size_of::<WideNode<4>>() == 128);
const _: () = assert!(std::mem::size_of::<WideNode<8>>() == 256);
const _: () = assert!(std::mem::size_of::<WideNode<16>>() == 448);

impl<const W: usize> WideNode<W> {
    pub(super) fn empty() -> Self {
        WideNode { bounds: [[f32::INFINITY; W]; ROWS], child: [ChildRef::EMPTY; W] }
    }

    pub(super) fn set(&mut self, i: usize, b: &Aabb, child: ChildRef) {
        for axis in 0..3 {
            self.bounds[axis][i] = b.min[axis];
            self.bounds[axis + 3][i] = b.max[axis];
        }
        self.child[i] = child;
    }

    /// The box of child `i`.
    pub fn child_bounds(&self, i: usize) -> Aabb {
        let row = |r: usize| Vec3A::new(self.bounds[r][i], self.bounds[r + 1][i], self.bounds[r + 2][i]);
        Aabb { min: row(0), max: row(3) }
    }
}

/// Four triangles in structure-of-arrays form, for one 4-wide watertight test: the leaves of
/// static triangles are stored as these. 160 bytes.
///
/// The corners are the mesh's own floats (no `v0 + e1` reconstruction), so a vertex shared by
/// two triangles is the same value in both, as the watertight test needs. Unused lanes, and
/// those of degenerate triangles ([`Triangle::is_degenerate`]), hold NaN corners: NaN never
/// hits, and unlike a zero-area triangle (whose edge functions are all exactly 0) it never
/// sends the test to its double-precision fallback.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// Vertices 0, by axis.
    pub v0: [[f32; 4]; 3],
    /// Vertices 1, by axis.
    pub v1: [[f32; 4]; 3],
    /// Vertices 2, by axis.
    pub v2: [[f32; 4]; 3],
    /// Primitive slot of each lane; [`EMPTY`] for an unused lane.
    pub slot: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 160);

impl Tri4 {
    pub(super) fn pack(tris: impl Iterator<Item = (u32, Triangle)>) -> Tri4 {
        let mut t = Tri4::EMPTY;
        for (lane, (slot, tri)) in tris.take(4).enumerate() {
            t.slot[lane] = slot;
            if tri.is_degenerate() {
                // Never hit, as the scalar test has it: NaN corners, so the kernels need not ask.
                continue;
            }
            for axis in 0..3 {
                t.v0[axis][lane] = tri.v0[axis];
                t.v1[axis][lane] = tri.v1[axis];
                t.v2[axis][lane] = tri.v2[axis];
            }
        }
        t
    }

    /// A block of four unused lanes (NaN corners, never hit).
    pub const EMPTY: Tri4 =
        Tri4 { v0: [[f32::NAN; 4]; 3], v1: [[f32::NAN; 4]; 3], v2: [[f32::NAN; 4]; 3], slot: [EMPTY; 4] };

    /// Copy lane `from` of `src` into lane `to`, bit for bit.
    pub fn copy_lane(&mut self, to: usize, src: &Tri4, from: usize) {
        for axis in 0..3 {
            self.v0[axis][to] = src.v0[axis][from];
            self.v1[axis][to] = src.v1[axis][from];
            self.v2[axis][to] = src.v2[axis][from];
        }
        self.slot[to] = src.slot[from];
    }

    /// The triangle in `lane`.
    pub fn triangle(&self, lane: usize) -> Triangle {
        let v = |a: &[[f32; 4]; 3]| Vec3A::new(a[0][lane], a[1][lane], a[2][lane]);
        Triangle { v0: v(&self.v0), v1: v(&self.v1), v2: v(&self.v2) }
    }
}

/// Blocks compare bit for bit (so that NaN lanes, unused, compare equal).
impl PartialEq for Tri4 {
    fn eq(&self, other: &Tri4) -> bool {
        let bits = |t: &Tri4| [t.v0, t.v1, t.v2].map(|v| v.map(|axis| axis.map(f32::to_bits)));
        self.slot == other.slot && bits(self) == bits(other)
    }
}

/// Where a range leaf's primitives are: slots `start..start + count`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeafRange {
    /// First slot.
    pub start: u32,
    /// Number of slots.
    pub count: u32,
}
