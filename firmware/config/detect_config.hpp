// [detect] section of the config -> DetectParams (obstacle detection, docs/detection.md).
#pragma once
#include <string>

#include "config.hpp"
#include "fuzzystereo/calib.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {

// Reads every detect.* field (ranges already checked by the loader against schema.toml). Throws
// ConfigError for the cross-field rules the schema cannot express (slope_min <= slope_max,
// near_m <= far_m).
DetectParams detect_params_from(const ConfigValues& v);

// Stereo calibration from TOML text: focal_px, baseline_m, cx, cy (required), height_m, pitch_deg
// (optional), at the top level or in a [calib] table. Throws ConfigError naming the missing field
// and the source.
StereoCalib parse_calib_toml(const std::string& toml_text, const std::string& source_name);

}  // namespace fs
