//! The allocator's settings for a long run. glibc's malloc gives a freed block above its mmap threshold
//! (128 KiB at first, raised with use up to 32 MiB) back to the system and trims the heap's top, so the
//! buffers a training step or a fit's frame allocates afresh (a few to tens of megabytes each) are
//! page-faulted and zeroed by the kernel again every time. Keeping freed memory for reuse: a toy's 1,000
//! training steps 60.0 → 53.7 s, the 48-frame drop's fit 145 → 129 s, the same bits out (profile
//! notebook, 2026-12-08). The cost: the process's resident memory stays near its peak until it exits.

/// Keep freed memory in the process for reuse (glibc: blocks up to 32 MiB from the heap, the heap never
/// trimmed, grown 256 MiB at a time). Call once at the start of a process that runs the method; elsewhere
/// (another C library) it does nothing.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets malloc's tuning parameters (thread-safe in glibc); the values are in range.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        // −1: never trim (mallopt(3)).
        libc::mallopt(libc::M_TRIM_THRESHOLD, -1);
        libc::mallopt(libc::M_TOP_PAD, 256 << 20);
    }
}
