// Public entry point of the fuzzystereo disparity pipeline (Section III up to and including ESR).
#pragma once
#include <array>
#include <memory>
#include <mutex>
#include <string>

#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/image.hpp"
#include "fuzzystereo/params.hpp"
#include "fuzzystereo/stages.hpp"

namespace fs {

// Stage names, in pipeline order, for timings and dumps.
enum class Stage : int { Gradient, Segmentation, Cost, Wta, LrCheck, Esr, Densify, Count };
const char* stage_name(Stage s);

struct StageTimings {
  std::array<double, static_cast<int>(Stage::Count)> ms{};
  double total_ms() const;
};

struct MatchResult {
  Segmentation seg_left, seg_right;
  SegmentDecision dec_left, dec_right;
  ImageI16 disp_left_wta, disp_right_wta;  // Q4, WTA per segment
  ImageI16 disp_lr;                         // Q4, after eq. (13)
  ImageU8 lr_mask;                          // 1 = consistent
  ImageI16 disp_esr;                        // Q4, after ESR (== disp_lr when ESR disabled)
  ImageU8 esr_replaced;                     // 1 = replaced by eq. (15)
  ImageI16 disp_final;                      // Q4, after densify (== disp_esr when densify disabled)
  ImageU8 densify_changed;                  // 0 kept, 1 filled, 2 removed as a speckle (then filled)
  std::uint32_t gradient_gain_q16 = 65536;  // factor applied to the right gradients (Q16; 65536 = none)
  double grey_quantile_shift = 0.0;         // grey-level shift that decided it [levels] (trigger "grey")
  double noise_sigma_left = 0.0, noise_sigma_right = 0.0;  // estimated noise std [grey levels] (docs/algorithm.md 2c)
  double noise_excess = 0.0;                // noise of the noisier image beyond the other's [grey levels]
  bool noise_equalised = false;             // both images were smoothed (noise_excess > cost.noise_excess)
  bool gain_triggered = false;              // the gain trigger fired (the right gradients were scaled by the factor)
  bool boundary_refined = false;            // the [boundary] refinement ran (enabled, or on_mismatch and a mismatch)
  int retry_recovered = 0;                  // segments recovered by the candidate retry after eq. (13) ([lr_check] retry_*)
  StageTimings timings;
};

class Matcher {
 public:
  Matcher(const MatcherParams& params, const FisDefinition& fis);

  // left/right: rectified 8-bit grey images of equal size.
  MatchResult match(const ImageU8& left, const ImageU8& right) const;
  // Same, with segmentations given (reference comparison with the firmware's labels).
  MatchResult match_with_labels(const ImageU8& left, const ImageU8& right, const ImageI32* labels_left,
                                const ImageI32* labels_right) const;

  const MatcherParams& params() const { return params_; }
  const FisLut& lut() const { return *lut_; }

 private:
  MatcherParams params_;
  std::shared_ptr<const FisLut> lut_;
  // Per-frame scratch reused across frames (no page faults in steady state). match() holds the
  // mutex, so one Matcher serves one frame at a time; use one Matcher per concurrent stream.
  mutable std::mutex scratch_mu_;
  std::shared_ptr<CostScratch> scratch_[2];
};

}  // namespace fs
