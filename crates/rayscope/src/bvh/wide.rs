//! A 4-wide BVH collapsed from the binary one, for rendering: each node holds its four
//! children's boxes as structure-of-arrays, so one SIMD slab test (`wide::f32x4`: SSE on
//! x86-64, NEON on AArch64, scalar elsewhere) checks all four. It halves the depth of the
//! tree, and with it the loop iterations, the stack traffic and the dependent loads per ray.
//! The binary BVH stays for the debugger's level view.

use wide::f32x4;

use super::{Bvh, BvhError, BvhHit, NoObserver, Primitives, TraversalObserver};
use crate::geometry::Aabb;
use crate::geometry::aabb::safe_inv_dir;
use crate::geometry::{PrimHit, Triangle};
use crate::ray::Ray;

/// The instruction set a traversal is compiled for. Both give bit-identical hits: the AVX2
/// variant is the same code compiled with more registers, three-operand instructions and
/// BMI, chosen at run time so the binary still runs on any x86-64.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SimdLevel {
    /// The target's baseline (SSE2 on x86-64, NEON on AArch64, scalar elsewhere).
    #[default]
    Portable,
    /// x86-64 with AVX2, FMA, BMI1/2 and LZCNT (x86-64-v3).
    Avx2,
}

impl SimdLevel {
    /// The best level this CPU supports.
    pub fn detect() -> SimdLevel {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("bmi1")
            && std::arch::is_x86_feature_detected!("bmi2")
            && std::arch::is_x86_feature_detected!("lzcnt")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            return SimdLevel::Avx2;
        }
        SimdLevel::Portable
    }
}

/// Marks an unused child slot.
pub const EMPTY: u32 = u32::MAX;
/// Set on a child reference that is a leaf.
const LEAF_BIT: u32 = 1 << 31;
/// Set, with [`LEAF_BIT`], on a leaf of packed triangles ([`Tri4`] blocks).
const PACKED_BIT: u32 = 1 << 30;
/// Bits of a packed leaf reference that hold its first block.
const BLOCK_BITS: u32 = 26;
/// Most blocks one packed leaf holds (4 bits of count - 1); larger leaves use ranges.
const MAX_BLOCKS: u32 = 16;

/// One node: four child boxes and four child references, 128 bytes (two cache lines).
///
/// | field | bytes | meaning |
/// |---|---|---|
/// | `min_x`, `min_y`, `min_z` | 0..48 | lower corners of the four child boxes, by axis |
/// | `max_x`, `max_y`, `max_z` | 48..96 | upper corners, by axis |
/// | `child` | 96..112 | per child: [`EMPTY`]; a node index; a packed leaf: bits 31 and 30 set, bits 26..30 the block count - 1, bits 0..26 the first [`Tri4`] block; or a range leaf: bit 31 set, bits 0..30 an index into [`Bvh4::ranges`] |
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

/// Four triangles in structure-of-arrays form, for one 4-wide Möller–Trumbore test: the
/// leaves of static triangles are stored as these. 160 bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// First vertices, by axis.
    pub v0: [[f32; 4]; 3],
    /// Edges from vertex 0 to vertex 1, by axis.
    pub e1: [[f32; 4]; 3],
    /// Edges from vertex 0 to vertex 2, by axis.
    pub e2: [[f32; 4]; 3],
    /// Primitive slot of each lane; [`EMPTY`] for an unused lane (whose triangle is
    /// degenerate and never hit).
    pub slot: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Tri4>() == 160);

impl Tri4 {
    fn pack(tris: impl Iterator<Item = (u32, Triangle)>) -> Tri4 {
        let mut t = Tri4 { v0: [[0.0; 4]; 3], e1: [[0.0; 4]; 3], e2: [[0.0; 4]; 3], slot: [EMPTY; 4] };
        for (lane, (slot, tri)) in tris.take(4).enumerate() {
            for axis in 0..3 {
                t.v0[axis][lane] = tri.v0[axis];
                t.e1[axis][lane] = tri.e1[axis];
                t.e2[axis][lane] = tri.e2[axis];
            }
            t.slot[lane] = slot;
        }
        t
    }

    /// The triangle in `lane`.
    pub fn triangle(&self, lane: usize) -> Triangle {
        let v = |a: &[[f32; 4]; 3]| crate::math::Vec3A::new(a[0][lane], a[1][lane], a[2][lane]);
        Triangle { v0: v(&self.v0), e1: v(&self.e1), e2: v(&self.e2) }
    }

    /// Möller–Trumbore on four triangles at once, with exactly the scalar test's arithmetic
    /// ([`Triangle::intersect`]), so hits are bit-identical: returns the lanes hit within
    /// `[t_min, t_max]` and their `t`, `u`, `v`.
    #[inline(always)]
    fn intersect(&self, r: &RayLanes, t_min: f32, t_max: f32) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        let l = |a: &[f32; 4]| f32x4::new(*a);
        let (e1x, e1y, e1z) = (l(&self.e1[0]), l(&self.e1[1]), l(&self.e1[2]));
        let (e2x, e2y, e2z) = (l(&self.e2[0]), l(&self.e2[1]), l(&self.e2[2]));
        // p = dir x e2
        let px = r.dy * e2z - r.dz * e2y;
        let py = r.dz * e2x - r.dx * e2z;
        let pz = r.dx * e2y - r.dy * e2x;
        let det = e1x * px + e1y * py + e1z * pz;
        let inv_det = f32x4::ONE / det;
        // s = origin - v0
        let sx = r.ox - l(&self.v0[0]);
        let sy = r.oy - l(&self.v0[1]);
        let sz = r.oz - l(&self.v0[2]);
        let u = (sx * px + sy * py + sz * pz) * inv_det;
        // q = s x e1
        let qx = sy * e1z - sz * e1y;
        let qy = sz * e1x - sx * e1z;
        let qz = sx * e1y - sy * e1x;
        let v = (r.dx * qx + r.dy * qy + r.dz * qz) * inv_det;
        let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
        let zero = f32x4::ZERO;
        // det != 0 and finite: |det| in (0, inf).
        let ok_det = det.abs().simd_gt(zero) & det.abs().simd_lt(f32x4::splat(f32::INFINITY));
        let ok_u = u.simd_ge(zero) & u.simd_le(f32x4::ONE);
        let ok_v = v.simd_ge(zero) & (u + v).simd_le(f32x4::ONE);
        let ok_t = t.simd_ge(f32x4::splat(t_min)) & t.simd_le(f32x4::splat(t_max));
        let mask = (ok_det & ok_u & ok_v & ok_t).to_bitmask();
        (mask, t.to_array(), u.to_array(), v.to_array())
    }
}

/// The blocks of a packed leaf reference: `first..first + count` in [`Bvh4::blocks`].
#[inline(always)]
fn packed_blocks(child: u32) -> std::ops::Range<usize> {
    let first = (child & ((1 << BLOCK_BITS) - 1)) as usize;
    first..first + ((child >> BLOCK_BITS) & 0xf) as usize + 1
}

/// Whether a child reference is a packed leaf.
#[inline(always)]
fn is_packed(child: u32) -> bool {
    child & (LEAF_BIT | PACKED_BIT) == LEAF_BIT | PACKED_BIT
}

/// Where a range leaf's primitives are: slots `start..start + count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LeafRange {
    /// First slot.
    pub start: u32,
    /// Number of slots.
    pub count: u32,
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
    /// Packed triangles of the leaves that hold only static triangles.
    pub blocks: Vec<Tri4>,
    /// The other leaves (spheres, moving shapes, mixes, oversized leaves): slot ranges whose
    /// primitives are intersected one by one through [`Primitives`].
    pub ranges: Vec<LeafRange>,
    /// The traversal variant: [`SimdLevel::detect`] when built. Private so that it can only
    /// name a level the CPU has; [`Bvh4::portable`] selects the baseline.
    simd: SimdLevel,
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
    dx: f32x4,
    dy: f32x4,
    dz: f32x4,
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
            dx: f32x4::splat(ray.dir.x),
            dy: f32x4::splat(ray.dir.y),
            dz: f32x4::splat(ray.dir.z),
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
    /// Ask for a child's memory as soon as its box is hit, so that the loads overlap the
    /// work on its siblings (incoherent rays wait on cache misses more than on arithmetic).
    #[inline(always)]
    fn prefetch(&self, child: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
            let (p, lines): (*const i8, usize) = if is_packed(child) {
                (self.blocks.as_ptr().wrapping_add(packed_blocks(child).start).cast(), 3)
            } else if child & LEAF_BIT == 0 {
                (self.nodes.as_ptr().wrapping_add(child as usize).cast(), 2)
            } else {
                return;
            };
            for line in 0..lines {
                // SAFETY: a prefetch is a hint and never faults, whatever the address.
                unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = child;
    }

    /// Collapse a binary BVH: each node takes its binary node's children and keeps opening
    /// the largest interior one (by surface area) until it has four. Leaves of static
    /// triangles (as `prims` reports them) are packed into [`Tri4`] blocks.
    pub fn from_binary<P: Primitives + ?Sized>(bin: &Bvh, prims: &P) -> Bvh4 {
        let mut out = Bvh4 { simd: SimdLevel::detect(), ..Bvh4::default() };
        let Some(root) = bin.nodes.first() else { return out };
        out.nodes.push(Node4::empty());
        if root.is_leaf() {
            let r = out.leaf(prims, root.start, root.count);
            out.nodes[0].set(0, &root.bounds(), r);
        } else {
            out.fill(bin, prims, 0, 0);
        }
        out
    }

    /// The traversal variant in use.
    pub fn simd_level(&self) -> SimdLevel {
        self.simd
    }

    /// The same tree traversed by the baseline code (to compare it with the detected one).
    pub fn portable(mut self) -> Bvh4 {
        self.simd = SimdLevel::Portable;
        self
    }

    /// A leaf reference for slots `start..start + count`: packed blocks when every primitive
    /// is a static triangle and there are few enough, else a range.
    fn leaf<P: Primitives + ?Sized>(&mut self, prims: &P, start: u32, count: u32) -> u32 {
        let packable = count.div_ceil(4) <= MAX_BLOCKS
            && (self.blocks.len() as u32) < (1 << BLOCK_BITS)
            && (start..start + count).all(|s| prims.triangle(s).is_some());
        if packable {
            let first = self.blocks.len() as u32;
            for chunk in (start..start + count).step_by(4) {
                let end = (chunk + 4).min(start + count);
                self.blocks.push(Tri4::pack((chunk..end).filter_map(|s| prims.triangle(s).map(|t| (s, t)))));
            }
            let n = self.blocks.len() as u32 - first;
            LEAF_BIT | PACKED_BIT | ((n - 1) << BLOCK_BITS) | first
        } else {
            self.ranges.push(LeafRange { start, count });
            LEAF_BIT | (self.ranges.len() as u32 - 1)
        }
    }

    fn fill<P: Primitives + ?Sized>(&mut self, bin: &Bvh, prims: &P, bin_index: usize, at: usize) {
        let node = &bin.nodes[bin_index];
        // The children, opened largest first until there are four (no allocation: this runs
        // once per node of the collapsed tree).
        let mut kids = [bin_index + 1, node.start as usize, 0, 0];
        let mut len = 2;
        while len < 4 {
            let widest =
                kids[..len].iter().enumerate().filter(|(_, k)| !bin.nodes[**k].is_leaf()).max_by(|a, b| {
                    bin.nodes[*a.1].bounds().half_area().total_cmp(&bin.nodes[*b.1].bounds().half_area())
                });
            let Some((i, &k)) = widest else { break };
            let n = &bin.nodes[k];
            kids[i] = k + 1;
            kids[len] = n.start as usize;
            len += 1;
        }
        let mut n4 = Node4::empty();
        let mut interior = [(0usize, 0usize); 4];
        let mut n_interior = 0;
        for (slot, &k) in kids[..len].iter().enumerate() {
            let child = &bin.nodes[k];
            if child.is_leaf() {
                let r = self.leaf(prims, child.start, child.count);
                n4.set(slot, &child.bounds(), r);
            } else {
                let idx = self.nodes.len();
                self.nodes.push(Node4::empty());
                n4.set(slot, &child.bounds(), idx as u32);
                interior[n_interior] = (k, idx);
                n_interior += 1;
            }
        }
        self.nodes[at] = n4;
        for &(k, idx) in &interior[..n_interior] {
            self.fill(bin, prims, k, idx);
        }
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> Option<BvhHit> {
        self.intersect_counted(ray, prims, &mut NoObserver)
    }

    /// [`Bvh4::intersect`], reporting the traversal to `obs`.
    #[inline]
    pub fn intersect_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        #[cfg(target_arch = "x86_64")]
        if self.simd == SimdLevel::Avx2 {
            // SAFETY: `simd` is Avx2 only where the CPU has those features (see the field).
            return unsafe { self.intersect_avx2(ray, prims, obs) };
        }
        self.intersect_impl(ray, prims, obs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn intersect_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        ray: &Ray,
        prims: &P,
        obs: &mut O,
    ) -> Option<BvhHit> {
        self.intersect_impl(ray, prims, obs)
    }

    #[inline(always)]
    fn intersect_impl<P: Primitives + ?Sized, O: TraversalObserver>(
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
            if is_packed(current) {
                for block in &self.blocks[packed_blocks(current)] {
                    obs.prim_tested();
                    let (mut mask, t, u, v) = block.intersect(&lanes, t_min, t_max);
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        // Lanes in order, each accepted at <= the best so far: the same
                        // choice among equal distances as the scalar loop makes.
                        if t[lane] <= t_max {
                            t_max = t[lane];
                            best = Some(BvhHit {
                                slot: block.slot[lane],
                                hit: PrimHit { t: t[lane], u: u[lane], v: v[lane] },
                            });
                        }
                    }
                }
            } else if current & LEAF_BIT != 0 {
                let LeafRange { start, count } = self.ranges[(current & !LEAF_BIT) as usize];
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
                            self.prefetch(child);
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
    #[inline]
    pub fn occluded<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.simd == SimdLevel::Avx2 {
            // SAFETY: `simd` is Avx2 only where the CPU has those features (see the field).
            return unsafe { self.occluded_avx2(ray, prims) };
        }
        self.occluded_impl(ray, prims)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn occluded_avx2<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        self.occluded_impl(ray, prims)
    }

    #[inline(always)]
    fn occluded_impl<P: Primitives + ?Sized>(&self, ray: &Ray, prims: &P) -> bool {
        if self.nodes.is_empty() || !ray_is_finite(ray) {
            return false;
        }
        let lanes = RayLanes::new(ray);
        let (t_min, t_max) = (ray.t.min, ray.t.max);
        let mut stack: Stack<u32> = Stack::new();
        let mut current = 0u32;
        loop {
            if is_packed(current) {
                for block in &self.blocks[packed_blocks(current)] {
                    if block.intersect(&lanes, t_min, t_max).0 != 0 {
                        return true;
                    }
                }
            } else if current & LEAF_BIT != 0 {
                let LeafRange { start, count } = self.ranges[(current & !LEAF_BIT) as usize];
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
                        self.prefetch(node.child[i]);
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
                    let slots: Vec<u32> = if is_packed(c) {
                        let range = packed_blocks(c);
                        let bad = BvhError::BadRange { node: i, start: range.start, end: range.end };
                        let blocks = self.blocks.get(range).ok_or(bad)?;
                        blocks.iter().flat_map(|b| b.slot).filter(|s| *s != EMPTY).collect()
                    } else {
                        let bad = BvhError::BadChild { node: i, child: c as usize };
                        let r = self.ranges.get((c & !LEAF_BIT) as usize).ok_or(bad)?;
                        (r.start..r.start + r.count).collect()
                    };
                    for slot in slots {
                        let Some(cov) = covered.get_mut(slot as usize) else {
                            return Err(BvhError::BadRange { node: i, start: slot as usize, end: slot as usize + 1 });
                        };
                        *cov += 1;
                        let prim = bin.prim_indices[slot as usize];
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
