#pragma once
// Process-wide memory policy for the per-frame loop.

namespace fs {

// Keep freed heap memory mapped in the process (glibc: mmap threshold 32 MiB, its maximum; trim
// threshold 1 GiB), so the large per-frame buffers (label images, disparity maps, entropy maps: 0.5-2 MB
// each on a KITTI frame) are served from memory that is already mapped instead of fresh mmap'd
// pages: no page fault and no kernel zero-fill per 4 KiB page on every frame. Measured on the
// matcher (tests/bench, KITTI-sized pair, 1 thread): -6 % time, SLIC -15 %; docs/results.md.
// The price is that the process keeps its peak heap (~100 MB at 1242 x 375, D = 160) until it
// exits, which is what a robot's frame loop wants anyway. Call once at program start, before the
// first frame; a no-op without glibc or under AddressSanitizer (its own allocator). Returns whether
// the policy was applied.
bool retain_freed_memory();

}  // namespace fs
