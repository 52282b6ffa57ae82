//! Allocator settings for the CPU backend's many large, short-lived buffers.
//!
//! Every op of the CPU backend returns a fresh buffer; at 350x518 the DPT heads' activations
//! are ~23 MB each. With glibc's defaults, buffers above its (adaptive) mmap threshold are
//! mapped and unmapped on every op, and freed heap tops are trimmed back to the kernel, so
//! each op pays page faults and zero-filling of fresh pages: ~25% of the tiny forward
//! (docs/PERFORMANCE.md, "What made the tiny widths fast"). Raising the mmap threshold to
//! glibc's maximum and disabling the trim keeps freed memory in the process for the next
//! op. Peak memory is still set by the live tensors; the process simply does not hand
//! memory back between ops.

/// glibc's largest accepted mmap threshold on 64-bit (`HEAP_MAX_SIZE / 2`).
pub const MMAP_THRESHOLD_BYTES: i32 = 32 << 20;

/// Applies the settings once, at the start of a process (binaries and benchmarks call it;
/// the library never does). Returns whether they took effect: `false` off glibc, or where
/// an environment variable (`MALLOC_*` / `GLIBC_TUNABLES`) is left to decide.
pub fn keep_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        if std::env::var_os("GLIBC_TUNABLES").is_some()
            || std::env::var_os("MALLOC_MMAP_THRESHOLD_").is_some()
            || std::env::var_os("MALLOC_TRIM_THRESHOLD_").is_some()
        {
            return false;
        }
        // SAFETY: mallopt only changes allocator parameters; it is called before other threads
        // allocate (process start), and glibc validates the values (returns 0 if refused).
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}
