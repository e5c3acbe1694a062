// fuzzystereo run        — the robot: capture -> match -> detect -> track -> plan -> motors.
// fuzzystereo sim suite  — N seeded closed-loop scenarios in the simulator, faster than real time.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
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
#include "detect_io.hpp"
#include "dump.hpp"
#include "fuzzystereo/link/device_server.hpp"
#include "fuzzystereo/link/port.hpp"
#include "fuzzystereo/robot/failsafe.hpp"
#include "robot_loop.hpp"

#include <condition_variable>
#include <filesystem>

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
    std::printf("watchdog (sim clock): stop commanded %.0f ms after the last plan, %.0f ms after the stall began (the frame that never came)\n",
                r.watchdog_stop_after_last_plan_ms, r.watchdog_stop_after_deadline_ms);
  if (r.watchdog_stop_wall_ms >= 0)
    std::printf("watchdog (wall clock): stop commanded %.1f ms after the last plan, %.1f ms after the stall began\n",
                r.watchdog_stop_wall_ms, r.watchdog_stop_wall_after_stall_ms);
  if (r.perception_stops > 0 || r.perception_fault_frames > 0)
    std::printf("perception failsafe: %d stop(s), %d faulty frame(s)\n", r.perception_stops, r.perception_fault_frames);
  if (r.camera_mismatch_frames > 0)  // docs/runtime.md: the two cameras do not see the scene alike
    std::printf("cameras: %d of %d frames read as mismatched (gain/tone %d, noise %d): give both cameras the same fixed "
                "exposure and gain (check with fuzzyctl rectcheck)\n",
                r.camera_mismatch_frames, r.frames, r.camera_gain_frames, r.camera_noise_frames);
  if (!r.record_warning.empty())
    std::printf("record incomplete: %s (%d snapshots, %d frame-log lines not written)\n", r.record_warning.c_str(),
                r.record_dropped_snapshots, r.record_dropped_frames);
  if (r.perception_stop_after_ms >= 0)
    std::printf("perception failsafe: stop commanded %.0f ms after the first blinded frame was captured\n",
                r.perception_stop_after_ms);
  std::printf("%-8s %9s %9s %9s\n", "stage", "median ms", "p90 ms", "max ms");
  for (const auto& [k, s] : r.stages) std::printf("%-8s %9.1f %9.1f %9.1f\n", k.c_str(), s.median, s.p90, s.max);
}

// Simulator diagnostics (docs/robot.md "Session 45"): what the robot achieves when one layer of its
// perception is replaced by the simulator's truth. disparity: the matcher's map; detections: the matcher's
// map and the detector's output; world-seen: the planner's obstacles (map cells, tracks and what the loop
// adds to them) are every scene obstacle the camera has seen so far, known exactly from then on; world:
// every scene obstacle, in view or not; movers-seen / statics-seen: only the moving / the static scene obstacles
// seen so far are the truth, the loop's own obstacles of the other kind stay; movers-seen-added: the movers seen so
// far, exact, added to the loop's own list (nothing removed); -cv (movers-seen-cv, world-seen-cv): out of view each is
// where its exact state at its last sighting extrapolates at constant velocity (a perfect tracker's prediction). With the world levels perception runs as usual (its output is
// recorded, the ground-seen-ahead stop still reads it); only the planner's obstacle list is the truth.
void set_oracle(LoopOptions& lo, const std::string& level) {
  lo.oracle_disparity = level == "disparity" || level == "detections";
  lo.oracle_detections = level == "detections";
  const bool seen = level.find("-seen") != std::string::npos;  // world-seen, movers-seen[-added], statics-seen
  lo.oracle_world = level == "world" || seen;
  lo.oracle_world_seen = seen;
  lo.oracle_labels = level.starts_with("mover-labels");
  lo.oracle_label_velocity = level == "mover-labels-velocity";
  lo.oracle_coast = level.ends_with("-cv");  // movers-seen-cv, world-seen-cv
  using Part = LoopOptions::OraclePart;
  lo.oracle_part = level == "movers-seen" || level == "movers-seen-cv" ? Part::kMovers
                   : level == "movers-seen-added"                       ? Part::kMoversAdded
                   : level == "statics-seen"                            ? Part::kStatics
                                                                        : Part::kAll;
}

void add_oracle_option(CLI::App* c, std::string& level) {
  c->add_option("--oracle", level,
                "Simulator diagnostic: replace a layer by the truth - disparity (the matcher's map), detections (the "
                "detector's output), world-seen (the planner gets every obstacle seen so far, exactly), world (every "
                "obstacle, in view or not), movers-seen / statics-seen (only the moving / static ones seen so far), "
                "movers-seen-added (the movers seen so far added to the loop's own obstacles); -cv: out of view, each "
                "where a perfect constant-velocity tracker would predict it from its last sighting (movers-seen-cv, "
                "world-seen-cv); mover-labels (the loop's moving test replaced by the truth), mover-labels-velocity (and the movers' "
                "tracks coasted from their last measurement at the true velocity)")
      ->check(CLI::IsMember({"disparity", "detections", "mover-labels", "mover-labels-velocity", "movers-seen", "movers-seen-cv", "movers-seen-added",
                             "statics-seen", "world-seen", "world-seen-cv", "world"}));
}

struct RunOptions {
  std::string source, motors = "sim", config, goal, record, json_out, blind_side = "left", blind_mode = "dark";
  int max_frames = 0, snapshot_every = 10, plan_every = 10, stall_frame = -1, blind_frame = -1, record_fail_frame = -1;
  double stall_ms = 0, latency_ms = 100, time_limit = 0;
  bool realtime = false, quiet = false;
  std::string oracle;  // simulator diagnostic (add_oracle_option)
  // Serial link (docs/protocol.md): device services next to the loop.
  std::string link, state_dir, pty_link;
  int baud = 115200;
};

// Telemetry message of one logged frame (robot_loop.cpp writes the JSON).
link::msg::Telemetry telemetry_of(const json& f, const std::string& source, std::uint32_t uptime_ms) {
  link::msg::Telemetry t;
  t.frame_id = f.value("frame", 0u);
  t.t_ms = uptime_ms;
  t.source = source;
  double total = 0;
  for (auto it = f["stage_ms"].begin(); it != f["stage_ms"].end(); ++it) {
    t.stages.push_back({it.key(), it.value().get<float>()});
    if (it.key() == "total") total = it.value().get<double>();
  }
  t.fps = total > 0 ? static_cast<float>(1000.0 / total) : 0.0f;
  int id = 0;
  for (const auto& d : f["detections"]) {
    if (t.obstacles.size() >= 32) break;
    link::msg::Obstacle o;
    o.track_id = static_cast<std::uint16_t>(id++);
    const std::string cls = d.value("class", "mid");
    o.cls = cls == "near" ? 0 : cls == "mid" ? 1 : 2;
    o.distance_m = d.value("distance_m", 0.0f);
    o.lateral_m = d.value("lateral_m", 0.0f);
    o.width_m = d.value("width_m", 0.0f);
    t.obstacles.push_back(o);
  }
  t.cmd_v_mps = f["cmd"][0].get<float>();
  t.cmd_w_radps = f["cmd"][1].get<float>();
  t.motor_left = f["wheels"][0].get<float>();
  t.motor_right = f["wheels"][1].get<float>();
  t.pose_x_m = f["pose"][0].get<float>();
  t.pose_y_m = f["pose"][1].get<float>();
  t.pose_yaw_deg = static_cast<float>(f["pose"][2].get<double>() * 180.0 / M_PI);
  return t;
}

// A snapshot asked for by the link thread, written by the loop after its next match.
struct SnapshotRequest {
  std::mutex m;
  std::condition_variable cv;
  bool wanted = false, ready = false;
  std::string error;
  std::vector<link::SnapshotFile> files;
};

void run_run(const RunOptions& o) {
  check_output_file("--json", o.json_out);  // before the mission, not after it
  Config cfg = load_config(o.config);
  LoopOptions lo;
  // ---- serial link: the config store owns the active config ----
  std::unique_ptr<link::DeviceServer> server;
  SnapshotRequest snap;
  std::mutex cfg_mu;
  bool have_store_cfg = false;
  if (!o.link.empty()) {
    if (o.state_dir.empty()) throw UserError("--link needs --state-dir DIR (config store and logs)");
    if (!o.config.empty())
      throw UserError("--config cannot be used with --link: the config store in --state-dir holds the active config "
                      "(push one with `fuzzyctl --port PORT config push FILE`)");
    link::DeviceHooks hooks;
    hooks.config_applied = [&](const Config& c) {
      std::lock_guard<std::mutex> g(cfg_mu);
      if (!have_store_cfg) cfg = c;  // startup config; later pushes take effect at the next start
      have_store_cfg = true;
    };
    hooks.control = [](link::msg::ControlAction a) {
      std::fprintf(stderr, "link: control %s\n", link::msg::to_string(a));
    };
    const std::filesystem::path tmp = std::filesystem::path(o.state_dir) / "snapshot.tmp";
    hooks.snapshot = [&snap] {
      std::unique_lock<std::mutex> l(snap.m);
      snap.wanted = true;
      snap.ready = false;
      if (!snap.cv.wait_for(l, std::chrono::seconds(10), [&] { return snap.ready; }))
        throw std::runtime_error("no frame within 10 s (is the loop paused at the end of its run?)");
      if (!snap.error.empty()) throw std::runtime_error(snap.error);
      return std::move(snap.files);
    };
    link::ServerOptions so;
    so.link = o.link;
    so.baud = o.baud;
    so.state_dir = o.state_dir;
    so.pty_link_file = o.pty_link;
    so.fw_version = FS_VERSION;
    server = std::make_unique<link::DeviceServer>(hooks, so);
    try {
      server->start();
    } catch (const link::PortError& e) {
      throw UserError(e.what());
    }
    lo.hold = [&server] { return server->state() != link::msg::RunState::RUNNING; };
    lo.on_frame = [&server, &o](const json& f) { server->publish(telemetry_of(f, o.source, server->uptime_ms())); };
    // The snapshot's dump names the settings the loop's matcher ran with: the detection consumers' ones
    // ([detect] matcher_*; detect_io.hpp), so that `fuzzyctl compare` re-runs the reference with them.
    lo.on_match = [&snap, robot_matcher = detection_matcher_params(cfg.matcher, cfg.values), tmp](
                      const ImageU8& l, const ImageU8& r, const MatchResult& m) {
      std::lock_guard<std::mutex> g(snap.m);
      if (!snap.wanted) return;
      snap.wanted = false;
      try {
        std::filesystem::remove_all(tmp);
        write_match_dump(tmp.string(), "run:left", "run:right", robot_matcher, load_fis_definition(""), l, r, m);
        snap.files.clear();
        for (const auto& ent : std::filesystem::directory_iterator(tmp)) {
          const std::string t = link::read_file_text(ent.path());
          snap.files.push_back({ent.path().filename().string(), std::vector<std::uint8_t>(t.begin(), t.end())});
        }
        std::sort(snap.files.begin(), snap.files.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
        snap.error.clear();
      } catch (const std::exception& ex) {
        snap.error = ex.what();
      }
      snap.ready = true;
      snap.cv.notify_all();
    };
    // Over a link the simulator runs at wall-clock pace, so telemetry and commands mean something.
    lo.realtime = o.source.rfind("sim", 0) == 0;
  }
  lo.source = o.source;
  lo.motors = o.motors;
  if (!o.goal.empty()) lo.goal = parse_goal(o.goal);
  lo.record_dir = o.record;
  lo.max_frames = o.max_frames;
  lo.snapshot_every = o.snapshot_every;
  lo.plan_every = o.plan_every;
  lo.stall_frame = o.stall_frame;
  lo.stall_ms = o.stall_ms;
  lo.blind_frame = o.blind_frame;
  lo.blind_side = o.blind_side;
  lo.blind_mode = o.blind_mode;
  lo.record_fail_frame = o.record_fail_frame;
  lo.sim_latency_ms = o.latency_ms;
  lo.time_limit_s = o.time_limit;
  lo.realtime = lo.realtime || o.realtime;
  lo.quiet = o.quiet;
  set_oracle(lo, o.oracle);
  LoopResult r;
  try {
    RobotLoop loop(cfg, lo);
    r = loop.run();
  } catch (const robot::HardwareError& e) {
    throw UserError(e.what());
  }
  print_result(r);
  std::fflush(stdout);
  if (server) {
    // The run is over (goal, stop, end of stream): the motors are stopped; keep the link up for
    // logs and config until SIGINT/SIGTERM.
    std::fprintf(stderr, "run: %s; link stays up until SIGINT/SIGTERM\n", r.status.c_str());
    while (!robot::stop_requested()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      link::msg::Telemetry t;
      t.source = o.source + " (finished: " + r.status + ")";
      t.t_ms = server->uptime_ms();
      server->publish(t);
      {
        std::lock_guard<std::mutex> g(snap.m);
        if (snap.wanted) {
          snap.wanted = false;
          snap.error = "the run has finished (" + r.status + "): no current frame";
          snap.ready = true;
          snap.cv.notify_all();
        }
      }
    }
    server->stop();
  }
  if (!o.json_out.empty()) {
    json j = r.to_json();
    json st;
    for (const auto& [k, s] : r.stages) st[k] = {{"median", s.median}, {"p90", s.p90}, {"max", s.max}};
    j["timing_ms"] = st;
    const char* wait_policy = std::getenv("OMP_WAIT_POLICY");  // main.cpp: passive unless set
    j["omp_wait_policy"] = wait_policy ? wait_policy : "";
    write_text_file("JSON file", o.json_out, j.dump(2) + "\n");
  }
}

struct SuiteOptions {
  int count = 100, blocked = -1, jobs = 1, snapshot_every = 0, plan_every = 10;
  std::uint64_t seed = 1;
  std::string config, json_out, record, only;
  double latency_ms = 100;
  std::string oracle;  // simulator diagnostic (add_oracle_option)
};

void run_suite(const SuiteOptions& o) {
  if (o.count < 0) throw UserError("--count must be >= 0");
  check_output_file("--json", o.json_out);  // before the suite's minutes of runs
  if (o.snapshot_every < 0) throw UserError("--snapshot-every must be >= 0 (0 = no annotated frames)");
  const int n_blocked = o.blocked >= 0 ? o.blocked : std::max(1, o.count / 10);
  // --only: a subset of the same seeded scenarios ("3,17,b0" = solvable 3 and 17, blocked 0).
  std::vector<std::pair<int, bool>> picked;
  if (!o.only.empty()) {
    std::stringstream ss(o.only);
    std::string tok;
    while (std::getline(ss, tok, ',')) {
      const bool b = !tok.empty() && tok[0] == 'b';
      try {
        const int idx = std::stoi(b ? tok.substr(1) : tok);
        if (idx < 0) throw std::invalid_argument("negative");
        picked.emplace_back(idx, b);
      } catch (const std::exception&) {
        throw UserError("--only: '" + tok + "' is not a scenario index (N for solvable, bN for blocked, N >= 0)");
      }
    }
  }
  const int total = picked.empty() ? o.count + n_blocked : static_cast<int>(picked.size());
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
      if (picked.empty()) {
        it.blocked = i >= o.count;
        it.index = it.blocked ? i - o.count : i;
      } else {
        it.index = picked[static_cast<std::size_t>(i)].first;
        it.blocked = picked[static_cast<std::size_t>(i)].second;
      }
      try {
        LoopOptions lo;
        lo.scene = make_suite_scene(o.seed, it.index, it.blocked, cfg, &it.features);
        lo.source = "sim:" + lo.scene->source;
        lo.quiet = true;
        lo.look_around = true;
        set_oracle(lo, o.oracle);
        lo.sim_latency_ms = o.latency_ms;
        if (!o.record.empty()) {
          lo.record_dir = o.record + "/" + lo.scene->source;
          lo.snapshot_every = o.snapshot_every;
          lo.plan_every = o.plan_every;
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
      gaps_ok = 0, errors = 0, stuck = 0, stuck_ok = 0, gave_up = 0, gave_up_blocked = 0;
  std::vector<double> ratios, fps, match_ms, total_ms;
  json per = json::array();
  for (const Item& it : items) {
    const LoopResult& r = it.r;
    if (r.status.rfind("error", 0) == 0) ++errors;
    if (r.collided) ++collisions;
    if (r.struck) ++struck;
    if (r.status == "no_progress_stop") {
      ++gave_up;
      gave_up_blocked += it.blocked;
    }
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
      if (r.stuck_frames > 0) {
        ++stuck;
        stuck_ok += ok;
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
  std::printf("  stuck on the way      %3d / %3d  ([loop] stuck_after_s: reached / runs that were stuck)\n", stuck_ok, stuck);
  std::printf("collisions            %3d          (target 0)\n", collisions);
  std::printf("struck while standing  %3d          (a moving obstacle from outside the camera view)\n", struck);
  std::printf("safe stop, no path    %3d / %3d  %.1f %%   (target 100 %%)\n", blocked_safe, blocked, safe);
  if (gave_up > 0)
    std::printf("  after no progress     %3d          ([loop] give_up_after_s: %d without a free path, %d solvable)\n", gave_up,
                gave_up_blocked, gave_up - gave_up_blocked);
  std::printf("path / shortest       mean %.3f  max %.3f\n", ratio_mean, ratio_max);
  std::printf("processing            median %.1f frames/s (match %.1f ms, whole frame %.1f ms)\n", med(fps),
              med(match_ms), med(total_ms));
  if (errors) std::printf("errors                %d (first: %s)\n", errors, first_error.c_str());
  if (!o.json_out.empty()) {
    json j{{"seed", o.seed},
           {"perception", o.oracle.empty() ? std::string("matcher") : "oracle " + o.oracle},
           {"solvable", solvable},
           {"reached", reached},
           {"success_pct", success},
           {"moving", moving},
           {"moving_reached", moving_ok},
           {"gaps", gaps},
           {"gaps_reached", gaps_ok},
           {"stuck", stuck},
           {"stuck_reached", stuck_ok},
           {"collisions", collisions},
           {"struck", struck},
           {"blocked", blocked},
           {"blocked_safe_stop", blocked_safe},
           {"safe_stop_pct", safe},
           {"no_progress_stops", gave_up},
           {"no_progress_stops_blocked", gave_up_blocked},
           {"path_ratio_mean", ratio_mean},
           {"path_ratio_max", ratio_max},
           {"fps_median", med(fps)},
           {"match_ms_median", med(match_ms)},
           {"frame_ms_median", med(total_ms)},
           {"errors", errors},
           {"scenarios", per}};
    write_text_file("JSON file", o.json_out, j.dump(2) + "\n");
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
  c->add_option("--plan-every", o->plan_every, "Record the planner's obstacles every N frames (1 for tracing a contact)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  c->add_option("--max-frames", o->max_frames, "Stop after N frames (0 = no limit)");
  c->add_option("--time-limit", o->time_limit, "Stop after this many seconds (0 = the scene's mission limit)");
  c->add_option("--latency-ms", o->latency_ms, "Simulated processing latency before a command reaches the motors")
      ->capture_default_str();
  c->add_option("--stall-frame", o->stall_frame, "Fault injection: the pipeline stalls at this frame");
  c->add_option("--stall-ms", o->stall_ms, "... for this long [ms]");
  c->add_option("--blind-frame", o->blind_frame, "Fault injection: from this frame on a camera is blind (perception failsafe test)");
  c->add_option("--blind-side", o->blind_side, "... which camera: left, right or both")->capture_default_str();
  c->add_option("--blind-mode", o->blind_mode, "... dark (black image) or covered (dark noisy image)")->capture_default_str();
  c->add_option("--record-fail-frame", o->record_fail_frame, "Fault injection: from this frame on record writes fail (disk full test)");
  c->add_flag("--realtime", o->realtime, "Simulator: pace frames on the wall clock");
  c->add_flag("--quiet", o->quiet, "No per-frame line on stderr");
  add_oracle_option(c, o->oracle);
  c->add_option("--json", o->json_out, "Write the result as JSON");
  c->add_option("--link", o->link, "Serial link: 'pty' (create and announce a pseudo-terminal) or a device, e.g. /dev/ttyAMA0");
  c->add_option("--baud", o->baud, "Serial baud rate")->capture_default_str();
  c->add_option("--state-dir", o->state_dir, "With --link: directory of the config store and the logs");
  c->add_option("--pty-link", o->pty_link, "With --link pty: also write the pty path to this file");
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
  c->add_option("--snapshot-every", o->snapshot_every,
                "With --record: an annotated frame every N frames (0 = none; 1 for tracing one scenario)")
      ->capture_default_str();
  c->add_option("--plan-every", o->plan_every,
                "With --record: the planner's obstacles every N frames (1 for tracing contacts: fuzzyctl contacts)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  c->add_option("--json", o->json_out, "Write the summary and every scenario as JSON");
  c->add_option("--only", o->only, "Run only these scenarios of the seed: e.g. 3,17,b0 (b = without a free path)");
  add_oracle_option(c, o->oracle);
  c->callback([o] { run_suite(*o); });
}

}  // namespace fs::app
