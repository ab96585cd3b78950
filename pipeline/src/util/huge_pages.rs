//! The process's allocator: the system allocator, with every block of [`MIN_ADVISED`] bytes
//! or more advised for transparent huge pages (`madvise(MADV_HUGEPAGE)`).
//!
//! A conversion at 1024³ allocates and fills a few hundred megabytes of tables once each, so
//! a good part of its kernel time was page faults and the clearing of fresh 4 KiB pages
//! (docs/record/PERFORMANCE-history.md, "The conversion stages (fifth part)"). Where the system's
//! transparent huge pages are set to `madvise` (a common default, and this machine's), an
//! advised block is faulted in 2 MiB at a time instead. Where they are `always` the advice
//! changes nothing, and where they are `never` the kernel ignores it. The advice never
//! changes what memory holds, so outputs are the same bytes with it or without.
//!
//! `SPARC3D_HUGE_PAGES=0` in the environment turns the advice off ([`configure_from_env`]),
//! for a machine where the kernel's synchronous compaction of advised regions
//! (`/sys/kernel/mm/transparent_hugepage/defrag` set to `madvise` or `always`) stalls.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether large blocks are advised; on unless [`configure_from_env`] turned it off.
static ENABLED: AtomicBool = AtomicBool::new(true);

/// Reads `SPARC3D_HUGE_PAGES` (`0` turns the advice off); called once at the start of `main`.
pub fn configure_from_env() {
    set_enabled(std::env::var_os("SPARC3D_HUGE_PAGES").is_none_or(|v| v != "0"));
}

/// Turns the advice on or off for blocks allocated from now on.
pub fn set_enabled(on: bool) {
    ENABLED.store(on, Ordering::Relaxed);
}

/// Blocks at least this large are advised (smaller ones rarely span a whole huge page).
pub const MIN_ADVISED: usize = 4 << 20;

/// The size and alignment of a transparent huge page on x86-64 and most aarch64 kernels.
const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, advising large blocks for huge pages.
pub struct HugePageAlloc;

/// Advises the whole huge pages inside the block `[ptr, ptr + size)`.
fn advise(ptr: *mut u8, size: usize) {
    if ptr.is_null() || size < MIN_ADVISED || !ENABLED.load(Ordering::Relaxed) {
        return;
    }
    let start = (ptr as usize).next_multiple_of(HUGE_PAGE);
    let end = (ptr as usize + size) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        #[cfg(target_os = "linux")]
        // SAFETY: `[start, end)` lies inside a block this allocator has just handed out and
        // is page aligned; MADV_HUGEPAGE only changes how those pages are faulted in, never
        // their contents. A failure (an old kernel, huge pages off) leaves them as they were.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

// SAFETY: every call is passed on to `System` unchanged; `advise` only touches the paging
// policy of memory inside the block `System` returned.
unsafe impl GlobalAlloc for HugePageAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc(layout);
        advise(ptr, layout.size());
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let ptr = System.alloc_zeroed(layout);
        advise(ptr, layout.size());
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let ptr = System.realloc(ptr, layout, new_size);
        advise(ptr, new_size);
        ptr
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// The `VmFlags` of the mapping of this process that holds `addr`, from /proc/self/smaps.
    fn vm_flags(addr: usize) -> String {
        let smaps = std::fs::read_to_string("/proc/self/smaps").unwrap();
        let mut inside = false;
        for line in smaps.lines() {
            let range = line.split_whitespace().next().unwrap_or_default();
            if let Some((lo, hi)) = range.split_once('-') {
                if let (Ok(lo), Ok(hi)) =
                    (usize::from_str_radix(lo, 16), usize::from_str_radix(hi, 16))
                {
                    inside = (lo..hi).contains(&addr);
                    continue;
                }
            }
            if inside {
                if let Some(flags) = line.strip_prefix("VmFlags:") {
                    return flags.trim().to_string();
                }
            }
        }
        panic!("no mapping holds {addr:#x}");
    }

    /// Allocates 40 MiB through the allocator, writes and reads it back, and returns the
    /// flags of the mapping that holds its first whole huge page. glibc maps blocks over
    /// 32 MiB afresh each time (its largest dynamic mmap threshold), so no block inherits an
    /// earlier one's advice.
    fn flags_of_a_large_block(zeroed: bool) -> String {
        let layout = Layout::from_size_align(40 << 20, 64).unwrap();
        // SAFETY: a non-zero layout; the block is written only within its size and freed
        // with the same layout.
        unsafe {
            let ptr = if zeroed {
                HugePageAlloc.alloc_zeroed(layout)
            } else {
                HugePageAlloc.alloc(layout)
            };
            assert!(!ptr.is_null());
            let block = std::slice::from_raw_parts_mut(ptr, layout.size());
            if zeroed {
                assert!(block.iter().all(|&b| b == 0));
            }
            for (i, b) in block.iter_mut().enumerate() {
                *b = (i % 251) as u8;
            }
            assert!(block.iter().enumerate().all(|(i, &b)| b == (i % 251) as u8));
            let flags = vm_flags((ptr as usize).next_multiple_of(HUGE_PAGE));
            HugePageAlloc.dealloc(ptr, layout);
            flags
        }
    }

    #[test]
    fn large_blocks_are_advised_for_huge_pages_unless_turned_off() {
        // One test, as the switch is process-wide.
        let thp = std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists();
        for zeroed in [false, true] {
            let flags = flags_of_a_large_block(zeroed);
            // "hg": the mapping was advised MADV_HUGEPAGE (proc(5)); a kernel without
            // transparent huge pages refuses the advice.
            assert_eq!(flags.split(' ').any(|f| f == "hg"), thp, "flags {flags}");
        }
        set_enabled(false);
        let flags = flags_of_a_large_block(false);
        set_enabled(true);
        assert!(!flags.split(' ').any(|f| f == "hg"), "flags {flags}");
    }
}
