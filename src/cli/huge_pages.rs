//! The CLI's allocator: the system's, with every large block marked for transparent
//! huge pages before it is first written.
//!
//! A file's streams are written once into memory the process has never touched, and
//! each 4 KiB page of it is a fault: for the 135 MB of samples of a 100 MB CSV, about
//! 33,000 faults, a third of `inspect`'s CPU time (`perf record`, 2026-11-28:
//! `clear_page_erms`, `exc_page_fault`, the LRU and memcg bookkeeping). Marked with
//! `madvise(MADV_HUGEPAGE)`, the system maps such a block 2 MiB at a time where it can
//! (`perf stat -e page-faults compass-pdr inspect` on that file: 34,409 faults before,
//! 7,832 after, 51 of them huge pages; most of the rest map the file itself). It is a hint (what glibc's `glibc.malloc.hugetlb=1` tunable does for
//! every mapped block): the contents never change, the kernel may ignore it (huge pages
//! disabled, or none free), and on another system nothing is done. A page in the
//! middle of a huge page that the program never writes still takes memory, so only
//! blocks of several MiB, written whole, are marked. The browser's module has no such
//! choice and is unaffected.

use std::alloc::{GlobalAlloc, Layout, System};

/// The system allocator with the huge-page hint on blocks of [`MIN_HINT_BYTES`] or more.
pub(super) struct HugePageHint;

/// The size of a transparent huge page on x86-64 and most aarch64 kernels.
#[cfg(target_os = "linux")]
const HUGE_PAGE_BYTES: usize = 2 << 20;

/// Blocks below this are left as the system makes them: at most a few small pages
/// would be saved.
const MIN_HINT_BYTES: usize = 4 << 20;

// SAFETY: every call is the system allocator's, with the same arguments; `hint` only
// advises the kernel on whole pages inside the block just returned.
unsafe impl GlobalAlloc for HugePageHint {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract for `GlobalAlloc::alloc`, passed on.
        let ptr = unsafe { System.alloc(layout) };
        hint(ptr, layout.size());
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let ptr = unsafe { System.alloc_zeroed(layout) };
        hint(ptr, layout.size());
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from `System` through this allocator, with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as for `dealloc`, with the caller's `new_size`.
        let new_ptr = unsafe { System.realloc(ptr, layout, new_size) };
        hint(new_ptr, new_size);
        new_ptr
    }
}

/// Advises the kernel to back the whole huge pages inside `[ptr, ptr + size)` with
/// huge pages. Failure is ignored: the memory is then mapped as before.
#[cfg_attr(not(target_os = "linux"), allow(unused_variables))]
fn hint(ptr: *mut u8, size: usize) {
    if ptr.is_null() || size < MIN_HINT_BYTES {
        return;
    }
    #[cfg(target_os = "linux")]
    {
        let start = (ptr as usize).next_multiple_of(HUGE_PAGE_BYTES);
        let end = (ptr as usize).saturating_add(size) / HUGE_PAGE_BYTES * HUGE_PAGE_BYTES;
        if end > start {
            // SAFETY: the range lies inside the block the allocator just returned, is
            // page-aligned, and MADV_HUGEPAGE changes no contents and no access.
            let _ = unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE)
            };
        }
    }
}
