// GpioLines over libgpiod 1.6 (the C API Debian bookworm / Raspberry Pi OS ship). The only file
// with a platform #if: without libgpiod (e.g. a cross build lacking libgpiod-dev:arm64) the
// factory throws HardwareError instead.
#include <cerrno>
#include <cstring>
#include <map>

#include "fuzzystereo/robot/motors.hpp"

#if FS_HAVE_LIBGPIOD
#include <gpiod.h>
#endif

namespace fs::robot {

#if FS_HAVE_LIBGPIOD
namespace {
std::string access_hint(const std::string& chip) {
  return "check that /dev/" + chip + " exists (`gpiodetect`; on a Pi 5 with an older kernel the header pins are "
         "gpiochip4), that [motors] gpio_chip names it, and that the service user is in the 'gpio' group "
         "(docs/robot.md)";
}

class GpiodLines final : public GpioLines {
 public:
  GpiodLines(const std::string& chip, const std::string& consumer) : name_(chip), consumer_(consumer) {
    chip_ = gpiod_chip_open_by_name(chip.c_str());
    if (!chip_)
      throw HardwareError("motors: cannot open GPIO chip /dev/" + chip + " (" + std::strerror(errno) + ") — " +
                          access_hint(chip));
  }
  ~GpiodLines() override {
    release_all();
    gpiod_chip_close(chip_);
  }
  void request_output(int offset, int initial) override {
    std::lock_guard<std::mutex> lk(m_);
    gpiod_line* line = gpiod_chip_get_line(chip_, static_cast<unsigned>(offset));
    if (!line)
      throw HardwareError("motors: " + name_ + " has no line " + std::to_string(offset) + " (" + std::strerror(errno) +
                          ") — check the [motors] line offsets (BCM numbers)");
    if (gpiod_line_request_output(line, consumer_.c_str(), initial ? 1 : 0) != 0)
      throw HardwareError("motors: cannot request " + name_ + " line " + std::to_string(offset) + " as output (" +
                          std::strerror(errno) + ") — is it used by another program or overlay? `gpioinfo " + name_ +
                          "` shows the consumer");
    lines_[offset] = line;
  }
  void set(int offset, int value) override {
    std::lock_guard<std::mutex> lk(m_);
    auto it = lines_.find(offset);
    if (it == lines_.end() || gpiod_line_set_value(it->second, value ? 1 : 0) != 0)
      throw HardwareError("motors: cannot set " + name_ + " line " + std::to_string(offset) + " (" +
                          std::strerror(errno) + ")");
  }
  void release_all() override {
    std::lock_guard<std::mutex> lk(m_);
    for (auto& [off, line] : lines_) gpiod_line_release(line);
    lines_.clear();
  }
  std::string describe() const override { return name_; }

 private:
  std::string name_, consumer_;
  gpiod_chip* chip_ = nullptr;
  std::mutex m_;
  std::map<int, gpiod_line*> lines_;
};
}  // namespace

std::unique_ptr<GpioLines> open_gpiod_lines(const std::string& chip_name, const std::string& consumer) {
  return std::make_unique<GpiodLines>(chip_name, consumer);
}
bool have_libgpiod() { return true; }

#else

std::unique_ptr<GpioLines> open_gpiod_lines(const std::string& chip_name, const std::string&) {
  throw HardwareError("motors: this build has no libgpiod, cannot open " + chip_name +
                      " — install libgpiod-dev (for the robot's architecture) and rebuild, or use [motors] backend = "
                      "\"sim\"");
}
bool have_libgpiod() { return false; }

#endif

}  // namespace fs::robot
