//! Global primitive ids (every mesh's triangles in order, then the spheres) and the
//! primitives they name, found from the meshes' sizes: an array of the answers took 12 bytes
//! a triangle for the scene's whole life.

use super::{Mesh, PrimRef};

/// Which primitive each global id names.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PrimIds {
    /// The first id of each mesh's triangles, then the first sphere's.
    first: Vec<u32>,
    /// Ids in all.
    count: u32,
}

impl PrimIds {
    /// The ids of `meshes`' triangles and `spheres` spheres.
    pub fn new(meshes: &[Mesh], spheres: usize) -> PrimIds {
        let mut first = Vec::with_capacity(meshes.len() + 1);
        let mut next = 0u32;
        for m in meshes {
            first.push(next);
            next += m.triangles.len() as u32;
        }
        first.push(next);
        PrimIds { first, count: next + spheres as u32 }
    }

    /// Number of primitives.
    pub fn len(&self) -> usize {
        self.count as usize
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The primitive of id `id` (below [`PrimIds::len`]).
    #[inline]
    pub fn get(&self, id: u32) -> PrimRef {
        // The last mesh starting at or before `id` (empty meshes start where the next does);
        // past the meshes, the spheres.
        let m = self.first.partition_point(|&f| f <= id) - 1;
        if m + 1 < self.first.len() {
            PrimRef::Triangle { mesh: m as u32, face: id - self.first[m] }
        } else {
            PrimRef::Sphere(id - self.first[m])
        }
    }
}
