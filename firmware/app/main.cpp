// fuzzystereo — the robot program. Subcommands are in cmd_*.cpp; this file only wires them and
// turns user errors into one line on stderr and exit code 2.
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>

#include <unistd.h>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "fuzzystereo/capture/camera.hpp"
#include "fuzzystereo/memory.hpp"
#include "fuzzystereo/robot/motors.hpp"
#include "config.hpp"
#include "io.hpp"

namespace {

// The robot loop (`run`, and `serve` beside it) shares its cores with the camera stack, the link
// and whatever else runs on the robot. libgomp's default is to spin at every barrier of the
// matcher's many short parallel regions; when another runnable thread takes a core, a spinning
// thread waits for a descheduled partner and frames take several times longer. Measured on a
// 2-core machine, `run` on common/sim/scenes/demo.toml (320 x 180) beside one busy process of the
// same priority: match median / p90 / max 8.8 / 59.8 / 79.9 ms spinning, 8.5 / 11.2 / 15.3 ms
// passive (whole frame p90 84.9 vs 32.7 ms); idle machine 4.2-4.6 vs 4.6-6.0 ms. libgomp reads
// OMP_WAIT_POLICY once, when it is loaded, so these commands re-execute themselves with
// OMP_WAIT_POLICY=passive unless the variable is already set (set it to choose otherwise).
// Offline commands (eval, bench, ...) keep libgomp's default.
void prefer_passive_openmp_waits(int argc, char** argv) {
  if (argc < 2 || std::getenv("OMP_WAIT_POLICY") != nullptr) return;
  if (std::strcmp(argv[1], "run") != 0 && std::strcmp(argv[1], "serve") != 0) return;
  if (setenv("OMP_WAIT_POLICY", "passive", 0) != 0) return;
  execv("/proc/self/exe", argv);  // returns only on failure: then carry on with the default policy
  std::fprintf(stderr, "fuzzystereo: note: could not re-execute with OMP_WAIT_POLICY=passive (%s)\n",
               std::strerror(errno));
}

}  // namespace

int main(int argc, char** argv) {
  prefer_passive_openmp_waits(argc, argv);
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
  fs::app::add_motors_command(app);
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
