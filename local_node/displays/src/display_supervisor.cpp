// SPDX-License-Identifier: MIT
// The display supervisor: the forked child's loop (system calls only) and the station's handle.
#include "telex/local/displays/display_supervisor.h"

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
#include <new>
#include <stdexcept>
#include <utility>

#include "telex/base/periodic.h"
#include "telex/local/displays/gravity_grabber.h"
#include "telex/local/displays/udp_sink.h"

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

// Where a line for the station's stderr is built: a fixed buffer, no allocation.
class Line {
 public:
  Line& operator<<(const char* text) { return add(text, std::strlen(text)); }
  Line& operator<<(const std::string& text) { return add(text.data(), text.size()); }
  Line& operator<<(std::uint64_t v) {
    if (end_ - p_ >= 20) p_ = put_u64(p_, v);
    return *this;
  }
  void write(int fd) const {
    if (fd >= 0) write_all(fd, buf_, static_cast<std::size_t>(p_ - buf_));
  }

 private:
  Line& add(const char* text, std::size_t n) {
    n = std::min(n, static_cast<std::size_t>(end_ - p_));
    std::memcpy(p_, text, n);
    p_ += n;
    return *this;
  }
  char buf_[768];
  char* p_ = buf_;
  char* const end_ = buf_ + sizeof buf_ - 1;  // room for the newline
};

}  // namespace

// The page the station and its supervisor share, mapped before the fork.
struct SupervisorPage {
  pthread_mutex_t alive;  // held by the station's starting thread until its goodbye
  StationHeartbeat heartbeat;
};

namespace {

enum class End { Goodbye, OwnerDied, SocketClosed, ParentChanged, Silent };

const char* seen_by(End e) {
  switch (e) {
    case End::OwnerDied:
      return "its main thread's robust mutex";
    case End::SocketClosed:
      return "its socket's end of file";
    case End::ParentChanged:
      return "a new parent";
    case End::Goodbye:
    case End::Silent:
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

timespec to_timespec(std::int64_t t_ns) {
  return {static_cast<time_t>(t_ns / 1'000'000'000), static_cast<long>(t_ns % 1'000'000'000)};
}

// What the supervisor watches. A silent heartbeat is answered once: `answered_beat_ns` is the
// beat it was silent after, not watched again; the station's next beat is.
struct Watch {
  int sock = -1;
  pid_t station = -1;
  SupervisorPage* page = nullptr;
  std::int64_t answered_beat_ns = 0;
  std::int64_t silent_for_ns = 0;  // at the answer: how long since that beat

  // When the heartbeat goes silent, or 0 while it is not watched (before the haptic loop's first
  // beat, after its last, or answered). `beat_ns` gets the beat it is counted from.
  std::int64_t silent_at(std::int64_t& beat_ns) const {
    const std::int64_t limit = page->heartbeat.limit_ns.load(std::memory_order_relaxed);
    beat_ns = page->heartbeat.beat_ns.load(std::memory_order_relaxed);
    if (limit <= 0 || beat_ns == 0 || beat_ns == answered_beat_ns) return 0;
    return beat_ns + limit;
  }
};

// Waits for the station's end or its silence. The station's main thread holds the page's robust
// process-shared mutex from before the fork until its goodbye: the kernel hands a robust mutex on
// (EOWNERDEAD) as the owning thread starts to exit, whatever killed it, within a fraction of a
// millisecond. The socket's end of file and the parent's death (getppid) come later, after the
// kernel has torn down the station's memory (25-33 ms for the station measured, 41 ms for
// 200 MB), and are checked every 10 ms as a second line. The wait also ends when the heartbeat
// is due to go silent, so that is seen without polling the 1 kHz beat.
End wait_for_end(Watch& w) {
  while (true) {
    std::int64_t beat_ns = 0;
    std::int64_t wake_ns = now_ns() + 10'000'000;
    if (const std::int64_t silent = w.silent_at(beat_ns); silent != 0)
      wake_ns = std::min(wake_ns, silent);
    const timespec deadline = to_timespec(wake_ns);
    const int r = ::pthread_mutex_clocklock(&w.page->alive, CLOCK_MONOTONIC, &deadline);
    bool eof = false;
    const bool goodbye = goodbye_waiting(w.sock, eof);
    if (r == 0) return End::Goodbye;  // only the station's goodbye unlocks it
    if (r == EOWNERDEAD) return goodbye ? End::Goodbye : End::OwnerDied;
    if (goodbye) return End::Goodbye;
    if (eof) return End::SocketClosed;
    if (::getppid() != w.station) return End::ParentChanged;
    // The time first: a beat read after it can only be newer, so a preemption between the two
    // never makes a beating station look silent.
    const std::int64_t now = now_ns();
    const std::int64_t silent = w.silent_at(beat_ns);
    if (silent != 0 && now >= silent) {
      w.answered_beat_ns = beat_ns;
      w.silent_for_ns = now - beat_ns;
      return End::Silent;
    }
    if (r != ETIMEDOUT) {  // never spin, even on an error the mutex should not give
      const timespec wait{0, 10'000'000};
      ::nanosleep(&wait, nullptr);
    }
  }
}

struct Sent {
  std::uint64_t sent = 0, tried = 0;
};

// `copies` zero commands, the k-th spacing_us x (2^k - 1) after the first. For a silent station
// (`heartbeat` given) the copies end once it beats again: it runs again, its own commands start
// from zero, and more zeros would fight them.
Sent command_zeros(const ZeroChannel& c, const SupervisorOptions& o, int copies,
                   const StationHeartbeat* heartbeat, std::int64_t silent_beat_ns) {
  Sent s;
  const std::int64_t start = now_ns();
  for (int k = 0; k < copies; ++k) {
    if (k > 0) sleep_until_ns(start + std::int64_t{o.spacing_us} * 1000 * ((1 << k) - 1));
    if (heartbeat && heartbeat->beat_ns.load(std::memory_order_relaxed) != silent_beat_ns) break;
    ++s.tried;
    if (command_zero(c)) ++s.sent;
  }
  return s;
}

int zero_copies(const ZeroChannel& c, const SupervisorOptions& o) {
  return c.kind == ZeroChannel::Kind::CsvRow ? 1 : std::clamp(o.repeats, 1, 16);
}

// The station went silent: zero, counted in the page first (a tick that runs again sees the count
// and starts its forces from zero), and a line. Only a display outside the station (UDP, HID) is
// answered: no one feels a sim display, and the live station is still writing the sim CSV, so a
// silence there (a starved haptic thread on a loaded machine) changes nothing.
void answer_silence(const ZeroChannel& c, const SupervisorOptions& o, const Watch& w) {
  if (c.kind != ZeroChannel::Kind::Udp && c.kind != ZeroChannel::Kind::Hid) return;
  StationHeartbeat& heartbeat = w.page->heartbeat;
  heartbeat.zeroed.fetch_add(1, std::memory_order_acq_rel);
  const Sent s = command_zeros(c, o, zero_copies(c, o), &heartbeat, w.answered_beat_ns);
  Line line;
  line << "telex-local: " << kSupervisorSilentLine << " (no heartbeat from its haptic loop for "
       << static_cast<std::uint64_t>(w.silent_for_ns / 1'000'000)
       << " ms: stopped or hung); commanded zero force on " << c.display << " (" << s.sent << " of "
       << s.tried << " sent)\n";
  line.write(o.report_fd);
}

// Never the forking thread's scheduling (a station started under chrt would pass on its own):
// SCHED_FIFO at the lowest priority, below every thread of the station, so it can never delay
// one, but ahead of ordinary programs when the station dies; else the default.
void set_scheduling(const SupervisorOptions& o) {
  sched_param fifo{};
  fifo.sched_priority = kSupervisorPriority;
  if (!o.realtime || ::sched_setscheduler(0, SCHED_FIFO, &fifo) != 0) {
    const sched_param normal{};
    ::sched_setscheduler(0, SCHED_OTHER, &normal);
  }
}

// A session of its own, so nothing a terminal sends its foreground process group reaches it:
// Ctrl-Z (SIGTSTP) stops the station, and the supervisor must stay awake to zero the display.
// Ctrl-C, a hang-up or a SIGTERM to the process group reach the station, which stops in order
// and says goodbye. It ignores all of those anyway, in case one is sent to it by pid.
void detach_from_terminal() {
  ::setsid();
  struct sigaction ignore {};
  ignore.sa_handler = SIG_IGN;
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGPIPE, SIGTSTP, SIGTTIN, SIGTTOU})
    ::sigaction(sig, &ignore, nullptr);
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
}

[[noreturn]] void supervise(const ZeroChannel& c, const SupervisorOptions& o, Watch w) {
  detach_from_terminal();
  set_scheduling(o);
  ::prctl(PR_SET_NAME, "telex-zero", 0, 0, 0);

  End end = End::Silent;
  while ((end = wait_for_end(w)) == End::Silent) answer_silence(c, o, w);
  // A goodbye still gets zero (zero is always safe; the station's own last command may have been
  // dropped), except the sim CSV, which the station closed with its own zero row.
  const bool csv_goodbye = end == End::Goodbye && c.kind == ZeroChannel::Kind::CsvRow;
  const Sent s = command_zeros(c, o, csv_goodbye ? 0 : zero_copies(c, o), nullptr, 0);
  if (end != End::Goodbye) {
    Line line;
    line << "telex-local: " << kSupervisorDiedLine << " (no goodbye); commanded zero force on "
         << c.display << " (" << s.sent << " of " << s.tried << " sent; seen by " << seen_by(end)
         << ")\n";
    line.write(o.report_fd);
  }
  ::_exit(s.sent == s.tried ? 0 : 1);
}

}  // namespace

DisplaySupervisor::DisplaySupervisor(DisplaySupervisor&& o) noexcept
    : pid_(std::exchange(o.pid_, -1)),
      pipe_fd_(std::exchange(o.pipe_fd_, -1)),
      page_(std::exchange(o.page_, nullptr)) {}

DisplaySupervisor& DisplaySupervisor::operator=(DisplaySupervisor&& o) noexcept {
  if (this != &o) {
    stop();
    pid_ = std::exchange(o.pid_, -1);
    pipe_fd_ = std::exchange(o.pipe_fd_, -1);
    page_ = std::exchange(o.page_, nullptr);
  }
  return *this;
}

DisplaySupervisor::~DisplaySupervisor() { stop(); }

StationHeartbeat* DisplaySupervisor::heartbeat() const {
  return page_ != nullptr ? &page_->heartbeat : nullptr;
}

std::string DisplaySupervisor::lost() {
  if (pid_ < 0) return {};
  int status = 0;
  if (::waitpid(pid_, &status, WNOHANG | WUNTRACED) != pid_) return {};
  const auto name = [](int sig) {
    const char* abbrev = sigabbrev_np(sig);
    return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(sig);
  };
  const std::string who = "telex-zero (pid " + std::to_string(pid_) + ")";
  if (WIFSTOPPED(status)) return who + " was stopped by " + name(WSTOPSIG(status));
  pid_ = -1;  // reaped
  if (WIFSIGNALED(status)) return who + " was killed by " + name(WTERMSIG(status));
  return who + " exited with status " + std::to_string(WEXITSTATUS(status));
}

int DisplaySupervisor::stop() {
  // One that was stopped (SIGSTOP by pid) runs again to hear the goodbye.
  if (pid_ >= 0) ::kill(pid_, SIGCONT);
  if (pipe_fd_ >= 0) {
    ::send(pipe_fd_, "B", 1, MSG_NOSIGNAL);  // a supervisor already gone must not SIGPIPE us
    ::close(pipe_fd_);
    pipe_fd_ = -1;
  }
  if (page_ != nullptr) {
    // From the thread that started the supervisor (a robust mutex has an owner); from any other
    // the unlock fails and the supervisor finds the goodbye byte within 10 ms instead.
    // The page stays mapped unless the unlock took the mutex off this thread's robust list, which
    // glibc links through the mutexes themselves.
    if (::pthread_mutex_unlock(&page_->alive) == 0) ::munmap(page_, sizeof(SupervisorPage));
    page_ = nullptr;
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
  void* mem = ::mmap(nullptr, sizeof(SupervisorPage), PROT_READ | PROT_WRITE,
                     MAP_SHARED | MAP_ANONYMOUS, -1, 0);
  if (mem == MAP_FAILED) throw fail("mmap");
  auto* page = new (mem) SupervisorPage;
  pthread_mutexattr_t attr;
  ::pthread_mutexattr_init(&attr);
  ::pthread_mutexattr_setpshared(&attr, PTHREAD_PROCESS_SHARED);
  ::pthread_mutexattr_setrobust(&attr, PTHREAD_MUTEX_ROBUST);
  ::pthread_mutex_init(&page->alive, &attr);
  ::pthread_mutexattr_destroy(&attr);
  ::pthread_mutex_lock(&page->alive);  // held by this thread until the goodbye, or its death
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) {
    const auto error = fail("socketpair");
    ::pthread_mutex_unlock(&page->alive);
    ::munmap(mem, sizeof(SupervisorPage));
    throw error;
  }
  const pid_t station = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    supervise(channel, options, Watch{fds[1], station, page});
  }
  if (pid < 0) {
    const auto error = fail("fork");
    ::close(fds[1]);
    ::close(fds[0]);
    ::pthread_mutex_unlock(&page->alive);
    ::munmap(mem, sizeof(SupervisorPage));
    throw error;
  }
  ::close(fds[1]);
  if (channel.fd >= 0) ::close(channel.fd);
  return DisplaySupervisor(pid, fds[0], page);
}

}  // namespace telex::local
