//! Big arrays on huge pages. A million-triangle build writes a few hundred megabytes of
//! fresh arrays (the builder's primitives, the trees, the packed triangles); on 4 KB pages the
//! system's page faults were 7% of its time. Asked for before their first touch, Linux backs
//! such arrays with transparent huge pages (2 MB) where it has them enabled ("madvise" or
//! "always"), as Embree asks for its own big blocks: 512 times fewer faults. Elsewhere, or with
//! huge pages off, the advice is a no-op.

use bytemuck::Zeroable;

/// Arrays of at least this many bytes are advised: two huge pages, so that at least one
/// whole aligned huge page lies inside.
const ADVISED_BYTES: usize = 4 << 20;

/// An empty vector with room for `capacity` items, its room advised (see the module).
pub(crate) fn with_capacity<T>(capacity: usize) -> Vec<T> {
    let v = Vec::with_capacity(capacity);
    advise(v.as_ptr(), v.capacity());
    v
}

/// `len` zeros, from zeroed memory ([`bytemuck::zeroed_vec`]: a large array comes as fresh
/// pages, untouched until the threads filling it write them), advised (see the module).
pub(crate) fn zeroed<T: Zeroable>(len: usize) -> Vec<T> {
    let v: Vec<T> = bytemuck::zeroed_vec(len);
    advise(v.as_ptr(), v.capacity());
    v
}

/// Advise the whole pages inside the `capacity` items from `start` for huge pages, where they
/// are [`ADVISED_BYTES`] or more.
fn advise<T>(start: *const T, capacity: usize) {
    let bytes = capacity.saturating_mul(std::mem::size_of::<T>());
    if bytes < ADVISED_BYTES {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        // SAFETY: sysconf has no preconditions.
        let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap_or(0);
        if !page.is_power_of_two() {
            return;
        }
        let (from, to) = ((start as usize).next_multiple_of(page), (start as usize + bytes) & !(page - 1));
        if from < to {
            // SAFETY: the range is whole pages inside one live allocation of ours; the advice
            // only changes which pages back it, never what it holds, and a refusal (huge pages
            // off, an old kernel) is harmless, so its result is not read.
            unsafe {
                libc::madvise(from as *mut libc::c_void, to - from, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = start;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advised_arrays_are_ordinary_arrays() {
        let mut v: Vec<u64> = with_capacity(1 << 20);
        assert!(v.capacity() >= 1 << 20);
        v.extend(0..1 << 20);
        assert_eq!(v.iter().sum::<u64>(), (1u64 << 20) * ((1 << 20) - 1) / 2);
        let z: Vec<[u32; 4]> = zeroed(1 << 19);
        assert_eq!(z.len(), 1 << 19);
        assert!(z.iter().all(|x| *x == [0; 4]));
        // Small ones are not advised, and empty ones are fine.
        assert!(with_capacity::<u8>(0).is_empty() && zeroed::<u8>(10) == [0; 10]);
    }
}
