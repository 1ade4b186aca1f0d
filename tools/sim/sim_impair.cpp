// SPDX-License-Identifier: MIT
// telex-sim-impair: a UDP proxy that applies a rate limit and seeded loss, delay, jitter, reorder,
// dup and corruption.

// Boost 1.74's asio.hpp uses std::exchange without including <utility>: it comes first.
// clang-format off
#include <utility>
// clang-format on
#include <array>
#include <boost/asio.hpp>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>

#include "telex/cli/command_line.h"
#include "telex/common/endpoint.h"
#include "telex/sim/impairment.h"

namespace asio = boost::asio;
using asio::ip::udp;
using telex::sim::Impairment;
using telex::sim::ImpairmentConfig;
using telex::sim::ImpairmentCounters;

namespace {

std::int64_t monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// HOST:PORT with a numeric IPv4/IPv6 address ([::1]:PORT); throws std::invalid_argument naming
// the flag.
udp::endpoint parse_udp_endpoint(const std::string& s, const char* flag, bool port_zero_ok) {
  const telex::Endpoint e = telex::parse_endpoint(s, flag, port_zero_ok);
  boost::system::error_code ec;
  const auto addr = asio::ip::make_address(e.host, ec);
  if (ec)
    throw std::invalid_argument(std::string(flag) + ": '" + e.host +
                                "' is not a numeric IP address");
  return {addr, e.port};
}

nlohmann::json to_json(const ImpairmentCounters& c) {
  return {{"received", c.received},         {"dropped", c.dropped},
          {"delivered", c.delivered},       {"reordered", c.reordered},
          {"duplicated", c.duplicated},     {"corrupted", c.corrupted},
          {"bytes_in", c.bytes_in},         {"bytes_out", c.bytes_out},
          {"rate_dropped", c.rate_dropped}, {"rate_queued", c.rate_queued}};
}

// Two sockets, two independent impairments, one timer queue. Single-threaded: every handler runs
// on the io_context thread, so nothing here needs a lock.
class Proxy {
 public:
  Proxy(asio::io_context& io, udp::endpoint listen, udp::endpoint forward,
        const ImpairmentConfig& config)
      : listen_sock_(io),
        upstream_sock_(io),
        timer_(io),
        forward_(forward),
        to_server_(config),
        to_client_([&] {
          ImpairmentConfig back = config;
          back.seed = config.seed ^ 0x5bd1e995u;  // the return path gets its own stream
          return back;
        }()) {
    open(listen_sock_, listen, "--listen");
    open(upstream_sock_,
         udp::endpoint(forward.protocol() == udp::v4()
                           ? asio::ip::address(asio::ip::address_v4::any())
                           : asio::ip::address(asio::ip::address_v6::any()),
                       0),
         "upstream");
  }

  udp::endpoint listen_endpoint() const { return listen_sock_.local_endpoint(); }

  void start() {
    receive_listen();
    receive_upstream();
  }

  nlohmann::json summary() const {
    return {{"client_to_server", to_json(to_server_.counters())},
            {"server_to_client", to_json(to_client_.counters())},
            {"sent", sent_},
            {"send_errors", send_errors_},
            {"foreign", foreign_},
            {"no_client", no_client_},
            {"client_changes", client_changes_},
            {"rate_limit_mbit", to_server_.config().rate_limit_mbit},
            {"pending", queue_.size()}};
  }

  std::string status() const {
    return "to-server " + telex::sim::to_string(to_server_.counters()) + " | to-client " +
           telex::sim::to_string(to_client_.counters()) + " | sent=" + std::to_string(sent_) +
           " send_errors=" + std::to_string(send_errors_) + " foreign=" + std::to_string(foreign_);
  }

 private:
  enum class Dir : std::uint8_t { ToServer, ToClient };
  struct Pending {
    Dir dir;
    std::vector<std::uint8_t> bytes;
  };

  static void open(udp::socket& s, const udp::endpoint& ep, const char* what) {
    s.open(ep.protocol());
    s.set_option(asio::socket_base::receive_buffer_size(4 << 20));
    s.set_option(asio::socket_base::send_buffer_size(4 << 20));
    boost::system::error_code ec;
    s.bind(ep, ec);
    if (ec)
      throw std::runtime_error(std::string("cannot bind ") + what + " " + ep.address().to_string() +
                               ":" + std::to_string(ep.port()) + ": " + ec.message());
  }

  void receive_listen() {
    listen_sock_.async_receive_from(
        asio::buffer(listen_buf_), listen_from_,
        [this](boost::system::error_code ec, std::size_t n) {
          if (ec == asio::error::operation_aborted) return;
          if (!ec) {
            // The client is whoever spoke last: a restarted sender (new ephemeral port) is
            // followed instead of being cut off.
            if (!client_ || *client_ != listen_from_) {
              if (client_) ++client_changes_;
              client_ = listen_from_;
            }
            enqueue(Dir::ToServer, to_server_.process({listen_buf_.data(), n}, monotonic_ns()));
          }
          receive_listen();
        });
  }

  void receive_upstream() {
    upstream_sock_.async_receive_from(
        asio::buffer(upstream_buf_), upstream_from_,
        [this](boost::system::error_code ec, std::size_t n) {
          if (ec == asio::error::operation_aborted) return;
          if (!ec) {
            if (upstream_from_ != forward_)
              ++foreign_;
            else
              enqueue(Dir::ToClient, to_client_.process({upstream_buf_.data(), n}, monotonic_ns()));
          }
          receive_upstream();
        });
  }

  void enqueue(Dir dir, std::vector<telex::sim::Delivery> deliveries) {
    for (auto& d : deliveries) queue_.emplace(d.deliver_at_ns, Pending{dir, std::move(d.bytes)});
    flush();
  }

  // Sends everything due and re-arms the timer for the next one. multimap keeps equal times in
  // insertion order, so duplicates follow their original.
  void flush() {
    const std::int64_t now = monotonic_ns();
    while (!queue_.empty() && queue_.begin()->first <= now) {
      auto node = queue_.extract(queue_.begin());
      send(node.mapped());
    }
    if (queue_.empty()) return;
    const std::int64_t next = queue_.begin()->first;
    if (armed_for_ && *armed_for_ == next) return;
    armed_for_ = next;
    timer_.expires_after(std::chrono::nanoseconds(next - now));
    timer_.async_wait([this](boost::system::error_code ec) {
      if (ec == asio::error::operation_aborted) return;
      armed_for_.reset();
      flush();
    });
  }

  void send(const Pending& p) {
    boost::system::error_code ec;
    if (p.dir == Dir::ToServer) {
      upstream_sock_.send_to(asio::buffer(p.bytes), forward_, 0, ec);
    } else {
      if (!client_) {
        ++no_client_;
        return;
      }
      listen_sock_.send_to(asio::buffer(p.bytes), *client_, 0, ec);
    }
    // ICMP port unreachable from a peer that is down shows up here; count it and go on.
    if (ec)
      ++send_errors_;
    else
      ++sent_;
  }

  udp::socket listen_sock_;
  udp::socket upstream_sock_;
  asio::steady_timer timer_;
  std::optional<std::int64_t> armed_for_;
  udp::endpoint forward_;
  std::optional<udp::endpoint> client_;
  udp::endpoint listen_from_, upstream_from_;
  std::array<std::uint8_t, 65536> listen_buf_{};
  std::array<std::uint8_t, 65536> upstream_buf_{};
  Impairment to_server_, to_client_;
  std::multimap<std::int64_t, Pending> queue_;
  std::uint64_t sent_ = 0, send_errors_ = 0, foreign_ = 0, no_client_ = 0, client_changes_ = 0;
};

// The link's impairments (ImpairmentConfig), each flag with its range.
void add_impairment_options(const telex::cli::CommandLine& app, ImpairmentConfig& cfg) {
  app.add_option("--loss", cfg.loss, "loss probability per datagram")
      ->check(telex::cli::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--delay-ms", cfg.delay_ms, "one-way delay, ms")
      ->check(telex::cli::Range(0.0, 60000.0))
      ->capture_default_str();
  app.add_option("--jitter-ms", cfg.jitter_ms, "uniform jitter +-ms around the delay (order kept)")
      ->check(telex::cli::Range(0.0, 60000.0))
      ->capture_default_str();
  app.add_option("--reorder", cfg.reorder, "probability that a datagram is held back")
      ->check(telex::cli::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--reorder-hold-ms", cfg.reorder_hold_ms, "how long a reordered one is held, ms")
      ->check(telex::cli::Range(0.0, 60000.0))
      ->capture_default_str();
  app.add_option("--duplicate", cfg.duplicate, "duplication probability")
      ->check(telex::cli::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--corrupt", cfg.corrupt, "probability of flipping one random bit")
      ->check(telex::cli::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--seed", cfg.seed, "random seed")->capture_default_str();
  app.add_option("--rate-limit-mbit", cfg.rate_limit_mbit,
                 "rate limit each way, Mbit/s (10^6 bit/s; 0 = none): a token bucket in front of "
                 "a bounded queue, datagrams beyond it dropped (rate_dropped)")
      ->check(telex::cli::Range(0.0, 100000.0))
      ->capture_default_str();
  app.add_option("--rate-burst-bytes", cfg.rate_burst_bytes,
                 "the rate limit's token bucket: bytes that may pass at once")
      ->check(telex::cli::Range(1.0, 1e9))
      ->capture_default_str();
  app.add_option("--rate-queue-ms", cfg.rate_queue_ms,
                 "the rate limit's queue: the longest a datagram waits for tokens, ms; longer "
                 "waits are drops")
      ->check(telex::cli::Range(0.0, 60000.0))
      ->capture_default_str();
  app.add_option("--rate-limit-from-s", cfg.rate_limit_from_s,
                 "the rate limit holds from this many seconds after the first datagram")
      ->check(telex::cli::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--rate-limit-until-s", cfg.rate_limit_until_s,
                 "... until this many (0 = to the end); must be above --rate-limit-from-s")
      ->check(telex::cli::Range(0.0, 1e7))
      ->capture_default_str();
}

}  // namespace

int main(int argc, char** argv) {
  telex::cli::Program program{
      "telex-sim-impair: UDP proxy between a sender and --forward that applies a rate limit and "
      "seeded loss, delay, jitter, reordering, duplication and bit corruption (both directions), "
      "since tc netem is not available here",
      "telex-sim-impair"};
  const telex::cli::CommandLine& app = program.command_line();
  std::string listen_text, forward_text;
  ImpairmentConfig cfg;
  double duration_s = 0.0, stats_every_s = 0.0;
  bool json = false;
  app.add_option("--listen", listen_text, "HOST:PORT to receive on (port 0 = any free port)")
      ->required();
  app.add_option("--forward", forward_text, "HOST:PORT to forward to")->required();
  add_impairment_options(app, cfg);
  app.add_option("--duration", duration_s, "exit after this many seconds (0 = until a signal)")
      ->check(telex::cli::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--stats-every", stats_every_s, "print counters on stderr every S seconds (0 off)")
      ->check(telex::cli::Range(0.0, 86400.0))
      ->capture_default_str();
  app.add_flag("--json-summary", json, "print the final counters as JSON on stdout");
  udp::endpoint listen_ep, forward_ep;
  if (const auto rc = program.parse(argc, argv)) return *rc;
  try {
    listen_ep = parse_udp_endpoint(listen_text, "--listen", true);
    forward_ep = parse_udp_endpoint(forward_text, "--forward", false);
    if (cfg.rate_limit_until_s != 0.0 && cfg.rate_limit_until_s <= cfg.rate_limit_from_s)
      throw std::invalid_argument("--rate-limit-until-s: must be 0 or above --rate-limit-from-s");
  } catch (const std::invalid_argument& e) {
    std::cerr << "telex-sim-impair: " << e.what() << "\n";
    return telex::cli::kUsageExit;
  }

  try {
    asio::io_context io;
    Proxy proxy(io, listen_ep, forward_ep, cfg);
    proxy.start();
    const auto bound = proxy.listen_endpoint();
    std::fprintf(stderr,
                 "telex-sim-impair: listening on %s:%u, forwarding to %s:%u (loss %.3f, delay %.1f "
                 "ms, jitter %.1f ms, reorder %.3f, duplicate %.3f, corrupt %.3f, rate limit %.3f "
                 "Mbit/s, seed %llu)\n",
                 bound.address().to_string().c_str(), bound.port(),
                 forward_ep.address().to_string().c_str(), forward_ep.port(), cfg.loss,
                 cfg.delay_ms, cfg.jitter_ms, cfg.reorder, cfg.duplicate, cfg.corrupt,
                 cfg.rate_limit_mbit, static_cast<unsigned long long>(cfg.seed));

    asio::signal_set signals(io, SIGINT, SIGTERM);
    signals.async_wait([&](boost::system::error_code ec, int) {
      if (!ec) io.stop();
    });
    asio::steady_timer end_timer(io);
    if (duration_s > 0) {
      end_timer.expires_after(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double>(duration_s)));
      end_timer.async_wait([&](boost::system::error_code ec) {
        if (!ec) io.stop();
      });
    }
    asio::steady_timer stats_timer(io);
    std::function<void()> arm_stats = [&] {
      stats_timer.expires_after(std::chrono::duration_cast<std::chrono::nanoseconds>(
          std::chrono::duration<double>(stats_every_s)));
      stats_timer.async_wait([&](boost::system::error_code ec) {
        if (ec) return;
        std::fprintf(stderr, "telex-sim-impair: %s\n", proxy.status().c_str());
        arm_stats();
      });
    };
    if (stats_every_s > 0) arm_stats();
    io.run();
    std::fprintf(stderr, "telex-sim-impair: done: %s\n", proxy.status().c_str());
    if (json) std::cout << proxy.summary().dump() << std::endl;
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "telex-sim-impair: error: %s\n", e.what());
    return 2;
  }
}
