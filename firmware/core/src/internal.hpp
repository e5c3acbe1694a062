// Internal helpers of the core: integer math, fixed-point tables, threading.
#pragma once
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <cstdint>
#include <vector>

#include "fuzzystereo/union_find.hpp"

#if defined(FS_HAVE_OPENMP)
#include <omp.h>
#endif

// Function multi-versioning for the hot cost loop: on x86-64 gcc emits an AVX2 clone and a baseline
// clone and picks one at load time; on aarch64 NEON is baseline, so plain code is vectorised as is.
// This is the only platform switch in the core. FS_TARGET_CLONES_V4 adds an x86-64-v4 (AVX-512)
// clone, used where it measured faster: the cost stage's register-blocked sums and its NCC /
// IGSAD normalisation (cost stage ~44 -> ~40 ms per KITTI frame at 1 thread), and the gradient,
// ESR row passes and densify kernels (~1 ms together). SLIC's window assignment keeps AVX2: with an
// AVX-512 clone it ran 1.6x slower (docs/results.md, session 11).
// The core builds with -ffp-contract=off (firmware/CMakeLists.txt), so every clone computes the same doubles.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define FS_TARGET_CLONES __attribute__((target_clones("avx2", "default")))
#define FS_TARGET_CLONES_V4 __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
// x86-64-v3 (AVX2 with POPCNT): the census Hamming sums of the boundary refinement (boundary/).
#define FS_TARGET_CLONES_V3 __attribute__((target_clones("arch=x86-64-v3", "default")))
// AVX-512 with VPOPCNTDQ (a vector popcount; Ice Lake, Zen 4): the boundary refinement's census
// Hamming tables. target_clones has no feature-only clone for it on gcc 12 (its arch= names test the
// CPU model, and Zen 4 matches none), so boundary/ picks it at run time with __builtin_cpu_supports.
#define FS_TARGET_VPOPCNT __attribute__((target("arch=x86-64-v4,avx512vpopcntdq")))
#define FS_HAVE_VPOPCNT_DISPATCH 1
// AVX-512 F/BW/CD/DQ/VL (x86-64-v4) for kernels written with gcc vector types whose operations only
// AVX-512BW has as single instructions (a 32-lane uint16 table lookup, vpermw): ESR's sorted block
// entropy (esr/). Without it gcc lowers them to scalar code, so esr/ picks them at run time
// (__builtin_cpu_supports) and otherwise keeps its scalar sliding-window kernel.
#define FS_TARGET_AVX512BW __attribute__((target("arch=x86-64-v4")))
#define FS_HAVE_AVX512BW_DISPATCH 1
// AVX2 for kernels written with its intrinsics (<immintrin.h>), picked at run time with
// cpu_has_avx2(): ESR's sorted block entropy on CPUs without AVX-512BW (vpshufb table lookups).
#define FS_TARGET_AVX2 __attribute__((target("avx2")))
#define FS_HAVE_AVX2_DISPATCH 1
// The same with POPCNT, for an AVX2 kernel whose scalar edges count bits (boundary/'s Hamming rows),
// picked at run time with cpu_has_avx2_popcnt().
#define FS_TARGET_AVX2_POPCNT __attribute__((target("avx2,popcnt")))
#else
#define FS_TARGET_CLONES_V3
#define FS_TARGET_CLONES
#define FS_TARGET_CLONES_V4
#endif

// gcc's -O3 loop unroll-and-jam fuses the pixel loop of a register-blocked kernel (an outer loop
// over pixels around a fixed-size inner loop over disparities) into a scalar loop over pixel pairs
// and leaves the vector code for the remainder; this keeps the inner loop vectorised instead.
#if defined(__GNUC__) && !defined(__clang__)
#define FS_NO_UNROLL_AND_JAM __attribute__((optimize("no-loop-unroll-and-jam")))
#else
#define FS_NO_UNROLL_AND_JAM
#endif

// A register-blocked kernel's accumulator arrays zeroed by a loop, not turned into a memset: gcc
// expands a memset of a few hundred bytes into `rep stos`, whose start-up cost was ~10 % of the
// cost stage's block loops at KITTI's segment sizes (the arrays live in registers after it). It carries
// FS_NO_UNROLL_AND_JAM's option as well and replaces it on those functions: a second `optimize` attribute
// on a function does not add to the first (with both, the loop ran 3.4x slower; session 50).
#if defined(__GNUC__) && !defined(__clang__)
#define FS_NO_MEMSET_PATTERNS __attribute__((optimize("no-loop-unroll-and-jam", "no-tree-loop-distribute-patterns")))
#else
#define FS_NO_MEMSET_PATTERNS
#endif

namespace fs::detail {

// The CPU runs FS_TARGET_AVX512BW code (x86-64-v4: AVX-512 F, BW, CD, DQ, VL); checked once.
inline bool cpu_has_avx512bw() {
#if defined(FS_HAVE_AVX512BW_DISPATCH)
  static const bool has = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                          __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") &&
                          __builtin_cpu_supports("avx512vl");
  return has;
#else
  return false;
#endif
}

// The CPU runs FS_TARGET_AVX2 code; checked once.
inline bool cpu_has_avx2() {
#if defined(FS_HAVE_AVX2_DISPATCH)
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

// The CPU runs FS_TARGET_AVX2_POPCNT code; checked once.
inline bool cpu_has_avx2_popcnt() {
#if defined(FS_HAVE_AVX2_DISPATCH)
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
  return has;
#else
  return false;
#endif
}

inline int resolve_threads(int requested) {
#if defined(FS_HAVE_OPENMP)
  return requested > 0 ? requested : omp_get_max_threads();
#else
  (void)requested;
  return 1;
#endif
}

// Sets the thread count of the OpenMP regions that the calling thread starts from now on
// (a per-thread setting in OpenMP, not a process global).
inline void use_threads(int requested) {
#if defined(FS_HAVE_OPENMP)
  omp_set_num_threads(resolve_threads(requested));
  omp_set_max_active_levels(2);  // left/right sections, each with its own worker threads
#else
  (void)requested;
#endif
}

// Runs two independent jobs of one stage (left and right image), side by side when two or more
// threads are allowed; each job may open its own parallel region (nested, see use_threads).
template <class F, class G>
void run_pair(int threads, F&& first, G&& second) {
#if defined(FS_HAVE_OPENMP)
  // Each job's own parallel regions get half of the threads, so the two jobs together do not
  // oversubscribe the cores (nested regions would otherwise each take all of them).
  const int nt = resolve_threads(threads);
  const int inner = nt >= 2 ? nt / 2 : 1;
#pragma omp parallel sections num_threads(nt >= 2 ? 2 : 1)
  {
#pragma omp section
    {
      omp_set_num_threads(inner);
      first();
    }
#pragma omp section
    {
      omp_set_num_threads(inner);
      second();
    }
  }
#else
  (void)threads;
  first();
  second();
#endif
}

// Union-find with the smaller index as root (fuzzystereo/union_find.hpp).
using fs::MinRootUnionFind;

// Calls f(x0, x1) for every run [x0, x1) of equal values in row[0..w), left to right (w >= 1).
// The run ends are found without a per-pixel branch: a vectorisable pass writes a 0/1 flag per
// pixel (value differs from its left neighbour), then the flags are read 8 at a time as one 64-bit
// word and the set bytes visited by count-trailing-zeros (runs are a few pixels long, so most
// words hold one or two ends). `flags` is caller scratch of at least w + 8 bytes.
static_assert(std::endian::native == std::endian::little, "for_each_run reads flag bytes as a little-endian word");
template <class T, class F>
void for_each_run(const T* __restrict row, int w, std::uint8_t* __restrict flags, F&& f) {
  if (w <= 0) return;
  flags[0] = 0;
  for (int x = 1; x < w; ++x) flags[x] = static_cast<std::uint8_t>(row[x] != row[x - 1]);
  flags[w] = 1;  // sentinel: the end of the last run
  for (int j = 1; j < 8; ++j) flags[w + j] = 0;
  int x0 = 0;
  for (int base = 0; base <= w; base += 8) {
    std::uint64_t word;
    std::memcpy(&word, flags + base, 8);
    while (word != 0) {
      const int e = base + std::countr_zero(word) / 8;
      f(x0, e);
      x0 = e;
      word &= word - 1;
    }
  }
}

// floor(sqrt(v)) for v < 2^62, exact.
inline std::uint64_t isqrt64(std::uint64_t v) {
  auto r = static_cast<std::uint64_t>(std::sqrt(static_cast<double>(v)));
  while (r * r > v) --r;
  while ((r + 1) * (r + 1) <= v) ++r;
  return r;
}

// T[c] = c * log2(c) in Q16 (T[0] = T[1] = 0): the n*log n table that makes histogram entropies
// incremental. H = log2(n) - (1/n) sum c log2 c = (T[n] - sum T[c]) / n   [bits, Q16].
// Values are rounded once when the table is built, so every user sees identical integers.
inline std::vector<std::uint64_t> nlogn_table_q16(std::size_t max_count) {
  std::vector<std::uint64_t> t(max_count + 1, 0);
  for (std::size_t c = 2; c <= max_count; ++c)
    t[c] = static_cast<std::uint64_t>(std::llround(static_cast<double>(c) * std::log2(static_cast<double>(c)) * 65536.0));
  return t;
}

// Entropy [bit, Q16] of a histogram with n samples and sum_t = sum_c T[c].
inline std::uint32_t entropy_q16(const std::vector<std::uint64_t>& t, std::uint64_t n, std::uint64_t sum_t) {
  if (n == 0) return 0;
  const std::uint64_t tn = t[n];
  return tn > sum_t ? static_cast<std::uint32_t>((tn - sum_t + n / 2) / n) : 0u;
}

}  // namespace fs::detail
