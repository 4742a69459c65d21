//! Allocator settings for a batch run.
//!
//! A map is built scan by scan, and each scan allocates, fills and frees
//! buffers of tens of megabytes (measured points, propagated ends, the local
//! grid). glibc serves allocations above its mmap threshold (128 KiB, raised
//! on the fly only up to the size of the last one freed) with fresh pages
//! from the kernel, so every scan pays their page faults and zeroing again:
//! about a tenth of an OPDF map's time at 5 cm (`sigmap map
//! experiments/octomap_bench.toml --resolution 0.05`: 45 600 minor faults,
//! 0.48 s; with the settings below 28 900 and 0.43 s). Keeping freed memory in
//! the heap lets the next scan reuse it; the cost is that the process keeps
//! its peak heap until it exits (peak RSS 109 → 122 MB there).

/// Keeps freed memory in the process for reuse: allocations up to 32 MiB
/// (glibc's largest mmap threshold) come from the heap, and the heap is
/// trimmed only beyond 1 GiB of free space. Does nothing off glibc.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        extern "C" {
            fn mallopt(param: i32, value: i32) -> i32;
        }
        const M_TRIM_THRESHOLD: i32 = -1;
        const M_MMAP_THRESHOLD: i32 = -3;
        // SAFETY: mallopt only changes glibc's allocation thresholds; it is
        // called before any other thread exists. A rejected value (return 0)
        // leaves glibc's default, which is correct, only slower.
        unsafe {
            mallopt(M_MMAP_THRESHOLD, 32 << 20);
            mallopt(M_TRIM_THRESHOLD, 1 << 30);
        }
    }
}
