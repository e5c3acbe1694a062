// Matcher parameters. Defaults mirror common/config/default.toml; ranges live in
// common/config/schema.toml and are checked once when the config is loaded (firmware/config).
// Per-frame code assumes valid parameters.
#pragma once

namespace fs {

// What decides that the right image's gradients are rescaled (docs/algorithm.md 2b).
enum class GainTrigger {
  Grey,      // the grey-level distributions differ (grey_quantile_shift > gradient_gain_grey_shift)
  Gradient,  // the mean gradient magnitudes differ by more than gradient_gain_deadband (session 6)
};

struct SegmentationParams {
  int region_size = 8;       // S [px]
  int compactness = 20;      // m
  int iterations = 4;         // full-resolution rounds
  int coarse_iterations = 0;  // rounds on the image halved before them (0 = off)
  int min_segment_pct = 25;  // [% of S*S]
};

struct CostParams {
  int max_disparity = 64;   // D [px]; disparities 0 .. D-1
  double alpha = 0.2;       // eq. (9)
  int nmi_bins = 16;        // eq. (2)-(4)
  int nmi_candidates = 8;   // 0 = exhaustive
  bool subpixel = true;     // parabola fit on the FIS scores around the winner
  bool subpixel_every_segment = false;  // ... also when d-1 or d+1 was not an NMI candidate (the
                                       // winner's NMI stands in there; docs/algorithm.md 4)
  bool gradient_gain_compensation = true;  // scale the right gradients to the left's level (eq. 5-7)
  double gradient_gain_deadband = 0.2;     // ... when their mean magnitudes differ by more than this
  GainTrigger gradient_gain_trigger = GainTrigger::Grey;  // ... or when the grey levels differ:
  double gradient_gain_grey_shift = 13.0;  // mean |quantile difference| [grey levels] above which
  double noise_excess = 2.3;         // docs/algorithm.md 2c: smooth both images when one has more noise
                                     // than the other by this [grey levels, std]; 0 = off
  int noise_image_passes = 1;        // ... binomial 3x3 passes of the images given to SLIC and the costs
  int noise_gradient_passes = 2;     // ... binomial 3x3 passes of the images the gradients (eq. 5) are taken of
  int inject_shift = 0;     // TEST ONLY: adds a bias to the right-image shift (fault injection)
};

struct FisParams {
  int lut_size = 257;
};

// How the boundary refinement counts census bits (boundary/; the same counts either way): kAuto the
// fastest count the CPU has (AVX-512 VPOPCNTDQ, AVX2 nibble lookups, NEON byte counts, else the portable
// SWAR count); kPortable always the portable one (tests: a CPU with a vector count checks it too).
enum class BitCount { kAuto, kPortable };

// Segment-boundary refinement of the two WTA maps before eq. (13) (not in the paper;
// docs/algorithm.md 4b).
struct BoundaryParams {
  bool enabled = false;
  // Also run on a pair the radiometric checks find mismatched (noise equalisation, docs/algorithm.md
  // 2c, or the grey-level gain trigger, 2b, fired) when `enabled` is false (4b "On a mismatched pair").
  bool on_mismatch = true;
  int census_radius = 2;  // census window (2 r + 1)^2 - 1 bits, r <= 2 (24 bits)
  int window = 7;         // [px], odd: side of the square over which census distances are summed
  double margin = 1.0;    // [bits per window pixel] a candidate must beat the own disparity by more
  int step = 4;           // [px] candidates are read at +-step and +-2 step along the row and column
  int min_jump = 1;       // [px] only disparities this far from the pixel's own are candidates
  int passes = 1;
  BitCount bit_count = BitCount::kAuto;  // not a config field (the result does not depend on it)
};

struct LrParams {
  int max_diff = 1;  // eq. (13) [px]
  // Candidate retry (not in the paper, docs/algorithm.md 5b): a left segment with no pixel passing eq. (13)
  // tries up to retry_candidates of its other cost candidates (0 = off), best FIS score first; the first one
  // consistent on at least retry_min_share of the segment's pixels is kept on those pixels. Default since
  // session 56 (a pre-registered rule); 0 turns it off.
  int retry_candidates = 3;
  double retry_min_share = 0.7;
};

// The block-entropy kernel of eq. (14) (block_entropy, esr/; docs/algorithm.md 6): both give the same
// integers. kSliding: the histogram sliding along the row (any window). kSorted (5 x 5 blocks): each
// block's 25 bins sorted by a compare-exchange network, 16 or 32 blocks at a time, in its fastest build
// for the CPU (AVX-512BW; AVX2 or NEON when max_disparity <= 254; else a portable one).
// kSortedPortable: always the portable build (gcc vector types, a scalar table lookup: for tests).
// kAuto: kSorted for window 5 on x86-64 with AVX-512BW or AVX2 (measured faster there), kSliding
// otherwise (aarch64 included: not measured on a Pi yet; `[esr] kernel` picks one by hand).
enum class EntropyKernel { kAuto, kSliding, kSorted, kSortedPortable };

struct EsrParams {
  bool enabled = true;
  int window = 5;     // [px], odd
  double tau = 0.5;   // [bit], eq. (15)
  EntropyKernel kernel = EntropyKernel::kAuto;  // eq. (14)'s kernel (same integers either way)
};

// Bilateral smoothing of the dense map on a sparse tap grid (docs/algorithm.md 6d).
struct SmoothParams {
  int radius = 6;                // [px] taps at -radius .. radius in steps of `step`, both axes
  int step = 6;                  // [px]
  double sigma_space = 8.0;      // [px]
  double sigma_range = 3.0;      // [px] of disparity, the least range sigma
  double sigma_range_rel = 0.1;  // range sigma = max(sigma_range, sigma_range_rel * d)
};

// Densification after ESR (not in the paper, docs/algorithm.md "Densification").
struct DensifyParams {
  bool enabled = true;
  int speckle_max_size = 100;  // [px]; components of <= this many pixels are removed, 0 = off
  int speckle_max_diff = 3;    // [px]; neighbours within this belong to one component
  bool fill = true;            // 8-direction median fill of pixels without an estimate
  int interpolate_max_diff = 8;  // [px]; opposite rays within this are interpolated before the median, 0 = off
  bool occlusion_fill = true;  // holes no right pixel sees take their row's background first (6c)
  int occlusion_dilate = 1;    // [px] a right pixel's hit also covers this many left pixels each side
  int occlusion_max_gap = 64;  // [px] longer runs of holes are left to the median fill
  int border_fit_px = 0;       // [px] (<= 256) left border band: extrapolate the line fitted to the row's first estimates in
                               // this many columns where it rises towards the border (6f; 0 = nearest estimate)
  double border_fit_min_slope = 0.0;  // [px per column] ... by at least this much
  bool smooth = true;          // edge-preserving smoothing after the fill (6d)
  SmoothParams smoothing;
};

struct RuntimeParams {
  int threads = 0;  // 0 = all cores
};

struct MatcherParams {
  SegmentationParams seg;
  CostParams cost;
  FisParams fis;
  BoundaryParams boundary;
  LrParams lr;
  EsrParams esr;
  DensifyParams densify;
  RuntimeParams runtime;
};

}  // namespace fs
