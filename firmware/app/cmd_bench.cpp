// `fuzzystereo bench`: per-stage timings of the matcher on one frame, single-threaded and with all
// cores, beside OpenCV StereoBM and StereoSGBM (3-way) at the same thread counts. Each figure is the
// median over --repeats runs after one untimed warm-up run (page faults, lazy allocations). The three
// methods run interleaved (fuzzystereo, BM, SGBM, then the next repeat), so a load change on a shared
// machine hits all three alike; the ratios are the medians of the per-repeat ratios.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
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
#include "radiometric.hpp"

namespace fs::app {
namespace {

struct BenchOptions {
  std::string dataset;  // empty: $FUZZYSTEREO_DATASETS or ../shared/datasets, synthetic if absent
  std::string frame;
  std::string config;
  std::string fis;
  std::string json;
  std::string radiometric = "none";  // a distortion of the right image, as `eval --radiometric`
  std::uint64_t noise_seed = kRadioNoiseSeed;
  int repeats = 5;
};

struct BenchInput {
  std::string label;
  cv::Mat left_gray, right_gray;
  int max_disparity = 0;
};

constexpr int kStages = static_cast<int>(Stage::Count);

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

template <class F>
double time_ms(F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// KITTI-sized random-texture pair (fixed seed): a slanted "road" plane (disparity 8 .. 56 from top to
// bottom) with a fronto-parallel box at disparity 90, searched over 160 disparities like KITTI.
BenchInput synthetic_input() {
  constexpr int kW = 1242, kH = 375;
  cv::RNG rng(20240601u);
  cv::Mat tex(kH, kW + 256, CV_8U);
  rng.fill(tex, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(tex, tex, cv::Size(5, 5), 1.0);
  BenchInput in;
  in.label = "synthetic random texture";
  in.max_disparity = 160;
  in.left_gray = tex(cv::Rect(0, 0, kW, kH)).clone();
  in.right_gray = cv::Mat(kH, kW, CV_8U);
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const bool box = x > 500 && x < 800 && y > 100 && y < 300;
      const int d = box ? 90 : 8 + 48 * y / kH;
      // right(x) = left(x + d); the texture is wider than the image so x + d stays inside it.
      in.right_gray.at<std::uint8_t>(y, x) = tex.at<std::uint8_t>(y, x + d);
    }
  }
  return in;
}

BenchInput frame_input(const Frame& f, const BenchOptions& o) {
  const FrameImages im = read_frame_images(f);
  BenchInput in;
  in.label = f.set + "/" + f.name;
  in.max_disparity = f.max_disparity;
  cv::cvtColor(im.left, in.left_gray, cv::COLOR_BGR2GRAY);
  // The distortion on the colour image, before the grey conversion: what `eval --radiometric` matches.
  const cv::Mat right = o.radiometric == "none" ? im.right : apply_radiometric(im.right, o.radiometric, o.noise_seed);
  cv::cvtColor(right, in.right_gray, cv::COLOR_BGR2GRAY);
  return in;
}

BenchInput choose_input(const BenchOptions& o) {
  std::string dir = o.dataset;
  const bool explicit_dir = !dir.empty();
  if (!explicit_dir) {
    const char* env = std::getenv("FUZZYSTEREO_DATASETS");
    dir = (env != nullptr && *env != '\0') ? env : "../shared/datasets";
  }
  std::vector<Frame> frames;
  try {
    frames = discover_dataset(dir);
  } catch (const UserError& e) {
    if (explicit_dir || !o.frame.empty()) throw;
    std::fprintf(stderr, "bench: no dataset at '%s'; using a synthetic random-texture pair\n", dir.c_str());
    BenchInput in = synthetic_input();
    if (o.radiometric != "none") in.right_gray = apply_radiometric(in.right_gray, o.radiometric, o.noise_seed);
    return in;
  }
  if (!o.frame.empty()) {
    for (const auto& f : frames)
      if (f.name == o.frame || f.set + "/" + f.name == o.frame) return frame_input(f, o);
    std::string names;
    for (std::size_t i = 0; i < frames.size() && i < 12; ++i) names += (i ? ", " : "") + frames[i].set + "/" + frames[i].name;
    if (frames.size() > 12) names += ", ...";
    throw UserError("no frame '" + o.frame + "' under '" + dir + "' (frames: " + names + ")");
  }
  for (const auto& f : frames)
    if (f.set == "kitti2015") return frame_input(f, o);
  return frame_input(frames.front(), o);
}

struct RunFigures {
  int threads = 0;
  std::array<double, kStages> stage_ms{};
  double fuzzy_ms = 0, bm_ms = 0, sgbm_ms = 0;
  double ratio_sgbm = 0, ratio_bm = 0;  // medians of the per-repeat ratios
  bool boundary_refined = false;         // the [boundary] refinement ran (enabled, or on a mismatched pair)
  bool noise_equalised = false, gain_triggered = false;
};

RunFigures bench_at(const BenchInput& in, MatcherParams params, const FisDefinition& fis, int threads, int repeats) {
  RunFigures r;
  r.threads = threads;
  params.runtime.threads = threads;
  params.cost.max_disparity = in.max_disparity;
  cv::setNumThreads(threads);
  const Matcher matcher(params, fis);  // builds the FIS table: not timed
  const ImageU8 left = to_core_gray(in.left_gray), right = to_core_gray(in.right_gray);

  std::array<std::vector<double>, kStages> stages;
  std::vector<double> total, t_bm, t_sgbm, r_sgbm, r_bm;
  const BaselineMatcher bm(Baseline::BM, in.max_disparity), sgbm(Baseline::SGBM, in.max_disparity);
  auto baseline_ms = [&](const BaselineMatcher& b, Baseline which) {
    try {
      return time_ms([&] { (void)b.compute_raw(in.left_gray, in.right_gray); });
    } catch (const cv::Exception& e) {
      throw UserError(std::string("OpenCV ") + baseline_name(which) + " failed on " + in.label + ": " + e.err);
    }
  };
  (void)matcher.match(left, right);  // warm-ups
  (void)baseline_ms(bm, Baseline::BM);
  (void)baseline_ms(sgbm, Baseline::SGBM);
  for (int i = 0; i < repeats; ++i) {
    MatchResult res;
    total.push_back(time_ms([&] { res = matcher.match(left, right); }));
    for (int s = 0; s < kStages; ++s) stages[s].push_back(res.timings.ms[s]);
    r.boundary_refined = res.boundary_refined, r.noise_equalised = res.noise_equalised, r.gain_triggered = res.gain_triggered;
    t_bm.push_back(baseline_ms(bm, Baseline::BM));
    t_sgbm.push_back(baseline_ms(sgbm, Baseline::SGBM));
    r_sgbm.push_back(total.back() / t_sgbm.back());
    r_bm.push_back(total.back() / t_bm.back());
  }
  for (int s = 0; s < kStages; ++s) r.stage_ms[s] = median(stages[s]);
  r.fuzzy_ms = median(total);
  r.bm_ms = median(t_bm);
  r.sgbm_ms = median(t_sgbm);
  r.ratio_sgbm = median(r_sgbm);
  r.ratio_bm = median(r_bm);
  return r;
}

void run_bench(const BenchOptions& o) {
  if (o.repeats < 1) throw UserError("--repeats must be >= 1");
  check_radiometric_name(o.radiometric);
  const MatcherParams params = load_matcher_config(o.config);
  const FisDefinition fis = load_fis_definition(o.fis);
  const BenchInput in = choose_input(o);
  std::ofstream json_out;  // opened now so a bad path fails before the run, not after it
  if (!o.json.empty()) {
    json_out.open(o.json);
    if (!json_out) throw UserError("cannot write JSON file '" + o.json + "'");
  }

  const int all = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  std::vector<int> thread_counts{1};
  if (all > 1) thread_counts.push_back(all);

  std::vector<RunFigures> runs;
  for (const int t : thread_counts) {
    std::fprintf(stderr, "bench: threads %d ...\n", t);
    runs.push_back(bench_at(in, params, fis, t, o.repeats));
  }

  std::printf("bench: %s, %dx%d, D=%d, median of %d interleaved runs after 1 warm-up [ms]; ratios = median per-run ratio\n", in.label.c_str(),
              in.left_gray.cols, in.left_gray.rows, in.max_disparity, o.repeats);
  // What the matcher made of the pair (docs/algorithm.md 2b, 2c, 4b): a mismatched pair costs more.
  const RunFigures& r0 = runs.front();
  std::printf("right image: %s; the matcher %s, %s, boundary refinement %s\n",
              o.radiometric == "none" ? "as captured" : ("radiometric '" + o.radiometric + "' applied").c_str(),
              r0.noise_equalised ? "equalised the noise" : "did not equalise noise",
              r0.gain_triggered ? "compensated the gain" : "did not compensate gain", r0.boundary_refined ? "on" : "off");
  std::printf("%-24s", "");
  for (const auto& r : runs) std::printf(" %12s", ("threads=" + std::to_string(r.threads)).c_str());
  std::printf("\n");
  auto row = [&](const std::string& name, auto get, const char* fmt) {
    std::printf("%-24s", name.c_str());
    for (const auto& r : runs) std::printf(fmt, get(r));
    std::printf("\n");
  };
  for (int s = 0; s < kStages; ++s)
    row(std::string("  ") + stage_name(static_cast<Stage>(s)), [s](const RunFigures& r) { return r.stage_ms[s]; },
        " %12.2f");
  row("fuzzystereo (wall)", [](const RunFigures& r) { return r.fuzzy_ms; }, " %12.2f");
  row("opencv bm", [](const RunFigures& r) { return r.bm_ms; }, " %12.2f");
  row("opencv sgbm 3-way", [](const RunFigures& r) { return r.sgbm_ms; }, " %12.2f");
  row("ratio fuzzystereo/sgbm", [](const RunFigures& r) { return r.ratio_sgbm; }, " %11.2fx");
  row("ratio fuzzystereo/bm", [](const RunFigures& r) { return r.ratio_bm; }, " %11.2fx");

  if (json_out.is_open()) {
    nlohmann::ordered_json j;
    j["frame"] = in.label;
    j["width"] = in.left_gray.cols;
    j["height"] = in.left_gray.rows;
    j["max_disparity"] = in.max_disparity;
    j["repeats"] = o.repeats;
    j["radiometric"] = o.radiometric;
    j["boundary_refined"] = runs.front().boundary_refined;
    j["runs"] = nlohmann::ordered_json::array();
    for (const auto& r : runs) {
      nlohmann::ordered_json st = nlohmann::ordered_json::object();
      for (int s = 0; s < kStages; ++s) st[stage_name(static_cast<Stage>(s))] = r.stage_ms[s];
      j["runs"].push_back({{"threads", r.threads},
                           {"stages_ms", st},
                           {"fuzzystereo_ms", r.fuzzy_ms},
                           {"bm_ms", r.bm_ms},
                           {"sgbm_ms", r.sgbm_ms},
                           {"ratio_fuzzystereo_sgbm", r.ratio_sgbm},
                           {"ratio_fuzzystereo_bm", r.ratio_bm}});
    }
    json_out << j.dump(2) << "\n";
    if (!json_out) throw UserError("cannot write JSON file '" + o.json + "'");
  }
}

}  // namespace

void add_bench_command(CLI::App& app) {
  auto opts = std::make_shared<BenchOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench", "Per-stage timings on one frame (1 thread and all cores) beside OpenCV StereoBM/StereoSGBM");
  cmd->add_option("--dataset", opts->dataset,
                  "Datasets directory (default: $FUZZYSTEREO_DATASETS or ../shared/datasets; a synthetic "
                  "pair if neither exists)");
  cmd->add_option("--frame", opts->frame, "Frame name or SET/NAME (default: the first KITTI 2015 frame)");
  cmd->add_option("--repeats", opts->repeats, "Timed runs per method; the median is reported")->capture_default_str();
  cmd->add_option("--config", opts->config, "Matcher config TOML (default: built-in defaults)");
  cmd->add_option("--fis", opts->fis, "FIS definition TOML (default: built-in common/fis/fis.toml)");
  cmd->add_option("--json", opts->json, "Write the figures to this JSON file");
  cmd->add_option("--radiometric", opts->radiometric,
                  "Distortion applied to the right image, as in eval: none, gain, gamma, mixed, noise (times a "
                  "mismatched pair: the matcher then runs the [boundary] refinement, docs/algorithm.md 4b)")
      ->capture_default_str();
  cmd->add_option("--noise-seed", opts->noise_seed, "Seed of the noise field of --radiometric noise");
  cmd->callback([opts] { run_bench(*opts); });
}

}  // namespace fs::app
