#include "detect_config.hpp"

#include <string>

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
  p.road_enabled = v.flag("detect.road_enabled");
  p.road_min_cell_count = v.integer("detect.road_min_cell_count");
  p.road_ransac_iterations = v.integer("detect.road_ransac_iterations");
  p.road_ransac_seed = v.integer("detect.road_ransac_seed");
  p.road_fit_tolerance_px = v.num("detect.road_fit_tolerance_px");
  p.road_slope_min = v.num("detect.road_slope_min");
  p.road_slope_max = v.num("detect.road_slope_max");
  p.road_min_support_pct = v.num("detect.road_min_support_pct");
  p.road_tolerance_px = v.num("detect.road_tolerance_px");
  p.road_close_radius = v.integer("detect.road_close_radius");
  p.sky_enabled = v.flag("detect.sky_enabled");
  p.sky_limit = v.str("detect.sky_limit") == "fraction" ? SkyLimit::Fraction : SkyLimit::Horizon;
  p.sky_upper_fraction = v.num("detect.sky_upper_fraction");
  p.sky_max_disparity_px = v.num("detect.sky_max_disparity_px");
  p.sky_ranges = {range_from(v, "blue"), range_from(v, "grey"), range_from(v, "sunset")};
  p.kmeans_k = v.integer("detect.kmeans_k");
  p.kmeans_max_iterations = v.integer("detect.kmeans_max_iterations");
  p.kmeans_min_disparity_px = v.num("detect.kmeans_min_disparity_px");
  p.kmeans_merge_px = v.num("detect.kmeans_merge_px");
  p.udisp_min_height_px = v.integer("detect.udisp_min_height_px");
  p.udisp_d_tolerance_px = v.integer("detect.udisp_d_tolerance_px");
  p.udisp_min_run_px = v.integer("detect.udisp_min_run_px");
  p.cc_max_step_px = v.num("detect.cc_max_step_px");
  p.min_area_px = v.integer("detect.min_area_px");
  p.near_m = v.num("detect.near_m");
  p.far_m = v.num("detect.far_m");
  const std::string src = " (in " + v.source + ")";
  if (p.road_slope_min > p.road_slope_max)
    throw ConfigError("detect.road_slope_min (" + std::to_string(p.road_slope_min) + ") must be <= detect.road_slope_max (" +
                      std::to_string(p.road_slope_max) + ")" + src);
  if (p.near_m > p.far_m)
    throw ConfigError("detect.near_m (" + std::to_string(p.near_m) + ") must be <= detect.far_m (" +
                      std::to_string(p.far_m) + ")" + src);
  return p;
}

}  // namespace fs
