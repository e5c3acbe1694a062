// Cross-platform golden hashes of the whole perception pipeline: a rendered scene, the matcher's
// every stage (defaults, and the detection consumers' boundary refinement) and the detector, each
// reduced to one FNV-1a hash. The expected hashes live in tests/golden/pipeline_hashes.txt; the same
// file is checked natively (x86-64, every SIMD clone the CPU picks) and under qemu-aarch64 (NEON),
// so a platform whose arithmetic differs anywhere in the chain — a fused multiply-add, a libm
// function, a vector kernel whose lanes round differently — fails here, named by its first stage.
//
// After an intended change of an output: FS_UPDATE_GOLDEN=1 build/default/tests/cpp/fs_sim_tests
// --gtest_filter='Golden.*' rewrites the file (on x86-64; tests/cpp/golden.hpp); commit it with the change, and the
// aarch64 run of `make test` then checks the Pi's build against it.
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "../golden.hpp"
#include "config.hpp"
#include "detect_config.hpp"
#include "fuzzystereo/detect.hpp"
#include "fuzzystereo/matcher.hpp"
#include "fuzzystereo/sim/scene.hpp"
#include "fuzzystereo/sim/world.hpp"

namespace {

using fs::golden::Fnv;
using fs::golden::hash_of;

// A scene with every kind of thing the detector looks for (road, clear sky, a box seen at an angle,
// a person-sized post, a cylinder, a far box) and sensor noise on both cameras; 320 x 184 keeps it
// to seconds under qemu.
const char* kScene = R"(seed = 2026
type = "clear"
[camera]
width = 320
height = 184
focal_px = 210.0
baseline_m = 0.12
height_m = 0.40
pitch_deg = 5.0
[sky]
kind = "clear"
[ground]
texture = "asphalt"
[radiometric.left]
noise_sigma = 1.0
[radiometric.right]
noise_sigma = 1.5
gain = 0.9
gamma = 1.1
[[obstacles]]
shape = "box"
x_m = 3.0
y_m = 0.5
yaw_deg = 25.0
length_m = 0.8
width_m = 0.6
height_m = 0.7
texture = "bricks"
color = [170, 80, 60]
[[obstacles]]
shape = "post"
x_m = 4.5
y_m = -1.0
texture = "camo"
color = [90, 110, 60]
[[obstacles]]
shape = "cylinder"
x_m = 2.2
y_m = -0.5
radius_m = 0.2
height_m = 0.9
texture = "stripes"
color = [230, 140, 30]
[[obstacles]]
shape = "box"
x_m = 7.0
y_m = 1.2
length_m = 1.0
width_m = 1.0
height_m = 1.2
texture = "wood"
color = [200, 160, 110]
)";

// Integer luma (BT.601 weights in Q8), the same on every platform.
fs::ImageU8 grey(const fs::ImageRgb8& rgb) {
  fs::ImageU8 g(rgb.width, rgb.height);
  for (std::size_t i = 0; i < rgb.data.size(); ++i) {
    const fs::Rgb8 p = rgb.data[i];
    g.data[i] = static_cast<std::uint8_t>((77 * p.r + 150 * p.g + 29 * p.b + 128) >> 8);
  }
  return g;
}

void add_match(std::map<std::string, std::uint64_t>& out, const std::string& tag, const fs::MatchResult& r) {
  out[tag + ".seg_left"] = hash_of(r.seg_left.labels, r.seg_left.count);
  out[tag + ".seg_right"] = hash_of(r.seg_right.labels, r.seg_right.count);
  out[tag + ".wta_left"] = hash_of(r.dec_left.disparity_q4, r.dec_left.score, r.dec_left.dc1, r.dec_left.dc2,
                                   r.disp_left_wta);
  out[tag + ".wta_right"] = hash_of(r.dec_right.disparity_q4, r.dec_right.score, r.dec_right.dc1,
                                    r.dec_right.dc2, r.disp_right_wta);
  out[tag + ".lr"] = hash_of(r.disp_lr, r.lr_mask);
  out[tag + ".esr"] = hash_of(r.disp_esr, r.esr_replaced);
  out[tag + ".final"] = hash_of(r.disp_final, r.densify_changed);
}

// Every stage's hash, by name ("render.left", "match.esr", "detect.obstacles", ...).
std::map<std::string, std::uint64_t> pipeline_hashes(int threads) {
  std::map<std::string, std::uint64_t> out;
  const fs::sim::World world(fs::sim::parse_scene(kScene, "golden.toml"));
  const fs::sim::RenderResult rr = world.render(threads);
  out["render.left"] = hash_of(rr.left);
  out["render.right"] = hash_of(rr.right);
  out["render.truth"] = hash_of(rr.disparity, rr.road_mask, rr.sky_mask, rr.obstacle_ids);

  const fs::ImageU8 gl = grey(rr.left), gr = grey(rr.right);
  const fs::Config cfg = fs::parse_config("", "default.toml");
  const fs::FisDefinition fis = fs::parse_fis_definition(fs::embedded_fis_definition(), "fis.toml");
  fs::MatcherParams mp = cfg.matcher;
  mp.runtime.threads = threads;
  mp.cost.max_disparity = 64;
  const fs::Matcher matcher(mp, fis);
  out["fis.table"] = hash_of(matcher.lut().table());
  const fs::MatchResult m = matcher.match(gl, gr);
  add_match(out, "match", m);
  // The whole cost volume behind the left map (NCC, IGSAD and the NMI candidates of every segment):
  // a difference in the last bit of one (segment, disparity) shows here even when no winner changes.
  // (On the plain grey pair and the left segmentation; the matcher's own inputs may be pre-filtered.)
  const fs::SegmentCosts costs = fs::compute_segment_costs(gl, gr, fs::gradient_magnitude(gl), fs::gradient_magnitude(gr),
                                                           m.seg_left, +1, mp.cost, matcher.lut(), threads);
  Fnv cv;
  cv.add(costs.ncc).add(costs.igsad);
  for (const fs::CostCandidate& c : costs.candidates) cv.add(c.ncc).add(c.igsad).add(c.nmi).add(c.d);
  out["cost.left"] = cv.h;

  // The detection consumers' matcher (the robot loop's; app detection_matcher_params): [detect] matcher_boundary
  // and its segmentation rounds, the ESR map in.
  fs::MatcherParams dp = mp;
  dp.boundary.enabled = cfg.values.flag("detect.matcher_boundary");
  dp.densify.enabled = false;
  if (const int c = cfg.values.integer("detect.matcher_coarse_iterations"); c >= 0) dp.seg.coarse_iterations = c;
  if (const int n = cfg.values.integer("detect.matcher_iterations"); n > 0) dp.seg.iterations = n;
  const fs::MatchResult mb = fs::Matcher(dp, fis).match(gl, gr);
  add_match(out, "boundary", mb);

  const fs::Detector det(fs::detect_params_from(cfg.values));
  const fs::DetectResult d = det.detect(mb.disp_esr, rr.left, rr.calib);
  out["detect.road"] = hash_of(d.road.found, d.road.a, d.road.b, d.road.horizon_row, d.road_mask);
  out["detect.sky"] = hash_of(d.sky_mask);
  out["detect.kmeans"] = hash_of(d.centres_q4, d.cluster_sizes, d.cluster_labels);
  out["detect.udisp"] = hash_of(d.kept, d.components);
  Fnv ob;
  for (const fs::Obstacle& o : d.obstacles)
    ob.add(o.id).add(o.x0).add(o.y0).add(o.x1).add(o.y1).add(o.pixel_count).add(o.disparity_q4).add(o.distance_m)
        .add(o.lateral_m).add(static_cast<int>(o.cls));
  out["detect.obstacles"] = ob.h;
  out["detect.count"] = d.obstacles.size();
  return out;
}

TEST(Golden, PipelineHashesMatchTheCommittedFile) {
  fs::golden::check(pipeline_hashes(2), FS_GOLDEN_FILE, "the perception pipeline (tests/cpp/sim/test_golden.cpp)");
}

TEST(Golden, OneThreadGivesTheSameHashesAsTwo) {
  EXPECT_EQ(pipeline_hashes(1), pipeline_hashes(2));
}

}  // namespace
