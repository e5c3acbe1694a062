// Loading and validating the TOML configuration and the FIS definition. Every check happens here,
// once, with an error that names the field (or file) and its valid range; the core assumes valid
// parameters.
#pragma once
#include <map>
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

// Every validated field of the config by dotted name ("section.field"). Numbers (int, float, bool
// as 0/1) and strings live apart. Each subsystem turns the fields it owns into its own parameter
// struct (e.g. MatcherParams below); the accessors throw ConfigError for a name that is not in the
// schema (a build error, never bad user input).
struct ConfigValues {
  std::map<std::string, double> nums;
  std::map<std::string, std::string> strs;
  std::string source;  // file the overrides came from ("default.toml" when none)

  double num(const std::string& key) const;
  int integer(const std::string& key) const;
  bool flag(const std::string& key) const;
  const std::string& str(const std::string& key) const;
};

struct Config {
  ConfigValues values;
  MatcherParams matcher;
};

// Defaults (embedded common/config/default.toml) overlaid with the file at `path` (if not empty):
// the one validator used at startup and for a config pushed over the link.
Config load_config(const std::string& path);
Config parse_config(const std::string& toml_text, const std::string& source_name);
// Every field, in schema order, as TOML text.
std::string config_to_toml(const ConfigValues& v);

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
