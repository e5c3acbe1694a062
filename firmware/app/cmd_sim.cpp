// `fuzzystereo sim`: the deterministic synthetic stereo world (docs/simulator.md).
//   sim render SCENE --out DIR     one stereo pair with its exact ground truth
//   sim generate --count N --seed S --out DIR    a KITTI-2015-like synthetic data set
//   sim track-eval [--config C] [--trials N ...]  the tracker on constant-velocity trajectories with exact
//                                                 ground truth (issue 5's tracking targets)
// The world itself (fs_sim) has no OpenCV; this file converts its images and writes the files.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "commands.hpp"
#include "config.hpp"
#include "fuzzystereo/robot/params.hpp"
#include "fuzzystereo/robot/track_eval.hpp"
#include "fuzzystereo/sim/generator.hpp"
#include "fuzzystereo/sim/world.hpp"
#include "io.hpp"

namespace fs::app {
namespace {

namespace stdfs = std::filesystem;
using json = nlohmann::ordered_json;

constexpr const char* kMarkerName = "fuzzystereo_sim.json";

void make_dir(const stdfs::path& d) { make_output_dir(d.string()); }

void write_text(const stdfs::path& p, const std::string& text) { write_text_file("file", p.string(), text); }

cv::Mat to_bgr(const ImageRgb8& im) {
  cv::Mat m(im.height, im.width, CV_8UC3);
  for (int y = 0; y < im.height; ++y) {
    const Rgb8* s = im.row(y);
    auto* d = m.ptr<cv::Vec3b>(y);
    for (int x = 0; x < im.width; ++x) d[x] = cv::Vec3b(s[x].b, s[x].g, s[x].r);
  }
  return m;
}

cv::Mat to_float(const Image<float>& im) {
  cv::Mat m(im.height, im.width, CV_32F);
  for (int y = 0; y < im.height; ++y) std::copy(im.row(y), im.row(y) + im.width, m.ptr<float>(y));
  return m;
}

cv::Mat to_u8(const ImageU8& im) {
  cv::Mat m(im.height, im.width, CV_8U);
  for (int y = 0; y < im.height; ++y) std::copy(im.row(y), im.row(y) + im.width, m.ptr<std::uint8_t>(y));
  return m;
}

// Obstacle ids as uint16: 0 = none, id + 1 otherwise.
cv::Mat ids_u16(const ImageI32& im) {
  cv::Mat m(im.height, im.width, CV_16U);
  for (int y = 0; y < im.height; ++y) {
    const std::int32_t* s = im.row(y);
    auto* d = m.ptr<std::uint16_t>(y);
    for (int x = 0; x < im.width; ++x) d[x] = static_cast<std::uint16_t>(s[x] < 0 ? 0 : s[x] + 1);
  }
  return m;
}

float max_disparity(const Image<float>& d) {
  return d.data.empty() ? 0.0f : *std::max_element(d.data.begin(), d.data.end());
}

// The per-frame ground-truth record (sim_gt/NNNNNN_10.json and obstacles.json).
json truth_json(const sim::Scene& s, const sim::RenderResult& r) {
  json obs = json::array();
  for (const auto& t : r.obstacles) {
    obs.push_back({{"id", t.id},
                   {"shape", sim::to_string(t.shape)},
                   {"box", t.visible_pixels > 0 ? json{t.x0, t.y0, t.x1, t.y1} : json(nullptr)},
                   {"position_world_m", {t.world[0], t.world[1], t.world[2]}},
                   {"position_cam_m", {t.cam[0], t.cam[1], t.cam[2]}},
                   {"distance_m", t.distance_m},
                   {"visible_pixels", t.visible_pixels},
                   {"truncated", t.truncated},
                   {"velocity_mps", {t.velocity[0], t.velocity[1]}}});
  }
  const StereoCalib& c = r.calib;
  return json{{"type", s.type},
              {"seed", s.seed},
              {"width", r.left.width},
              {"height", r.left.height},
              {"calib",
               {{"focal_px", c.focal_px},
                {"cx", c.cx},
                {"cy", c.cy},
                {"baseline_m", c.baseline_m},
                {"height_m", c.height_m},
                {"pitch_deg", s.camera.pitch_deg}}},
              {"max_gt_disparity", max_disparity(r.disparity)},
              {"obstacles", obs}};
}

// KITTI 2015 calib_cam_to_cam: rectified projections P = K [I | t], P_rect_03[3] = -f*B, so
// firmware/app/dataset.cpp derives f and B as for the real KITTI files.
std::string kitti_calib(const StereoCalib& c, int w, int h) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "S_rect_02: %d %d\nP_rect_02: %.12g 0 %.12g 0 0 %.12g %.12g 0 0 0 1 0\n"
                "S_rect_03: %d %d\nP_rect_03: %.12g 0 %.12g %.12g 0 %.12g %.12g 0 0 0 1 0\n",
                w, h, c.focal_px, c.cx, c.focal_px, c.cy, w, h, c.focal_px, c.cx, -c.focal_px * c.baseline_m,
                c.focal_px, c.cy);
  return buf;
}

cv::Mat disparity_preview(const Image<float>& d, double max_disp) {
  cv::Mat f = to_float(d);
  f.setTo(-1.0f, f <= 0.0f);  // sky / no hit drawn black
  return colorize_disparity(f, max_disp);
}

// Left image with every visible obstacle's box and "id Z".
cv::Mat boxes_preview(const sim::RenderResult& r) {
  cv::Mat m = to_bgr(r.left);
  for (const auto& t : r.obstacles) {
    if (t.visible_pixels == 0) continue;
    const cv::Scalar col = t.truncated ? cv::Scalar(0, 200, 255) : cv::Scalar(0, 255, 0);
    cv::rectangle(m, cv::Point(t.x0, t.y0), cv::Point(t.x1, t.y1), col, 1);
    char label[64];
    std::snprintf(label, sizeof label, "%d %.1fm", t.id, t.distance_m);
    cv::putText(m, label, cv::Point(t.x0 + 2, std::max(10, t.y0 - 3)), cv::FONT_HERSHEY_SIMPLEX, 0.35, col, 1,
                cv::LINE_AA);
  }
  return m;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// ---- sim render ----------------------------------------------------------------------------------

struct RenderOptions {
  std::string scene;
  std::string out;
  double time_s = 0.0;
  int threads = 0;
  int repeat = 1;
  bool reference = false;
};

void run_render(const RenderOptions& o) {
  const sim::Scene scene = sim::load_scene(o.scene);
  if (o.threads < 0) throw UserError("--threads must be >= 0 (0 = all cores)");
  if (!(o.time_s >= 0.0)) throw UserError("--time must be >= 0 s");
  const stdfs::path out(o.out);
  make_dir(out);
  if (o.repeat < 1) throw UserError("--repeat must be >= 1");
  const sim::World world(scene);
  // --repeat N: N identical renders, median times reported (timing); the files are the last one.
  std::vector<double> wall, cpu;
  sim::RenderResult r;
  for (int i = 0; i < o.repeat; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::clock_t c0 = std::clock();
    r = o.reference ? world.render_reference(world.scene_pose(), o.time_s, o.threads)
                    : world.render(world.scene_pose(), o.time_s, o.threads);
    wall.push_back(ms_since(t0));
    // Process CPU time (all threads): the wall time's lower bound on an idle machine is about this
    // divided by the thread count.
    cpu.push_back(1000.0 * static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
  }
  std::sort(wall.begin(), wall.end());
  std::sort(cpu.begin(), cpu.end());
  const double ms = wall[wall.size() / 2], cpu_ms = cpu[cpu.size() / 2];
  write_image((out / "left.png").string(), to_bgr(r.left));
  write_image((out / "right.png").string(), to_bgr(r.right));
  const cv::Mat disp = to_float(r.disparity);
  write_disp_kitti((out / "disp_gt.png").string(), disp);
  const double dmax = std::max(16.0, static_cast<double>(max_disparity(r.disparity)));
  write_image((out / "disp_gt_color.png").string(), disparity_preview(r.disparity, dmax));
  write_image((out / "road_mask.png").string(), to_u8(r.road_mask));
  write_image((out / "sky_mask.png").string(), to_u8(r.sky_mask));
  write_image((out / "obstacles.png").string(), ids_u16(r.obstacle_ids));
  write_image((out / "preview.png").string(), boxes_preview(r));
  json j = truth_json(scene, r);
  j["scene"] = o.scene;
  j["time_s"] = o.time_s;
  j["render_ms"] = ms;
  j["render_cpu_ms"] = cpu_ms;
  write_text(out / "obstacles.json", j.dump(2) + "\n");
  write_text(out / "calib_cam_to_cam.txt", kitti_calib(r.calib, r.left.width, r.left.height));
  std::printf("rendered %s: %dx%d, supersample %dx%d, %zu obstacles, max GT disparity %.2f px, %.1f ms (CPU %.1f ms)%s%s -> %s\n",
              o.scene.c_str(), r.left.width, r.left.height, scene.render.supersample, scene.render.supersample,
              r.obstacles.size(), static_cast<double>(max_disparity(r.disparity)), ms, cpu_ms,
              o.repeat > 1 ? (", median of " + std::to_string(o.repeat)).c_str() : "",
              o.reference ? ", reference renderer" : "", o.out.c_str());
}

// ---- sim generate --------------------------------------------------------------------------------

struct GenerateOptions {
  int count = 0;
  std::uint64_t seed = 1;
  std::string out;
  int width = 640, height = 360;
  int threads = 0;
};

void run_generate(const GenerateOptions& o) {
  if (o.count < 1 || o.count > 999999) throw UserError("--count must be in [1, 999999]");
  if (o.width < 16 || o.width > 4096) throw UserError("--width must be in [16, 4096] px");
  if (o.height < 16 || o.height > 4096) throw UserError("--height must be in [16, 4096] px");
  if (o.threads < 0) throw UserError("--threads must be >= 0 (0 = all cores)");
  if (o.seed > 0x7fffffffffffffffULL) throw UserError("--seed must be in [0, 2^63-1]");
  const stdfs::path root(o.out), train = root / "training";
  for (const char* sub : {"image_2", "image_3", "disp_occ_0", "calib_cam_to_cam", "sim_gt", "scenes"})
    make_dir(train / sub);
  sim::GeneratorOptions gopt;
  gopt.width = o.width;
  gopt.height = o.height;
  float max_d = 0.0f;
  std::map<std::string, int> type_counts;
  double total_ms = 0.0;
  for (int i = 0; i < o.count; ++i) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d", i);
    const std::string id(name), frame = id + "_10.png";
    // Render the scene as read back from the file we write, so `sim render` of that file gives
    // the same bytes.
    const std::string text = sim::scene_to_toml(sim::generate_scene(o.seed, i, gopt));
    const stdfs::path scene_path = train / "scenes" / (id + ".toml");
    write_text(scene_path, text);
    const sim::Scene scene = sim::parse_scene(text, scene_path.string());
    const sim::World world(scene);
    const auto t0 = std::chrono::steady_clock::now();
    const sim::RenderResult r = world.render(world.scene_pose(), 0.0, o.threads);
    const double ms = ms_since(t0);
    total_ms += ms;
    write_image((train / "image_2" / frame).string(), to_bgr(r.left));
    write_image((train / "image_3" / frame).string(), to_bgr(r.right));
    write_disp_kitti((train / "disp_occ_0" / frame).string(), to_float(r.disparity));
    write_text(train / "calib_cam_to_cam" / (id + ".txt"), kitti_calib(r.calib, r.left.width, r.left.height));
    write_text(train / "sim_gt" / (id + "_10.json"), truth_json(scene, r).dump(2) + "\n");
    write_image((train / "sim_gt" / (id + "_10_road.png")).string(), to_u8(r.road_mask));
    write_image((train / "sim_gt" / (id + "_10_sky.png")).string(), to_u8(r.sky_mask));
    write_image((train / "sim_gt" / (id + "_10_obstacles.png")).string(), ids_u16(r.obstacle_ids));
    const float md = max_disparity(r.disparity);
    max_d = std::max(max_d, md);
    ++type_counts[scene.type];
    std::fprintf(stderr, "[%d/%d] %s %-15s %2zu obstacles, max disparity %5.1f px, render %.0f ms\n", i + 1, o.count,
                 id.c_str(), scene.type.c_str(), scene.obstacles.size(), static_cast<double>(md), ms);
  }
  // Search range for matchers: the smallest multiple of 16 above the largest GT disparity.
  const int max_disparity_16 = (static_cast<int>(std::floor(max_d / 16.0f)) + 1) * 16;
  json marker{{"format", "fuzzystereo-sim"},
              {"generator_version", sim::kGeneratorVersion},
              {"count", o.count},
              {"seed", o.seed},
              {"width", o.width},
              {"height", o.height},
              {"max_disparity", max_disparity_16},
              {"max_gt_disparity", max_d},
              {"scenario_types", sim::scenario_types()},
              {"type_counts", type_counts}};
  write_text(root / kMarkerName, marker.dump(2) + "\n");
  std::fprintf(stderr, "generate: %d frames in %s (max disparity %d, mean render %.0f ms)\n", o.count, o.out.c_str(),
               max_disparity_16, total_ms / o.count);
}

struct TrackEvalCliOptions {
  std::string config, json_out;
  robot::TrackEvalOptions eval;
};

// The issue-5 tracking targets: filtered position RMSE below the raw measurements', and the velocity
// error within 0.1 m/s after 10 frames (the 95th percentile is held to it; RMS and max are printed too).
void run_track_eval(const TrackEvalCliOptions& o) {
  const Config cfg = load_config(o.config);
  const robot::TrackerParams tp = robot::tracker_params_from(cfg.values);
  robot::TrackEvalResult r;
  try {
    r = robot::evaluate_constant_velocity(tp, o.eval);
  } catch (const std::invalid_argument& e) {
    throw UserError(e.what());
  }
  const bool pos_ok = r.filt_pos_rmse_m < r.raw_pos_rmse_m, vel_ok = r.vel_p95_after_mps <= 0.1;
  std::printf("track-eval: %d constant-velocity trajectories x %d frames at %.0f Hz, noise %.3f m per axis, speeds up to "
              "%.2f m/s, [tracker] from %s\n",
              o.eval.trials, o.eval.frames, 1.0 / o.eval.dt_s, o.eval.sigma_m, r.max_speed_mps,
              o.config.empty() ? "the defaults" : o.config.c_str());
  std::printf("  position RMSE   filter %.4f m   raw measurements %.4f m   (%.0f %% of raw)   %s\n", r.filt_pos_rmse_m,
              r.raw_pos_rmse_m, 100.0 * r.filt_pos_rmse_m / r.raw_pos_rmse_m, pos_ok ? "target met" : "TARGET MISSED");
  std::printf("  velocity error from frame %d on   RMS %.4f m/s   p95 %.4f m/s   max %.4f m/s   %s (p95 <= 0.1 m/s)\n",
              o.eval.settle_frames, r.vel_rmse_after_mps, r.vel_p95_after_mps, r.vel_max_after_mps,
              vel_ok ? "target met" : "TARGET MISSED");
  if (r.frames_not_one_track > 0)
    std::printf("  warning: %ld of %ld frames did not hold exactly one track (left out of the figures)\n",
                r.frames_not_one_track, r.frames_total);
  if (!o.json_out.empty()) {
    json j{{"format", "fuzzystereo-track-eval"},
           {"trials", o.eval.trials},
           {"frames", o.eval.frames},
           {"dt_s", o.eval.dt_s},
           {"sigma_m", o.eval.sigma_m},
           {"max_axis_speed_mps", o.eval.max_axis_speed_mps},
           {"settle_frames", o.eval.settle_frames},
           {"seed", o.eval.seed},
           {"max_speed_mps", r.max_speed_mps},
           {"filt_pos_rmse_m", r.filt_pos_rmse_m},
           {"raw_pos_rmse_m", r.raw_pos_rmse_m},
           {"vel_rmse_after_mps", r.vel_rmse_after_mps},
           {"vel_p95_after_mps", r.vel_p95_after_mps},
           {"vel_max_after_mps", r.vel_max_after_mps},
           {"frames_not_one_track", r.frames_not_one_track},
           {"frames_total", r.frames_total},
           {"position_target_met", pos_ok},
           {"velocity_target_met", vel_ok},
           {"config_toml", config_to_toml(cfg.values)}};
    write_text(o.json_out, j.dump(2) + "\n");
    std::printf("wrote %s\n", o.json_out.c_str());
  }
}

}  // namespace

void add_sim_command(CLI::App& app) {
  CLI::App* sim = app.add_subcommand("sim", "Synthetic stereo world: render a scene file, generate a data set");
  add_sim_suite_command(*sim);
  sim->require_subcommand(1);

  auto ro = std::make_shared<RenderOptions>();
  CLI::App* render = sim->add_subcommand("render", "Render a scene (TOML) with its exact ground truth into DIR");
  render->add_option("scene", ro->scene, "Scene file (docs/simulator.md)")->required();
  render->add_option("--out", ro->out, "Output directory")->required();
  render->add_option("--time", ro->time_s, "Scene time [s] (moving obstacles)")->capture_default_str();
  render->add_option("--threads", ro->threads, "Render threads (0 = all cores)")->capture_default_str();
  render->add_option("--repeat", ro->repeat, "Render N times, report the median time (timing)")->capture_default_str();
  render->add_flag("--reference", ro->reference, "Use the plain reference renderer (same output, slower; for checks)");
  render->callback([ro] { run_render(*ro); });

  auto go = std::make_shared<GenerateOptions>();
  CLI::App* gen = sim->add_subcommand("generate", "Generate a KITTI-2015-like synthetic data set with ground truth");
  gen->add_option("--count", go->count, "Number of frames")->required();
  gen->add_option("--seed", go->seed, "Set seed (same seed, same set)")->capture_default_str();
  gen->add_option("--out", go->out, "Output directory")->required();
  gen->add_option("--width", go->width, "Image width [px]")->capture_default_str();
  gen->add_option("--height", go->height, "Image height [px]")->capture_default_str();
  gen->add_option("--threads", go->threads, "Render threads (0 = all cores)")->capture_default_str();
  gen->callback([go] { run_generate(*go); });

  auto to = std::make_shared<TrackEvalCliOptions>();
  CLI::App* te = sim->add_subcommand("track-eval", "Kalman tracking on generated constant-velocity trajectories with exact ground truth");
  te->add_option("--config", to->config, "TOML config (its [tracker] section)");
  te->add_option("--trials", to->eval.trials, "Trajectories")->capture_default_str();
  te->add_option("--frames", to->eval.frames, "Frames per trajectory")->capture_default_str();
  te->add_option("--dt", to->eval.dt_s, "Frame period [s]")->capture_default_str();
  te->add_option("--sigma", to->eval.sigma_m, "Measurement noise per axis [m]")->capture_default_str();
  te->add_option("--speed", to->eval.max_axis_speed_mps, "Velocity components uniform in [-speed, speed] [m/s]")
      ->capture_default_str();
  te->add_option("--settle", to->eval.settle_frames, "Velocity errors count from this frame on")->capture_default_str();
  te->add_option("--seed", to->eval.seed, "Seed (same seed, same trajectories)")->capture_default_str();
  te->add_option("--json", to->json_out, "Write the figures as JSON");
  te->callback([to] { run_track_eval(*to); });
}

}  // namespace fs::app
