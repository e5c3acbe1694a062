// fuzzystereo — the robot program. Subcommands are in cmd_*.cpp; this file only wires them and
// turns user errors into one line on stderr and exit code 2.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "fuzzystereo/capture/camera.hpp"
#include "fuzzystereo/memory.hpp"
#include "fuzzystereo/robot/motors.hpp"
#include "config.hpp"
#include "io.hpp"

int main(int argc, char** argv) {
  fs::retain_freed_memory();  // per-frame buffers reuse mapped memory (fuzzystereo/memory.hpp)
  CLI::App app{"fuzzystereo " FS_VERSION " — multi-cost fuzzy stereo matching for a stereo robot"};
  app.require_subcommand(1);
  app.set_version_flag("--version", FS_VERSION);
  fs::app::add_match_command(app);
  fs::app::add_fis_command(app);
  fs::app::add_eval_command(app);
  fs::app::add_bench_command(app);
  fs::app::add_sim_command(app);
  fs::app::add_detect_command(app);
  fs::app::add_detect_eval_command(app);
  fs::app::add_capture_command(app);
  fs::app::add_run_command(app);
  fs::app::add_serve_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const fs::UserError& e) {
    std::fprintf(stderr, "fuzzystereo: error: %s\n", e.what());
    return 2;
  } catch (const fs::ConfigError& e) {
    std::fprintf(stderr, "fuzzystereo: config error: %s\n", e.what());
    return 2;
  } catch (const fs::capture::CaptureError& e) {  // camera missing / busy / no permission / bad source
    std::fprintf(stderr, "fuzzystereo: camera error: %s\n", e.what());
    return 2;
  } catch (const fs::robot::HardwareError& e) {  // GPIO chip / PWM channel missing or not permitted
    std::fprintf(stderr, "fuzzystereo: hardware error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fuzzystereo: internal error: %s\n", e.what());
    return 3;
  }
  return 0;
}
