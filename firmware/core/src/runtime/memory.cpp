// Process-wide memory policy (see fuzzystereo/memory.hpp). glibc's malloc serves requests above
// its mmap threshold (128 KiB, growing dynamically up to 32 MiB) with fresh anonymous mappings and
// unmaps them on free; heap tops beyond the trim threshold are returned to the kernel. Either way
// the next frame's buffers are new pages, each a page fault plus a kernel zero-fill. Raising both
// thresholds keeps the buffers in the heap for reuse. (A per-stage buffer pool would do the same
// for the matcher only; the policy covers every stage and the robot loop with two lines.)
#include "fuzzystereo/memory.hpp"

#include <cstdlib>  // defines __GLIBC__ on glibc systems (via <features.h>)

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace fs {

bool retain_freed_memory() {
#if defined(__SANITIZE_ADDRESS__)
  return false;  // ASan's allocator replaces glibc malloc; mallopt does not reach it
#elif defined(__GLIBC__)
  // 32 MiB is the largest mmap threshold glibc accepts on 64-bit targets (a larger value is
  // refused and leaves the dynamic threshold in place); every per-frame buffer is smaller.
  const bool mmap_ok = mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024) == 1;
  const bool trim_ok = mallopt(M_TRIM_THRESHOLD, 1024 * 1024 * 1024) == 1;
  return mmap_ok && trim_ok;
#else
  return false;
#endif
}

}  // namespace fs
