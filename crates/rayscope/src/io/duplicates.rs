//! Exact duplicate faces, dropped at load as mesh tools clean them: a face with the same
//! three vertices in the same orientation (a rotation of its corners) as an earlier face of
//! its group never shows (it is hit exactly where its first is, and ties go to the lower
//! slot), but rays test it all the same (10M copies of one triangle: every ray tested every
//! copy).

use std::collections::HashSet;
use std::path::Path;

use super::index_hash::{IndexHash, pack};
use super::memory::MeshSize;
use crate::error::Result;

/// The triangles of `corners` (three a triangle) but the duplicates, which are counted in
/// `duplicates`. The set of seen triangles is reserved fallibly (`size` and `path` make the
/// error of a mesh that does not fit).
pub fn without_duplicates(
    corners: &[u32],
    duplicates: &mut usize,
    size: MeshSize,
    path: &Path,
) -> Result<Vec<[u32; 3]>> {
    let mut seen = HashSet::with_hasher(IndexHash::new());
    seen.try_reserve(corners.len() / 3).map_err(|_| size.out_of_memory(path))?;
    let mut triangles = size.vec(path, corners.len() / 3)?;
    for c in corners.chunks_exact(3) {
        let t = [c[0], c[1], c[2]];
        // The rotation that starts at the smallest index: one key for the three.
        let first = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
        if seen.insert(pack([t[first], t[(first + 1) % 3], t[(first + 2) % 3]])) {
            triangles.push(t);
        } else {
            *duplicates += 1;
        }
    }
    triangles.shrink_to_fit();
    Ok(triangles)
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
}
