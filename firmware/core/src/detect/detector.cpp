// The detection pipeline (Section III-B, Fig. 12): one line per stage, timings per stage.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "fuzzystereo/detect.hpp"

namespace fs {

const char* obstacle_class_name(ObstacleClass c) {
  switch (c) {
    case ObstacleClass::Near: return "near";
    case ObstacleClass::Mid: return "mid";
    case ObstacleClass::Far: return "far";
  }
  return "?";
}

const char* detect_stage_name(DetectStage s) {
  switch (s) {
    case DetectStage::Road: return "road";
    case DetectStage::Sky: return "sky";
    case DetectStage::KMeans: return "kmeans";
    case DetectStage::UDisparity: return "udisparity";
    case DetectStage::Objects: return "objects";
    case DetectStage::Count: break;
  }
  return "?";
}

double DetectTimings::total_ms() const {
  double t = 0;
  for (double v : ms) t += v;
  return t;
}

DetectParams::DetectParams() {
  // Defaults of common/config/default.toml [detect] (docs/detection.md explains each range).
  sky_ranges[0] = {true, 180, 250, 12, 100, 35, 100};  // blue sky
  sky_ranges[1] = {true, 0, 359, 0, 12, 65, 100};      // overcast / bright grey-white
  sky_ranges[2] = {true, 345, 45, 20, 100, 55, 100};   // sunset orange-red (wraps through 0)
}

Detector::Detector(const DetectParams& params)
    : params_(params), scratch_(std::make_unique<detect::UDispScratch>()) {}
Detector::~Detector() = default;

DetectResult Detector::detect(const ImageI16& disp_in, const ImageRgb8& rgb, const StereoCalib& calib) const {
  using clock = std::chrono::steady_clock;
  const std::lock_guard<std::mutex> lock(scratch_mu_);
  const DetectParams& p = params_;
  DetectResult r;
  const int w = disp_in.width, h = disp_in.height;
  auto t = clock::now();
  auto lap = [&](DetectStage s) {
    const auto n = clock::now();
    r.timings.ms[std::size_t(s)] = std::chrono::duration<double, std::milli>(n - t).count();
    t = n;
  };
  // (0) hole filling (timed with the road stage), then every stage reads r.disp.
  r.disp = detect::fill_holes(disp_in, p.fill_max_run_px, p.fill_left_border);
  const ImageI16& disp = r.disp;
  std::int64_t valid = 0;
  for (const auto q : disp.data) valid += q >= 0;

  // (a) road: v-disparity eq. (16)-(17), line fit, on-line pixels, closing.
  r.bins = detect::disparity_bins(disp);
  r.vdisp = detect::v_disparity(disp, r.bins);
  if (p.road_enabled) {
    DetectParams pr = p;  // the slope range, narrowed by the mounting when known (slope prior)
    if (detect::road_slope_range(p, calib, &pr.road_slope_min, &pr.road_slope_max))
      r.road = detect::fit_road_line(r.vdisp, valid, pr);
  }
  r.road_line_q4 = detect::road_line_table(r.road, h);
  r.road_raw = detect::road_pixels(disp, r.road_line_q4, p.road_tolerance_px, p.road_tolerance_rel);
  r.road_mask = detect::complete_road(detect::close_mask(r.road_raw, p.road_close_radius), disp, r.road_line_q4,
                                      p.road_fill_invalid_px);
  lap(DetectStage::Road);

  // (b) sky: HSV eq. (18)-(21) in the upper part (above the horizon, or the upper fraction).
  r.sky_skipped = rgb.empty() || !p.sky_enabled;
  if (!r.sky_skipped) {
    const int frac_rows = int(std::lround(p.sky_upper_fraction * h));
    r.sky_rows = (p.sky_limit == SkyLimit::Horizon && r.road.found) ? r.road.horizon_row : frac_rows;
    r.sky_mask = detect::sky_mask(rgb, disp, r.sky_rows, p);
  } else {
    r.sky_mask = ImageU8(w, h, 0);
  }
  lap(DetectStage::Sky);

  // (c) k-means eq. (22)-(23) on the remaining valid disparities.
  r.candidates = ImageU8(w, h, 0);
  const std::int32_t dmin = std::int32_t(std::lround(p.kmeans_min_disparity_px * kDispScale));
  for (std::size_t i = 0; i < disp.size(); ++i)
    r.candidates.data[i] = std::uint8_t(disp.data[i] >= 0 && disp.data[i] >= dmin && !r.road_mask.data[i] && !r.sky_mask.data[i]);
  detect::KMeansResult km = detect::kmeans_disparity(disp, r.candidates, p.kmeans_k, p.kmeans_max_iterations,
                                                          int(std::lround(p.kmeans_merge_px * kDispScale)));
  r.centres_q4 = std::move(km.centres_q4);
  r.cluster_sizes = std::move(km.sizes);
  r.kmeans_iterations = km.iterations;
  r.cluster_labels = std::move(km.labels);
  lap(DetectStage::KMeans);

  // (d) u-disparity eq. (24)-(25) per cluster: cells, runs, back to pixels.
  detect::UDispResult ud = detect::u_disparity_filter(disp, r.cluster_labels, int(r.centres_q4.size()), r.bins, p,
                                                         scratch_.get());
  r.udisp_kept = std::move(ud.kept_cells);
  r.kept = std::move(ud.kept);
  lap(DetectStage::UDisparity);

  // (e) components, boxes, Z = f*B/d, classes.
  int n = 0;
  r.components = detect::connected_components(r.kept, disp, int(std::lround(p.cc_max_step_px * kDispScale)), &n,
                                                   p.cc_max_rel_step, int(std::lround(p.cc_min_step_px * kDispScale)));
  // Splitting components whose disparity histogram has two modes (our addition).
  r.components = detect::split_bimodal_components(r.components, n, disp, p.split_min_px, p.split_min_rel,
                                                  p.split_max_valley, p.split_rounds, &n);
  r.obstacles = detect::measure_obstacles(r.components, n, disp, calib, p, &r.obstacle_labels);
  // Pieces cut out of obstacles (necks, seams) are measured again with merging off (they were one group
  // and stay apart), except across a nearer occluder: a farther obstacle seen on both sides of a thin
  // nearer one is one obstacle (merge_occluded).
  auto measure_apart = [&](const ImageI32& cut, int count) {
    DetectParams pm = p;
    pm.merge_gap_px = 0;
    pm.merge_edge_rel_disparity = 0;
    pm.contain_min_inside = 0;
    r.obstacles = detect::measure_obstacles(cut, count, disp, calib, pm, &r.obstacle_labels);
  };
  // Necks (session 30): an obstacle that fragment merging or a thin strip of pixels joined across a
  // run of thin columns is cut there and measured again, without merging.
  if (p.neck_min_width_px > 0) {
    int nn = 0;
    const ImageI32 cut = detect::split_necks(r.obstacle_labels, int(r.obstacles.size()), p.neck_min_width_px,
                                             p.neck_max_share, p.neck_min_px, p.neck_foot_share, &nn);
    if (nn != int(r.obstacles.size())) measure_apart(cut, nn);  // a cut leaves at least one label more
  }
  // Seams (session 33): two obstacles side by side at nearly one depth, cut where the colour changes.
  if (p.seam_min_step > 0 && !rgb.empty()) {
    int ns = 0;
    const ImageI32 cut = detect::split_seams(r.obstacle_labels, int(r.obstacles.size()), rgb, p.seam_min_step,
                                             p.seam_window_px, p.seam_min_width_px, p.seam_min_px, p.seam_max_cuts, p.seam_min_rows,
                                             p.seam_drop_share, &ns);
    // A cut adds a label, unless seam_drop_share dropped a piece as well: then the labels tell.
    if (ns != int(r.obstacles.size()) || cut.data != r.obstacle_labels.data) measure_apart(cut, ns);
  }
  // Below the road (session 7): wrong-depth blobs the road at their depth would hide.
  detect::drop_below_road(r.obstacles, r.obstacle_labels, r.road_line_q4, p);
  // Seen through (session 8): a farther obstacle enclosed above and below by a nearer one.
  detect::drop_seen_through(r.obstacles, r.obstacle_labels, p);
  // Box extent (our addition): sparse side columns cut, then the foot rows the road band removed.
  detect::trim_sparse_columns(r.obstacles, r.obstacle_labels, calib, p, &r.sky_mask, &disp);
  detect::extend_to_ground(r.obstacles, r.road_line_q4, p);
  // Inside a nearer face (session 14): a farther blob whose box lies in a larger nearer obstacle's box.
  detect::drop_inside_nearer(r.obstacles, r.obstacle_labels, p);
  // Side faces (session 33): the receding side of a box seen at an angle joins its front face.
  detect::merge_side_faces(r.obstacles, r.obstacle_labels, p);
  // Ground contact over a gap (session 14): the lower part the matcher lost, where nothing nearer hides it.
  detect::extend_over_gap(r.obstacles, r.obstacle_labels, r.road_line_q4, p);
  lap(DetectStage::Objects);
  return r;
}

}  // namespace fs
