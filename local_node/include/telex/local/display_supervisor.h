// SPDX-License-Identifier: MIT
// The display supervisor: a child process forked at start that commands zero force on the haptic
// display when the station dies without saying goodbye (SIGKILL, abort, a segfault).
#pragma once

#include <netinet/in.h>
#include <pthread.h>
#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

#include "telex/local/haptic_display.h"

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

// The zero commands the supervisor sends when the station dies: `repeats` copies (UDP may lose
// one), the k-th after `spacing_us` x (2^k - 1) microseconds: 0, 0.5, 1.5, 3.5 and 7.5 ms by
// default, so a burst of loss does not take them all and the last goes out within 8 ms.
struct SupervisorOptions {
  int repeats = 5;
  int spacing_us = 500;
  // SCHED_FIFO kSupervisorPriority where the machine grants it (telex-local's --no-realtime:
  // SCHED_OTHER), whatever the forking thread had.
  bool realtime = true;
  // Where the line saying the station died, what was commanded and what saw it goes (-1: nowhere).
  int report_fd = 2;
};

// The running supervisor, seen from the station. Destroying it is the station's clean exit: it
// says goodbye (the supervisor commands zero once more, zero is always safe, and exits) and reaps
// it. A station that dies without that gets zero force on the channel within milliseconds: the
// starting thread holds a robust process-shared mutex the kernel hands to the waiting supervisor
// as that thread starts to exit; the socket's end of file and getppid() are checked every 10 ms
// as a second line (they come only after the kernel has freed the station's memory).
class DisplaySupervisor {
 public:
  DisplaySupervisor() = default;  // none (--no-supervisor)
  DisplaySupervisor(pid_t pid, int pipe_fd, pthread_mutex_t* alive)
      : pid_(pid), pipe_fd_(pipe_fd), alive_(alive) {}
  DisplaySupervisor(DisplaySupervisor&& o) noexcept;
  DisplaySupervisor& operator=(DisplaySupervisor&& o) noexcept;
  DisplaySupervisor(const DisplaySupervisor&) = delete;
  DisplaySupervisor& operator=(const DisplaySupervisor&) = delete;
  ~DisplaySupervisor();

  pid_t pid() const { return pid_; }
  // Says goodbye and waits up to 1 s for the supervisor to exit; its exit status (0 after a
  // goodbye), or -1 when there is none or it did not exit.
  int stop();

 private:
  pid_t pid_ = -1;
  int pipe_fd_ = -1;
  pthread_mutex_t* alive_ = nullptr;  // shared with the supervisor, held by the starting thread
};

// Forks the supervisor for `channel` (whose fd it takes over). Call it before any thread starts,
// from the main thread, which must live until the station ends (it holds the mutex the supervisor
// waits on): the child is a copy of the calling thread only, and replaces the scheduling it
// inherits (SupervisorOptions::realtime). Throws std::runtime_error when the fork fails.
DisplaySupervisor start_display_supervisor(ZeroChannel channel, const SupervisorOptions& options);

// The supervisor's log prefix and wording, for tests that read it.
inline constexpr const char* kSupervisorDiedLine = "display supervisor: the station died";

}  // namespace telex::local
