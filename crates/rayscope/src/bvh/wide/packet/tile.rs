//! Closest hits for a tile of camera rays: up to [`TILE_RUNS`] packets (runs of pixels of a
//! tile's rows, each as [`WideBvh::intersect_packet`] takes one) that share their origin,
//! walking the tree once for all of them.
//!
//! A tile's runs enter nearly the same inner nodes: walked one after the other, eight
//! packets pay eight times for those nodes' tests, their children's sorting and the branches
//! on both (the dragon's camera packets entered 220,000 inner nodes a render; their tiles,
//! 32,000 different ones). Here inner nodes are tested once for the tile, by the packet's
//! interval test over the union of the packets' inverse-direction ranges; each leaf child a
//! node lets the tile into is tested per packet, ray by ray, by the packet's own leaf test,
//! and its triangles as a packet's are (`packet_leaf`).
//!
//! Each ray's closest hit is the one the single-ray traversal reports, bit for bit (the
//! packets' argument: the tile may visit more inner nodes than any of its packets would,
//! never fewer; leaves are culled by each ray's own test; ties go to the lower slot).

use wide::f32x8;

use super::super::kernels::{Lanes, NodeTest, NodeWidth};
use super::super::simd::Baseline;
#[cfg(target_arch = "x86_64")]
use super::super::simd::{Avx2, Avx512};
use super::super::stack::Stack;
use super::super::traverse::descend;
use super::super::{ChildRef, Simd, WideBvh};
use super::{NO_SETUPS, PACKET, Packet, PacketHits, PacketNodeTest, PacketRays, PacketWidth, greater, lesser};
use crate::bvh::{NoObserver, Primitives, QueryKind, TraversalObserver};
use crate::ray::Ray;

/// Most packets (runs of a tile's rows) traced as one tile.
pub const TILE_RUNS: usize = 8;

/// The closest hit of each ray of each run of a tile (`None` beyond the runs and rays given).
pub type TileHits = [PacketHits; TILE_RUNS];

/// A tile stack entry: a child reference, the rays still to trace into it (eight bits a
/// packet: packet `r`'s rays in bits `8 r` to `8 r + 7`), and the tile's lower-bound entry
/// distance.
#[derive(Clone, Copy)]
struct TileEntry {
    child: ChildRef,
    lanes: u64,
    near: f32,
}

/// The bits of packet `r`'s rays in a [`TileEntry`]'s lanes.
#[inline(always)]
fn run_lanes(lanes: u64, r: usize) -> u32 {
    (lanes >> (8 * r)) as u32 & 0xff
}

impl<const W: usize> WideBvh<W>
where
    Lanes<W>: NodeWidth<W> + PacketWidth<W>,
{
    /// The closest hit of each ray of up to [`TILE_RUNS`] `runs` (each as
    /// [`WideBvh::intersect_packet`] takes one), identical to [`WideBvh::intersect`] on each
    /// ray: as one tile when every run forms a packet and all share their origin (bit for
    /// bit) and direction signs, else run by run. Runs beyond [`TILE_RUNS`] are not traced
    /// (as rays beyond [`PACKET`] in a packet are not).
    pub fn intersect_tile<P: Primitives + ?Sized>(&self, runs: &[&[Ray]], prims: &P) -> TileHits {
        self.intersect_tile_counted(runs, prims, &mut [[NoObserver; PACKET]; TILE_RUNS])
    }

    /// [`WideBvh::intersect_tile`], reporting each ray's traversal to its observer in `obs`
    /// (`obs[r][i]` for `runs[r][i]`): a ray traced in the tile is told [`QueryKind::Tile`]
    /// and every inner node the tile enters, and the leaves
    /// its own box test lets it into; runs traced apart are told what
    /// [`WideBvh::intersect_packet_counted`] tells.
    pub fn intersect_tile_counted<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
    ) -> TileHits {
        let mut hits = [[None; PACKET]; TILE_RUNS];
        if runs.is_empty() || runs.len() > TILE_RUNS || runs.iter().any(|r| r.is_empty()) || self.nodes.is_empty() {
            self.tile_by_packets(runs, prims, obs, &mut hits);
            return hits;
        }
        // SAFETY: each `#[target_feature]` variant is called with the token (`cpu`) that proves
        // the CPU has its features.
        unsafe {
            match self.simd {
                #[cfg(target_arch = "x86_64")]
                Simd::Avx512(cpu) => self.tile_avx512(cpu, runs, prims, obs, &mut hits),
                #[cfg(target_arch = "x86_64")]
                Simd::Avx2(cpu) => self.tile_avx2(cpu, runs, prims, obs, &mut hits),
                _ => self.tile_portable(runs, prims, obs, &mut hits),
            }
        }
        hits
    }

    /// The runs of a tile traced one after the other as packets (or rays, where a run forms
    /// none).
    fn tile_by_packets<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        for ((hits, rays), obs) in hits.iter_mut().zip(runs).zip(obs.iter_mut()) {
            *hits = self.intersect_packet_counted(rays, prims, obs);
        }
    }

    /// The portable tile traversal, kept out of line (see [`WideBvh::intersect_counted`]).
    #[inline(never)]
    fn tile_portable<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        self.tile_setup::<<Lanes<W> as NodeWidth<W>>::Portable, super::PortablePacketTest, P, O>(
            Baseline, Baseline, runs, prims, obs, hits,
        );
    }

    /// [`WideBvh::intersect_tile`] compiled for AVX2, the packets' set-up included.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    fn tile_avx2<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx2,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        self.tile_setup::<<Lanes<W> as NodeWidth<W>>::Avx2, <Lanes<W> as PacketWidth<W>>::Avx2, P, O>(
            cpu.into(),
            cpu.into(),
            runs,
            prims,
            obs,
            hits,
        );
    }

    /// [`WideBvh::intersect_tile`] compiled for AVX-512, the packets' set-up included.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt,avx512f,avx512vl,avx512bw,avx512dq")]
    fn tile_avx512<P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        cpu: Avx512,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        self.tile_setup::<<Lanes<W> as NodeWidth<W>>::Avx512, <Lanes<W> as PacketWidth<W>>::Avx512, P, O>(
            cpu.into(),
            cpu.into(),
            runs,
            prims,
            obs,
            hits,
        );
    }

    /// The tile's set-up (a packet per run, and the bounds over them all) and traversal with
    /// leaf test `T` and inner-node test `Q` (on the CPU `leaf_cpu` and `node_cpu` vouch
    /// for); `runs` holds 1 to [`TILE_RUNS`] runs, none empty.
    #[inline(always)]
    fn tile_setup<T: NodeTest<W>, Q: PacketNodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf_cpu: T::Cpu,
        node_cpu: Q::Cpu,
        runs: &[&[Ray]],
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        let mut packets: [std::mem::MaybeUninit<Packet>; TILE_RUNS] =
            [const { std::mem::MaybeUninit::uninit() }; TILE_RUNS];
        for (packet, rays) in packets.iter_mut().zip(runs) {
            match Q::packet(node_cpu, rays, self.reach) {
                Some(p) => {
                    packet.write(p);
                }
                // (`Packet` has no destructor: the packets made are simply left.)
                None => return self.tile_by_packets(runs, prims, obs, hits),
            }
        }
        // SAFETY: a packet was written for each of the `runs.len()` runs, the rest are not
        // in the slice.
        let packets = unsafe { std::slice::from_raw_parts(packets.as_ptr().cast::<Packet>(), runs.len()) };
        let first = &packets[0];
        let bits = |p: &Packet| p.o.to_array().map(f32::to_bits);
        // One origin and one direction sign per axis (the packets' entry planes) for all.
        if !packets.iter().all(|p| bits(p) == bits(first) && p.near_row == first.near_row) {
            return self.tile_by_packets(runs, prims, obs, hits);
        }
        // The inner nodes' test over the whole tile: each bound of the packets' widened to
        // hold them all (the origin and planes are the same).
        let mut tile = first.clone();
        for p in &packets[1..] {
            for a in 0..3 {
                tile.inv_lo[a] = lesser(tile.inv_lo[a], p.inv_lo[a]);
                tile.inv_hi[a] = greater(tile.inv_hi[a], p.inv_hi[a]);
                tile.slack[a] = greater(tile.slack[a], p.slack[a]);
            }
            tile.t_min_lo = lesser(tile.t_min_lo, p.t_min_lo);
            tile.t_far = greater(tile.t_far, p.t_far);
        }
        if O::WATCHES {
            for (rays, obs) in runs.iter().zip(obs.iter_mut()) {
                for (ray, o) in rays.iter().zip(obs.iter_mut()) {
                    o.query(QueryKind::Tile, ray);
                }
            }
        }
        self.tile_with::<T, Q, P, O>(leaf_cpu, node_cpu, runs, packets, &tile, prims, obs, hits);
    }

    /// The tile traversal of `packets` (made of `runs`; `tile` bounds them all for the inner
    /// nodes), with `T` for the rays' leaf tests and `Q` for the nodes: the closest hits go
    /// into `hits`, all `None` as the caller gives them (see [`WideBvh::packet_with`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn tile_with<T: NodeTest<W>, Q: PacketNodeTest<W>, P: Primitives + ?Sized, O: TraversalObserver>(
        &self,
        leaf_cpu: T::Cpu,
        node_cpu: Q::Cpu,
        runs: &[&[Ray]],
        packets: &[Packet],
        tile: &Packet,
        prims: &P,
        obs: &mut [[O; PACKET]; TILE_RUNS],
        hits: &mut TileHits,
    ) {
        let nodes = Q::new(node_cpu, tile);
        // Runs beyond the tile's have no rays (and no say in `t_far`).
        let mut state = [const { PacketRays::NONE }; TILE_RUNS];
        for ((s, p), rays) in state.iter_mut().zip(packets).zip(runs) {
            s.start(p, rays.len());
        }
        let mut setups = [NO_SETUPS; TILE_RUNS];
        // The tile's farthest interval end, for the inner nodes' test and the stack.
        let mut t_far = tile.t_far;
        let all = packets.iter().enumerate().fold(0u64, |m, (r, p)| m | u64::from(p.active) << (8 * r));
        let mut stack: Stack<TileEntry> = Stack::new();
        let mut current = TileEntry { child: ChildRef::ROOT, lanes: all, near: 0.0 };
        loop {
            if current.child.is_leaf() {
                for (r, p) in packets.iter().enumerate() {
                    let lanes = run_lanes(current.lanes, r);
                    if lanes != 0 {
                        self.packet_leaf::<T, P, O>(
                            leaf_cpu,
                            current.child,
                            lanes,
                            runs[r],
                            p,
                            prims,
                            &mut obs[r],
                            (&mut state[r], &mut setups[r], &mut hits[r]),
                        );
                    }
                }
                t_far = state.iter().map(PacketRays::t_far).fold(f32::NEG_INFINITY, greater);
            } else {
                let node = &self.nodes[current.child.node_index() as usize];
                if O::WATCHES {
                    // Every ray of the entry pays for the node's test.
                    for (r, obs) in obs.iter_mut().enumerate() {
                        for lane in super::lanes_of(run_lanes(current.lanes, r)) {
                            obs[lane].entered(current.child.node_index());
                            obs[lane].boxes_tested(W as u32);
                        }
                    }
                }
                let (near, mut mask) = nodes.test(tile, node, t_far);
                let mut order = [TileEntry { child: ChildRef::EMPTY, lanes: 0, near: 0.0 }; W];
                let mut k = 0;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let child = node.child[i];
                    let lanes = if child.is_leaf() {
                        // Each ray's own box test, packet by packet.
                        let mut lanes = 0;
                        for (r, p) in packets.iter().enumerate() {
                            let t_max = f32x8::new(state[r].t_max);
                            lanes |= u64::from(nodes.leaf_lanes(p, node, i, t_max)) << (8 * r);
                        }
                        lanes & current.lanes
                    } else {
                        current.lanes
                    };
                    if lanes != 0 {
                        order[k] = TileEntry { child, lanes, near: near[i] };
                        self.prefetch(child);
                        k += 1;
                    }
                }
                if k > 0 {
                    current = descend(&mut order[..k], &mut stack, |e| e.near);
                    continue;
                }
            }
            loop {
                let Some(e) = stack.pop() else { return };
                if e.near <= t_far {
                    current = e;
                    break;
                }
            }
        }
    }
}
