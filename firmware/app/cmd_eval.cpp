// `fuzzystereo eval`: accuracy and speed of fuzzystereo and the OpenCV baselines on every frame of
// the datasets under a directory, in one process, with the same thread count for all methods.
//
// Per frame: left/right read in colour, the radiometric distortion (if any) applied to the right
// colour image, both converted to grey once (cv::cvtColor) and that same grey pair given to every
// method. Only each method's compute call is timed (steady_clock), not I/O or conversions, after one untimed
// warm-up call per matcher.
// Scores are KITTI-devkit style (metrics.hpp); a set's figures are the means of its per-frame
// figures (each frame weighs the same, whatever its number of GT pixels). Every figure is over all
// pixels with ground truth; where a set ships a non-occlusion mask (KITTI disp_noc, MiddEval3
// mask0nocc) the same figures over its non-occluded pixels follow in a second table and under "noc"
// in the JSON (the devkits' two evaluation areas; the paper's Table II does not say which it used).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "baselines.hpp"
#include "commands.hpp"
#include "config.hpp"
#include "dataset.hpp"
#include "fuzzystereo/matcher.hpp"
#include "io.hpp"
#include "metrics.hpp"
#include "radiometric.hpp"

namespace fs::app {
namespace {

struct EvalOptions {
  std::string dataset;
  std::vector<std::string> baselines;
  std::string radiometric = "none";
  std::uint64_t noise_seed = kRadioNoiseSeed;  // --noise-seed (radiometric "noise" only)
  std::string config;
  std::string fis;  // --fis: FIS definition TOML (default: the built-in common/fis/fis.toml)
  std::string json;
  std::string out;
  int threads = -1;  // -1: take runtime.threads from the config
  int limit = 0;     // frames per set, 0 = all
};

// Sums of per-frame figures of one (set, method).
struct Accum {
  double avg_err = 0, bad2 = 0, bad3 = 0, d1 = 0, density = 0, ms = 0;
  int frames = 0;
  void add(const DispMetrics& m, double ms_frame) {
    avg_err += m.avg_err;
    bad2 += m.bad2;
    bad3 += m.bad3;
    d1 += m.d1;
    density += m.density;
    ms += ms_frame;
    ++frames;
  }
  double mean(double sum) const { return frames > 0 ? sum / frames : 0.0; }
};

constexpr const char* kFuzzy = "fuzzystereo";

template <class F>
double time_ms(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

cv::Mat to_gray(const cv::Mat& bgr) {
  cv::Mat g;
  cv::cvtColor(bgr, g, cv::COLOR_BGR2GRAY);
  return g;
}

void write_preview(const std::string& out_dir, const Frame& f, const std::string& what, const cv::Mat& disp) {
  const std::filesystem::path dir = std::filesystem::path(out_dir) / f.set;
  make_output_dir(dir.string());
  write_image((dir / (f.name + "_" + what + ".png")).string(), colorize_disparity(disp, f.max_disparity));
}

void run_eval(const EvalOptions& o) {
  // Everything the user can get wrong is checked before the first frame.
  const std::vector<Baseline> baselines = parse_baselines(o.baselines);
  check_radiometric_name(o.radiometric);
  MatcherParams params = load_matcher_config(o.config);
  const FisDefinition fis = load_fis_definition(o.fis);
  if (o.limit < 0) throw UserError("--limit must be >= 0 (0 = all frames)");
  int threads = o.threads >= 0 ? o.threads : params.runtime.threads;
  if (threads <= 0) threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  params.runtime.threads = threads;
  cv::setNumThreads(threads);  // note: 0 would mean "sequential" to OpenCV, hence the resolution above

  std::vector<Frame> frames;
  {
    std::map<std::string, int> per_set;
    for (auto& f : discover_dataset(o.dataset)) {
      if (!f.has_gt()) {
        std::fprintf(stderr, "eval: skipping %s/%s (no ground truth)\n", f.set.c_str(), f.name.c_str());
        continue;
      }
      if (o.limit > 0 && per_set[f.set] >= o.limit) continue;
      ++per_set[f.set];
      frames.push_back(std::move(f));
    }
  }
  if (frames.empty()) throw UserError("no frames with ground truth under '" + o.dataset + "'");
  std::ofstream json_out;  // opened now so a bad path fails before the run, not after it
  if (!o.json.empty()) {
    json_out.open(o.json);
    if (!json_out) throw UserError("cannot write JSON file '" + o.json + "'");
  }

  // One Matcher per search range: the constructor builds the FIS lookup table.
  std::map<int, std::unique_ptr<Matcher>> matchers;
  std::vector<std::string> set_order;
  std::map<std::string, std::map<std::string, Accum>> acc, acc_noc;  // all pixels / non-occluded only

  std::fprintf(stderr, "eval: %zu frames, threads %d, radiometric '%s'\n", frames.size(), threads,
               o.radiometric.c_str());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Frame& f = frames[i];
    FrameImages im = read_frame_images(f);
    const cv::Mat gt = load_ground_truth(f);
    if (gt.size() != im.left.size())
      throw UserError("ground truth '" + f.gt_path + "' is " + std::to_string(gt.cols) + "x" +
                      std::to_string(gt.rows) + " but left image '" + f.left_path + "' is " +
                      std::to_string(im.left.cols) + "x" + std::to_string(im.left.rows));
    const cv::Mat noc = f.has_noc() ? load_nonoccluded_mask(f) : cv::Mat();
    if (!noc.empty() && noc.size() != gt.size())
      throw UserError("non-occlusion mask '" + f.noc_path + "' is " + std::to_string(noc.cols) + "x" +
                      std::to_string(noc.rows) + " but ground truth '" + f.gt_path + "' is " +
                      std::to_string(gt.cols) + "x" + std::to_string(gt.rows));
    if (o.radiometric != "none") im.right = apply_radiometric(im.right, o.radiometric, o.noise_seed);
    const cv::Mat left_gray = to_gray(im.left), right_gray = to_gray(im.right);
    if (std::find(set_order.begin(), set_order.end(), f.set) == set_order.end()) set_order.push_back(f.set);

    std::string line;
    char buf[160];
    auto record = [&](const std::string& method, const cv::Mat& disp, double ms) {
      const cv::Mat filled = fill_invalid_kitti(disp);  // once for both areas
      const DispMetrics m = evaluate_filled(disp, filled, gt);
      acc[f.set][method].add(m, ms);
      if (!noc.empty()) acc_noc[f.set][method].add(evaluate_filled(disp, filled, gt, noc), ms);
      std::snprintf(buf, sizeof buf, " | %s %.1f ms d1 %.2f%% bad3 %.2f%% dens %.1f%%", method.c_str(), ms, m.d1,
                    m.bad3, m.density);
      line += buf;
      if (!o.out.empty()) write_preview(o.out, f, method, disp);
    };

    // fuzzystereo
    auto& matcher = matchers[f.max_disparity];
    const ImageU8 core_left = to_core_gray(left_gray), core_right = to_core_gray(right_gray);
    if (!matcher) {
      MatcherParams p = params;
      p.cost.max_disparity = f.max_disparity;
      matcher = std::make_unique<Matcher>(p, fis);
      // One untimed warm-up match per matcher (first-touch allocations, the thread pool's start): without it
      // the first frame of a run timed 1.2-1.4x its steady-state time (KITTI 2012, the first set: 83.8 ms
      // against 61.4 in `bench`), and every set's first frame carried it.
      (void)matcher->match(core_left, core_right);
    }
    MatchResult result;
    const double fs_ms = time_ms([&] { result = matcher->match(core_left, core_right); });
    record(kFuzzy, disp_q4_to_float(result.disp_final), fs_ms);
    // The radiometric decisions of docs/algorithm.md 2b and 2c: the grey-level shift read and the
    // factor applied to the right gradients (x1.00 = none); the noise estimates, the excess and
    // whether the pair was smoothed.
    std::snprintf(buf, sizeof buf, " (grey shift %.1f, gradient gain x%.2f, noise %.2f/%.2f excess %.2f%s%s)",
                  result.grey_quantile_shift, result.gradient_gain_q16 / 65536.0, result.noise_sigma_left,
                  result.noise_sigma_right, result.noise_excess, result.noise_equalised ? " smoothed" : "",
                  result.boundary_refined ? ", boundary refined" : "");
    line += buf;

    // OpenCV baselines
    for (const Baseline b : baselines) {
      const BaselineMatcher bm(b, f.max_disparity);
      if (i == 0) (void)bm.compute_raw(left_gray, right_gray);  // the same untimed warm-up, once per run
      cv::Mat raw;
      double ms = 0.0;
      try {
        ms = time_ms([&] { raw = bm.compute_raw(left_gray, right_gray); });
      } catch (const cv::Exception& e) {
        throw UserError(std::string("OpenCV ") + baseline_name(b) + " failed on '" + f.left_path + "': " + e.err);
      }
      record(baseline_name(b), BaselineMatcher::raw_to_float(raw), ms);
    }
    if (!o.out.empty()) {
      cv::Mat gt_preview = gt.clone();
      gt_preview.setTo(-1.0f, gt == 0.0f);  // unknown -> black in the preview
      write_preview(o.out, f, "gt", gt_preview);
    }
    std::fprintf(stderr, "[%zu/%zu] %s/%s %dx%d D=%d%s\n", i + 1, frames.size(), f.set.c_str(), f.name.c_str(),
                 im.left.cols, im.left.rows, f.max_disparity, line.c_str());
  }

  // Table (means of per-frame figures) and JSON.
  std::vector<std::string> methods{kFuzzy};
  for (const Baseline b : baselines) methods.emplace_back(baseline_name(b));
  const auto header = [] {
    std::printf("%-22s %-12s %6s %8s %7s %7s %7s %8s %10s\n", "set", "method", "frames", "avg_err", "bad2%", "bad3%",
                "d1%", "density%", "ms/frame");
  };
  const auto row = [](const std::string& s, const std::string& m, const Accum& a) {
    std::printf("%-22s %-12s %6d %8.3f %7.2f %7.2f %7.2f %8.2f %10.1f\n", s.c_str(), m.c_str(), a.frames,
                a.mean(a.avg_err), a.mean(a.bad2), a.mean(a.bad3), a.mean(a.d1), a.mean(a.density), a.mean(a.ms));
  };
  const auto figures = [](const Accum& a) {
    return nlohmann::ordered_json{{"avg_err", a.mean(a.avg_err)}, {"bad2", a.mean(a.bad2)},
                                  {"bad3", a.mean(a.bad3)},       {"d1", a.mean(a.d1)},
                                  {"density", a.mean(a.density)}, {"ms_per_frame", a.mean(a.ms)},
                                  {"frames", a.frames}};
  };
  std::printf("\n");
  header();
  nlohmann::ordered_json sets = nlohmann::ordered_json::object();
  for (const auto& s : set_order) {
    for (const auto& m : methods) {
      const Accum& a = acc[s][m];
      row(s, m, a);
      sets[s][m] = figures(a);
      // "noc": the same figures over the non-occluded pixels of the set's frames that have a mask.
      if (acc_noc.count(s) != 0) sets[s][m]["noc"] = figures(acc_noc[s][m]);
    }
  }
  const std::string radio =
      o.radiometric == "noise" ? "noise, seed " + std::to_string(o.noise_seed) : o.radiometric;
  std::printf("(threads %d; radiometric '%s'; figures are per-frame means over all pixels with ground truth; errors after KITTI hole filling)\n",
              threads, radio.c_str());
  if (!acc_noc.empty()) {
    std::printf("\nnon-occluded pixels only (sets that ship a mask: KITTI disp_noc, MiddEval3 mask0nocc)\n");
    header();
    for (const auto& s : set_order) {
      if (acc_noc.count(s) == 0) continue;
      for (const auto& m : methods) row(s, m, acc_noc[s][m]);
    }
  }
  if (json_out.is_open()) {
    json_out << nlohmann::ordered_json{{"sets", sets}}.dump(2) << "\n";
    if (!json_out) throw UserError("cannot write JSON file '" + o.json + "'");
  }
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto opts = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Score fuzzystereo (and OpenCV baselines) on every dataset frame under a directory (KITTI metrics)");
  cmd->add_option("--dataset", opts->dataset,
                  "Datasets root, one set's folder or one scene folder (KITTI 2012/2015, Middlebury 2001-2014)")
      ->required();
  cmd->add_option("--baseline", opts->baselines, "Comma-separated OpenCV baselines to run as well: bm, sgbm")
      ->delimiter(',');
  cmd->add_option("--radiometric", opts->radiometric,
                  "Distortion applied to the right image: none, gain, gamma, mixed, noise")
      ->capture_default_str();
  cmd->add_option("--noise-seed", opts->noise_seed,
                  "Seed of the noise field of --radiometric noise (default: the fixed seed of docs/results.md); "
                  "another seed shows how much a figure depends on the one draw")
      ->check(CLI::Validator(
          [](std::string& v) {
            return v.find('-') == std::string::npos ? std::string() : "must be a whole number in [0, 2^64 - 1], got " + v;
          },
          "SEED"))
      ->capture_default_str();
  cmd->add_option("--config", opts->config, "Matcher config TOML (default: built-in defaults)");
  cmd->add_option("--fis", opts->fis, "FIS definition TOML (default: built-in common/fis/fis.toml)");
  cmd->add_option("--json", opts->json, "Write the per-set, per-method figures to this JSON file");
  cmd->add_option("--threads", opts->threads, "Threads for every method (0 = all cores; default: config runtime.threads)")
      ->check(CLI::Range(0, 256));
  cmd->add_option("--limit", opts->limit, "Evaluate at most N frames per set (0 = all)")->capture_default_str();
  cmd->add_option("--out", opts->out, "Write colourised disparity PNGs per frame and method to DIR/<set>/");
  cmd->callback([opts] { run_eval(*opts); });
}

}  // namespace fs::app
