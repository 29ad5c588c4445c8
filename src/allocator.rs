//! Allocator settings for the `penumbra` command (and benches that want
//! the command's behaviour).

/// Keeps freed memory in the process: the raster pipeline allocates and
/// frees tens of MB per pass (a shadow map's setup and tile buffers), and
/// glibc's defaults hand large blocks back to the kernel (mmap'd blocks,
/// trimmed thread-arena tops), so every pass page-faults fresh zeroed
/// pages — a third of the many-map techniques' CPU time
/// (docs/performance.md, issue 14). Serving blocks up to 32 MiB from the
/// heap and never trimming it removes those faults; the peak resident size
/// is unchanged (freed memory is reused, not added to).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_freed_memory() {
    const M_TRIM_THRESHOLD: i32 = -1;
    const M_MMAP_THRESHOLD: i32 = -3;
    extern "C" {
        fn mallopt(param: i32, value: i32) -> i32;
    }
    // SAFETY: `mallopt` is glibc's (this cfg), takes two plain ints, only
    // sets allocator parameters and is MT-Safe (glibc manual), so calling
    // it at any time from any thread cannot break memory safety. 32 MiB is
    // glibc's largest accepted mmap threshold on 64-bit; a refused value
    // leaves the default (the return value is ignored).
    unsafe {
        mallopt(M_MMAP_THRESHOLD, 32 << 20);
        mallopt(M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Elsewhere the system allocator's defaults are kept.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_freed_memory() {}
