// The device end of the link: a serial device (termios raw 8N1, given baud) or, on a desktop, a
// pseudo-terminal the firmware creates (the host opens its slave path, which name() returns).
// Linux only (termios, openpty); the byte parser lives apart in framing.hpp.
#pragma once
#include <memory>
#include <stdexcept>
#include <string>

namespace fs::link {

class PortError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Port {
 public:
  // "pty" creates a pseudo-terminal; anything else is a device path (e.g. /dev/ttyAMA0).
  static std::unique_ptr<Port> open(const std::string& link, int baud);
  ~Port();
  Port(const Port&) = delete;
  Port& operator=(const Port&) = delete;
  int fd() const { return fd_; }
  const std::string& name() const { return name_; }  // pty slave path or device path
  bool is_pty() const { return keep_fd_ >= 0; }
  int baud() const { return baud_; }

 private:
  Port() = default;
  int fd_ = -1;
  int keep_fd_ = -1;  // pty: our own handle on the slave, so reads never see EIO between host sessions
  std::string name_;
  int baud_ = 0;
};

}  // namespace fs::link
