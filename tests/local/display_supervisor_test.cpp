// SPDX-License-Identifier: MIT
// The display supervisor with a stand-in station: a forked child that starts the supervisor, sends
// a press on the channel, and dies (SIGKILL, abort, a segfault) or says goodbye; the test reads
// what the channel got.
#include "telex/local/displays/display_supervisor.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <linux/futex.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>
#include <thread>

#include "process.h"
#include "telex/base/periodic.h"
#include "telex/local/displays/gravity_grabber.h"
#include "telex/local/displays/udp_sink.h"
#include "test_support.h"

namespace telex::local {
namespace {

// KillWithoutRobustList: the station's robust-mutex list is lost first (as a heap-smashing bug
// could lose it), so the kernel cannot hand the mutex on and the supervisor's second line must see
// it.
enum class Death { Goodbye, Kill, Abort, Segfault, KillWithoutRobustList };

const char* name_of(Death d) {
  switch (d) {
    case Death::Goodbye:
      return "Goodbye";
    case Death::Kill:
      return "Kill";
    case Death::Abort:
      return "Abort";
    case Death::Segfault:
      return "Segfault";
    case Death::KillWithoutRobustList:
      return "KillWithoutRobustList";
  }
  return "?";
}

// A loopback UDP receiver on an ephemeral port.
struct Receiver {
  int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  Receiver() {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  ~Receiver() { ::close(fd); }
  int port() const {
    sockaddr_in a{};
    socklen_t len = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    return ntohs(a.sin_port);
  }
  // Every datagram until `quiet_ms` pass without one, with its sender's port.
  std::vector<std::pair<std::string, int>> drain(int quiet_ms) const {
    std::vector<std::pair<std::string, int>> got;
    pollfd p{fd, POLLIN, 0};
    while (::poll(&p, 1, quiet_ms) > 0) {
      char buf[512];
      sockaddr_in from{};
      socklen_t len = sizeof from;
      const ssize_t n =
          ::recvfrom(fd, buf, sizeof buf, 0, reinterpret_cast<sockaddr*>(&from), &len);
      if (n >= 0)
        got.emplace_back(std::string(buf, static_cast<std::size_t>(n)), ntohs(from.sin_port));
    }
    return got;
  }
};

// The stand-in station: forks, starts the supervisor on `channel`, runs `press` (its own command
// on the channel), then ends as `death` says. Returns the stand-in's exit status as Process::wait
// gives it (128 + signal). `press` gets the supervisor's pid; `before_start` runs in the stand-in
// first; the supervisor's death line goes to `report_fd`.
int run_station(Death death, ZeroChannel channel, const std::function<void(pid_t)>& press,
                const std::function<void()>& before_start = {}, int report_fd = -1) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (before_start) before_start();
    SupervisorOptions options;
    options.report_fd = report_fd;
    DisplaySupervisor s = start_display_supervisor(std::move(channel), options);
    press(s.pid());
    switch (death) {
      case Death::Goodbye:
        ::_exit(s.stop() == 0 ? 0 : 3);
      case Death::Kill:
        ::raise(SIGKILL);
        break;
      case Death::Abort:
        std::abort();
      case Death::Segfault: {
        // Both volatile: GCC would drop a plain store, or turn a known null one into a trap.
        volatile int* volatile nowhere = nullptr;
        *nowhere = 1;
        break;
      }
      case Death::KillWithoutRobustList: {
        static robust_list_head empty{{&empty.list}, 0, nullptr};
        ::syscall(SYS_set_robust_list, &empty, sizeof empty);
        ::raise(SIGKILL);
        break;
      }
    }
    ::_exit(4);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string press_datagram() {
  std::array<FingerForce, 1> f{FingerForce{1, 2.5, 0.0, true}};
  std::array<char, kUdpSinkMaxBytes> buf{};
  return std::string(buf.data(), format_udp_sink(udp_sink_channels(f), buf));
}

bool all_zero(const std::string& datagram) {
  std::array<double, kUdpSinkChannels> ch{};
  if (!parse_udp_sink(datagram, ch)) return false;
  for (double v : ch)
    if (v != 0.0) return false;
  return true;
}

// The real-time priority and policy fields of /proc/PID/stat (the 40th and 41st), or -1.
std::pair<int, int> scheduling_of(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = stat.rfind(')');
  if (close == std::string::npos) return {-1, -1};
  std::istringstream rest(stat.substr(close + 2));
  std::string field;
  int priority = -1;
  for (int i = 3; i <= 41 && rest >> field; ++i) {
    if (i == 40) priority = std::stoi(field);
    if (i == 41) return {std::stoi(field), priority};
  }
  return {-1, -1};
}

class SupervisorUdp : public ::testing::TestWithParam<Death> {};

// The station's last datagram is a press; whatever ends it, the supervisor's five zero datagrams
// come after it, from the supervisor's own socket, and its line says what saw the death.
TEST_P(SupervisorUdp, ZeroDatagramsFollowThePressFromTheSupervisorsOwnSocket) {
  const Death death = GetParam();
  Receiver rx;
  int said[2];
  ASSERT_EQ(::pipe(said), 0);
  ZeroChannel ch = zero_channel_for("udp:127.0.0.1:" + std::to_string(rx.port()), DisplayConfig{});
  ASSERT_EQ(ch.kind, ZeroChannel::Kind::Udp);
  const int station_rc = run_station(
      death, std::move(ch),
      [&](pid_t) {
        auto display = open_udp_sink("127.0.0.1", rx.port());
        std::array<FingerForce, 1> f{FingerForce{1, 2.5, 0.0, true}};
        display->write(monotonic_ns(), f);
        display.release();  // dies holding the press, as a killed station does
      },
      {}, said[1]);
  ::close(said[1]);
  const int want_rc = death == Death::Goodbye    ? 0
                      : death == Death::Abort    ? 128 + SIGABRT
                      : death == Death::Segfault ? 128 + SIGSEGV
                                                 : 128 + SIGKILL;
  if (death == Death::Goodbye) {
    EXPECT_EQ(station_rc, want_rc);
  } else {
    EXPECT_TRUE(test::died_by_signal(station_rc, want_rc - 128)) << station_rc;
  }
  const auto got = rx.drain(300);
  ASSERT_EQ(got.size(), 6u) << "the press and five zeros";
  EXPECT_EQ(got[0].first, press_datagram());
  for (std::size_t i = 1; i < got.size(); ++i) {
    EXPECT_TRUE(all_zero(got[i].first)) << i << ": '" << got[i].first << "'";
    EXPECT_NE(got[i].second, got[0].second) << "the zero came from the station's socket";
  }
  // The line ends when the supervisor exits and closes its end of the pipe.
  std::string line;
  char buf[256];
  for (ssize_t n; (n = ::read(said[0], buf, sizeof buf)) > 0;)
    line.append(buf, static_cast<std::size_t>(n));
  ::close(said[0]);
  const char* seen = death == Death::Goodbye ? nullptr
                     : death == Death::KillWithoutRobustList
                         ? "seen by its socket's end of file)"
                         : "seen by its main thread's robust mutex)";
  if (seen == nullptr) {
    EXPECT_EQ(line, "") << "a goodbye is quiet";
  } else {
    EXPECT_NE(line.find(kSupervisorDiedLine), std::string::npos) << line;
    EXPECT_NE(line.find("(5 of 5 sent; "), std::string::npos) << line;
    EXPECT_NE(line.find(seen), std::string::npos) << line;
  }
}

INSTANTIATE_TEST_SUITE_P(Ends, SupervisorUdp,
                         ::testing::Values(Death::Goodbye, Death::Kill, Death::Abort,
                                           Death::Segfault, Death::KillWithoutRobustList),
                         [](const auto& info) { return std::string(name_of(info.param)); });

// The HID channel is a file descriptor and the motors-off report: a pipe stands in for the hidraw
// node, and after the station's death it holds exactly the five reports.
TEST(SupervisorHid, MotorsOffReportsOnTheHeldDescriptorAfterAKill) {
  int hid[2];
  ASSERT_EQ(::pipe(hid), 0);
  GravityGrabberConfig cfg;
  cfg.report_id = 0x07;
  const auto off = gravity_grabber_report({}, cfg, 0);
  ZeroChannel ch;
  ch.kind = ZeroChannel::Kind::Hid;
  ch.display = "gravity-grabber:pipe";
  ch.fd = hid[1];
  ch.bytes.assign(off.begin(), off.end());
  EXPECT_EQ(run_station(Death::Kill, std::move(ch), [](pid_t) {}), 128 + SIGKILL);
  ::close(hid[1]);
  // The supervisor holds the last write end; its exit closes it, so this read ends.
  std::string got;
  char buf[256];
  for (ssize_t n; (n = ::read(hid[0], buf, sizeof buf)) > 0;)
    got.append(buf, static_cast<std::size_t>(n));
  ::close(hid[0]);
  ASSERT_EQ(got.size(), 5 * kGravityGrabberReportBytes);
  for (int i = 0; i < 5; ++i)
    EXPECT_EQ(got.substr(i * kGravityGrabberReportBytes, kGravityGrabberReportBytes),
              std::string(off.begin(), off.end()))
        << i;
  EXPECT_EQ(static_cast<unsigned char>(got[0]), 0x07) << "report id";
  EXPECT_EQ(got[2], 0) << "motors enabled bit clear";
}

// sim:CSV: the station dies halfway through a row; the supervisor ends that line and appends a
// zero-force row, so the file's last record is zero force.
TEST(SupervisorSimCsv, ZeroRowEndsTheFileAfterAnAbort) {
  const auto dir = test::scratch_dir("display_supervisor_csv");
  const auto csv = dir / "sim.csv";
  ZeroChannel ch = zero_channel_for("sim:" + csv.string(), DisplayConfig{});
  ASSERT_EQ(ch.kind, ZeroChannel::Kind::CsvRow);
  const std::int64_t before = monotonic_ns();
  EXPECT_EQ(run_station(Death::Abort, std::move(ch),
                        [&](pid_t) { std::ofstream(csv) << "time_ns,thumb_pressure_N\n1,2.5000"; }),
            128 + SIGABRT);
  ASSERT_TRUE(test::eventually(std::chrono::seconds(2), [&] {
    return test::read_text(csv).find("0.000000,0\n") != std::string::npos;
  }));
  std::istringstream lines(test::read_text(csv));
  std::vector<std::string> rows;
  for (std::string l; std::getline(lines, l);) rows.push_back(l);
  ASSERT_EQ(rows.size(), 3u) << test::read_text(csv);
  EXPECT_EQ(rows[1], "1,2.5000");
  const auto comma = rows[2].find(',');
  ASSERT_NE(comma, std::string::npos);
  EXPECT_GE(std::stoll(rows[2].substr(0, comma)), before) << "stamped on the station's clock";
  EXPECT_EQ(rows[2].substr(comma),
            ",0.000000,0.000000,0,0.000000,0.000000,0,0.000000,0.000000,0,0.000000,0.000000,0,"
            "0.000000,0.000000,0");
}

// A goodbye leaves the sim CSV alone: the station closed it with its own zero row.
TEST(SupervisorSimCsv, GoodbyeAppendsNothing) {
  const auto dir = test::scratch_dir("display_supervisor_csv_bye");
  const auto csv = dir / "sim.csv";
  EXPECT_EQ(run_station(Death::Goodbye, zero_channel_for("sim:" + csv.string(), DisplayConfig{}),
                        [&](pid_t) { std::ofstream(csv) << "header\n"; }),
            0);
  EXPECT_EQ(test::read_text(csv), "header\n");
}

// A station started at SCHED_FIFO 10 (under chrt) forks a supervisor that does not keep that
// policy: SCHED_FIFO kSupervisorPriority (1, below every thread of the station), or with
// realtime off SCHED_OTHER.
class SupervisorScheduling : public ::testing::TestWithParam<bool> {};

TEST_P(SupervisorScheduling, TheSupervisorReplacesTheSchedulingOfARealtimeStation) {
  const bool realtime = GetParam();
  sched_param fifo{};
  fifo.sched_priority = 10;
  const bool granted = ::sched_setscheduler(0, SCHED_FIFO, &fifo) == 0;
  const sched_param normal{};
  if (granted) ::sched_setscheduler(0, SCHED_OTHER, &normal);
  if (!granted) GTEST_SKIP() << "SCHED_FIFO is not granted here";
  const int want_policy = realtime ? SCHED_FIFO : SCHED_OTHER;
  const int want_priority = realtime ? kSupervisorPriority : 0;
  int seen[2];
  ASSERT_EQ(::pipe(seen), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::sched_setscheduler(0, SCHED_FIFO, &fifo);
    SupervisorOptions options;
    options.report_fd = -1;
    options.realtime = realtime;
    DisplaySupervisor s = start_display_supervisor(ZeroChannel{}, options);
    // The supervisor starts as a copy of this SCHED_FIFO 10 thread and then sets its own.
    std::array<int, 4> got{::sched_getscheduler(0), -1, -1, -1};
    test::eventually(std::chrono::seconds(2), [&] {
      const auto [policy, priority] = scheduling_of(s.pid());
      got[1] = policy;
      got[2] = priority;
      return policy == want_policy && priority == want_priority;
    });
    got[3] = s.stop();
    (void)!::write(seen[1], got.data(), sizeof got);
    ::_exit(0);
  }
  ::close(seen[1]);
  std::array<int, 4> got{-1, -1, -1, -1};
  EXPECT_EQ(::read(seen[0], got.data(), sizeof got), static_cast<ssize_t>(sizeof got));
  ::close(seen[0]);
  ::waitpid(pid, nullptr, 0);
  EXPECT_EQ(got[0], SCHED_FIFO) << "the stand-in station";
  EXPECT_EQ(got[1], want_policy) << "its supervisor's policy";
  EXPECT_EQ(got[2], want_priority) << "its supervisor's real-time priority";
  EXPECT_EQ(got[3], 0) << "the supervisor's exit after the goodbye";
}

INSTANTIATE_TEST_SUITE_P(Realtime, SupervisorScheduling, ::testing::Bool(), [](const auto& info) {
  return std::string(info.param ? "LowestFifo" : "Default");
});

// The haptic loop's heartbeat in a stand-in station: beating, no zero; silent (a hung tick), five
// zeros once, counted in the page, with a line; beating again, quiet; then the goodbye's five. The
// beats are due every 100 ms here, so a loaded machine's late wake-up is not a silence.
TEST(SupervisorHeartbeat, ASilenceGetsZeroOnceAndBeatingAgainNone) {
  Receiver rx;
  int said[2], counts[2];
  ASSERT_EQ(::pipe(said), 0);
  ASSERT_EQ(::pipe(counts), 0);
  ZeroChannel ch = zero_channel_for("udp:127.0.0.1:" + std::to_string(rx.port()), DisplayConfig{});
  const pid_t pid = ::fork();
  if (pid == 0) {
    SupervisorOptions options;
    options.report_fd = said[1];
    DisplaySupervisor s = start_display_supervisor(std::move(ch), options);
    StationHeartbeat& heartbeat = *s.heartbeat();
    const auto beat_for = [&](std::chrono::milliseconds how_long) {
      const std::int64_t end = monotonic_ns() + how_long.count() * 1'000'000;
      for (std::int64_t now = monotonic_ns(); now < end; now = monotonic_ns()) {
        heartbeat.beat(now);
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    };
    heartbeat.arm(100'000'000);
    beat_for(std::chrono::milliseconds(300));
    std::array<std::uint64_t, 3> zeroings{heartbeat.zeroings(), 0, 0};
    std::this_thread::sleep_for(std::chrono::milliseconds(600));  // silent
    zeroings[1] = heartbeat.zeroings();
    beat_for(std::chrono::milliseconds(300));
    zeroings[2] = heartbeat.zeroings();
    heartbeat.disarm();
    (void)!::write(counts[1], zeroings.data(), sizeof zeroings);
    ::_exit(s.stop() == 0 ? 0 : 3);
  }
  ::close(said[1]);
  ::close(counts[1]);
  std::array<std::uint64_t, 3> zeroings{9, 9, 9};
  EXPECT_EQ(::read(counts[0], zeroings.data(), sizeof zeroings),
            static_cast<ssize_t>(sizeof zeroings));
  ::close(counts[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  EXPECT_EQ(zeroings[0], 0u) << "zero while beating";
  EXPECT_EQ(zeroings[1], 1u) << "the silence";
  EXPECT_EQ(zeroings[2], 1u) << "zero again after the beats came back";
  const auto got = rx.drain(300);
  EXPECT_EQ(got.size(), 10u) << "five for the silence, five for the goodbye";
  for (const auto& [datagram, port] : got) EXPECT_TRUE(all_zero(datagram)) << datagram;
  std::string line;
  char buf[256];
  for (ssize_t n; (n = ::read(said[0], buf, sizeof buf)) > 0;)
    line.append(buf, static_cast<std::size_t>(n));
  ::close(said[0]);
  EXPECT_NE(line.find(kSupervisorSilentLine), std::string::npos) << line;
  EXPECT_NE(line.find("stopped or hung); commanded zero force on udp:127.0.0.1:"),
            std::string::npos)
      << line;
  EXPECT_NE(line.find("(5 of 5 sent)\n"), std::string::npos) << line;
  EXPECT_EQ(line.find(kSupervisorDiedLine), std::string::npos) << line;
}

// What /proc says of a process: its state letter, process group and session (stat's 3rd, 5th and
// 6th fields) and the signals it ignores (status's SigIgn mask).
struct ProcState {
  char state = '?';
  pid_t group = -1, session = -1;
  std::uint64_t ignored = 0;
};

ProcState proc_state(pid_t pid) {
  ProcState p;
  const std::string stat = test::read_text("/proc/" + std::to_string(pid) + "/stat");
  const auto close = stat.rfind(')');
  if (close == std::string::npos) return p;
  std::istringstream rest(stat.substr(close + 1));
  pid_t parent = -1;
  rest >> p.state >> parent >> p.group >> p.session;
  std::istringstream status(test::read_text("/proc/" + std::to_string(pid) + "/status"));
  for (std::string line; std::getline(status, line);)
    if (line.rfind("SigIgn:", 0) == 0) p.ignored = std::stoull(line.substr(7), nullptr, 16);
  return p;
}

bool ignores(const ProcState& p, int sig) { return (p.ignored >> (sig - 1)) & 1U; }

// Ctrl-Z (SIGTSTP) and a background read or write of the terminal (SIGTTIN, SIGTTOU) stop the
// terminal's foreground process group, which held the supervisor with the station: the supervisor
// runs in a session of its own and ignores them, so it still zeroes the display of a station they
// stopped.
TEST(SupervisorSignals, ItsOwnSessionAndTerminalStopsIgnored) {
  int seen[2];
  ASSERT_EQ(::pipe(seen), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {
    SupervisorOptions options;
    options.report_fd = -1;
    DisplaySupervisor s = start_display_supervisor(ZeroChannel{}, options);
    test::eventually(std::chrono::seconds(2),
                     [&] { return ignores(proc_state(s.pid()), SIGTTOU); });
    for (const int sig : {SIGTSTP, SIGTTIN, SIGTTOU}) ::kill(s.pid(), sig);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const ProcState got = proc_state(s.pid());
    ::kill(s.pid(), SIGCONT);  // one that was stopped hears the goodbye
    const int rc = s.stop();
    (void)!::write(seen[1], &got, sizeof got);
    (void)!::write(seen[1], &rc, sizeof rc);
    ::_exit(0);
  }
  ::close(seen[1]);
  ProcState got;
  int rc = -1;
  EXPECT_EQ(::read(seen[0], &got, sizeof got), static_cast<ssize_t>(sizeof got));
  EXPECT_EQ(::read(seen[0], &rc, sizeof rc), static_cast<ssize_t>(sizeof rc));
  ::close(seen[0]);
  ::waitpid(pid, nullptr, 0);
  for (const int sig : {SIGTSTP, SIGTTIN, SIGTTOU}) EXPECT_TRUE(ignores(got, sig)) << sig;
  EXPECT_NE(got.state, 'T') << "stopped";
  EXPECT_NE(got.session, ::getsid(0)) << "in the station's session";
  EXPECT_NE(got.group, ::getpgrp()) << "in the station's process group";
  EXPECT_EQ(rc, 0) << "the supervisor's exit after the goodbye";
}

}  // namespace
}  // namespace telex::local
