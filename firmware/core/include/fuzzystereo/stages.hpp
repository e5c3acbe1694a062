// The matcher's stages, in pipeline order. Each stage is a free function with explicit inputs and
// outputs, implemented in one folder of firmware/core/src/ and tested against a plain scalar
// reference in tests/cpp/. matcher.cpp chains them, one line per stage.
#pragma once
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/image.hpp"
#include "fuzzystereo/params.hpp"

namespace fs {

// ---- image/ ---------------------------------------------------------------------------------
// eq. (5): gradient magnitude sqrt(gx^2 + gy^2) of 3x3 Sobel derivatives, border replicated,
// rounded to the nearest integer (uint16, <= 1443).
ImageU16 gradient_magnitude(const ImageU8& img);
// Gain compensation of the gradient images (not in the paper; docs/algorithm.md 2b). When the
// mean magnitudes differ by more than `deadband` (sum_l > (1 + deadband) sum_r or the reverse),
// `other` is scaled to the reference's level: g' = min(1443, (g * f + 2^15) >> 16) with
// f = round(2^16 * sum_ref / sum_other) (Q16, at most 2^20). Returns f (65536 = unchanged; also for
// an all-zero image).
std::uint32_t compensate_gradient_gain(const ImageU16& ref, ImageU16& other, double deadband);
// The 5 %, 10 %, ..., 95 % grey-level quantiles of an image (quantile p: the smallest level v with
// 100 * #(<= v) >= p * N, exact integers; all 0 for an empty image). Both camera-difference detectors
// (2b, 2c) read them, so the matcher computes them once per image and frame.
using GreyQuantiles = std::array<int, 19>;
GreyQuantiles grey_quantiles(const ImageU8& img);
// Mean absolute difference [grey levels] of the two images' quantiles (docs/algorithm.md 2b).
double grey_quantile_shift(const GreyQuantiles& a, const GreyQuantiles& b);
double grey_quantile_shift(const ImageU8& a, const ImageU8& b);
// Noise equalisation (not in the paper; docs/algorithm.md 2c).
// Robust Immerkaer estimate of the white-noise std [grey levels]: median |N * I| / (6 * 0.67449)
// with N = [1 -2 1; -2 4 -2; 1 -2 1] over the interior pixels (0 for images under 3 x 3).
double estimate_noise_sigma(const ImageU8& img);
// q95 - q5 of the grey levels (at least 1).
int grey_spread(const GreyQuantiles& q);
int grey_spread(const ImageU8& img);
// sqrt(|sigma_l^2 - (sigma_r * spread_l / spread_r)^2|): the noise one image has beyond the
// other's, at the left image's contrast [grey levels].
double noise_excess(double sigma_l, double sigma_r, int spread_l, int spread_r);
// One pass of the 3x3 binomial filter [1 2 1]^T [1 2 1] / 16, border replicated, rounded half up.
ImageU8 binomial_smooth(const ImageU8& img);

// ---- segmentation/ --------------------------------------------------------------------------
// Horizontal run of one segment in one row: pixels [x0, x1) of row y.
struct Run {
  std::int32_t y, x0, x1;
};

// A segmentation as labels plus, per segment, its runs (row-major order) — the variable-size
// matching windows of Section III.
struct Segmentation {
  ImageI32 labels;                           // 0 .. count-1
  int count = 0;
  std::vector<std::int32_t> run_begin;       // runs of segment s: runs[run_begin[s] .. run_begin[s+1])
  std::vector<Run> runs;
  std::vector<std::int32_t> pixels;          // pixel count per segment
};

// Integer SLIC on intensity + position (grid step S, compactness m), then connectivity enforcement.
Segmentation slic_segment(const ImageU8& img, const SegmentationParams& p);
// Build runs/pixel counts from a label image (labels must be dense 0..count-1).
Segmentation segmentation_from_labels(ImageI32 labels);

// ---- cost/ ----------------------------------------------------------------------------------
// Per segment and disparity: the two FIS inputs in Q16. Layout [segment * D + d].
//   dc1 = max(0, NCC) (eq. 1, 8); dc2 = alpha*NMI + (1-alpha)*IGSAD (eq. 2-7, 9).
// NCC and IGSAD are dense (every d: they rank the NMI candidates). NMI is evaluated only for the
// K = nmi_candidates best disparities of a segment (K = D when nmi_candidates is 0 or >= D); those K
// are listed per segment in ascending d with all three costs, so the WTA reads K consecutive
// 16-byte records instead of three scattered entries of the dense arrays each (the dense arrays of
// a KITTI frame, ~9 MB per direction, do not stay in cache between the stages).
struct CostCandidate {
  std::uint32_t ncc;    // Q16 (dc1)
  std::uint32_t igsad;  // Q16
  std::uint32_t nmi;    // Q16, eq. (4)
  std::int32_t d;       // integer disparity
};
struct SegmentCosts {
  int segments = 0;
  int disparities = 0;
  std::vector<std::uint32_t> ncc;     // Q16, clamped to [0, 1]
  std::vector<std::uint32_t> igsad;   // Q16
  int candidates_per_segment = 0;     // K (<= D)
  std::vector<CostCandidate> candidates;  // [segment * K + k], ascending d within a segment
};

// Scratch memory of the cost stage (padded partner rows, ~(W + D) * H * 13 bytes). Reusing one
// across frames keeps the per-frame path free of page faults; a null scratch allocates per call.
struct CostScratch;
std::shared_ptr<CostScratch> make_cost_scratch();

// direction = +1: reference is the left image, its pixel x matches x - d in the other image.
// direction = -1: reference is the right image, its pixel x matches x + d in the other image.
// fis is used only to rank candidates for NMI (when nmi_candidates > 0).
SegmentCosts compute_segment_costs(const ImageU8& ref, const ImageU8& other, const ImageU16& ref_grad,
                                   const ImageU16& other_grad, const Segmentation& seg, int direction,
                                   const CostParams& p, const FisLut& fis, int threads,
                                   CostScratch* scratch = nullptr);
// The same into `out`, reusing its memory (~13 bytes per segment and disparity, 15 MB on a KITTI
// frame at D = 160): a caller that keeps `out` across frames (the Matcher keeps it in the scratch,
// scratch_costs) allocates and page-faults it once instead of every frame.
void compute_segment_costs(SegmentCosts& out, const ImageU8& ref, const ImageU8& other, const ImageU16& ref_grad,
                           const ImageU16& other_grad, const Segmentation& seg, int direction, const CostParams& p,
                           const FisLut& fis, int threads, CostScratch* scratch = nullptr);
// The cost buffer kept in a scratch for compute_segment_costs(out, ...).
SegmentCosts& scratch_costs(CostScratch& scratch);

// ---- fis/ + wta/ ----------------------------------------------------------------------------
struct SegmentDecision {
  std::vector<std::int16_t> disparity;  // per segment, integer px (kInvalidDisp if no candidate)
  std::vector<std::int16_t> disparity_q4;  // with the sub-pixel offset, Q4 (kInvalidDisp if none)
  std::vector<std::uint32_t> score;     // FIS output of the winner, Q16
  std::vector<std::uint32_t> dc1;       // winner's inputs, Q16
  std::vector<std::uint32_t> dc2;
};

// Data Cost 2 of eq. (9) in Q16 from NMI and IGSAD in Q16.
std::uint32_t data_cost2_q16(std::uint32_t nmi_q16, std::uint32_t igsad_q16, std::uint32_t alpha_q16);

// Winner-take-all over the FIS score (Section III): per segment, argmax_d FIS(dc1, dc2) over its
// candidates (ties keep the smaller d). With p.subpixel, a parabola through the scores at d-1, d,
// d+1 moves the winner by at most half a pixel: disparity_q4 = 16 d + offset. The scores are the
// candidates' own when both neighbours are candidates; otherwise (p.subpixel_every_segment) all
// three are FIS(NCC(d'), eq. (9) with the winner's NMI and IGSAD(d')), from the dense NCC / IGSAD
// rows of the costs (the segment is left at 16 d without subpixel_every_segment).
SegmentDecision fis_winner_take_all(const SegmentCosts& costs, const FisLut& fis, const CostParams& p);

// Paint per-segment Q4 disparities into a Q4 disparity map.
ImageI16 paint_segments(const Segmentation& seg, const std::vector<std::int16_t>& seg_disp_q4);

// Integer pixel of the partner of x for a Q4 disparity: x - round(d).
inline int partner_x(int x, std::int16_t d_q4) { return x - ((d_q4 + kDispScale / 2) >> kDispShift); }

// ---- boundary/ ------------------------------------------------------------------------------
// Census transform (not in the paper): bit i set where the i-th neighbour of the
// (2 radius + 1)^2 window (row-major, centre skipped) is darker than the centre; border replicated.
// radius 1 or 2 (8 or 24 bits; others throw std::invalid_argument).
ImageU32 census_transform(const ImageU8& img, int radius);
// Segment-boundary refinement of a WTA map (not in the paper; docs/algorithm.md 4b), computed
// segment by segment (`seg` is the segmentation the map was painted from; every pixel belongs to
// one segment) with one summed-area table of census distances per disparity a segment needs. For every
// valid pixel, the map's values at +-step and +-2 step along its row and column that differ from
// its own by >= min_jump px are candidates; the windowed census cost (sum over the window of the
// Hamming distance between the pixel's census code and its partner's at the rounded disparity,
// partner column x - direction * d, all (2 census_radius + 1)^2 - 1 bits where the partner is outside the
// image; the census codes are census_transform(., p.census_radius)) of the
// best candidate replaces the pixel's disparity when it is lower than the own disparity's by more
// than margin * window^2 (ties keep the earlier candidate). `passes` rounds, each reading the
// previous round's map. switched (optional): 1 where the final map differs from the input.
ImageI16 refine_boundaries(const ImageI16& disp, const Segmentation& seg, const ImageU32& census_ref,
                           const ImageU32& census_other, int direction, const BoundaryParams& p, ImageU8* switched);

// ---- lrcheck/ -------------------------------------------------------------------------------
// eq. (13): keeps d_l(x,y) where |d_l(x,y) - d_r(x - d_l(x,y), y)| <= max_diff, else kInvalidDisp.
// mask (optional) receives 1 for consistent pixels, 0 otherwise.
ImageI16 left_right_check(const ImageI16& disp_left, const ImageI16& disp_right, const LrParams& p,
                          ImageU8* mask);

// Candidate retry after eq. (13) (not in the paper, docs/algorithm.md 5b; p.retry_candidates > 0). A left
// segment whose winner kept no pixel (every pixel invalid in disp_lr) ranks its other cost candidates by FIS
// score (ties: smaller d), skipping those within max_diff of the winner; for each of the first
// p.retry_candidates the integer disparity d is checked against disp_right on every pixel of the segment
// (eq. 13 with d_l = d), and the first consistent on >= p.retry_min_share of the pixels is written (d in Q4)
// into disp_lr (and mask = 1) on its consistent pixels. Returns the segments recovered.
int retry_rejected_segments(ImageI16& disp_lr, ImageU8* mask, const Segmentation& seg, const SegmentCosts& costs,
                            const SegmentDecision& dec, const ImageI16& disp_right, const FisLut& fis,
                            const CostParams& cp, const LrParams& p);

// ---- esr/ -----------------------------------------------------------------------------------
// eq. (14): Shannon entropy [bit] of the integer disparities in a w x w block around every pixel
// (invalid pixels excluded), in Q16; sliding window updated incrementally with an n*log2(n) table.
// need (optional, same size): only pixels with need != 0 are computed, the others are 0 (a gap
// between needed pixels wider than the window rebuilds the block instead of sliding across it).
// Two kernels give the same integers (EntropyKernel, params.hpp).
ImageI32 block_entropy(const ImageI16& disp, int window, int max_disparity, const ImageU8* need = nullptr,
                       EntropyKernel kernel = EntropyKernel::kAuto);
// Mean disparity (Q4) of the valid pixels of a w x w block around every pixel (integral image).
ImageI16 block_mean(const ImageI16& disp, int window);
// eq. (15): replace d with the mean of the lower-entropy block when |E_l - E_r| > tau.
// The right block is taken at the corresponding position x - d_l(x, y).
// replaced (optional) receives 1 where a pixel was replaced.
// disp_lr: left map after eq. (13); disp_right: right-reference WTA map.
ImageI16 entropy_selective_refinement(const ImageI16& disp_lr, const ImageI16& disp_right, const EsrParams& p,
                                      int max_disparity, ImageU8* replaced);

// ---- densify/ ------------------------------------------------------------------------------
// Not in the paper (docs/algorithm.md "Densification"). All maps Q4, kInvalidDisp = no estimate.
// Speckle removal: 4-connected components of valid pixels whose neighbours differ by at most
// max_diff_q4 are set invalid when they hold <= max_size pixels (max_size 0: nothing removed).
// removed (optional, pre-sized) receives 1 per removed pixel. Returns the number removed.
int remove_speckles(ImageI16& disp, int max_size, int max_diff_q4, ImageU8* removed);
// 8-direction median fill: each invalid pixel takes the median of the first valid disparity met
// along each of the 8 rays (horizontal, vertical, diagonal) from it (mean of the two middle values,
// rounded half up, for an even count); in the left border band, where no ray from the left meets
// an estimate, it takes the nearest estimate to its right. filled (optional) receives 1 per filled pixel.
// interp_max_diff_q4 > 0 (slant-aware fill): before the median, each of the 4 pairs of opposite
// rays whose two values differ by at most interp_max_diff_q4 (one surface on both sides) gives
// both its slots the linear interpolation between them, (a*tb + b*ta) / (ta + tb) rounded half
// up, ta and tb = the steps to each value; 0 = the plain median of the 8 ray values.
ImageI16 median_fill(const ImageI16& disp, ImageU8* filled, int interp_max_diff_q4 = 0);
// Q4 value 0 (disparity 0, no match in range) counts as no estimate; then remove_speckles, then
// occlusion_fill when p.occlusion_fill (disp_right required then, else std::invalid_argument), then
// median_fill (with p.interpolate_max_diff) when p.fill. changed (optional): 0 kept, 1 filled, 2 zero or removed
// as a speckle (then filled when p.fill).
// Then, when p.border_fit_px > 0, extrapolate_left_border on the filled map (max_disparity > 0 caps its values
// below max_disparity px), then smooth_disparity when p.smooth.
ImageI16 densify(const ImageI16& disp, const DensifyParams& p, ImageU8* changed, const ImageI16* disp_right = nullptr,
                 int max_disparity = 0);
// Left border band extrapolation (docs/algorithm.md 6f; not in the paper). Per row of `before` (the map
// the fill started from, Q4) whose first estimate is at x0 > 0: the least-squares line d = a + b x
// through its estimates in [x0, x0 + window_px) (at least 3 and a quarter of the window); when it
// rises towards the border (b < 0), out's pixels [0, x0) take its value, rounded to nearest
// (exact integer arithmetic) and capped at cap_q4 (> 0); otherwise they stay as they are. Returns
// the number of rows extrapolated.
int extrapolate_left_border(ImageI16& out, const ImageI16& before, int window_px, int cap_q4, double min_slope_q4 = 0.0);
// Occlusion fill (p.occlusion_fill, between speckle removal and the median fill; needs disp_right,
// the right-reference WTA map): a left pixel without an estimate that no right pixel sees
// (xr + round(d_r(xr)) misses it by more than `dilate` px) is taken as occluded in the right image.
// Per row, in a run of holes of at most max_gap px, those pixels take the background: the smaller of
// the two estimates bounding the run (the one there is at an image border). filled (optional,
// pre-sized) receives 1 per filled pixel. Returns the count.
int occlusion_fill(ImageI16& disp, const ImageI16& disp_right, int dilate, int max_gap, ImageU8* filled);
// Bilateral smoothing (p.smooth, after the median fill; docs/algorithm.md 6d): every valid pixel
// becomes the weighted mean of the valid taps (dx, dy) in {-r, -r + step, .., r}^2 (r = radius rounded
// down to a multiple of step; the image edge replicated), weight = exp(-(dx^2 + dy^2) / 2 sigma_space^2)
// * (1 - (|d_tap - d| / 2 s)^2)^2 (Tukey's biweight, 0 from 2 s on; s = max(sigma_range,
// sigma_range_rel * d)), both Q12, product >> 12; the mean rounded to nearest Q4. Invalid pixels stay
// invalid and weigh nothing.
// radius / step <= kMaxSmoothReach (at most 11 x 11 taps: the sums stay int32), else std::invalid_argument.
inline constexpr int kMaxSmoothReach = 5;
ImageI16 smooth_disparity(const ImageI16& disp, const SmoothParams& p);

}  // namespace fs
