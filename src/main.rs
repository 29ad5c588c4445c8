//! The `penumbra` command; everything lives in the library.

fn main() -> std::process::ExitCode {
    tune_allocator();
    penumbra::cli::main_with_args()
}

/// Keeps freed memory in the process: the raster pipeline allocates and
/// frees tens of MB per pass (a shadow map's setup and tile buffers), and
/// glibc's defaults hand large blocks back to the kernel (mmap'd blocks,
/// trimmed thread-arena tops), so every pass page-faults fresh zeroed
/// pages — a third of the many-map techniques' CPU time
/// (docs/performance.md, issue 14). Serving blocks up to 32 MiB from the
/// heap and never trimming it removes those faults; the peak resident size
/// is unchanged (freed memory is reused, not added to).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn tune_allocator() {
    const M_TRIM_THRESHOLD: i32 = -1;
    const M_MMAP_THRESHOLD: i32 = -3;
    extern "C" {
        fn mallopt(param: i32, value: i32) -> i32;
    }
    // SAFETY: `mallopt` is glibc's (this cfg), takes two plain ints and
    // only sets allocator parameters; it is called before any other thread
    // exists. 32 MiB is glibc's largest accepted mmap threshold on 64-bit;
    // a refused value leaves the default (the return value is ignored).
    unsafe {
        mallopt(M_MMAP_THRESHOLD, 32 << 20);
        mallopt(M_TRIM_THRESHOLD, i32::MAX);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_allocator() {}
