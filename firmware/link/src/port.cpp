#include "fuzzystereo/link/port.hpp"

#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fs::link {

namespace {
speed_t speed_of(int baud) {
  switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 1500000: return B1500000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    default: throw PortError("unsupported baud rate " + std::to_string(baud) +
                             " (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 921600, 1000000, 1500000, 2000000, 3000000)");
  }
}

void make_raw(int fd, int baud, const std::string& name) {
  termios t{};
  if (::tcgetattr(fd, &t) != 0) throw PortError("'" + name + "' is not a terminal: " + std::strerror(errno));
  ::cfmakeraw(&t);
  t.c_cflag |= CLOCAL | CREAD;
  t.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
  t.c_cc[VMIN] = 0;
  t.c_cc[VTIME] = 0;
  const speed_t s = speed_of(baud);
  ::cfsetispeed(&t, s);
  ::cfsetospeed(&t, s);
  if (::tcsetattr(fd, TCSANOW, &t) != 0) throw PortError("cannot configure '" + name + "': " + std::strerror(errno));
}
}  // namespace

std::unique_ptr<Port> Port::open(const std::string& link, int baud) {
  std::unique_ptr<Port> p(new Port());
  p->baud_ = baud;
  if (link == "pty") {
    int master = -1, slave = -1;
    char name[256] = {};
    if (::openpty(&master, &slave, name, nullptr, nullptr) != 0)
      throw PortError(std::string("cannot create a pseudo-terminal: ") + std::strerror(errno));
    p->fd_ = master;
    p->keep_fd_ = slave;
    p->name_ = name;
    make_raw(slave, baud, p->name_);
  } else {
    p->name_ = link;
    p->fd_ = ::open(link.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    if (p->fd_ < 0) {
      const int e = errno;
      if (e == EACCES)
        throw PortError("permission denied on '" + link + "' (add the user to the 'dialout' group: sudo usermod -aG dialout $USER)");
      if (e == ENOENT) throw PortError("serial device '" + link + "' does not exist");
      if (e == EBUSY) throw PortError("serial device '" + link + "' is busy (another program has it open)");
      throw PortError("cannot open '" + link + "': " + std::strerror(e));
    }
    make_raw(p->fd_, baud, link);
  }
  ::fcntl(p->fd_, F_SETFL, ::fcntl(p->fd_, F_GETFL) | O_NONBLOCK);
  ::fcntl(p->fd_, F_SETFD, FD_CLOEXEC);
  if (p->keep_fd_ >= 0) ::fcntl(p->keep_fd_, F_SETFD, FD_CLOEXEC);
  return p;
}

Port::~Port() {
  if (fd_ >= 0) ::close(fd_);
  if (keep_fd_ >= 0) ::close(keep_fd_);
}

}  // namespace fs::link
