// SPDX-License-Identifier: MIT
// The serial port of the Dynamixel head: termios raw 8N1 at the spec's baud, polled reads.
#include <fcntl.h>
#include <linux/serial.h>
#include <poll.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "head_impl.h"

namespace telex::remote::detail {

namespace {

speed_t speed_constant(int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 1000000:
      return B1000000;
    case 2000000:
      return B2000000;
    case 3000000:
      return B3000000;
    case 4000000:
      return B4000000;
    default:
      throw std::invalid_argument("dynamixel: baud " + std::to_string(baud) +
                                  " has no termios speed");
  }
}

}  // namespace

SerialPort::SerialPort(std::string path, int baud) : path_(std::move(path)), baud_(baud) {
  const speed_t speed = speed_constant(baud);
  const std::string who = "--head dynamixel:" + path_;
  fd_ = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int e = errno;
    if (e == ENOENT || e == ENODEV || e == ENXIO)
      throw std::runtime_error(
          who + ": no serial port " + path_ + " (" + std::strerror(e) +
          "). Is the USB adapter (U2D2, USB2Dynamixel) plugged in? List the ports with `ls "
          "/dev/ttyUSB* /dev/ttyACM* /dev/serial/by-id/` or `telex devices`.");
    if (e == EACCES || e == EPERM)
      throw std::runtime_error(who + ": no permission to open " + path_ +
                               ". Add your user to the dialout group (sudo usermod -aG dialout "
                               "$USER, then log in again) or check `ls -l " +
                               path_ + "`.");
    throw std::runtime_error(who + ": cannot open " + path_ + ": " + std::strerror(e));
  }
  const auto fail = [&](const std::string& what) {
    const std::string why = std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error(who + ": " + what + ": " + why);
  };
  // One program on the bus: a second would garble the half-duplex line.
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    if (errno == EWOULDBLOCK)
      fail(path_ + " is in use by another program (another telex-remote, DYNAMIXEL Wizard?)");
    fail("cannot lock " + path_);
  }
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) fail(path_ + " is not a serial port");
  ::cfmakeraw(&tio);
  tio.c_cflag &= ~static_cast<tcflag_t>(PARENB | CSTOPB | CSIZE | CRTSCTS);
  tio.c_cflag |= CS8 | CLOCAL | CREAD;
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, speed);
  ::cfsetospeed(&tio, speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0)
    fail("cannot set " + std::to_string(baud) + " baud 8N1 on " + path_);
  // USB adapters (FTDI) hold received bytes up to their latency timer, 16 ms by default; the low
  // latency flag makes it 1 ms, as the DynamixelSDK does. Ports without the ioctl (a pty) keep
  // their behaviour.
  serial_struct ss{};
  if (::ioctl(fd_, TIOCGSERIAL, &ss) == 0) {
    ss.flags |= ASYNC_LOW_LATENCY;
    (void)::ioctl(fd_, TIOCSSERIAL, &ss);
  }
  ::tcflush(fd_, TCIOFLUSH);
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) ::close(fd_);
}

bool SerialPort::write_all(std::span<const std::uint8_t> bytes, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      error_ = std::string("write to ") + path_ + ": " + std::strerror(errno);
      return false;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      error_ = "write to " + path_ + ": the port took no more bytes in time";
      return false;
    }
    pollfd p{fd_, POLLOUT, 0};
    (void)::poll(&p, 1, static_cast<int>(left.count()));
  }
  return true;
}

std::ptrdiff_t SerialPort::read_some(std::span<std::uint8_t> out,
                                     std::chrono::steady_clock::time_point deadline) {
  while (true) {
    const ssize_t n = ::read(fd_, out.data(), out.size());
    if (n > 0) return n;
    if (n < 0 && errno != EAGAIN && errno != EINTR) {
      error_ = std::string("read from ") + path_ + ": " + std::strerror(errno);
      return -1;
    }
    const auto left_us = std::chrono::duration_cast<std::chrono::microseconds>(
                             deadline - std::chrono::steady_clock::now())
                             .count();
    if (left_us <= 0) return 0;
    pollfd p{fd_, POLLIN, 0};
    // Rounded up, so a deadline less than 1 ms away still waits.
    const int r = ::poll(&p, 1, static_cast<int>((left_us + 999) / 1000));
    if (r < 0 && errno != EINTR) {
      error_ = std::string("poll on ") + path_ + ": " + std::strerror(errno);
      return -1;
    }
    if (r > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0 && (p.revents & POLLIN) == 0) {
      error_ = "the port " + path_ + " hung up";
      return -1;
    }
  }
}

void SerialPort::discard_input() { ::tcflush(fd_, TCIFLUSH); }

}  // namespace telex::remote::detail
