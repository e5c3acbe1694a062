// The disparity pipeline of Section III, one line per stage (see stages.hpp for each stage).
#include "fuzzystereo/matcher.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "internal.hpp"

namespace fs {

const char* stage_name(Stage s) {
  switch (s) {
    case Stage::Gradient: return "gradient";
    case Stage::Segmentation: return "segmentation";
    case Stage::Cost: return "cost";
    case Stage::Wta: return "wta";
    case Stage::LrCheck: return "lrcheck";
    case Stage::Esr: return "esr";
    case Stage::Densify: return "densify";
    default: return "?";
  }
}

double StageTimings::total_ms() const {
  double t = 0;
  for (double v : ms) t += v;
  return t;
}

Matcher::Matcher(const MatcherParams& params, const FisDefinition& fis)
    : params_(params), lut_(FisLut::cached(fis, params.fis.lut_size)), scratch_{make_cost_scratch(), make_cost_scratch()} {}

MatchResult Matcher::match(const ImageU8& left, const ImageU8& right) const {
  return match_with_labels(left, right, nullptr, nullptr);
}

namespace {

class StageClock {
 public:
  explicit StageClock(StageTimings& t) : t_(t), last_(std::chrono::steady_clock::now()) {}
  void lap(Stage s) {
    const auto now = std::chrono::steady_clock::now();
    t_.ms[static_cast<std::size_t>(s)] += std::chrono::duration<double, std::milli>(now - last_).count();
    last_ = now;
  }

 private:
  StageTimings& t_;
  std::chrono::steady_clock::time_point last_;
};

}  // namespace

MatchResult Matcher::match_with_labels(const ImageU8& left_in, const ImageU8& right_in, const ImageI32* labels_left,
                                       const ImageI32* labels_right) const {
  if (left_in.width != right_in.width || left_in.height != right_in.height || left_in.empty())
    throw std::invalid_argument("Matcher: left and right images must be non-empty and of equal size");
  if (left_in.width > kMaxImageWidth || left_in.height > kMaxImageWidth)
    throw std::invalid_argument("Matcher: images wider or taller than 32767 px are not supported");
  const MatcherParams& p = params_;
  std::lock_guard<std::mutex> lock(scratch_mu_);
  const int threads = p.runtime.threads;
  detail::use_threads(threads);
  MatchResult r;
  StageClock clock(r.timings);

  // Grey-level quantiles of the inputs: read by the noise excess (2c) and the gain trigger (2b).
  const bool grey_trigger = p.cost.gradient_gain_compensation && p.cost.gradient_gain_trigger == GainTrigger::Grey;
  GreyQuantiles q_l{}, q_r{};
  if (p.cost.noise_excess > 0.0 || grey_trigger)
    detail::run_pair(threads, [&] { q_l = grey_quantiles(left_in); }, [&] { q_r = grey_quantiles(right_in); });

  // Noise equalisation (not in the paper, docs/algorithm.md 2c): when one camera is noisier than
  // the other, both images are smoothed; `left` / `right` feed SLIC and the costs, `gin_*` the
  // gradients (eq. 5). Otherwise all of them are the inputs, untouched.
  ImageU8 smooth_l, smooth_r, gsmooth_l, gsmooth_r;
  const ImageU8 *in_l = &left_in, *in_r = &right_in, *gin_l = &left_in, *gin_r = &right_in;
  if (p.cost.noise_excess > 0.0) {
    detail::run_pair(threads, [&] { r.noise_sigma_left = estimate_noise_sigma(left_in); },
                     [&] { r.noise_sigma_right = estimate_noise_sigma(right_in); });
    r.noise_excess = noise_excess(r.noise_sigma_left, r.noise_sigma_right, grey_spread(q_l), grey_spread(q_r));
    r.noise_equalised = r.noise_excess > p.cost.noise_excess;
    if (r.noise_equalised) {
      // Binomial passes compose: the gradient input continues from the image input when it has more passes.
      auto passes = [](ImageU8 img, int from, int to) {
        for (int k = from; k < to; ++k) img = binomial_smooth(img);
        return img;
      };
      const int ni = p.cost.noise_image_passes, ng = p.cost.noise_gradient_passes;
      auto smooth = [&](const ImageU8& img, ImageU8& out, ImageU8& gout) {
        out = passes(img, 0, ni);
        gout = ng >= ni ? passes(out, ni, ng) : passes(img, 0, ng);
      };
      detail::run_pair(threads, [&] { smooth(left_in, smooth_l, gsmooth_l); },
                       [&] { smooth(right_in, smooth_r, gsmooth_r); });
      in_l = &smooth_l, in_r = &smooth_r, gin_l = &gsmooth_l, gin_r = &gsmooth_r;
      if (grey_trigger)  // the gain trigger reads the images the costs see
        detail::run_pair(threads, [&] { q_l = grey_quantiles(smooth_l); }, [&] { q_r = grey_quantiles(smooth_r); });
    }
  }
  const ImageU8& left = *in_l;
  const ImageU8& right = *in_r;

  ImageU16 grad_l, grad_r;                                                              // eq. (5)
  detail::run_pair(threads, [&] { grad_l = gradient_magnitude(*gin_l); }, [&] { grad_r = gradient_magnitude(*gin_r); });
  if (p.cost.gradient_gain_compensation) {  // docs/algorithm.md 2b (not in the paper)
    if (p.cost.gradient_gain_trigger == GainTrigger::Gradient) {
      r.gradient_gain_q16 = compensate_gradient_gain(grad_l, grad_r, p.cost.gradient_gain_deadband);
      r.gain_triggered = r.gradient_gain_q16 != 65536;
    } else {
      r.grey_quantile_shift = grey_quantile_shift(q_l, q_r);
      r.gain_triggered = r.grey_quantile_shift > p.cost.gradient_gain_grey_shift;
      if (r.gain_triggered) r.gradient_gain_q16 = compensate_gradient_gain(grad_l, grad_r, 0.0);
    }
  }
  clock.lap(Stage::Gradient);

  detail::run_pair(
      threads,
      [&] { r.seg_left = labels_left ? segmentation_from_labels(*labels_left) : slic_segment(left, p.seg); },
      [&] { r.seg_right = labels_right ? segmentation_from_labels(*labels_right) : slic_segment(right, p.seg); });
  clock.lap(Stage::Segmentation);

  // The two directions run side by side with half of the threads each (one direction alone with
  // a single thread).
  // The cost buffers live in the scratch, so repeated frames reuse their memory.
  SegmentCosts& cost_l = scratch_costs(*scratch_[0]);                                   // eq. (1)-(9)
  SegmentCosts& cost_r = scratch_costs(*scratch_[1]);
  const int nt = detail::resolve_threads(threads);
  const int cost_threads = nt >= 2 ? nt / 2 : 1;
  detail::run_pair(
      threads,
      [&] { compute_segment_costs(cost_l, left, right, grad_l, grad_r, r.seg_left, +1, p.cost, *lut_, cost_threads, scratch_[0].get()); },
      [&] { compute_segment_costs(cost_r, right, left, grad_r, grad_l, r.seg_right, -1, p.cost, *lut_, cost_threads, scratch_[1].get()); });
  clock.lap(Stage::Cost);

  detail::run_pair(                                                                     // eq. (10)-(12), WTA
      threads,
      [&] {
        r.dec_left = fis_winner_take_all(cost_l, *lut_, p.cost);
        r.disp_left_wta = paint_segments(r.seg_left, r.dec_left.disparity_q4);
      },
      [&] {
        r.dec_right = fis_winner_take_all(cost_r, *lut_, p.cost);
        r.disp_right_wta = paint_segments(r.seg_right, r.dec_right.disparity_q4);
      });
  // docs/algorithm.md 4b (not in the paper), timed with the WTA: always when enabled, else on a pair the
  // radiometric checks above found mismatched (census distances do not see a monotone grey-level change,
  // and the window sum averages the noise).
  r.boundary_refined = p.boundary.enabled || (p.boundary.on_mismatch && (r.noise_equalised || r.gain_triggered));
  if (r.boundary_refined) {
    ImageU32 census_l, census_r;
    const int rad = p.boundary.census_radius;
    detail::run_pair(threads, [&] { census_l = census_transform(left, rad); },
                     [&] { census_r = census_transform(right, rad); });
    detail::run_pair(
        threads, [&] { r.disp_left_wta = refine_boundaries(r.disp_left_wta, r.seg_left, census_l, census_r, +1, p.boundary, nullptr); },
        [&] { r.disp_right_wta = refine_boundaries(r.disp_right_wta, r.seg_right, census_r, census_l, -1, p.boundary, nullptr); });
  }
  clock.lap(Stage::Wta);

  r.disp_lr = left_right_check(r.disp_left_wta, r.disp_right_wta, p.lr, &r.lr_mask);  // eq. (13)
  if (p.lr.retry_candidates > 0)  // docs/algorithm.md 5b (not in the paper)
    r.retry_recovered = retry_rejected_segments(r.disp_lr, &r.lr_mask, r.seg_left, cost_l, r.dec_left, r.disp_right_wta,
                                                *lut_, p.cost, p.lr);
  clock.lap(Stage::LrCheck);

  if (p.esr.enabled) {                                                                  // eq. (14)-(15)
    r.disp_esr = entropy_selective_refinement(r.disp_lr, r.disp_right_wta, p.esr, p.cost.max_disparity,
                                              &r.esr_replaced);
  } else {
    r.disp_esr = r.disp_lr;
    r.esr_replaced = ImageU8(left.width, left.height, 0);
  }
  clock.lap(Stage::Esr);

  if (p.densify.enabled) {                                                              // not in the paper
    r.disp_final = densify(r.disp_esr, p.densify, &r.densify_changed, &r.disp_right_wta, p.cost.max_disparity);
  } else {
    r.disp_final = r.disp_esr;
    r.densify_changed = ImageU8(left.width, left.height, 0);
  }
  clock.lap(Stage::Densify);
  return r;
}

}  // namespace fs
