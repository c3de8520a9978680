//! Large buffers, backed by huge pages where the system allows it.
//!
//! A build writes tens of megabytes of fresh memory (references, the partition's second
//! buffer, the collapse's table, the leaf groups, the nodes): with 4 KiB pages the kernel
//! takes one fault and clears one page per 4 KiB written, and the random reads of the leaf
//! packing, and later of every incoherent ray, miss the TLB. On Linux with transparent huge pages in `madvise` mode (the common default), advising
//! a buffer before it is first written gets it 2 MiB pages instead. Only the buffers quiver
//! allocates are advised; nothing process-wide is set.

/// `Vec::with_capacity(n)`, its whole 2 MiB pages advised for huge pages.
pub(crate) fn with_capacity<T>(n: usize) -> Vec<T> {
    let v: Vec<T> = Vec::with_capacity(n);
    advise(v.as_ptr().cast(), v.capacity() * std::mem::size_of::<T>());
    v
}

/// `bytemuck::zeroed_vec(n)`, advised as [`with_capacity`] does (pages the allocator hands
/// over untouched, as it does for large zeroed blocks, are then cleared as huge pages).
pub(crate) fn zeroed_vec<T: bytemuck::Zeroable + Clone>(n: usize) -> Vec<T> {
    let v: Vec<T> = bytemuck::zeroed_vec(n);
    advise(v.as_ptr().cast(), v.capacity() * std::mem::size_of::<T>());
    v
}

/// Buffers below this are left alone. Their faults cost little, while a huge page can cost a
/// stall (with `defrag` at `madvise`, the kernel compacts memory to find one): measured side by
/// side, advising from 4 MiB made 100k-triangle builds at 2 threads slower in some runs, while
/// million-triangle builds gained.
const MIN_BYTES: usize = 16 << 20;

const HUGE_PAGE: usize = 2 << 20;

#[cfg(target_os = "linux")]
fn advise(start: *const u8, bytes: usize) {
    const MADV_HUGEPAGE: i32 = 14;
    extern "C" {
        fn madvise(addr: *mut std::ffi::c_void, len: usize, advice: i32) -> i32;
    }
    if bytes < MIN_BYTES {
        return;
    }
    let first = (start as usize).next_multiple_of(HUGE_PAGE);
    let end = (start as usize + bytes) / HUGE_PAGE * HUGE_PAGE;
    if end <= first {
        return;
    }
    // SAFETY: `first..end` lies inside one live allocation of `bytes` bytes from `start`
    // (rounded inwards to whole huge pages, so page-aligned as madvise requires), which the
    // caller's Vec owns. MADV_HUGEPAGE only changes how the kernel backs those pages: it
    // reads, writes and frees nothing, so no Rust-visible memory changes. A kernel without
    // transparent huge pages answers EINVAL, which leaves the buffer as it was; the result
    // is therefore ignored.
    unsafe {
        madvise(first as *mut std::ffi::c_void, end - first, MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise(_start: *const u8, _bytes: usize) {}

#[cfg(test)]
mod tests {
    #[test]
    fn advised_buffers_are_ordinary_vectors() {
        let mut v: Vec<u64> = super::with_capacity(1 << 20);
        assert!(v.capacity() >= 1 << 20 && v.is_empty());
        v.extend(0..1 << 20);
        assert_eq!(v[12345], 12345);
        let z: Vec<[f32; 8]> = super::zeroed_vec(1 << 18);
        assert_eq!(z.len(), 1 << 18);
        assert!(z.iter().all(|x| x.iter().all(|&f| f == 0.0)));
    }
}
