// `fuzzystereo match`: one stereo pair -> disparity maps (+ every stage with --dump).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.hpp"
#include "config.hpp"
#include "dataset.hpp"
#include "dump.hpp"
#include "fuzzystereo/matcher.hpp"
#include "io.hpp"
#include "metrics.hpp"

namespace fs::app {

namespace {

struct MatchOptions {
  std::string left, right, config, out, gt, labels_from, fis;
  double gt_scale = 1.0;
  int downscale = 1;
  int max_disparity = 0;
  int threads = -1;
  bool dump = false;
};

void run_match(const MatchOptions& o) {
  MatcherParams params = load_matcher_config(o.config);
  if (o.max_disparity > 0) params.cost.max_disparity = o.max_disparity;
  if (o.threads >= 0) params.runtime.threads = o.threads;
  if (params.cost.max_disparity < 2 || params.cost.max_disparity > 256)
    throw UserError("--max-disparity must be in [2, 256]");
  const FisDefinition fis = load_fis_definition(o.fis);

  cv::Mat lc = read_image(o.left, cv::IMREAD_COLOR), rc = read_image(o.right, cv::IMREAD_COLOR);
  if (lc.size() != rc.size())
    throw UserError("left '" + o.left + "' is " + std::to_string(lc.cols) + "x" + std::to_string(lc.rows) + " but right '" +
                    o.right + "' is " + std::to_string(rc.cols) + "x" + std::to_string(rc.rows) + "; a rectified pair must match");
  if (o.downscale > 1) {
    const cv::Size s(lc.cols / o.downscale, lc.rows / o.downscale);
    if (s.width < 1 || s.height < 1)
      throw UserError("--downscale " + std::to_string(o.downscale) + " leaves no pixel of the " + std::to_string(lc.cols) +
                      "x" + std::to_string(lc.rows) + " images (at most " +
                      std::to_string(std::max(1, std::min(lc.cols, lc.rows))) + " for these)");
    cv::resize(lc, lc, s, 0, 0, cv::INTER_AREA);
    cv::resize(rc, rc, s, 0, 0, cv::INTER_AREA);
  }
  const ImageU8 left = to_core_gray(lc), right = to_core_gray(rc);

  ImageI32 ll, lr;
  if (!o.labels_from.empty()) {
    ll = read_npy_labels(o.labels_from + "/labels_left.npy");
    lr = read_npy_labels(o.labels_from + "/labels_right.npy");
    if (ll.width != left.width || ll.height != left.height || lr.width != left.width || lr.height != left.height)
      throw UserError("labels in '" + o.labels_from + "' do not match the image size");
  }

  make_output_dir(o.out);  // before the work: a bad --out fails at once
  const auto t0 = std::chrono::steady_clock::now();
  const Matcher matcher(params, fis);
  const auto t1 = std::chrono::steady_clock::now();
  const MatchResult r = o.labels_from.empty() ? matcher.match(left, right)
                                              : matcher.match_with_labels(left, right, &ll, &lr);

  const cv::Mat dl = disp_q4_to_float(r.disp_final), dr = disp_q4_to_float(r.disp_right_wta);
  write_disp_kitti(o.out + "/disp_left.png", dl);
  write_disp_kitti(o.out + "/disp_right.png", dr);
  write_image(o.out + "/disp_left_color.png", colorize_disparity(dl, params.cost.max_disparity));
  write_image(o.out + "/disp_right_color.png", colorize_disparity(dr, params.cost.max_disparity));
  if (o.dump) write_match_dump(o.out + "/dump", o.left, o.right, params, fis, left, right, r);

  std::printf("fuzzystereo match: %dx%d, D=%d, %d + %d segments, FIS LUT %dx%d built in %.1f ms\n", left.width,
              left.height, params.cost.max_disparity, r.seg_left.count, r.seg_right.count, params.fis.lut_size,
              params.fis.lut_size, std::chrono::duration<double, std::milli>(t1 - t0).count());
  std::printf("  stage ms:");
  for (int i = 0; i < static_cast<int>(Stage::Count); ++i) std::printf(" %s %.1f", stage_name(Stage(i)), r.timings.ms[std::size_t(i)]);
  std::printf(" | total %.1f\n", r.timings.total_ms());

  if (!o.gt.empty()) {
    cv::Mat g = read_image(o.gt, cv::IMREAD_UNCHANGED);
    if (g.channels() != 1) throw UserError("ground truth '" + o.gt + "' must be a single-channel image");
    cv::Mat gf;
    g.convertTo(gf, CV_32F, 1.0 / o.gt_scale);
    if (o.downscale > 1) {
      cv::Mat small(left.height, left.width, CV_32F);
      for (int y = 0; y < small.rows; ++y)  // nearest sample, no blending across depth edges
        for (int x = 0; x < small.cols; ++x)
          small.at<float>(y, x) = gf.at<float>(y * o.downscale, x * o.downscale) / static_cast<float>(o.downscale);
      gf = small;
    }
    if (gf.size() != dl.size()) throw UserError("ground truth '" + o.gt + "' does not match the image size");
    const DispMetrics m = evaluate_disparity(dl, gf);
    std::printf("  vs ground truth: avg err %.3f px | bad-2 %.2f %% | bad-3 %.2f %% | D1 %.2f %% | density %.1f %%\n",
                m.avg_err, m.bad2, m.bad3, m.d1, m.density);
  }
  std::printf("  wrote %s/disp_left.png, disp_right.png, disp_left_color.png%s\n", o.out.c_str(),
              o.dump ? ", dump/" : "");
}

}  // namespace

void add_match_command(CLI::App& app) {
  auto o = std::make_shared<MatchOptions>();
  CLI::App* c = app.add_subcommand("match", "Match one rectified stereo pair");
  c->add_option("--left", o->left, "left image")->required();
  c->add_option("--right", o->right, "right image")->required();
  c->add_option("--out", o->out, "output directory")->required();
  c->add_option("--config", o->config, "TOML config (defaults: common/config/default.toml)");
  c->add_option("--fis", o->fis, "FIS definition TOML (default: built-in common/fis/fis.toml)");
  c->add_option("--max-disparity", o->max_disparity, "override cost.max_disparity");
  c->add_option("--threads", o->threads, "override runtime.threads (0 = all cores)")->check(CLI::Range(0, 256));
  c->add_option("--downscale", o->downscale, "shrink the inputs by this integer factor first")->check(CLI::Range(1, 8));
  c->add_option("--gt", o->gt, "ground-truth disparity image to score against");
  c->add_option("--gt-scale", o->gt_scale, "ground-truth value per pixel of disparity (KITTI 256, Middlebury 2006 third 3)")
      ->check(CLI::PositiveNumber);
  c->add_option("--labels-from", o->labels_from, "reuse labels_left/right.npy from this dump directory");
  c->add_flag("--dump", o->dump, "write every stage to OUT/dump (docs/formats.md)");
  c->callback([o] { run_match(*o); });
}

}  // namespace fs::app
