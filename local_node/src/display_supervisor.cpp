// SPDX-License-Identifier: MIT
// The display supervisor: the forked child's loop (system calls only) and the station's handle.
#include "telex/local/display_supervisor.h"

#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
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

#include "telex/base/periodic.h"
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

// What follows runs in the forked child: system calls on memory prepared before the fork and the
// shared robust mutex, nothing that allocates or touches a library's state, so it would be safe
// even after a fork from a threaded process (the station forks before its first thread anyway).

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

enum class End { Goodbye, OwnerDied, SocketClosed, ParentChanged };

const char* seen_by(End e) {
  switch (e) {
    case End::OwnerDied:
      return "its main thread's robust mutex";
    case End::SocketClosed:
      return "its socket's end of file";
    case End::ParentChanged:
      return "a new parent";
    case End::Goodbye:
      break;
  }
  return "its goodbye";
}

// Whether the station's goodbye byte is waiting on the socket; `eof` is set when its end closed.
bool goodbye_waiting(int sock, bool& eof) {
  char buf[16];
  const ssize_t n = ::recv(sock, buf, sizeof buf, MSG_DONTWAIT);
  eof = n == 0;
  return n > 0 && std::memchr(buf, 'B', static_cast<std::size_t>(n)) != nullptr;
}

// Waits for the station's end. The station's main thread holds `alive`, a robust process-shared
// mutex, from before the fork until its goodbye: the kernel hands a robust mutex on (EOWNERDEAD)
// as the owning thread starts to exit, whatever killed it, within a fraction of a millisecond.
// The socket's end of file and the parent's death (getppid) come later, after the kernel has torn
// down the station's memory (25-33 ms for the station measured, 41 ms for 200 MB), and are
// checked every 10 ms as a second line.
End wait_for_end(int sock, pid_t station, pthread_mutex_t* alive) {
  while (true) {
    timespec deadline{};
    clock_gettime(CLOCK_MONOTONIC, &deadline);
    deadline.tv_nsec += 10'000'000;
    if (deadline.tv_nsec >= 1'000'000'000) {
      deadline.tv_nsec -= 1'000'000'000;
      ++deadline.tv_sec;
    }
    const int r = ::pthread_mutex_clocklock(alive, CLOCK_MONOTONIC, &deadline);
    bool eof = false;
    const bool goodbye = goodbye_waiting(sock, eof);
    if (r == 0) return End::Goodbye;  // only the station's goodbye unlocks it
    if (r == EOWNERDEAD) return goodbye ? End::Goodbye : End::OwnerDied;
    if (goodbye) return End::Goodbye;
    if (eof) return End::SocketClosed;
    if (::getppid() != station) return End::ParentChanged;
    if (r != ETIMEDOUT) {  // never spin, even on an error the mutex should not give
      const timespec wait{0, 10'000'000};
      ::nanosleep(&wait, nullptr);
    }
  }
}

[[noreturn]] void supervise(const ZeroChannel& c, const SupervisorOptions& o, int sock,
                            pid_t station, pthread_mutex_t* alive, const std::string& died_line) {
  // Never the forking thread's scheduling (a station started under chrt would pass on its own):
  // SCHED_FIFO at the lowest priority, below every thread of the station, so it can never delay
  // one, but ahead of ordinary programs when the station dies; else the default.
  sched_param fifo{};
  fifo.sched_priority = kSupervisorPriority;
  if (!o.realtime || ::sched_setscheduler(0, SCHED_FIFO, &fifo) != 0) {
    const sched_param normal{};
    ::sched_setscheduler(0, SCHED_OTHER, &normal);
  }
  // Ctrl-C, a terminal hang-up or a SIGTERM to the process group reach the station, which stops
  // in order and says goodbye; the supervisor outlives it to see that, whatever the station does.
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE})
    ::sigaction(sig, &ignore, nullptr);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  ::prctl(PR_SET_NAME, "telex-zero", 0, 0, 0);

  const End end = wait_for_end(sock, station, alive);
  // A goodbye still gets zero (zero is always safe; the station's own last command may have been
  // dropped), except the sim CSV, which the station closed with its own zero row.
  int sent = 0, tried = 0;
  if (end != End::Goodbye || c.kind != ZeroChannel::Kind::CsvRow) {
    const std::int64_t start = now_ns();
    const int copies = c.kind == ZeroChannel::Kind::CsvRow ? 1 : std::clamp(o.repeats, 1, 16);
    for (int k = 0; k < copies; ++k) {
      if (k > 0) sleep_until_ns(start + std::int64_t{o.spacing_us} * 1000 * ((1 << k) - 1));
      ++tried;
      if (command_zero(c)) ++sent;
    }
  }
  if (end != End::Goodbye && o.report_fd >= 0) {
    char line[640];
    const char* how = seen_by(end);
    const std::size_t how_n = std::strlen(how);
    const std::size_t n = std::min(died_line.size(), sizeof line - 128);
    std::memcpy(line, died_line.data(), n);
    char* p = put_u64(line + n, static_cast<std::uint64_t>(sent));
    std::memcpy(p, " of ", 4);
    p = put_u64(p + 4, static_cast<std::uint64_t>(tried));
    std::memcpy(p, " sent; seen by ", 15);
    p += 15;
    std::memcpy(p, how, how_n);
    p += how_n;
    std::memcpy(p, ")\n", 2);
    write_all(o.report_fd, line, static_cast<std::size_t>(p + 2 - line));
  }
  ::_exit(sent == tried ? 0 : 1);
}

}  // namespace

DisplaySupervisor::DisplaySupervisor(DisplaySupervisor&& o) noexcept
    : pid_(std::exchange(o.pid_, -1)),
      pipe_fd_(std::exchange(o.pipe_fd_, -1)),
      alive_(std::exchange(o.alive_, nullptr)) {}

DisplaySupervisor& DisplaySupervisor::operator=(DisplaySupervisor&& o) noexcept {
  if (this != &o) {
    stop();
    pid_ = std::exchange(o.pid_, -1);
    pipe_fd_ = std::exchange(o.pipe_fd_, -1);
    alive_ = std::exchange(o.alive_, nullptr);
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
  if (alive_ != nullptr) {
    // From the thread that started the supervisor (a robust mutex has an owner); from any other
    // the unlock fails and the supervisor finds the goodbye byte within 10 ms instead.
    // The page stays mapped unless the unlock took the mutex off this thread's robust list, which
    // glibc links through the mutexes themselves.
    if (::pthread_mutex_unlock(alive_) == 0) ::munmap(alive_, sizeof(pthread_mutex_t));
    alive_ = nullptr;
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
  const auto fail = [&](const char* what) {
    const int err = errno;
    if (channel.fd >= 0) ::close(channel.fd);
    return std::runtime_error(std::string("display supervisor: ") + what + ": " +
                              std::strerror(err) + " (--no-supervisor runs without it)");
  };
  void* page = ::mmap(nullptr, sizeof(pthread_mutex_t), PROT_READ | PROT_WRITE,
                      MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (page == MAP_FAILED) throw fail("mmap");
  auto* alive = static_cast<pthread_mutex_t*>(page);
  pthread_mutexattr_t attr;
  ::pthread_mutexattr_init(&attr);
  ::pthread_mutexattr_setpshared(&attr, PTHREAD_PROCESS_SHARED);
  ::pthread_mutexattr_setrobust(&attr, PTHREAD_MUTEX_ROBUST);
  ::pthread_mutex_init(alive, &attr);
  ::pthread_mutexattr_destroy(&attr);
  ::pthread_mutex_lock(alive);  // held by this thread until the goodbye, or its death
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) {
    const auto error = fail("socketpair");
    ::pthread_mutex_unlock(alive);
    ::munmap(page, sizeof(pthread_mutex_t));
    throw error;
  }
  const std::string died_line = std::string("telex-local: ") + kSupervisorDiedLine +
                                " (no goodbye); commanded zero force on " + channel.display + " (";
  const pid_t station = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    supervise(channel, options, fds[1], station, alive, died_line);
  }
  if (pid < 0) {
    const auto error = fail("fork");
    ::close(fds[1]);
    ::close(fds[0]);
    ::pthread_mutex_unlock(alive);
    ::munmap(page, sizeof(pthread_mutex_t));
    throw error;
  }
  ::close(fds[1]);
  if (channel.fd >= 0) ::close(channel.fd);
  return DisplaySupervisor(pid, fds[0], alive);
}

}  // namespace telex::local
