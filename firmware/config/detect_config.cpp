#include "detect_config.hpp"

#include <cmath>
#include <sstream>
#include <string>

#include <toml++/toml.h>

namespace fs {

namespace {
HsvRange range_from(const ConfigValues& v, const std::string& n) {
  const std::string k = "detect.sky_" + n + "_";
  HsvRange r;
  r.enabled = v.flag(k + "enabled");
  r.h_min = v.integer(k + "h_min"), r.h_max = v.integer(k + "h_max");
  r.s_min = v.integer(k + "s_min"), r.s_max = v.integer(k + "s_max");
  r.v_min = v.integer(k + "v_min"), r.v_max = v.integer(k + "v_max");
  return r;
}
}  // namespace

DetectParams detect_params_from(const ConfigValues& v) {
  DetectParams p;
  p.fill_max_run_px = v.integer("detect.fill_max_run_px");
  p.fill_left_border = v.flag("detect.fill_left_border");
  p.road_enabled = v.flag("detect.road_enabled");
  p.road_min_cell_count = v.integer("detect.road_min_cell_count");
  p.road_ransac_iterations = v.integer("detect.road_ransac_iterations");
  p.road_ransac_seed = v.integer("detect.road_ransac_seed");
  p.road_fit_tolerance_px = v.num("detect.road_fit_tolerance_px");
  p.road_slope_min = v.num("detect.road_slope_min");
  p.road_slope_max = v.num("detect.road_slope_max");
  p.road_min_support_pct = v.num("detect.road_min_support_pct");
  p.road_tolerance_px = v.num("detect.road_tolerance_px");
  p.road_tolerance_rel = v.num("detect.road_tolerance_rel");
  p.road_close_radius = v.integer("detect.road_close_radius");
  p.road_fill_invalid_px = v.integer("detect.road_fill_invalid_px");
  p.sky_enabled = v.flag("detect.sky_enabled");
  p.sky_limit = v.str("detect.sky_limit") == "fraction" ? SkyLimit::Fraction : SkyLimit::Horizon;
  p.sky_upper_fraction = v.num("detect.sky_upper_fraction");
  p.sky_max_disparity_px = v.num("detect.sky_max_disparity_px");
  p.sky_max_texture = v.num("detect.sky_max_texture");
  p.sky_texture_radius = v.integer("detect.sky_texture_radius");
  p.sky_ranges = {range_from(v, "blue"), range_from(v, "grey"), range_from(v, "sunset")};
  p.kmeans_k = v.integer("detect.kmeans_k");
  p.kmeans_max_iterations = v.integer("detect.kmeans_max_iterations");
  p.kmeans_min_disparity_px = v.num("detect.kmeans_min_disparity_px");
  p.kmeans_merge_px = v.num("detect.kmeans_merge_px");
  p.udisp_min_height_px = v.integer("detect.udisp_min_height_px");
  p.udisp_d_tolerance_px = v.integer("detect.udisp_d_tolerance_px");
  p.udisp_min_run_px = v.integer("detect.udisp_min_run_px");
  p.cc_max_step_px = v.num("detect.cc_max_step_px");
  p.cc_max_rel_step = v.num("detect.cc_max_rel_step");
  p.cc_min_step_px = v.num("detect.cc_min_step_px");
  p.min_area_px = v.integer("detect.min_area_px");
  p.merge_occluded_max_gap_px = v.integer("detect.merge_occluded_max_gap_px");
  p.merge_edge_rel_disparity = v.num("detect.merge_edge_rel_disparity");
  p.merge_edge_columns = v.integer("detect.merge_edge_columns");
  p.contain_min_inside = v.num("detect.contain_min_inside");
  p.contain_merge_rel_disparity = v.num("detect.contain_merge_rel_disparity");
  p.contain_drop_max_px = v.integer("detect.contain_drop_max_px");
  p.contain_drop_nearer_only = v.flag("detect.contain_drop_nearer_only");
  const std::string surround = v.str("detect.contain_surround");
  p.contain_surround = surround == "off" ? ContainSurround::Off : surround == "all" ? ContainSurround::All : ContainSurround::Opposite;
  p.max_distance_m = v.num("detect.max_distance_m");
  p.foot_extend = v.flag("detect.foot_extend");
  p.foot_slack_px = v.num("detect.foot_slack_px");
  p.trim_col_min_share = v.num("detect.trim_col_min_share");
  p.trim_col_top_share = v.num("detect.trim_col_top_share");
  p.road_slope_prior_rel = v.num("detect.road_slope_prior_rel");
  p.below_road_drop_share = v.num("detect.below_road_drop_share");
  p.seen_through_drop_share = v.num("detect.seen_through_drop_share");
  p.foot_gap_extend = v.flag("detect.foot_gap_extend");
  p.foot_gap_max_occluded = v.num("detect.foot_gap_max_occluded");
  p.inside_drop_min_share = v.num("detect.inside_drop_min_share");
  p.inside_drop_min_ring = v.num("detect.inside_drop_min_ring");
  p.inside_drop_ring_px = v.integer("detect.inside_drop_ring_px");
  p.side_face_max_rel = v.num("detect.side_face_max_rel");
  p.side_face_max_width = v.num("detect.side_face_max_width");
  p.side_face_min_rows = v.num("detect.side_face_min_rows");
  p.side_face_max_gap_px = v.integer("detect.side_face_max_gap_px");
  p.split_min_rel = v.num("detect.split_min_rel");
  p.split_max_valley = v.num("detect.split_max_valley");
  p.split_min_px = v.integer("detect.split_min_px");
  p.split_rounds = v.integer("detect.split_rounds");
  p.neck_min_width_px = v.integer("detect.neck_min_width_px");
  p.neck_max_share = v.num("detect.neck_max_share");
  p.neck_min_px = v.integer("detect.neck_min_px");
  p.neck_foot_share = v.num("detect.neck_foot_share");
  p.seam_min_step = v.num("detect.seam_min_step");
  p.seam_window_px = v.integer("detect.seam_window_px");
  p.seam_min_width_px = v.integer("detect.seam_min_width_px");
  p.seam_min_px = v.integer("detect.seam_min_px");
  p.seam_max_cuts = v.integer("detect.seam_max_cuts");
  p.seam_min_rows = v.num("detect.seam_min_rows");
  p.seam_drop_share = v.num("detect.seam_drop_share");
  p.min_area_m2 = v.num("detect.min_area_m2");
  p.merge_gap_px = v.integer("detect.merge_gap_px");
  p.merge_gap_vertical_px = v.integer("detect.merge_gap_vertical_px");
  p.merge_max_rel_disparity = v.num("detect.merge_max_rel_disparity");
  p.merge_group_max_rel = v.num("detect.merge_group_max_rel");
  p.merge_attach = v.flag("detect.merge_attach");
  p.merge_bridge_max_px = v.integer("detect.merge_bridge_max_px");
  p.merge_bridge_max_overlap = v.num("detect.merge_bridge_max_overlap");
  p.min_height_m = v.num("detect.min_height_m");
  p.near_m = v.num("detect.near_m");
  p.far_m = v.num("detect.far_m");
  // Cross-field rules, worded as the other config errors: the file, both fields and their values.
  auto ordered = [&](const char* lo_name, double lo, const char* hi_name, double hi) {
    if (lo <= hi) return;
    std::ostringstream ss;
    ss << v.source << ": fields 'detect." << lo_name << "' = " << lo << " and 'detect." << hi_name << "' = " << hi << ": "
       << lo_name << " must be <= " << hi_name;
    throw ConfigError(ss.str());
  };
  ordered("road_slope_min", p.road_slope_min, "road_slope_max", p.road_slope_max);
  ordered("near_m", p.near_m, "far_m", p.far_m);
  return p;
}

StereoCalib parse_calib_toml(const std::string& text, const std::string& source) {
  toml::table root;
  try {
    root = toml::parse(text, source);
  } catch (const toml::parse_error& e) {
    std::ostringstream ss;
    ss << "calibration '" << source << "' is not valid TOML: " << e.description() << " (line " << e.source().begin.line << ")";
    throw ConfigError(ss.str());
  }
  const toml::table* t = root["calib"].as_table() ? root["calib"].as_table() : &root;
  auto get = [&](const char* key, bool required, double fallback) {
    const toml::node* n = t->get(key);
    if (!n) {
      if (required)
        throw ConfigError(std::string("calibration '") + source + "' has no '" + key +
                          "' (needed: focal_px, baseline_m, cx, cy; optional: height_m, pitch_deg)");
      return fallback;
    }
    const auto v = n->value<double>();
    if (!v) throw ConfigError(std::string("calibration '") + source + "': '" + key + "' must be a number");
    return *v;
  };
  StereoCalib c;
  c.focal_px = get("focal_px", true, 0);
  c.baseline_m = get("baseline_m", true, 0);
  c.cx = get("cx", true, 0);
  c.cy = get("cy", true, 0);
  c.height_m = get("height_m", false, 0);
  c.pitch_rad = get("pitch_deg", false, 0) * M_PI / 180.0;
  if (!(c.focal_px > 0) || !(c.baseline_m > 0))
    throw ConfigError("calibration '" + source + "': focal_px and baseline_m must be > 0");
  return c;
}

}  // namespace fs
