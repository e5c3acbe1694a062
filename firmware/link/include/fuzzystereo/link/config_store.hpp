// The device's config files (docs/protocol.md "Config store"):
//   <dir>/active.toml   the config in force
//   <dir>/backup.toml   the one before it
// A pushed config is validated completely by fs::parse_config (the startup validator), written to
// a temp file, fsync'd, the old active hard-linked to backup, the temp renamed over active and the
// directory fsync'd: a power cut at any point leaves either the old or the new file as active.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

#include "config.hpp"

namespace fs::link {

struct ActiveConfig {
  fs::Config config;
  std::string text;        // the file's bytes (the embedded defaults when no file)
  std::uint32_t id = 0;    // CRC-32C of text
  std::string source;      // "active", "backup" or "defaults"
  std::string warning;     // why the active file was not used (empty when it was)
};

class ConfigStore {
 public:
  explicit ConfigStore(std::filesystem::path dir);
  // Startup: the active file; when it is missing or fails validation, the backup (warning says
  // why); when that fails too, the built-in defaults.
  ActiveConfig load() const;
  // Validates `text` (throws fs::ConfigError naming the field; nothing on disk changes), then
  // replaces the active file atomically, keeping the previous one as backup.
  ActiveConfig commit(const std::string& text) const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

// Whole file as bytes; throws std::runtime_error with the path when unreadable.
std::string read_file_text(const std::filesystem::path& p);

}  // namespace fs::link
