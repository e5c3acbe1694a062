// fuzzystereo run        — the robot: capture -> match -> detect -> track -> plan -> motors.
// fuzzystereo sim suite  — N seeded closed-loop scenarios in the simulator, faster than real time.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "config.hpp"
#include "fuzzystereo/robot/motors.hpp"
#include "fuzzystereo/sim/scene.hpp"
#include "io.hpp"
#include "robot_loop.hpp"

namespace fs::app {

using json = nlohmann::json;

namespace {

robot::Vec2 parse_goal(const std::string& s) {
  double x = 0, y = 0;
  char comma = 0;
  std::istringstream in(s);
  if (!(in >> x >> comma >> y) || comma != ',' || !std::isfinite(x) || !std::isfinite(y))
    throw UserError("--goal '" + s + "' is not valid: expected X,Y in metres (world frame, e.g. 5,0.5)");
  return {x, y};
}

void print_result(const LoopResult& r) {
  std::printf("status %s  frames %d  time %.1f s  path %.2f m (shortest %.2f m)  min clearance %.3f m\n", r.status.c_str(),
              r.frames, r.time_s, r.path_m, r.shortest_m, r.min_clearance_m);
  std::printf("front stops %d  blocked frames %d  watchdog trips %d  %.1f frames/s of processing\n", r.front_stops,
              r.blocked_frames, r.watchdog_trips, r.fps_wall);
  if (r.watchdog_stop_after_last_plan_ms >= 0)
    std::printf("watchdog (sim clock): stop commanded %.0f ms after the last plan, %.0f ms after the missed frame deadline\n",
                r.watchdog_stop_after_last_plan_ms, r.watchdog_stop_after_deadline_ms);
  if (r.watchdog_stop_wall_ms >= 0)
    std::printf("watchdog (wall clock): stop commanded %.1f ms after the last plan\n", r.watchdog_stop_wall_ms);
  std::printf("%-8s %9s %9s %9s\n", "stage", "median ms", "p90 ms", "max ms");
  for (const auto& [k, s] : r.stages) std::printf("%-8s %9.1f %9.1f %9.1f\n", k.c_str(), s.median, s.p90, s.max);
}

struct RunOptions {
  std::string source, motors = "sim", config, goal, record, json_out;
  int max_frames = 0, snapshot_every = 10, stall_frame = -1;
  double stall_ms = 0, latency_ms = 100, time_limit = 0;
  bool realtime = false, quiet = false;
};

void run_run(const RunOptions& o) {
  const Config cfg = load_config(o.config);
  LoopOptions lo;
  lo.source = o.source;
  lo.motors = o.motors;
  if (!o.goal.empty()) lo.goal = parse_goal(o.goal);
  lo.record_dir = o.record;
  lo.max_frames = o.max_frames;
  lo.snapshot_every = o.snapshot_every;
  lo.stall_frame = o.stall_frame;
  lo.stall_ms = o.stall_ms;
  lo.sim_latency_ms = o.latency_ms;
  lo.time_limit_s = o.time_limit;
  lo.realtime = o.realtime;
  lo.quiet = o.quiet;
  LoopResult r;
  try {
    RobotLoop loop(cfg, lo);
    r = loop.run();
  } catch (const robot::HardwareError& e) {
    throw UserError(e.what());
  }
  print_result(r);
  if (!o.json_out.empty()) {
    json j = r.to_json();
    json st;
    for (const auto& [k, s] : r.stages) st[k] = {{"median", s.median}, {"p90", s.p90}, {"max", s.max}};
    j["timing_ms"] = st;
    std::ofstream(o.json_out) << j.dump(2) << '\n';
  }
}

struct SuiteOptions {
  int count = 100, blocked = -1, jobs = 1;
  std::uint64_t seed = 1;
  std::string config, json_out, record;
  double latency_ms = 100;
};

void run_suite(const SuiteOptions& o) {
  if (o.count < 0) throw UserError("--count must be >= 0");
  const int n_blocked = o.blocked >= 0 ? o.blocked : std::max(1, o.count / 10);
  const int total = o.count + n_blocked;
  if (total == 0) throw UserError("nothing to run: --count and --blocked are 0");
  Config cfg = load_config(o.config);
  const int jobs = std::max(1, o.jobs);
  if (jobs > 1) cfg.matcher.runtime.threads = 1;
  struct Item {
    int index;
    bool blocked;
    std::string features;
    LoopResult r;
  };
  std::vector<Item> items(static_cast<std::size_t>(total));
  std::atomic<int> next{0}, done{0};
  std::mutex print_mu;
  std::string first_error;
  auto worker = [&] {
    for (;;) {
      const int i = next.fetch_add(1);
      if (i >= total) return;
      Item& it = items[static_cast<std::size_t>(i)];
      it.blocked = i >= o.count;
      it.index = it.blocked ? i - o.count : i;
      try {
        LoopOptions lo;
        lo.scene = make_suite_scene(o.seed, it.index, it.blocked, cfg, &it.features);
        lo.source = "sim:" + lo.scene->source;
        lo.quiet = true;
        lo.look_around = true;
        lo.sim_latency_ms = o.latency_ms;
        if (!o.record.empty()) {
          lo.record_dir = o.record + "/" + lo.scene->source;
          lo.snapshot_every = 0;
        }
        RobotLoop loop(cfg, lo);
        it.r = loop.run();
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> g(print_mu);
        if (first_error.empty()) first_error = e.what();
        it.r.status = std::string("error: ") + e.what();
      }
      const int d = ++done;
      std::lock_guard<std::mutex> g(print_mu);
      std::fprintf(stderr, "[%3d/%3d] %s %3d %-22s %-13s %5.1f s  path %.2f/%.2f m  clearance %.3f m\n", d, total,
                   it.blocked ? "blocked " : "solvable", it.index, it.features.c_str(), it.r.status.c_str(), it.r.time_s,
                   it.r.path_m, it.r.shortest_m, it.r.min_clearance_m);
    }
  };
  std::vector<std::thread> pool;
  for (int j = 0; j < jobs; ++j) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (!first_error.empty() && first_error.find("error") != std::string::npos) {
  }

  int struck = 0;
  int solvable = 0, reached = 0, collisions = 0, blocked = 0, blocked_safe = 0, moving = 0, moving_ok = 0, gaps = 0,
      gaps_ok = 0, errors = 0;
  std::vector<double> ratios, fps, match_ms, total_ms;
  json per = json::array();
  for (const Item& it : items) {
    const LoopResult& r = it.r;
    if (r.status.rfind("error", 0) == 0) ++errors;
    if (r.collided) ++collisions;
    if (r.struck) ++struck;
    if (it.blocked) {
      ++blocked;
      if (r.safe_stop && !r.collided) ++blocked_safe;
    } else {
      ++solvable;
      const bool ok = r.reached && !r.collided;
      if (ok) {
        ++reached;
        if (r.shortest_m > 0 && std::isfinite(r.shortest_m)) ratios.push_back(r.path_m / r.shortest_m);
      }
      if (it.features.find("moving") != std::string::npos) {
        ++moving;
        moving_ok += ok;
      }
      if (it.features.find("gap") != std::string::npos) {
        ++gaps;
        gaps_ok += ok;
      }
    }
    if (r.fps_wall > 0) fps.push_back(r.fps_wall);
    for (const auto& [k, s] : r.stages) {
      if (k == "match") match_ms.push_back(s.median);
      if (k == "total") total_ms.push_back(s.median);
    }
    json j = r.to_json();
    j["index"] = it.index;
    j["blocked"] = it.blocked;
    j["features"] = it.features;
    per.push_back(j);
  }
  auto med = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  double ratio_mean = 0, ratio_max = 0;
  for (double r : ratios) {
    ratio_mean += r;
    ratio_max = std::max(ratio_max, r);
  }
  if (!ratios.empty()) ratio_mean /= static_cast<double>(ratios.size());
  const double success = solvable ? 100.0 * reached / solvable : 0.0;
  const double safe = blocked ? 100.0 * blocked_safe / blocked : 0.0;
  std::printf("suite seed %llu: %d solvable + %d without a free path\n", static_cast<unsigned long long>(o.seed), solvable,
              blocked);
  std::printf("reached goal          %3d / %3d  %.1f %%   (target >= 98 %%)\n", reached, solvable, success);
  std::printf("  with moving obstacles %3d / %3d\n", moving_ok, moving);
  std::printf("  through narrow gaps   %3d / %3d\n", gaps_ok, gaps);
  std::printf("collisions            %3d          (target 0)\n", collisions);
  std::printf("struck while standing  %3d          (a moving obstacle from outside the camera view)\n", struck);
  std::printf("safe stop, no path    %3d / %3d  %.1f %%   (target 100 %%)\n", blocked_safe, blocked, safe);
  std::printf("path / shortest       mean %.3f  max %.3f\n", ratio_mean, ratio_max);
  std::printf("processing            median %.1f frames/s (match %.1f ms, whole frame %.1f ms)\n", med(fps),
              med(match_ms), med(total_ms));
  if (errors) std::printf("errors                %d (first: %s)\n", errors, first_error.c_str());
  if (!o.json_out.empty()) {
    json j{{"seed", o.seed},
           {"solvable", solvable},
           {"reached", reached},
           {"success_pct", success},
           {"moving", moving},
           {"moving_reached", moving_ok},
           {"gaps", gaps},
           {"gaps_reached", gaps_ok},
           {"collisions", collisions},
           {"struck", struck},
           {"blocked", blocked},
           {"blocked_safe_stop", blocked_safe},
           {"safe_stop_pct", safe},
           {"path_ratio_mean", ratio_mean},
           {"path_ratio_max", ratio_max},
           {"fps_median", med(fps)},
           {"match_ms_median", med(match_ms)},
           {"frame_ms_median", med(total_ms)},
           {"errors", errors},
           {"scenarios", per}};
    std::ofstream(o.json_out) << j.dump(2) << '\n';
  }
  if (errors) throw UserError("suite: " + std::to_string(errors) + " scenario(s) failed to run: " + first_error);
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto o = std::make_shared<RunOptions>();
  CLI::App* c = app.add_subcommand("run", "Run the robot: capture -> match -> detect -> track -> plan -> motors");
  c->add_option("--source", o->source, "sim:SCENE | replay:DIR | uvc:DEV[,DEV] | libcamera[:ID,ID]")->required();
  c->add_option("--motors", o->motors, "sim | gpiod")->capture_default_str();
  c->add_option("--config", o->config, "TOML config (defaults: common/config/default.toml)");
  c->add_option("--goal", o->goal, "Goal X,Y in metres, world frame (default: the scene's [mission])");
  c->add_option("--record", o->record, "Write the run record (frames.jsonl, run.json, annotated frames) here");
  c->add_option("--snapshot-every", o->snapshot_every, "Record an annotated frame every N frames")->capture_default_str();
  c->add_option("--max-frames", o->max_frames, "Stop after N frames (0 = no limit)");
  c->add_option("--time-limit", o->time_limit, "Stop after this many seconds (0 = the scene's mission limit)");
  c->add_option("--latency-ms", o->latency_ms, "Simulated processing latency before a command reaches the motors")
      ->capture_default_str();
  c->add_option("--stall-frame", o->stall_frame, "Fault injection: the pipeline stalls at this frame");
  c->add_option("--stall-ms", o->stall_ms, "... for this long [ms]");
  c->add_flag("--realtime", o->realtime, "Simulator: pace frames on the wall clock");
  c->add_flag("--quiet", o->quiet, "No per-frame line on stderr");
  c->add_option("--json", o->json_out, "Write the result as JSON");
  c->callback([o] { run_run(*o); });
}

void add_sim_suite_command(CLI::App& sim) {
  auto o = std::make_shared<SuiteOptions>();
  CLI::App* c = sim.add_subcommand("suite", "Closed-loop scenario suite in the simulator (faster than real time)");
  c->add_option("--count", o->count, "Scenarios with a free path")->capture_default_str();
  c->add_option("--blocked", o->blocked, "Scenarios without a free path (default: count/10, at least 1)");
  c->add_option("--seed", o->seed, "Suite seed")->capture_default_str();
  c->add_option("--jobs", o->jobs, "Scenarios run in parallel (each single-threaded when > 1)")->capture_default_str();
  c->add_option("--config", o->config, "TOML config");
  c->add_option("--latency-ms", o->latency_ms, "Simulated processing latency")->capture_default_str();
  c->add_option("--record", o->record, "Write each scenario's run record under this directory");
  c->add_option("--json", o->json_out, "Write the summary and every scenario as JSON");
  c->callback([o] { run_suite(*o); });
}

}  // namespace fs::app
