// The robot's main loop (issue 5): capture -> rectify -> match -> refine -> detect -> track -> plan
// -> motors, with the failsafes, per-stage timings, a decision log and an optional run record.
//
// One RobotLoop serves `fuzzystereo run` (any camera source, sim or gpiod motors) and
// `fuzzystereo sim suite` (closed loop in the synthetic world, on a simulated clock so it runs
// faster than real time). The loop is single-threaded and deterministic on the simulated clock:
// the same scene and config give the same run.
#pragma once
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/robot/geometry.hpp"
#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/sim/scene.hpp"
#include "fuzzystereo/sim/world.hpp"

namespace fs::app {

struct LoopOptions {
  std::string source;            // "sim:SCENE" | "replay:DIR" | "uvc:DEV" | "libcamera[...]"
  std::optional<sim::Scene> scene;  // sim: this scene instead of the file named in `source`
  std::string motors = "sim";    // "sim" | "gpiod"
  std::optional<robot::Vec2> goal;  // overrides the scene's [mission] goal
  std::string record_dir;        // empty = no record
  int snapshot_every = 10;       // record: annotated frame every N frames (0 = none)
  int plan_every = 10;           // record: the planner's obstacles (plan_obstacles, plan_kinds) every N frames
  int max_frames = 0;            // 0 = until goal / time limit / end of stream / SIGINT
  double time_limit_s = 0;       // 0 = the scene's mission time limit (sim) or none
  bool realtime = false;         // sim: pace frames on the wall clock
  // Simulated processing latency: the command computed from the frame captured at t reaches the
  // motors at t + latency (sim only) [ms]. Models the Pi's pipeline time.
  double sim_latency_ms = 100.0;
  // Fault injection (watchdog test): at frame `stall_frame` the pipeline produces nothing for
  // `stall_ms` (sim: simulated time; other sources: a real sleep).
  int stall_frame = -1;
  double stall_ms = 0;
  // Fault injection (perception health test): from frame `blind_frame` on, the chosen camera's image
  // is replaced — "dark": all black (no contrast); "covered": a lens under a hand, grey 12 with
  // sensor noise of std 3 (contrast stays, the views no longer match).
  int blind_frame = -1;
  std::string blind_side = "left";   // left | right | both
  std::string blind_mode = "dark";   // dark | covered
  // Fault injection (record test): from this frame on every record write fails, as on a full disk.
  int record_fail_frame = -1;
  // Turn once on the spot before driving (sim suite default: the camera sees 74 deg, an obstacle
  // beside the start is unknown otherwise).
  bool look_around = false;
  // Simulator diagnostic (docs/robot.md "Session 45"): the detector, the map and the tracker read the
  // rendered ground-truth disparity, limited to the matcher's search range [0, max_disparity), instead
  // of the matcher's map. The matcher still runs (its timings and the perception health stay real).
  // Separates what the matcher's errors cost the robot from what the rest of the loop costs.
  bool oracle_disparity = false;
  // The next rung (session 45): the detector's output is the simulator's truth as well — one obstacle per
  // scene obstacle with visible pixels in range (its pixels, box and median true disparity), the true road
  // mask — so tracking, mapping and planning run on exact detections (reads the oracle disparity).
  bool oracle_detections = false;
  // The last rung (session 45): the planner gets every scene obstacle within [loop] plan_radius_m as it is
  // (footprints covered by circles, true velocities), in view or not, instead of the map and the tracks:
  // what the planner alone achieves with perfect knowledge. Perception still runs (timings, records).
  bool oracle_world = false;
  // ... only the obstacles the camera has seen so far (at least 50 pixels within [loop] map_range_m in some
  // frame), each then known exactly from that frame on: perfect tracking and memory, the real field of view.
  bool oracle_world_seen = false;
  // ... only part of the planner's list is the truth: kMovers (the scene's moving obstacles seen so far, exact; the
  // loop's own static obstacles - map cells, fitted bodies, unseen ground - stay, its mover-related ones and the
  // soft memory go) or kStatics (the other way round); kMoversAdded = the movers seen so far added to the loop's
  // own list, nothing removed; kAll = all of it.
  enum class OraclePart { kAll, kMovers, kMoversAdded, kStatics };
  OraclePart oracle_part = OraclePart::kAll;
  // ... and each obstacle out of view where a perfect constant-velocity tracker would predict it: its exact position
  // and velocity at the last frame it was seen, extrapolated at that velocity (its turns and stops since then unknown;
  // session 46). In view it is exact, as above.
  bool oracle_coast = false;
  // A rung of its own (session 46): the loop's moving test replaced by the truth - a confirmed track whose last
  // measurement lies within 0.3 m of a scene mover's footprint (nearer than to any other obstacle) is a mover, with
  // the tracker's own position and velocity; any other track is not. Everything else is the loop's.
  bool oracle_labels = false;
  // ... and such a track's circle is its last measurement coasted at the mover's true velocity at that time (radius and
  // uncertainty growth the tracker's).
  bool oracle_label_velocity = false;
  bool quiet = false;            // no per-frame line on stderr
  std::function<void(const nlohmann::json& frame)> on_frame;  // telemetry tap (serial link)
  // Called after the matcher of every frame with its inputs and outputs (snapshot over the link).
  std::function<void(const ImageU8& left, const ImageU8& right, const MatchResult& r)> on_match;
  // While this returns true (link e-stop / pause) the motors stay stopped and no plan is made.
  std::function<bool()> hold;
};

// The simulator's exact left disparity [px] as a matcher map: Q4, kInvalidDisp where d <= 0 (sky) or
// d >= max_disparity (outside the search range). LoopOptions::oracle_disparity.
ImageI16 oracle_disparity_q4(const Image<float>& disparity_px, int max_disparity);
// The simulator's truth as a detector output (LoopOptions::oracle_detections): obstacle_labels = id + 1 of
// every scene obstacle pixel with a valid oracle disparity (`disp`), one Obstacle per scene obstacle with at
// least `min_pixels` of them (box, median disparity, distance, class by `p`), the true road mask.
// Footprints as planner circles (LoopOptions::oracle_world): a circle of the footprint's radius; a box as
// circles along its long axis, spaced at most its half width, each covering its slice of the box. vel
// = the true velocity (finite difference of the footprints at t and t + dt when they move).
std::vector<robot::CircleObstacle> oracle_world_circles(const std::vector<sim::Footprint>& now,
                                                        const std::vector<sim::Footprint>& later, double dt_s);
DetectResult oracle_detections_of(const sim::RenderResult& rr, const ImageI16& disp, const StereoCalib& calib,
                                  const DetectParams& p, int min_pixels = 50);

struct StageStat {
  double median = 0, p90 = 0, max = 0;
};

struct LoopResult {
  std::string status;       // reached | collision | struck | blocked_stop | no_progress_stop | timeout | end_of_stream | interrupted | frames
  bool reached = false, collided = false, safe_stop = false, timed_out = false;
  // sim: a moving obstacle ran into the standing robot from outside the camera's view (not counted
  // as a collision of the robot, not a success either; docs/robot.md "Closed-loop suite")
  bool struck = false;
  int frames = 0;
  double time_s = 0;        // simulated (sim) or wall time of the run [s]
  double path_m = 0;        // distance driven (true pose in sim) [m]
  double shortest_m = 0;    // shortest collision-free path among the static obstacles (sim) [m]
  double min_clearance_m = 0;  // smallest robot-surface gap to any obstacle (sim) [m]
  int front_stops = 0;      // frames where the stop-distance failsafe held the robot
  int ground_stops = 0;     // frames where the ground-seen-ahead failsafe held the robot ([robot] ground_ahead_min_pct)
  int look_turns = 0;       // sensing actions begun ([loop] look_before_turn_m)
  int stuck_frames = 0;     // frames planned without near-track circles and reachable sets ([loop] stuck_after_s)
  int static_meas = 0;      // detections found static ([loop] static_meas_age_s)
  int blocked_frames = 0;   // frames where the planner found no path
  int watchdog_trips = 0;
  int perception_stops = 0;         // times the perception health failsafe stopped the robot
  int perception_fault_frames = 0;  // frames that failed a health test (not given to map and tracker)
  // Frames whose pair the matcher's camera-difference checks read as mismatched (noise equalised or the
  // grey-level gain trigger fired; docs/algorithm.md 2b, 2c, 4b): cameras that differ in exposure, gain or noise.
  int camera_mismatch_frames = 0;
  int camera_gain_frames = 0, camera_noise_frames = 0;  // of those, by which check
  double perception_stop_after_ms = -1;  // blind test: stop command after the blind frame's capture
  int record_dropped_snapshots = 0;  // --record: snapshots not written (disk full, write error)
  int record_dropped_frames = 0;     // --record: frame-log lines not written
  std::string record_warning;        // why the record stopped ("" = complete)
  double watchdog_stop_after_last_plan_ms = -1;  // stall test: stop command after the last plan
  double watchdog_stop_after_deadline_ms = -1;   // ... after the stall began (the frame that was due)
  double watchdog_stop_wall_ms = -1;             // ... wall-clock watchdog thread (real sleep)
  double watchdog_stop_wall_after_stall_ms = -1e18;  // ... after the stall began (wall clock)
  double fps_wall = 0;      // frames per wall-clock second of processing
  std::vector<std::pair<std::string, StageStat>> stages;
  nlohmann::json to_json() const;
};

class RobotLoop {
 public:
  RobotLoop(const Config& cfg, LoopOptions opt);
  ~RobotLoop();
  LoopResult run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A closed-loop scenario of the simulator suite as a scene (obstacles, start, goal, mission time
// limit). `blocked` scenarios have no collision-free path to the goal.
sim::Scene make_suite_scene(std::uint64_t seed, int index, bool blocked, const Config& cfg, std::string* features);

}  // namespace fs::app
