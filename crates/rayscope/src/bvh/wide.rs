//! A 4-wide BVH collapsed from the binary one, for rendering: each node holds its four
//! children's boxes as structure-of-arrays, so one SIMD slab test (`wide::f32x4`: SSE on
//! x86-64, NEON on AArch64, scalar elsewhere) checks all four. It halves the depth of the
//! tree, and with it the loop iterations, the stack traffic and the dependent loads per ray.
//! The binary BVH stays for the debugger's level view.

use wide::f32x4;

use super::{Bvh, BvhError, BvhHit, NoObserver, Primitives, TraversalObserver};
use crate::geometry::Aabb;
use crate::geometry::aabb::safe_inv_dir;
use crate::ray::Ray;

/// Marks an unused child slot.
pub const EMPTY: u32 = u32::MAX;
/// Set on a child reference that is a leaf.
const LEAF_BIT: u32 = 1 << 31;
/// Bits of a leaf reference that hold its first primitive slot.
const START_BITS: u32 = 25;
/// Most primitives one leaf reference can hold (6 bits of count - 1).
pub const MAX_LEAF_REF: u32 = 64;

/// One node: four child boxes and four child references, 128 bytes (two cache lines).
///
/// | field | bytes | meaning |
/// |---|---|---|
/// | `min_x`, `min_y`, `min_z` | 0..48 | lower corners of the four child boxes, by axis |
/// | `max_x`, `max_y`, `max_z` | 48..96 | upper corners, by axis |
/// | `child` | 96..112 | per child: [`EMPTY`]; a node index; or a leaf: bit 31 set, bits 25..31 the primitive count - 1, bits 0..25 the first primitive slot |
/// | padding | 112..128 | keeps nodes aligned to cache lines |
///
/// Empty slots have boxes at `+inf` that no ray with a finite `t_max` can hit.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    /// Lower x of the four children.
    pub min_x: [f32; 4],
    /// Lower y.
    pub min_y: [f32; 4],
    /// Lower z.
    pub min_z: [f32; 4],
    /// Upper x.
    pub max_x: [f32; 4],
    /// Upper y.
    pub max_y: [f32; 4],
    /// Upper z.
    pub max_z: [f32; 4],
    /// Child references (see the table).
    pub child: [u32; 4],
    _pad: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Node4>() == 128);

impl Node4 {
    fn empty() -> Node4 {
        let inf = [f32::INFINITY; 4];
        Node4 {
            min_x: inf,
            min_y: inf,
            min_z: inf,
            max_x: inf,
            max_y: inf,
            max_z: inf,
            child: [EMPTY; 4],
            _pad: [0; 4],
        }
    }

    fn set(&mut self, i: usize, b: &Aabb, child: u32) {
        self.min_x[i] = b.min.x;
        self.min_y[i] = b.min.y;
        self.min_z[i] = b.min.z;
        self.max_x[i] = b.max.x;
        self.max_y[i] = b.max.y;
        self.max_z[i] = b.max.z;
        self.child[i] = child;
    }

    /// The box of child `i`.
    pub fn child_bounds(&self, i: usize) -> Aabb {
        Aabb {
            min: crate::math::Vec3A::new(self.min_x[i], self.min_y[i], self.min_z[i]),
            max: crate::math::Vec3A::new(self.max_x[i], self.max_y[i], self.max_z[i]),
        }
    }
}

/// A leaf reference's first slot and count.
#[inline(always)]
pub fn leaf_range(child: u32) -> (u32, u32) {
    (child & ((1 << START_BITS) - 1), ((child >> START_BITS) & 0x3f) + 1)
}

fn leaf_ref(start: u32, count: u32) -> u32 {
    debug_assert!((1..=MAX_LEAF_REF).contains(&count) && start < (1 << START_BITS));
    LEAF_BIT | ((count - 1) << START_BITS) | start
}

#[inline(always)]
fn ray_is_finite(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && !ray.t.min.is_nan() && !ray.t.max.is_nan()
}

/// The 4-wide BVH.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    /// Nodes; `nodes[0]` is the root. Empty for an empty scene.
    pub nodes: Vec<Node4>,
}

/// Deepest traversal stack: three pushes per level of a tree at most [`super::MAX_DEPTH`] deep.
const STACK: usize = 3 * super::MAX_DEPTH + 4;

/// A fixed-capacity stack on the machine stack. Its storage is left uninitialised: zeroing
/// ~1.5 KiB per ray showed up in profiles as a few percent of render time.
struct Stack<T: Copy> {
    items: [std::mem::MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack { items: [const { std::mem::MaybeUninit::uninit() }; STACK], len: 0 }
    }

    #[inline(always)]
    fn push(&mut self, v: T) {
        // Cannot overflow: the tree is at most MAX_DEPTH levels deep and each level pushes
        // at most three entries; the bounds check stays as a guard.
        self.items[self.len].write(v);
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }
}

/// The ray's data for slab tests, splatted across the four lanes once per ray.
struct RayLanes {
    ox: f32x4,
    oy: f32x4,
    oz: f32x4,
    ix: f32x4,
    iy: f32x4,
    iz: f32x4,
}

impl RayLanes {
    #[inline(always)]
    fn new(ray: &Ray) -> RayLanes {
        let inv = safe_inv_dir(ray.dir);
        RayLanes {
            ox: f32x4::splat(ray.origin.x),
            oy: f32x4::splat(ray.origin.y),
            oz: f32x4::splat(ray.origin.z),
            ix: f32x4::splat(inv.x),
            iy: f32x4::splat(inv.y),
            iz: f32x4::splat(inv.z),
        }
    }

    /// Entry distances of the four child boxes and the mask of those hit within
    /// `[t_min, t_max]` (computed exactly as the scalar [`Aabb::hit_distance`] does).
    #[inline(always)]
    fn test(&self, n: &Node4, t_min: f32, t_max: f32) -> (f32x4, u32) {
        let tx0 = (f32x4::new(n.min_x) - self.ox) * self.ix;
        let tx1 = (f32x4::new(n.max_x) - self.ox) * self.ix;
        let ty0 = (f32x4::new(n.min_y) - self.oy) * self.iy;
        let ty1 = (f32x4::new(n.max_y) - self.oy) * self.iy;
        let tz0 = (f32x4::new(n.min_z) - self.oz) * self.iz;
        let tz1 = (f32x4::new(n.max_z) - self.oz) * self.iz;
        let near =
            tx0.fast_min(tx1).fast_max(ty0.fast_min(ty1)).fast_max(tz0.fast_min(tz1)).fast_max(f32x4::splat(t_min));
        // A finite t_max keeps empty slots (boxes at +inf) out.
        let far = tx0
            .fast_max(tx1)
            .fast_min(ty0.fast_max(ty1))
            .fast_min(tz0.fast_max(tz1))
            .fast_min(f32x4::splat(t_max.min(f32::MAX)));
        (near, near.simd_le(far).to_bitmask())
    }
}

impl Bvh4 {
    /// Collapse a binary BVH: each node takes its binary node's children and keeps opening
    /// the largest interior one (by surface area) until it has four.
    pub fn from_binary(bin: &Bvh) -> Bvh4 {
        let mut out = Bvh4::default();
        let Some(root) = bin.nodes.first() else { return out };
        if root.is_leaf() {
            out.nodes.push(Node4::empty());
            let r = out.leaf_child(root.start, root.count, &root.bounds());
            out.nodes[0].set(0, &root.bounds(), r);
            return out;
        }
        out.nodes.push(Node4::empty());
        out.fill(bin, 0, 0);
        out
    }

    /// A child reference for a binary leaf: one leaf reference, or (for a leaf larger than a
    /// reference can hold, which only the depth cap makes) nodes of leaf references.
    fn leaf_child(&mut self, start: u32, count: u32, bounds: &Aabb) -> u32 {
        if count <= MAX_LEAF_REF {
            return leaf_ref(start, count);
        }
        // Split the range in four and make a node of it (recursively).
        let idx = self.nodes.len() as u32;
        self.nodes.push(Node4::empty());
        let quarter = count.div_ceil(4);
        let mut n = Node4::empty();
        for i in 0..4u32 {
            let s = start + i * quarter;
            let c = quarter.min((start + count).saturating_sub(s));
            if c == 0 {
                break;
            }
            let r = self.leaf_child(s, c, bounds);
            n.set(i as usize, bounds, r);
        }
        self.nodes[idx as usize] = n;
        idx
    }

    fn fill(&mut self, bin: &Bvh, bin_index: usize, at: usize) {
        let node = &bin.nodes[bin_index];
        let mut kids = vec![bin_index + 1, node.start as usize];
        while kids.len() < 4 {
            let widest =
                kids.iter().enumerate().filter(|(_, k)| !bin.nodes[**k].is_leaf()).max_by(|a, b| {
                    bin.nodes[*a.1].bounds().half_area().total_cmp(&bin.nodes[*b.1].bounds().half_area())
                });
            let Some((i, &k)) = widest else { break };
            let n = &bin.nodes[k];
            kids[i] = k + 1;
            kids.push(n.start as usize);
        }
        let mut n4 = Node4::empty();
        let mut interior = Vec::new();
        for (slot, &k) in kids.iter().enumerate() {
            let child = &bin.nodes[k];
            if child.is_leaf() {
                let r = self.leaf_child(child.start, child.count, &child.bounds());
                n4.set(slot, &child.bounds(), r);
            } else {
                let idx = self.nodes.len();
                self.nodes.push(Node4::empty());
                n4.set(slot, &child.bounds(), idx as u32);
                interior.push((k, idx));
            }
        }
        self.nodes[at] = n4;
        for (k, idx) in interior {
            self.fill(bin, k, idx);
        }
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> Option<BvhHit> {
        self.intersect_counted(ray, prims, &mut NoObserver)
    }

    /// [`Bvh4::intersect`], reporting the traversal to `obs`.
    pub fn intersect_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        // NaN rays would pass every slab test (SIMD min/max pass NaN through); they hit nothing.
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return None;
        }
        let lanes = RayLanes::new(ray);
        let (t_min, mut t_max) = (ray.t.min, ray.t.max);
        let mut best = None;
        // Entries: a child reference and its entry distance, so that entries a closer hit
        // has since ruled out are dropped when popped.
        let mut stack: Stack<(u32, f32)> = Stack::new();
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT != 0 {
                let (start, count) = leaf_range(current);
                for slot in start..start + count {
                    obs.prim_tested();
                    if let Some(hit) = prims.intersect(slot, ray, t_min, t_max) {
                        t_max = hit.t;
                        best = Some(BvhHit { slot, hit });
                    }
                }
            } else {
                let node = &self.nodes[current as usize];
                obs.entered(current);
                obs.boxes_tested(4);
                let (near, mask) = lanes.test(node, t_min, t_max);
                if mask != 0 {
                    let near = near.to_array();
                    // Visit the nearest hit child now; push the others, farthest first.
                    let mut order = [(0u32, 0.0f32); 4];
                    let mut k = 0;
                    for (i, (&child, &d)) in node.child.iter().zip(&near).enumerate() {
                        if mask & (1 << i) != 0 {
                            order[k] = (child, d);
                            k += 1;
                        }
                    }
                    let order = &mut order[..k];
                    if k > 1 {
                        order.sort_unstable_by(|a, b| b.1.total_cmp(&a.1));
                    }
                    for &e in &order[..k - 1] {
                        stack.push(e);
                    }
                    current = order[k - 1].0;
                    continue;
                }
            }
            loop {
                let Some((c, entry)) = stack.pop() else { return best };
                if entry <= t_max {
                    current = c;
                    break;
                }
            }
        }
    }

    /// Whether anything blocks `ray` within its interval; stops at the first hit found.
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return false;
        }
        let lanes = RayLanes::new(ray);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let mut stack: Stack<u32> = Stack::new();
        let mut current = 0u32;
        loop {
            if current & LEAF_BIT != 0 {
                let (start, count) = leaf_range(current);
                for slot in start..start + count {
                    if prims.intersect(slot, ray, t_min, t_max).is_some() {
                        return true;
                    }
                }
            } else {
                let node = &self.nodes[current as usize];
                let (_, mut mask) = lanes.test(node, t_min, t_max);
                if mask != 0 {
                    // Any order finds a blocker; the first hit child is visited next.
                    let first = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    while mask != 0 {
                        let i = mask.trailing_zeros() as usize;
                        stack.push(node.child[i]);
                        mask &= mask - 1;
                    }
                    current = node.child[first];
                    continue;
                }
            }
            match stack.pop() {
                Some(c) => current = c,
                None => return false,
            }
        }
    }

    /// Check the collapsed tree: every primitive slot is in exactly one leaf reference,
    /// inside its box, and every node is reachable exactly once.
    pub fn validate(&self, bin: &Bvh, prim_bounds: &[Aabb]) -> Result<(), BvhError> {
        let mut covered = vec![0usize; bin.prim_indices.len()];
        if self.nodes.is_empty() {
            return if covered.is_empty() { Ok(()) } else { Err(BvhError::Coverage { slot: 0, times: 0 }) };
        }
        let mut reached = vec![0u32; self.nodes.len()];
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            reached[i] += 1;
            let n = &self.nodes[i];
            for k in 0..4 {
                let c = n.child[k];
                if c == EMPTY {
                    continue;
                }
                let b = n.child_bounds(k);
                if c & LEAF_BIT != 0 {
                    let (start, count) = leaf_range(c);
                    let end = (start + count) as usize;
                    if end > covered.len() {
                        return Err(BvhError::BadRange { node: i, start: start as usize, end });
                    }
                    for (c, &prim) in
                        covered[start as usize..end].iter_mut().zip(&bin.prim_indices[start as usize..end])
                    {
                        *c += 1;
                        if !b.contains(&prim_bounds[prim as usize]) {
                            return Err(BvhError::PrimOutside { node: i, prim });
                        }
                    }
                } else {
                    let c = c as usize;
                    if c <= i || c >= self.nodes.len() {
                        return Err(BvhError::BadChild { node: i, child: c });
                    }
                    for j in 0..4 {
                        if self.nodes[c].child[j] != EMPTY && !b.contains(&self.nodes[c].child_bounds(j)) {
                            return Err(BvhError::ChildOutside { node: i, child: c });
                        }
                    }
                    stack.push(c);
                }
            }
        }
        if let Some((slot, &times)) = covered.iter().enumerate().find(|(_, c)| **c != 1) {
            return Err(BvhError::Coverage { slot, times });
        }
        if let Some(n) = reached.iter().position(|r| *r != 1) {
            return Err(BvhError::Unreachable(n));
        }
        Ok(())
    }
}
