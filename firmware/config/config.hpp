// Loading and validating the TOML configuration and the FIS definition. Every check happens here,
// once, with an error that names the field (or file) and its valid range; the core assumes valid
// parameters.
#pragma once
#include <stdexcept>
#include <string>

#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/params.hpp"

namespace fs {

// Thrown for bad user input (config, FIS definition, files). what() is one line for the user.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Defaults (common/config/default.toml, embedded in the binary) overlaid with the file at `path`
// (if not empty). Unknown keys, wrong types and out-of-range values throw ConfigError.
MatcherParams load_matcher_config(const std::string& path);
MatcherParams parse_matcher_config(const std::string& toml_text, const std::string& source_name);

// FIS definition: the embedded common/fis/fis.toml, or the file at `path` if not empty.
FisDefinition load_fis_definition(const std::string& path);
FisDefinition parse_fis_definition(const std::string& toml_text, const std::string& source_name);

// The resolved config as TOML text (for dumps, so a run records exactly what it used).
std::string config_to_toml(const MatcherParams& p);

// Embedded texts.
const char* embedded_default_config();
const char* embedded_fis_definition();
const char* embedded_config_schema();

}  // namespace fs
