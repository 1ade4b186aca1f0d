// SPDX-License-Identifier: MIT
// telex-sim-display: a UDP haptic display (telex-local --haptics udp:HOST:PORT) that logs what it
// is commanded. Each datagram is read with the station's own parser (parse_udp_sink) and written
// as one CSV line with its wall-clock arrival time, so a script can line the commands up with the
// moments it injected faults (tools/fault_soak.sh).
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <iostream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "telex/cli/command_line.h"
#include "telex/common/endpoint.h"
#include "telex/local/displays/udp_sink.h"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) { g_stop = 1; }

std::int64_t realtime_ns() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

int open_socket(const telex::Endpoint& at) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(at.port));
  if (::inet_pton(AF_INET, at.host.c_str(), &addr.sin_addr) != 1) {
    ::close(fd);
    throw std::invalid_argument("--listen: '" + at.host + "' is not a numeric IPv4 address");
  }
  const int one = 1;
  ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  // The kernel stamps each datagram's arrival: a late read (this process starved on a loaded
  // machine) must not look like a late command.
  ::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    throw std::runtime_error("cannot listen on " + at.host + ":" + std::to_string(at.port) + ": " +
                             why);
  }
  return fd;
}

struct Counts {
  std::uint64_t datagrams = 0, malformed = 0, nonzero = 0;
  double peak_N = 0.0;
};

// One line: rx_ns,from_port,the largest pressure of the five fingers (N),its finger,fingers in
// contact. The largest pressure is what a fault must bring to zero.
void log_line(std::FILE* csv, std::int64_t rx_ns, int from_port,
              const std::array<double, telex::local::kUdpSinkChannels>& ch, Counts& counts) {
  int finger = 0, contacts = 0;
  for (int f = 0; f < 5; ++f) {
    if (ch[2 * f] > ch[2 * finger]) finger = f;
    if (ch[10 + f] > 0.5) ++contacts;
  }
  const double pressure = ch[2 * finger];
  if (pressure > 0.0) ++counts.nonzero;
  counts.peak_N = std::max(counts.peak_N, pressure);
  std::fprintf(csv, "%lld,%d,%.3f,%d,%d\n", static_cast<long long>(rx_ns), from_port, pressure,
               finger, contacts);
}

}  // namespace

int main(int argc, char** argv) {
  telex::cli::Program program{
      "telex-sim-display: a UDP haptic display (telex-local --haptics udp:HOST:PORT) that writes "
      "every command it receives to a CSV: rx_ns (CLOCK_REALTIME, the kernel's arrival "
      "stamp),from_port,pressure_N (the "
      "largest of the five fingers),finger,contacts",
      "telex-sim-display"};
  const telex::cli::CommandLine& app = program.command_line();
  std::string listen = "127.0.0.1:1234";
  std::string csv_path;
  double duration_s = 0.0;
  bool append = false;
  app.add_option("--listen", listen, "HOST:PORT to receive on (a numeric IPv4 address)")
      ->capture_default_str();
  app.add_option("--csv", csv_path, "the CSV to write (- for stdout)")->required();
  app.add_flag("--append", append, "append to the CSV instead of starting it afresh");
  telex::cli::add(app, "--duration", duration_s, "exit after this long (0 = until a signal)", "s")
      ->check(telex::cli::Range(0.0, 1e7));
  if (const auto rc = program.parse(argc, argv)) return *rc;

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  int fd = -1;
  std::FILE* csv = nullptr;
  try {
    fd = open_socket(telex::parse_endpoint(listen, "--listen", false));
  } catch (const std::invalid_argument& e) {  // a bad --listen: a usage error
    std::cerr << "telex-sim-display: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "telex-sim-display: " << e.what() << "\n";
    return 1;
  }
  const bool to_stdout = csv_path == "-";
  const bool fresh = !append || ::access(csv_path.c_str(), F_OK) != 0;
  csv = to_stdout ? stdout : std::fopen(csv_path.c_str(), append ? "a" : "w");
  if (!csv) {
    std::cerr << "telex-sim-display: cannot write " << csv_path << ": " << std::strerror(errno)
              << "\n";
    ::close(fd);
    return 1;
  }
  if (to_stdout || fresh) std::fprintf(csv, "rx_ns,from_port,pressure_N,finger,contacts\n");
  std::fflush(csv);
  std::cerr << "telex-sim-display: listening on " << listen << "\n";

  Counts counts;
  const std::int64_t end_ns =
      duration_s > 0 ? realtime_ns() + static_cast<std::int64_t>(duration_s * 1e9) : 0;
  std::array<char, 2048> buf{};
  std::array<double, telex::local::kUdpSinkChannels> ch{};
  std::int64_t flushed_ns = realtime_ns();
  while (!g_stop && (end_ns == 0 || realtime_ns() < end_ns)) {
    // At most 100 ms behind on disk: a script reads the newest commands while this runs.
    if (realtime_ns() - flushed_ns > 100'000'000) {
      std::fflush(csv);
      flushed_ns = realtime_ns();
    }
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    sockaddr_in from{};
    socklen_t from_len = sizeof from;
    iovec iov{buf.data(), buf.size()};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
    msghdr m{};
    m.msg_name = &from;
    m.msg_namelen = from_len;
    m.msg_iov = &iov;
    m.msg_iovlen = 1;
    m.msg_control = control;
    m.msg_controllen = sizeof control;
    const ssize_t n = ::recvmsg(fd, &m, 0);
    if (n < 0) continue;
    std::int64_t rx_ns = realtime_ns();  // if the kernel gave no stamp
    for (cmsghdr* c = CMSG_FIRSTHDR(&m); c != nullptr; c = CMSG_NXTHDR(&m, c))
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        rx_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      }
    ++counts.datagrams;
    if (!telex::local::parse_udp_sink(std::string_view(buf.data(), static_cast<std::size_t>(n)),
                                      ch)) {
      ++counts.malformed;
      continue;
    }
    log_line(csv, rx_ns, ntohs(from.sin_port), ch, counts);
  }
  std::fflush(csv);
  if (!to_stdout) std::fclose(csv);
  ::close(fd);
  std::cerr << "telex-sim-display: " << counts.datagrams << " datagrams, " << counts.malformed
            << " malformed, " << counts.nonzero << " with force, peak " << counts.peak_N << " N\n";
  return 0;
}
