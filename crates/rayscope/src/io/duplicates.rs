//! Exact duplicate faces, dropped at load as mesh tools clean them: a face with the same
//! three vertices in the same orientation (a rotation of its corners) as an earlier face of
//! its group never shows (it is hit exactly where its first is, and ties go to the lower
//! slot), but rays test it all the same (10M copies of one triangle: every ray tested every
//! copy).
//!
//! They are found by a counting sort of the triangles on their smallest corner: a triangle's
//! duplicates share its smallest corner, so each is looked for among the few triangles of
//! that corner's bucket, buckets on every core. The sort runs on every core too (counts and
//! places taken with atomic operations), so a bucket's triangles come in any order: a
//! triangle is a duplicate when a triangle before it in the file, wherever in the bucket,
//! has its key, which no order changes. A hash set of every triangle did the same on one
//! core, in about 5% of a big mesh's load and BVH; the sort on one core was a tenth of the
//! load of a 4M-triangle mesh.

use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering::Relaxed};

use rayon::prelude::*;

use super::memory::MeshSize;
use crate::error::Result;

/// Buckets up to this size are searched pair by pair; larger ones (many triangles around one
/// vertex, or copies of one triangle) are sorted.
const SMALL_BUCKET: usize = 16;

/// Vertices whose buckets one task searches.
const VERTICES_PER_TASK: usize = 1 << 14;

/// The triangles of `corners` (three a triangle) but the duplicates, which are counted in
/// `duplicates`. The arrays are reserved fallibly (`size` and `path` make the error of a mesh
/// that does not fit).
pub fn without_duplicates(
    corners: &[u32],
    duplicates: &mut usize,
    size: MeshSize,
    path: &Path,
) -> Result<Vec<[u32; 3]>> {
    let triangles: &[[u32; 3]] = bytemuck::cast_slice(&corners[..corners.len() / 3 * 3]);
    let n = triangles.len();
    let smallest = |t: &[u32; 3]| t[0].min(t[1]).min(t[2]) as usize;
    let vertices = corners.par_iter().max().map_or(0, |&m| m as usize + 1);
    // `end[v]`, then `first[v]`: where the bucket of the triangles whose smallest corner is `v`
    // ends, then starts, in `order` (`end[vertices]` is `n`).
    let bounds: Vec<AtomicU32> = size.zeroed(path, vertices + 1)?;
    triangles.par_iter().for_each(|t| {
        bounds[smallest(t)].fetch_add(1, Relaxed);
    });
    let mut end = 0;
    for b in &bounds {
        end += b.load(Relaxed);
        b.store(end, Relaxed);
    }
    let order: Vec<AtomicU32> = size.zeroed(path, n)?;
    triangles.par_iter().enumerate().for_each(|(t, tri)| {
        let at = bounds[smallest(tri)].fetch_sub(1, Relaxed) - 1;
        order[at as usize].store(t as u32, Relaxed);
    });
    let order: Vec<u32> = order.into_iter().map(AtomicU32::into_inner).collect();
    let first: Vec<u32> = bounds.into_iter().map(AtomicU32::into_inner).collect();
    let key = |t: u32| rotated(&triangles[t as usize]);
    let mut found: Vec<u32> = (0..vertices.div_ceil(VERTICES_PER_TASK))
        .into_par_iter()
        .flat_map_iter(|task| {
            let (lo, hi) = (task * VERTICES_PER_TASK, ((task + 1) * VERTICES_PER_TASK).min(vertices));
            let mut found = Vec::new();
            for v in lo..hi {
                let bucket = &order[first[v] as usize..first[v + 1] as usize];
                bucket_duplicates(bucket, &key, &mut found);
            }
            found
        })
        .collect();
    *duplicates += found.len();
    if found.is_empty() {
        let mut kept = size.vec(path, n)?;
        triangles.par_iter().copied().collect_into_vec(&mut kept);
        return Ok(kept);
    }
    found.par_sort_unstable();
    let mut kept = size.vec(path, n - found.len())?;
    let mut next = found.iter().peekable();
    for (t, tri) in triangles.iter().enumerate() {
        if next.next_if_eq(&&(t as u32)).is_none() {
            kept.push(*tri);
        }
    }
    Ok(kept)
}

/// The rotation of a triangle's corners that starts at its smallest index: one key for the
/// three rotations (a reversal is another face, seen from the other side).
#[inline(always)]
fn rotated(c: &[u32; 3]) -> [u32; 3] {
    let first = (0..3).min_by_key(|&k| c[k]).unwrap_or(0);
    [c[first], c[(first + 1) % 3], c[(first + 2) % 3]]
}

/// Push onto `found` the triangles of `bucket` (in any order) whose key a triangle before
/// them in the file has.
fn bucket_duplicates(bucket: &[u32], key: &impl Fn(u32) -> [u32; 3], found: &mut Vec<u32>) {
    if bucket.len() <= SMALL_BUCKET {
        for &t in bucket {
            let k = key(t);
            if bucket.iter().any(|&e| e < t && key(e) == k) {
                found.push(t);
            }
        }
        return;
    }
    // By key, then file order: all but the first of each run of equal keys are duplicates.
    let mut sorted: Vec<([u32; 3], u32)> = bucket.iter().map(|&t| (key(t), t)).collect();
    sorted.sort_unstable();
    found.extend(sorted.windows(2).filter(|w| w[0].0 == w[1].0).map(|w| w[1].1));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_are_duplicates_and_reversals_are_not() {
        let corners = [0, 1, 2, 1, 2, 0, 2, 0, 1, 0, 2, 1, 0, 1, 2, 3, 4, 5];
        let mut duplicates = 0;
        let kept = without_duplicates(&corners, &mut duplicates, MeshSize::default(), Path::new("t.obj")).unwrap();
        assert_eq!(kept, vec![[0, 1, 2], [0, 2, 1], [3, 4, 5]]);
        assert_eq!(duplicates, 3);
    }

    /// The same triangles as a hash set of rotated keys keeps, in small and large buckets
    /// (few vertices, so buckets hold up to hundreds of triangles, many of them duplicates;
    /// many, so most buckets are small), on one thread and on several (buckets filled in
    /// any order).
    #[test]
    fn matches_a_set_of_seen_triangles() {
        let mut seed = 12345u64;
        for vertices in [3u64, 5, 12, 40, 400, 20_000] {
            let mut corners = Vec::new();
            for _ in 0..30_000 {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                corners.extend([seed >> 20, seed >> 30, seed >> 40].map(|x| (x % vertices) as u32));
            }
            let mut seen = std::collections::HashSet::new();
            let want: Vec<[u32; 3]> =
                corners.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).filter(|t| seen.insert(rotated(t))).collect();
            for threads in [1, 4] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let mut duplicates = 0;
                let got = pool.install(|| {
                    without_duplicates(&corners, &mut duplicates, MeshSize::default(), Path::new("t.obj")).unwrap()
                });
                assert_eq!(got, want, "{vertices} vertices, {threads} threads");
                assert_eq!(duplicates, 30_000 - want.len());
            }
        }
    }
}
