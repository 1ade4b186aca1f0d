// SPDX-License-Identifier: MIT
// The display supervisor: a child process forked at start that commands zero force on the haptic
// display when the station dies without saying goodbye (SIGKILL, abort, a segfault) or its haptic
// loop's heartbeat goes silent (stopped, hung); the station stops when it loses its supervisor.
#pragma once

#include <netinet/in.h>
#include <pthread.h>
#include <sys/types.h>

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "telex/local/displays/haptic_display.h"

namespace telex::local {

// Everything the supervisor needs to command zero on the display's channel, prepared before the
// fork: after it the child only writes bytes it already holds, with system calls (no allocation,
// no library), which is what is safe in a forked child.
struct ZeroChannel {
  enum class Kind {
    None,    // sim: nothing outside the station to command
    Udp,     // `bytes` (the zero datagram) from `fd` (its own socket) to `to`
    Hid,     // `bytes` (the motors-off report) written on `fd` (its own handle on the hidraw node)
    CsvRow,  // sim:CSV: a zero-force row appended to `path`, as the sim display would record it
  };
  Kind kind = Kind::None;
  std::string display;  // the display's name for messages: udp:HOST:PORT, gravity-grabber:PATH
  int fd = -1;          // owned: closed by the parent after the fork, kept by the child
  sockaddr_in to{};
  std::string bytes;  // Udp, Hid: the zero command; CsvRow: the row after its time stamp
  std::string path;   // CsvRow
};

// The channel of the display `spec` names (make_display's grammar): resolves, opens and encodes as
// the display does, with its errors (std::invalid_argument for a bad spec, std::runtime_error for
// a device or host that cannot be opened).
ZeroChannel zero_channel_for(const std::string& spec, const DisplayConfig& config);

// The station's haptic loop's heartbeat, in the page the station shares with its supervisor. The
// supervisor commands zero force on a UDP or HID display when no beat came for the loop's period +
// kSilenceNs, whatever silenced it: a SIGSTOP or Ctrl-Z (every thread stops), a hung tick, a
// starved thread. It reads `beat_ns` and `limit_ns` and counts its zeroings in `zeroed`; the
// station calls the methods.
struct StationHeartbeat {
  static constexpr std::int64_t kSilenceNs = 20'000'000;
  // The haptic thread, before its first tick: beats are due every `period_ns`.
  void arm(std::int64_t period_ns) {
    limit_ns.store(period_ns + kSilenceNs, std::memory_order_relaxed);
  }
  // The haptic thread, every tick, at its time (CLOCK_MONOTONIC, monotonic_ns()): one relaxed
  // store to memory mapped before the thread started, so no system call, lock or allocation.
  void beat(std::int64_t now_ns) { beat_ns.store(now_ns, std::memory_order_relaxed); }
  // The haptic thread, after its last zero command: nothing to watch any more.
  void disarm() { limit_ns.store(0, std::memory_order_relaxed); }
  // How many times the supervisor zeroed the display because the heartbeat went silent.
  std::uint64_t zeroings() const { return zeroed.load(std::memory_order_acquire); }

  std::atomic<std::int64_t> beat_ns{0};
  std::atomic<std::int64_t> limit_ns{0};  // 0: not watched (before the loop, after it)
  std::atomic<std::uint64_t> zeroed{0};
  // Shared between two processes: only lock-free atomics work there.
  static_assert(std::atomic<std::int64_t>::is_always_lock_free);
  static_assert(std::atomic<std::uint64_t>::is_always_lock_free);
};

// The zero commands the supervisor sends when the station dies or goes silent: `repeats` copies
// (UDP may lose one), the k-th after `spacing_us` x (2^k - 1) microseconds: 0, 0.5, 1.5, 3.5
// and 7.5 ms by default, so a burst of loss does not take them all and the last goes out within 8
// ms.
struct SupervisorOptions {
  int repeats = 5;
  int spacing_us = 500;
  // SCHED_FIFO kSupervisorPriority where the machine grants it (telex-local's --no-realtime:
  // SCHED_OTHER), whatever the forking thread had.
  bool realtime = true;
  // Where the line saying the station died, what was commanded and what saw it goes (-1: nowhere).
  int report_fd = 2;
};

struct SupervisorPage;  // the shared page: the robust mutex and the heartbeat

// The running supervisor, seen from the station. Destroying it is the station's clean exit: it
// says goodbye (the supervisor commands zero once more, zero is always safe, and exits) and reaps
// it. A station that dies without that gets zero force on the channel within milliseconds: the
// starting thread holds a robust process-shared mutex the kernel hands to the waiting supervisor
// as that thread starts to exit; the socket's end of file and getppid() are checked every 10 ms
// as a second line (they come only after the kernel has freed the station's memory). A station
// whose heartbeat goes silent gets zero within kSilenceNs (+ a period) of its last beat, once per
// silence; the supervisor watches again from the next beat.
class DisplaySupervisor {
 public:
  DisplaySupervisor() = default;  // none (--no-supervisor)
  DisplaySupervisor(pid_t pid, int pipe_fd, SupervisorPage* page)
      : pid_(pid), pipe_fd_(pipe_fd), page_(page) {}
  DisplaySupervisor(DisplaySupervisor&& o) noexcept;
  DisplaySupervisor& operator=(DisplaySupervisor&& o) noexcept;
  DisplaySupervisor(const DisplaySupervisor&) = delete;
  DisplaySupervisor& operator=(const DisplaySupervisor&) = delete;
  ~DisplaySupervisor();

  pid_t pid() const { return pid_; }
  // The heartbeat the station's haptic loop writes (nullptr when there is no supervisor).
  StationHeartbeat* heartbeat() const;
  // Why the supervisor can no longer zero the display ("was killed by SIGKILL", "exited with
  // status 1", "was stopped by SIGSTOP"), empty while it can or when there is none. Never blocks;
  // reaps a supervisor that ended. For the station's signal thread (SIGCHLD), before stop().
  std::string lost();
  // Says goodbye and waits up to 1 s for the supervisor to exit; its exit status (0 after a
  // goodbye), or -1 when there is none or it did not exit.
  int stop();

 private:
  pid_t pid_ = -1;
  int pipe_fd_ = -1;
  SupervisorPage* page_ = nullptr;  // its mutex held by the starting thread
};

// Forks the supervisor for `channel` (whose fd it takes over). Call it before any thread starts,
// from the main thread, which must live until the station ends (it holds the mutex the supervisor
// waits on): the child is a copy of the calling thread only, and replaces the scheduling it
// inherits (SupervisorOptions::realtime). The child runs in a session of its own (setsid) and
// ignores the terminal's signals (Ctrl-C, Ctrl-Z, SIGTTIN, SIGTTOU, a hang-up), so what stops the
// station's process group leaves it awake. Throws std::runtime_error when the fork fails.
DisplaySupervisor start_display_supervisor(ZeroChannel channel, const SupervisorOptions& options);

// The supervisor's log prefix and wording, for tests that read it.
inline constexpr const char* kSupervisorDiedLine = "display supervisor: the station died";
// The supervisor's line when the station's heartbeat went silent (stopped, hung).
inline constexpr const char* kSupervisorSilentLine = "display supervisor: the station went silent";
// The station's line, once it runs again, after the supervisor zeroed the display.
inline constexpr const char* kSupervisorZeroedLine =
    "the display supervisor commanded zero force while this station was silent";
// The station's error when its supervisor died or was stopped.
inline constexpr const char* kSupervisorLostLine = "display supervisor lost";

}  // namespace telex::local
