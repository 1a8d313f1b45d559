//! The memory a mesh needs, asked for before it is read: a mesh too large for the memory the
//! process may have (an address-space limit, `ulimit -v`, or the machine's) is an error that
//! says so ([`Error::OutOfMemory`]), not an abort in the middle of the OBJ reader or the BVH
//! build, whose allocations are not ours to check one by one.

use std::path::Path;

use bytemuck::Zeroable;

use crate::error::{Error, Result};

/// Bytes of peak memory (address space) per triangle, loading and building the BVH included:
/// measured 184 for 10M copies of one triangle (the OBJ reader's face list is the peak) and
/// 223 for a 10M-triangle grid (the wide BVH's build, with the mesh, the binary BVH and the
/// shapes alive), rounded up.
pub const BYTES_PER_TRIANGLE: u64 = 256;

/// Bytes of peak memory per `v`, `vt` or `vn` line: the reader's copy, ours and the map that
/// unifies them (about 70 measured), rounded up.
pub const BYTES_PER_VERTEX: u64 = 96;

/// The size of a mesh file, as the scan of its lines counted it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshSize {
    /// The triangles of its faces (a face of n corners is n - 2).
    pub triangles: u64,
    /// Its `v`, `vt` and `vn` lines.
    pub vertices: u64,
}

impl MeshSize {
    /// The peak memory loading it and building its BVH take, estimated.
    pub fn bytes(&self) -> u64 {
        let triangles = self.triangles.saturating_mul(BYTES_PER_TRIANGLE);
        triangles.saturating_add(self.vertices.saturating_mul(BYTES_PER_VERTEX))
    }

    /// Check that [`MeshSize::bytes`] can be had, by reserving them (address space only: no
    /// page is touched) and giving them back; `path` names the file in the error.
    pub fn reserve(&self, path: &Path) -> Result<()> {
        let fits = usize::try_from(self.bytes()).is_ok_and(|b| Vec::<u8>::new().try_reserve_exact(b).is_ok());
        if fits { Ok(()) } else { Err(self.out_of_memory(path)) }
    }

    /// An empty vector with room for `capacity` items, or the error that the mesh at `path`
    /// does not fit (where an allocation of the loader fails despite [`MeshSize::reserve`]).
    pub fn vec<T>(&self, path: &Path, capacity: usize) -> Result<Vec<T>> {
        let mut v = Vec::new();
        v.try_reserve_exact(capacity).map_err(|_| self.out_of_memory(path))?;
        Ok(v)
    }

    /// `len` zeros, from zeroed memory (for a large array, fresh pages that the system zeroes
    /// as the threads filling them first touch them: writing the zeros took a pass on one
    /// thread), or the error that the mesh at `path` does not fit.
    pub fn zeroed<T: Zeroable>(&self, path: &Path, len: usize) -> Result<Vec<T>> {
        bytemuck::allocation::try_zeroed_slice_box(len).map(Vec::from).map_err(|_| self.out_of_memory(path))
    }

    /// The error of the mesh at `path` not fitting.
    pub fn out_of_memory(&self, path: &Path) -> Error {
        Error::OutOfMemory { path: path.to_path_buf(), triangles: self.triangles, bytes: self.bytes() }
    }
}

/// Give the heap's free pages back to the system. glibc keeps the memory of freed blocks below
/// its mapping threshold (which grows to 32 MB as big blocks are freed) in its heaps, resident,
/// for later allocations: a big scene's build frees tens of megabytes that way (the wide
/// collapse's plan, 14 MB for a million triangles), which then counted in the peak resident
/// memory beside the slots' arrays made after it. Elsewhere a no-op.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim has no preconditions; it only returns free heap pages to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mesh_larger_than_any_memory_is_an_error_naming_it() {
        let huge = MeshSize { triangles: 1 << 60, vertices: 3 };
        match huge.reserve(Path::new("huge.obj")) {
            Err(e @ Error::OutOfMemory { .. }) => {
                let text = e.to_string();
                assert!(text.contains("huge.obj") && text.contains(&format!("{} triangles", 1u64 << 60)), "{text}");
            }
            other => panic!("{other:?}"),
        }
        assert!(MeshSize { triangles: 1000, vertices: 500 }.reserve(Path::new("small.obj")).is_ok());
    }
}
