// SPDX-License-Identifier: MIT
// The display supervisor: the forked child's loop (system calls only) and the station's handle.
#include "telex/local/display_supervisor.h"

#include <fcntl.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "telex/local/gravity_grabber.h"
#include "telex/local/udp_sink.h"

namespace telex::local {

ZeroChannel zero_channel_for(const std::string& spec, const DisplayConfig& config) {
  const DisplaySpec d = parse_display_spec(spec, config);
  ZeroChannel c;
  switch (d.kind) {
    case DisplaySpec::Kind::Sim:
      c.display = spec;
      if (!d.target.empty()) {
        c.kind = ZeroChannel::Kind::CsvRow;
        c.path = d.target;
        // The sim display's row after its time_ns (haptic_display.cpp, SimDisplay::drain).
        for (int finger = 0; finger < 5; ++finger) c.bytes += ",0.000000,0.000000,0";
        c.bytes += '\n';
      }
      return c;
    case DisplaySpec::Kind::GravityGrabber: {
      const GravityGrabberZero z = open_gravity_grabber_zero(
          d.target, config.gravity_grabber_config_path, config.gravity_grabber);
      c.kind = ZeroChannel::Kind::Hid;
      c.display = "gravity-grabber:" + z.path;
      c.fd = z.fd;
      c.bytes.assign(z.report.begin(), z.report.end());
      return c;
    }
    case DisplaySpec::Kind::Udp: {
      const UdpSinkZero z = open_udp_sink_zero(d.host, d.port);
      c.kind = ZeroChannel::Kind::Udp;
      c.display = z.name;
      c.fd = z.fd;
      c.to = z.to;
      c.bytes = z.datagram;
      return c;
    }
  }
  throw std::logic_error("unreachable display kind");
}

namespace {

// What follows runs in the forked child: system calls on memory prepared before the fork, nothing
// that allocates, locks or touches a library's state (POSIX's async-signal-safe set).

void on_parent_death(int) {}  // only interrupts poll(); getppid() says what happened

void write_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

// Decimal digits of v at p, returning the end (no allocation).
char* put_u64(char* p, std::uint64_t v) {
  char digits[20];
  int n = 0;
  do {
    digits[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0);
  while (n > 0) *p++ = digits[--n];
  return p;
}

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);  // the clock monotonic_ns() reads
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}

void sleep_until_ns(std::int64_t t_ns) {
  const timespec t{static_cast<time_t>(t_ns / 1'000'000'000),
                   static_cast<long>(t_ns % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

// Appends the zero row, stamped now, to the sim display's CSV; a line the station was writing when
// it died is ended first so the row stands on its own.
bool append_zero_row(const ZeroChannel& c) {
  const int fd = ::open(c.path.c_str(), O_RDWR | O_APPEND | O_CLOEXEC);
  if (fd < 0) return false;
  char last = '\n';
  if (::lseek(fd, -1, SEEK_END) >= 0 && ::read(fd, &last, 1) != 1) last = '\n';
  char row[64];
  char* p = row;
  if (last != '\n') *p++ = '\n';
  p = put_u64(p, static_cast<std::uint64_t>(now_ns()));
  write_all(fd, row, static_cast<std::size_t>(p - row));
  write_all(fd, c.bytes.data(), c.bytes.size());
  return ::close(fd) == 0;
}

bool command_zero(const ZeroChannel& c) {
  switch (c.kind) {
    case ZeroChannel::Kind::None:
      return true;
    case ZeroChannel::Kind::Udp:
      return ::sendto(c.fd, c.bytes.data(), c.bytes.size(), 0,
                      reinterpret_cast<const sockaddr*>(&c.to),
                      sizeof c.to) == static_cast<ssize_t>(c.bytes.size());
    case ZeroChannel::Kind::Hid:
      return ::write(c.fd, c.bytes.data(), c.bytes.size()) == static_cast<ssize_t>(c.bytes.size());
    case ZeroChannel::Kind::CsvRow:
      return append_zero_row(c);
  }
  return false;
}

enum class End { Goodbye, Died };

// Waits for the station's end: a goodbye byte, or its death, seen three ways: the socket's end of
// file (the kernel closes the station's end whatever killed it: the robust signal), the parent
// death signal (in case a child of the station without exec holds a copy of its end), and getppid()
// changing (checked after the signal is armed, on every wake-up, and once a second).
End wait_for_end(int sock, pid_t station) {
  while (true) {
    if (::getppid() != station) return End::Died;
    pollfd p{sock, POLLIN, 0};
    const int r = ::poll(&p, 1, 1000);
    if (r <= 0) continue;  // timeout, or EINTR from the death signal: getppid() decides
    char buf[16];
    const ssize_t n = ::read(sock, buf, sizeof buf);
    if (n == 0) return End::Died;
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return End::Died;
    }
    if (std::memchr(buf, 'B', static_cast<std::size_t>(n)) != nullptr) return End::Goodbye;
  }
}

[[noreturn]] void supervise(const ZeroChannel& c, const SupervisorOptions& o, int sock,
                            pid_t station, const std::string& died_line) {
  // Never above the station's threads: whatever scheduling the forking thread had, this one waits
  // at the default. (A blocked process starves no one; this guards a station started under chrt.)
  const sched_param normal{};
  ::sched_setscheduler(0, SCHED_OTHER, &normal);
  // Ctrl-C, a terminal hang-up or a SIGTERM to the process group reach the station, which stops
  // in order and says goodbye; the supervisor outlives it to see that, whatever the station does.
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE})
    ::sigaction(sig, &ignore, nullptr);
  struct sigaction wake {};
  wake.sa_handler = on_parent_death;  // no SA_RESTART: the signal interrupts poll()
  ::sigaction(SIGUSR2, &wake, nullptr);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  ::prctl(PR_SET_NAME, "telex-zero", 0, 0, 0);
  ::prctl(PR_SET_PDEATHSIG, SIGUSR2, 0, 0, 0);

  const End end = wait_for_end(sock, station);
  // A goodbye still gets zero (zero is always safe; the station's own last command may have been
  // dropped), except the sim CSV, which the station closed with its own zero row.
  int sent = 0, tried = 0;
  if (end == End::Died || c.kind != ZeroChannel::Kind::CsvRow) {
    const std::int64_t start = now_ns();
    const int copies = c.kind == ZeroChannel::Kind::CsvRow ? 1 : std::clamp(o.repeats, 1, 16);
    for (int k = 0; k < copies; ++k) {
      if (k > 0) sleep_until_ns(start + std::int64_t{o.spacing_us} * 1000 * ((1 << k) - 1));
      ++tried;
      if (command_zero(c)) ++sent;
    }
  }
  if (end == End::Died && o.report) {
    char line[512];
    const std::size_t n = std::min(died_line.size(), sizeof line - 64);
    std::memcpy(line, died_line.data(), n);
    char* p = put_u64(line + n, static_cast<std::uint64_t>(sent));
    std::memcpy(p, " of ", 4);
    p = put_u64(p + 4, static_cast<std::uint64_t>(tried));
    std::memcpy(p, " sent)\n", 7);
    write_all(STDERR_FILENO, line, static_cast<std::size_t>(p + 7 - line));
  }
  ::_exit(sent == tried ? 0 : 1);
}

}  // namespace

DisplaySupervisor::DisplaySupervisor(DisplaySupervisor&& o) noexcept
    : pid_(std::exchange(o.pid_, -1)), pipe_fd_(std::exchange(o.pipe_fd_, -1)) {}

DisplaySupervisor& DisplaySupervisor::operator=(DisplaySupervisor&& o) noexcept {
  if (this != &o) {
    stop();
    pid_ = std::exchange(o.pid_, -1);
    pipe_fd_ = std::exchange(o.pipe_fd_, -1);
  }
  return *this;
}

DisplaySupervisor::~DisplaySupervisor() { stop(); }

int DisplaySupervisor::stop() {
  if (pipe_fd_ >= 0) {
    ::send(pipe_fd_, "B", 1, MSG_NOSIGNAL);  // a supervisor already gone must not SIGPIPE us
    ::close(pipe_fd_);
    pipe_fd_ = -1;
  }
  if (pid_ < 0) return -1;
  const pid_t pid = std::exchange(pid_, -1);
  for (int ms = 0; ms <= 1000; ++ms) {
    int status = 0;
    const pid_t r = ::waitpid(pid, &status, WNOHANG);
    if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (r < 0) return -1;
    const timespec one_ms{0, 1'000'000};
    ::nanosleep(&one_ms, nullptr);
  }
  return -1;  // stuck (a hung device write?); init reaps it once the station exits
}

DisplaySupervisor start_display_supervisor(ZeroChannel channel, const SupervisorOptions& options) {
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) {
    if (channel.fd >= 0) ::close(channel.fd);
    throw std::runtime_error(std::string("display supervisor: socketpair: ") +
                             std::strerror(errno));
  }
  const std::string died_line = std::string("telex-local: ") + kSupervisorDiedLine +
                                " (no goodbye); commanded zero force on " + channel.display + " (";
  const pid_t station = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    supervise(channel, options, fds[1], station, died_line);
  }
  ::close(fds[1]);
  if (channel.fd >= 0) ::close(channel.fd);
  if (pid < 0) {
    const int err = errno;
    ::close(fds[0]);
    throw std::runtime_error(std::string("display supervisor: fork: ") + std::strerror(err) +
                             " (--no-supervisor runs without it)");
  }
  return DisplaySupervisor(pid, fds[0]);
}

}  // namespace telex::local
