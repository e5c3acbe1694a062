// `fuzzystereo motors test`: bring-up check of the motor wiring. Drives each wheel alone, forward
// then backward, at a low duty for a short time, stopped in between, and says what the robot should
// do at each step — so a swapped side, a motor wired backwards or a dead channel shows before the
// first autonomous run (docs/robot.md "Motors", "Bring-up").
//
// Safety: real motors only with --yes (wheels off the ground); duty at most 0.5 unless --force;
// SIGINT/SIGTERM stop at once (the flag is polled every 10 ms); every exit path stops the motors
// (explicit stop(), and the driver's destructor).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "config.hpp"
#include "fuzzystereo/robot/failsafe.hpp"
#include "fuzzystereo/robot/motors.hpp"
#include "fuzzystereo/robot/params.hpp"
#include "io.hpp"

namespace fs::app {
namespace {

struct MotorsTestOptions {
  std::string config, motors = "sim", wheel = "sequence";
  double duty = 0.3, ms = 500.0, pause_ms = 500.0;
  bool yes = false, force = false;
};

struct Step {
  const char* what;
  double left, right;
  const char* expect;
};

void run_motors_test(const MotorsTestOptions& o) {
  const Config cfg = load_config(o.config);
  const robot::RobotParams rp = robot::robot_params_from(cfg.values);
  const robot::MotorParams mp = robot::motor_params_from(cfg.values);
  if (!(o.duty > 0.0 && o.duty <= 1.0)) throw UserError("--duty must be in (0, 1] (got " + std::to_string(o.duty) + ")");
  if (o.duty > 0.5 && !o.force)
    throw UserError("--duty " + std::to_string(o.duty) + " > 0.5: a wiring test needs no more (add --force to insist)");
  if (!(o.ms >= 50.0 && o.ms <= 5000.0)) throw UserError("--ms must be in [50, 5000] (got " + std::to_string(o.ms) + ")");
  if (o.motors != "sim" && o.motors != "gpiod") throw UserError("--motors must be sim or gpiod (got '" + o.motors + "')");
  if (o.motors == "gpiod" && !o.yes)
    throw UserError("motors test drives the real wheels: put the robot on a stand (wheels off the ground), then add --yes");
  const double d = o.duty;
  std::vector<Step> steps;
  const bool all = o.wheel == "sequence";
  if (all || o.wheel == "left") {
    steps.push_back({"left wheel forward", d, 0.0, "the LEFT wheel turns forwards (robot would turn right, clockwise from above)"});
    steps.push_back({"left wheel backward", -d, 0.0, "the LEFT wheel turns backwards (robot would turn left)"});
  }
  if (all || o.wheel == "right") {
    steps.push_back({"right wheel forward", 0.0, d, "the RIGHT wheel turns forwards (robot would turn left, counter-clockwise)"});
    steps.push_back({"right wheel backward", 0.0, -d, "the RIGHT wheel turns backwards (robot would turn right)"});
  }
  if (all || o.wheel == "both") steps.push_back({"both wheels forward", d, d, "both wheels turn forwards (robot would drive straight ahead)"});
  if (steps.empty()) throw UserError("--wheel must be sequence, left, right or both (got '" + o.wheel + "')");

  std::unique_ptr<robot::MotorDriver> motors;
  robot::SimMotors* sim = nullptr;
  if (o.motors == "sim") {
    auto sm = std::make_unique<robot::SimMotors>(rp, robot::Pose2D{}, 0);
    sim = sm.get();
    motors = std::move(sm);
  } else {
    motors = robot::open_gpiod_motors(mp);  // HardwareError names the chip / PWM path
  }
  motors->stop();
  robot::install_stop_signal_handlers();
  std::printf("motors test: backend %s, duty %.2f x max_duty %.2f, %.0f ms per step, invert_left %d invert_right %d\n",
              o.motors.c_str(), d, mp.max_duty, o.ms, mp.invert_left ? 1 : 0, mp.invert_right ? 1 : 0);
  // Runs `ms` of the current command (sim: on the simulated clock; real: sleeping in 10 ms steps so
  // a signal stops the wheels at once). False when interrupted.
  std::int64_t t_ns = 0;
  const auto hold = [&](double ms) {
    const auto step = std::chrono::milliseconds(10);
    for (double t = 0; t < ms; t += 10.0) {
      if (robot::stop_requested()) return false;
      if (sim) {
        t_ns += 10'000'000;
        sim->advance_to(t_ns);
      } else {
        std::this_thread::sleep_for(step);
      }
    }
    return true;
  };
  bool interrupted = false;
  for (std::size_t i = 0; i < steps.size() && !interrupted; ++i) {
    const Step& s = steps[i];
    std::printf("[%zu/%zu] %s (left %+.2f, right %+.2f): %s\n", i + 1, steps.size(), s.what, s.left, s.right, s.expect);
    std::fflush(stdout);
    const robot::Pose2D p0 = sim ? sim->pose() : robot::Pose2D{};
    motors->set(s.left, s.right);
    interrupted = !hold(o.ms);
    motors->stop();
    if (!interrupted) interrupted = !hold(o.pause_ms);  // the wheels run down before the next step
    if (sim) {
      const robot::Pose2D p1 = sim->pose();
      const double c = std::cos(p0.yaw), sn = std::sin(p0.yaw);
      const double fwd = c * (p1.x - p0.x) + sn * (p1.y - p0.y);
      std::printf("      simulated: forward %+.3f m, turned %+.1f deg (+ = counter-clockwise)\n", fwd,
                  (p1.yaw - p0.yaw) * 180.0 / M_PI);
    }
  }
  motors->stop();
  if (interrupted) {
    std::printf("motors test: interrupted, motors stopped\n");
    return;
  }
  std::printf("motors test: done, motors stopped. A wheel that turned the wrong way: set [motors] invert_left / "
              "invert_right (or swap its IN1/IN2 offsets); the other wheel moved: swap the left and right offsets "
              "and PWM channels; nothing moved: check the driver's supply, STBY/EN and [motors] max_duty "
              "(docs/robot.md \"Wiring\").\n");
}

}  // namespace

void add_motors_command(CLI::App& app) {
  auto* m = app.add_subcommand("motors", "Motor bring-up tools");
  m->require_subcommand(1);
  auto o = std::make_shared<MotorsTestOptions>();
  auto* c = m->add_subcommand("test", "Drive each wheel alone, forward and backward, to check the wiring");
  c->add_option("--config", o->config, "TOML config ([motors] wiring; defaults: common/config/default.toml)");
  c->add_option("--motors", o->motors, "sim | gpiod")->capture_default_str();
  c->add_option("--wheel", o->wheel, "sequence (left, right, both) | left | right | both")->capture_default_str();
  c->add_option("--duty", o->duty, "Command in (0, 0.5] (x [motors] max_duty)")->capture_default_str();
  c->add_option("--ms", o->ms, "Duration of each step [ms], 50-5000")->capture_default_str();
  c->add_flag("--yes", o->yes, "Real motors: the robot is on a stand, wheels off the ground");
  c->add_flag("--force", o->force, "Allow --duty above 0.5");
  c->callback([o] { run_motors_test(*o); });
}

}  // namespace fs::app
