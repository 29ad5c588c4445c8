//! Allocator settings for the `penumbra` command (and benches that want
//! the command's behaviour), and how much memory is left to allocate.

/// Keeps freed memory in the process: the raster pipeline allocates and
/// frees tens of MB per pass (a shadow map's setup and tile buffers), and
/// glibc's defaults hand large blocks back to the kernel (mmap'd blocks,
/// trimmed thread-arena tops), so every pass page-faults fresh zeroed
/// pages — a third of the many-map techniques' CPU time
/// (docs/performance.md). Serving blocks up to 32 MiB from the
/// heap and never trimming it removes those faults; the peak resident size
/// is unchanged (freed memory is reused, not added to).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn keep_freed_memory() {
    // SAFETY: `mallopt` is glibc's (this cfg), takes two plain ints, only
    // sets allocator parameters and is MT-Safe (glibc manual), so calling
    // it at any time from any thread cannot break memory safety. 32 MiB is
    // glibc's largest accepted mmap threshold on 64-bit; a refused value
    // leaves the default (the return value is ignored).
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, libc::c_int::MAX);
    }
}

/// Elsewhere the system allocator's defaults are kept.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn keep_freed_memory() {}

/// Memory this process can still allocate: the machine's available memory
/// (`MemAvailable`) or, if lower, what an address-space limit (`ulimit
/// -v`, `RLIMIT_AS`) leaves beside what is already mapped; `None` where
/// neither is readable (not Linux). The one probe behind every "needs
/// about N GiB, more than the M GiB available" refusal (images and
/// built-in geometry), read from `/proc` so that no `unsafe` call is
/// needed.
pub fn memory_budget() -> Option<u64> {
    let field = |file: &str, name: &str| -> Option<u64> {
        let text = std::fs::read_to_string(file).ok()?;
        let line = text.lines().find(|l| l.starts_with(name))?;
        line[name.len()..].split_whitespace().next()?.parse().ok()
    };
    let available = field("/proc/meminfo", "MemAvailable:").map(|kib| kib * 1024);
    // "Max address space   <soft> <hard> bytes"; the soft limit applies.
    let limit = field("/proc/self/limits", "Max address space");
    let mapped = field("/proc/self/status", "VmSize:").map_or(0, |kib| kib * 1024);
    let address_space = limit.map(|l| l.saturating_sub(mapped));
    match (available, address_space) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}
