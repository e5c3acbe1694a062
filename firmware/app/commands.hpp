// Subcommands of the `fuzzystereo` program. Each lives in its own cmd_*.cpp and registers itself
// on the CLI11 app; its callback throws fs::UserError / fs::ConfigError for bad input, which main()
// turns into one line on stderr and exit code 2.
#pragma once
#include <CLI/CLI.hpp>

namespace fs::app {

void add_match_command(CLI::App& app);  // cmd_match.cpp
void add_fis_command(CLI::App& app);    // cmd_fis.cpp
void add_eval_command(CLI::App& app);   // cmd_eval.cpp
void add_bench_command(CLI::App& app);  // cmd_bench.cpp
void add_sim_command(CLI::App& app);    // cmd_sim.cpp
void add_detect_command(CLI::App& app);       // cmd_detect.cpp
void add_detect_eval_command(CLI::App& app);  // cmd_detect_eval.cpp
void add_capture_command(CLI::App& app);  // cmd_capture.cpp
void add_run_command(CLI::App& app);      // cmd_run.cpp
void add_sim_suite_command(CLI::App& sim);  // cmd_run.cpp, under `sim`
void add_serve_command(CLI::App& app);  // cmd_serve.cpp
void add_motors_command(CLI::App& app);  // cmd_motors.cpp

}  // namespace fs::app
