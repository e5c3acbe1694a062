// [detect] section of the config -> DetectParams (obstacle detection, docs/detection.md).
#pragma once
#include "config.hpp"
#include "fuzzystereo/detect.hpp"

namespace fs {

// Reads every detect.* field (ranges already checked by the loader against schema.toml). Throws
// ConfigError for the cross-field rules the schema cannot express (slope_min <= slope_max,
// near_m <= far_m).
DetectParams detect_params_from(const ConfigValues& v);

}  // namespace fs
