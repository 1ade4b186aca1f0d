// SPDX-License-Identifier: MIT
// Fault tests on both daemons: loss and delay through telex-sim-impair, remote and station killed
// and restarted, junk on every listening port, and bad remote configuration.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <sstream>
#include <thread>

#include "daemons.h"
#include "process.h"
#include "telex/base/periodic.h"
#include "telex/proto/fragment.h"
#include "telex/proto/messages.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

#define TELEX_REQUIRE_REMOTE() TELEX_REQUIRE_BINARIES("telex-remote")

nlohmann::json last_json_line(std::string out) {
  while (!out.empty() && out.back() == '\n') out.pop_back();
  const auto nl = out.rfind('\n');
  return nlohmann::json::parse(nl == std::string::npos ? out : out.substr(nl + 1), nullptr, false);
}

Process start_remote(std::uint16_t port, const std::filesystem::path& dir, const std::string& tag) {
  return Process(
      {built_binary("telex-remote").string(), "--listen", "127.0.0.1:" + std::to_string(port),
       "--transport", "udp", "--source", "synthetic:plane", "--stats", "full"},
      dir / ("remote" + tag + ".out"), dir / ("remote" + tag + ".err"));
}

std::vector<std::string> local_argv(std::uint16_t port, std::vector<std::string> extra) {
  std::vector<std::string> a{built_binary("telex-local").string(),
                             "--connect",
                             "127.0.0.1:" + std::to_string(port),
                             "--haptics",
                             "sim",
                             "--no-realtime",
                             "--quiet",
                             "--json-summary",
                             "--first-surface-timeout",
                             "20"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

class LossThroughProxy : public ::testing::TestWithParam<double> {};

// The depth stream through telex-sim-impair at a loss rate p. The station publishes a frame when
// its manifest arrives (missing tiles keep their last value, PROTOCOL.md 2.3), so of the F frames
// the remote sent, F (1-p)^m arrive, m being the manifest's fragments; the bound is that less
// 4 binomial sd. The station builds a surface of nearly every frame it gets. What the station's
// reassembler counts as lost agrees with what the proxy dropped.
TEST_P(LossThroughProxy, SurfaceRateFollowsTheLossAndTheStationCountsWhatTheProxyDropped) {
  TELEX_REQUIRE_REMOTE();
  const double loss = GetParam();
  const auto dir = scratch_dir("loss_" + std::to_string(static_cast<int>(loss * 100)));
  const auto port = free_port(), udp_port = free_port(), proxy_port = free_port();
  Process remote = start_remote(port, dir, "");
  Process proxy({built_binary("telex-sim-impair").string(), "--listen",
                 "127.0.0.1:" + std::to_string(proxy_port), "--forward",
                 "127.0.0.1:" + std::to_string(udp_port), "--loss", std::to_string(loss),
                 "--delay-ms", "50", "--seed", "7", "--json-summary"},
                dir / "proxy.out", dir / "proxy.err");
  Process local(
      local_argv(port, {"--udp-port", std::to_string(udp_port), "--udp-announce-port",
                        std::to_string(proxy_port), "--hand", "script:press", "--duration", "5"}),
      dir / "local.out", dir / "local.err");
  const auto rc = local.wait(45s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_TRUE(remote.running()) << remote.stderr_text();
  // The remote stops sending when the station says Bye; its next stats line has the total.
  std::this_thread::sleep_for(1500ms);
  proxy.signal(SIGINT);
  ASSERT_TRUE(proxy.wait(10s).has_value());
  const auto s = last_json_line(local.stdout_text());
  ASSERT_TRUE(s.is_object()) << local.stdout_text();
  EXPECT_EQ(path_scheduling_problem(s, /*realtime=*/false), "");  // --no-realtime
  const auto j = last_json_line(proxy.stdout_text());
  ASSERT_TRUE(j.is_object()) << proxy.stdout_text();
  const auto& up = j["client_to_server"];
  const double received = up["received"].get<double>(), dropped = up["dropped"].get<double>(),
               delivered = up["delivered"].get<double>();
  ASSERT_GT(received, 100) << "the depth stream did not go through the proxy";
  // The proxy's own loss: binomial, 5 sd plus one datagram.
  EXPECT_NEAR(dropped, loss * received, 5 * std::sqrt(received * loss * (1 - loss)) + 1);

  // Frames: the manifest of a full frame of the synthetic plane (640x480 in 80x60 tiles).
  proto::FrameManifest full;
  full.tile_count = 64;
  for (std::uint16_t t = 0; t < 64; ++t) full.changed_tiles.push_back(t);
  const auto manifest_bytes = proto::encode(proto::Header{}, full).size();
  const double m = std::ceil(static_cast<double>(manifest_bytes) / proto::kFragmentChunkBytes);
  const double sent = static_cast<double>(last_counter(remote.stderr_text(), "frames-sent"));
  ASSERT_GT(sent, 60 / kSanitizerSlowdown) << remote.stderr_text();
  const double q = std::pow(1 - loss, m);
  const double min_frames = sent * q - 4 * std::sqrt(sent * q * (1 - q)) - 2;
  const double frames = s["frames"].get<double>(), surfaces = s["surfaces"].get<double>();
  EXPECT_GE(frames, min_frames) << sent << " frames sent, manifest of " << m << " fragment(s)";
  EXPECT_LE(frames, sent);
  EXPECT_GE(surfaces, 0.8 * min_frames) << frames << " frames";

  // The station's count: datagrams in are what the proxy delivered (less what was still in
  // flight when the station closed its socket). What its reassembler knows was lost counts a
  // message lost whole as one datagram: of the S_n messages of n fragments it saw, S_n / (1-p^n)
  // were sent and S_n p^n / (1-p^n) lost whole, n - 1 datagrams each unseen. With that added, the
  // station's loss is the proxy's, within 5 binomial sd.
  const double in = s["udp_datagrams"].get<double>(), lost = s["udp_lost"].get<double>();
  EXPECT_LE(in, delivered);
  EXPECT_GE(in, delivered - 0.02 * delivered - 50) << "delivered " << delivered;
  const auto by_n = s["udp_messages_by_fragments"].get<std::vector<double>>();
  ASSERT_EQ(by_n.size(), 8u);
  double unseen_whole = 0;
  for (std::size_t k = 1; k < 7; ++k) {  // n = k + 1 fragments (the last bin is open-ended)
    const double n = static_cast<double>(k + 1), pn = std::pow(loss, n);
    unseen_whole += by_n[k] * pn / (1 - pn) * (n - 1);
  }
  EXPECT_EQ(by_n[7], 0) << "messages of 8 or more fragments: no bound derived for them";
  const double sd = std::sqrt(received * loss * (1 - loss));
  EXPECT_LE(lost, dropped) << "dropped by the proxy " << dropped;
  EXPECT_NEAR(lost + unseen_whole, dropped, 5 * sd + 10)
      << "station counted " << lost << " + " << unseen_whole << " lost whole; proxy dropped "
      << dropped;
  remote.signal(SIGINT);
  remote.wait(5s);
}

INSTANTIATE_TEST_SUITE_P(Faults, LossThroughProxy, ::testing::Values(0.05, 0.20));

// Repair (docs/PROTOCOL.md 2.5) through telex-sim-impair at 10 % loss and 20 ms delay. The scene
// is the still plane without noise, so after the key frame the remote sends a tile only when
// asked: a tile lost under the fingertip stays stale until the next key frame (30 frames) unless
// the station's TileNack brings it back. With repair the fingertip windows' tiles are at most two
// frame periods old at p99 (sampled at every closed frame); without it they are older, so the
// measure can tell.
struct RepairRun {
  nlohmann::json station;
  std::string remote_log;
};

RepairRun run_repair(bool repair, const std::string& loss, const std::string& name) {
  const auto dir = scratch_dir(name);
  const auto port = free_port(), udp_port = free_port(), proxy_port = free_port();
  Process remote(
      {built_binary("telex-remote").string(), "--listen", "127.0.0.1:" + std::to_string(port),
       "--transport", "udp", "--source", "synthetic:plane,noise=off", "--stats", "full"},
      dir / "remote.out", dir / "remote.err");
  Process proxy(
      {built_binary("telex-sim-impair").string(), "--listen",
       "127.0.0.1:" + std::to_string(proxy_port), "--forward",
       "127.0.0.1:" + std::to_string(udp_port), "--loss", loss, "--delay-ms", "20", "--seed", "11"},
      dir / "proxy.out", dir / "proxy.err");
  std::vector<std::string> extra{"--udp-port",
                                 std::to_string(udp_port),
                                 "--udp-announce-port",
                                 std::to_string(proxy_port),
                                 "--hand",
                                 "script:press",
                                 "--repeat",
                                 "--duration",
                                 "8"};
  if (!repair) extra.push_back("--no-repair");
  Process local(local_argv(port, extra), dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  EXPECT_TRUE(rc.has_value()) << "telex-local did not finish";
  EXPECT_EQ(rc.value_or(-1), 0) << local.stderr_text();
  std::this_thread::sleep_for(1200ms);  // the remote's next stats line
  proxy.signal(SIGINT);
  remote.signal(SIGINT);
  remote.wait(5s);
  proxy.wait(5s);
  return {last_json_line(local.stdout_text()), remote.stderr_text()};
}

TEST(Repair, LostFingertipTilesAreRepairedWithinTwoFramePeriods) {
  TELEX_REQUIRE_REMOTE();
  const RepairRun on = run_repair(true, "0.10", "repair_on");
  const auto& s = on.station;
  ASSERT_TRUE(s.is_object());
  ASSERT_GT(s["udp_lost"].get<double>(), 0) << "the proxy lost nothing";
  ASSERT_GT(s["tile_age_watched_samples"].get<double>(), 100 / kSanitizerSlowdown)
      << "no fingertip window was watched";
  EXPECT_GT(s["nacks"].get<double>(), 0);
  EXPECT_GT(s["watched_tiles_nacked"].get<double>(), 0) << "no fingertip tile was lost";
  EXPECT_GT(s["tiles_repaired"].get<double>(), 0);
  EXPECT_LE(s["tile_age_watched_p99_frames"].get<double>(), 2.0) << s.dump();
  // The remote answered every NACK it got from its cache.
  EXPECT_GT(last_counter(on.remote_log, "nacks"), 0) << on.remote_log;
  EXPECT_GT(last_counter(on.remote_log, "repaired"), 0);
  EXPECT_EQ(last_counter(on.remote_log, "unavailable"), 0);

  // The control, at 20 % loss so that a short run surely loses fingertip tiles: without repair
  // they wait for the next key frame, and the age measured shows it.
  const RepairRun off = run_repair(false, "0.20", "repair_off");
  ASSERT_TRUE(off.station.is_object());
  EXPECT_EQ(off.station["nacks"].get<double>(), 0);
  EXPECT_EQ(last_counter(off.remote_log, "nacks"), 0);
  EXPECT_GT(off.station["tile_age_watched_p99_frames"].get<double>(), 4.0)
      << "without repair the fingertip tiles were not older: the test shows nothing";
}

struct Row {
  double t = 0, pressure = 0;
  std::string status;
};

std::vector<Row> index_rows(const std::filesystem::path& csv) {
  std::vector<Row> rows;
  const CsvFile table = read_csv_file(csv);
  for (const auto& f : table.rows) {
    if (f.size() < 10 || f[1] != "index") continue;
    rows.push_back({std::stod(f[0]), std::stod(f[2]), f[9]});
  }
  return rows;
}

// Waits until the station streams, then `for_s` more. False when it never streamed.
bool streams_for(Process& local, std::chrono::seconds for_s) {
  if (!eventually(
          20s, [&] { return local.stderr_text().find("remote streaming") != std::string::npos; }))
    return false;
  std::this_thread::sleep_for(for_s);
  return true;
}

// The first row from `from` on where `pred` holds; rows.size() when none does.
template <typename Pred>
std::size_t first_row(const std::vector<Row>& rows, std::size_t from, Pred pred) {
  while (from < rows.size() && !pred(rows[from])) ++from;
  return from;
}
bool zero(const Row& r) { return r.pressure == 0.0; }
bool stale(const Row& r) { return r.status == "stale-surface"; }

// The remote is killed mid-session. On the forces log's time base (the summary's
// log_origin_monotonic_ns): no stale row before the kill, the force zero as soon as the session's
// end is known (before the surface is stale), then the surface goes stale within the
// stale limit, the force fades steadily (never rising) to zero within the fade time and stays
// zero until the restarted remote's surfaces arrive.
TEST(RemoteRestart, ForcesFadeWithinTheStaleLimitAndTheStationReconnects) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("remote_restart");
  const auto port = free_port();
  constexpr double kStaleLimit = 0.5, kFadeOut = 0.1;  // --stale-limit; HapticParams::fade_out_s
  auto remote = std::make_unique<Process>(start_remote(port, dir, "1"));
  Process local(
      local_argv(port, {"--hand", "script:press", "--repeat", "--duration", "14", "--stiffness",
                        "500", "--max-force", "10", "--stale-limit", std::to_string(kStaleLimit),
                        "--log-forces", (dir / "forces.csv").string()}),
      dir / "local.out", dir / "local.err");
  ASSERT_TRUE(streams_for(local, 4s)) << local.stderr_text();
  remote->signal(SIGKILL);
  const std::int64_t killed_ns = monotonic_ns();
  remote->wait(5s);
  std::this_thread::sleep_for(1.5s);
  const std::int64_t restarted_ns = monotonic_ns();
  remote = std::make_unique<Process>(start_remote(port, dir, "2"));
  const auto rc = local.wait(40s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_TRUE(remote->running()) << remote->stderr_text();
  const auto summary = last_json_line(local.stdout_text());
  ASSERT_TRUE(summary.is_object()) << local.stdout_text();
  const auto origin = summary["log_origin_monotonic_ns"].get<std::int64_t>();
  const double t_kill = static_cast<double>(killed_ns - origin) / 1e9;
  const double t_restart = static_cast<double>(restarted_ns - origin) / 1e9;

  const auto rows = index_rows(dir / "forces.csv");
  ASSERT_GT(rows.size(), 1000u);
  ASSERT_LT(rows.front().t, t_kill - 2.0) << "the log starts too late";
  // Before the kill: every row on a fresh surface, and the press touched the plane.
  double peak_before = 0;
  std::size_t i = 0;
  for (; i < rows.size() && rows[i].t < t_kill; ++i) {
    EXPECT_NE(rows[i].status, "stale-surface")
        << "force dropout at " << rows[i].t << " s, " << t_kill - rows[i].t << " s before the kill";
    EXPECT_NE(rows[i].status, "no-surface") << rows[i].t;
    peak_before = std::max(peak_before, rows[i].pressure);
  }
  EXPECT_GT(peak_before, 0.5) << "the press never touched the plane before the kill";
  // Stale within the stale limit of the kill (the last surface is at most that old then).
  const std::size_t first_stale = first_row(rows, i, stale);
  ASSERT_LT(first_stale, rows.size()) << "forces never went stale after the remote was killed";
  // Before that the link's end zeroed the force at once (--link-silence-ms): the closed session
  // is known long before the surface is stale, and from then on nothing presses.
  const std::size_t first_zero = first_row(rows, i, zero);
  EXPECT_LT(first_zero, first_stale) << "the force waited for the stale limit";
  for (std::size_t k = first_zero; k < first_stale; ++k)
    ASSERT_EQ(rows[k].pressure, 0.0) << "force again " << rows[k].t - t_kill << " s after the kill";
  EXPECT_GT(summary["ticks_link_silent"].get<std::uint64_t>(), 0u);
  EXPECT_LE(rows[first_stale].t, t_kill + kStaleLimit + 0.05) << "kill at " << t_kill << " s";
  // A steady fade: under a linear ramp to zero within the fade time, zero until the remote is back.
  std::size_t recovered = rows.size();
  for (std::size_t k = first_stale; k < rows.size(); ++k) {
    if (rows[k].status != "stale-surface") {
      recovered = k;
      break;
    }
    // The gain falls linearly over the fade time while the scripted finger may still press in,
    // so the force stays under the peak press times the remaining gain.
    const double tau = rows[k].t - rows[first_stale].t;
    ASSERT_LE(rows[k].pressure, peak_before * std::max(0.0, 1.0 - tau / kFadeOut) + 0.05)
        << "force above the fade " << tau << " s after going stale";
    if (rows[k].t > rows[first_stale].t + kFadeOut + 0.01) {
      ASSERT_EQ(rows[k].pressure, 0.0)
          << "force not zero " << rows[k].t - rows[first_stale].t << " s after going stale";
    }
  }
  ASSERT_LT(recovered, rows.size()) << "no fresh surface after the remote came back";
  // The outage lasts until the restart at least, and ends within 2 s of it (back-off is at most
  // 1 s; 1 s more for a loaded machine).
  EXPECT_GT(rows[recovered].t, t_restart) << "fresh surface while the remote was down";
  EXPECT_LT(rows[recovered].t, t_restart + 2.0) << "restart at " << t_restart << " s";
  remote->signal(SIGINT);
  remote->wait(5s);
}

// The remote hangs (SIGSTOP: no end of session, no more messages) for 1.5 s and goes on. The
// station's probes go unanswered, so the force is zero from the link's silence on (35 ms,
// --link-silence-ms) while the last surface is still fresh (--stale-limit 0.5 s): zero rows come
// first, stale ones only after them, nothing presses until the remote speaks again, and then the
// press comes back on the same session.
TEST(RemoteHang, AStoppedRemoteZeroesTheForceBeforeTheSurfaceIsStale) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("remote_hang");
  const auto port = free_port();
  Process remote = start_remote(port, dir, "");
  // The index finger 1 cm into the plane (0.8 m) from 0.5 s on, held: a steady 5 N press.
  const auto script = dir / "hold.script";
  std::ofstream(script)
      << "time_s finger x_m y_m z_m\n0 1 0 0 0.6\n0.5 1 0 0 0.81\n60 1 0 0 0.81\n";
  Process local(local_argv(port, {"--hand", "script:" + script.string(), "--duration", "9",
                                  "--stiffness", "500", "--max-force", "10", "--stale-limit", "0.5",
                                  "--log-forces", (dir / "forces.csv").string()}),
                dir / "local.out", dir / "local.err");
  ASSERT_TRUE(streams_for(local, 4s)) << local.stderr_text();
  remote.signal(SIGSTOP);
  const std::int64_t stopped_ns = monotonic_ns();
  std::this_thread::sleep_for(1.5s);
  remote.signal(SIGCONT);
  const std::int64_t resumed_ns = monotonic_ns();
  const auto rc = local.wait(30s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  const auto summary = last_json_line(local.stdout_text());
  ASSERT_TRUE(summary.is_object()) << local.stdout_text();
  EXPECT_GT(summary["ticks_link_silent"].get<std::uint64_t>(), 0u);
  const auto origin = summary["log_origin_monotonic_ns"].get<std::int64_t>();
  const double t_stop = static_cast<double>(stopped_ns - origin) / 1e9;
  const double t_resume = static_cast<double>(resumed_ns - origin) / 1e9;
  const auto rows = index_rows(dir / "forces.csv");
  std::size_t i = 0;
  double peak_before = 0;
  for (; i < rows.size() && rows[i].t < t_stop; ++i)
    peak_before = std::max(peak_before, rows[i].pressure);
  EXPECT_GT(peak_before, 0.5) << "the press never touched the plane before the hang";
  const std::size_t first_zero = first_row(rows, i, zero);
  const std::size_t first_stale = first_row(rows, i, stale);
  ASSERT_LT(first_stale, rows.size()) << "the surface never went stale in a 1.5 s hang";
  EXPECT_LT(first_zero, first_stale) << "the force waited for the stale limit";
  // Nothing presses from the first zero until the remote was let go.
  std::size_t k = first_zero;
  for (; k < rows.size() && rows[k].t < t_resume; ++k)
    ASSERT_EQ(rows[k].pressure, 0.0) << "force " << rows[k].t - t_stop << " s into the hang";
  double peak_after = 0;
  for (; k < rows.size(); ++k) peak_after = std::max(peak_after, rows[k].pressure);
  EXPECT_GT(peak_after, 0.5) << "the press did not come back after the hang";
  remote.signal(SIGINT);
  remote.wait(5s);
}

TEST(StationRestart, RemoteAcceptsTheStationAgainAfterSigkill) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("station_restart");
  const auto port = free_port();
  Process remote = start_remote(port, dir, "");
  {
    Process first(local_argv(port, {"--hand", "script:press", "--duration", "20"}),
                  dir / "local1.out", dir / "local1.err");
    ASSERT_TRUE(eventually(20s, [&] {
      return first.stderr_text().find("remote streaming") != std::string::npos;
    })) << first.stderr_text();
    std::this_thread::sleep_for(1s);
    first.signal(SIGKILL);
    first.wait(5s);
  }
  Process second(local_argv(port, {"--hand", "script:press", "--duration", "3"}),
                 dir / "local2.out", dir / "local2.err");
  const auto rc = second.wait(40s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << second.stderr_text() << remote.stderr_text();
  const auto s = last_json_line(second.stdout_text());
  ASSERT_TRUE(s.is_object()) << second.stdout_text();
  EXPECT_GT(s["surfaces"].get<int>(), 0);
  EXPECT_TRUE(remote.running());
  remote.signal(SIGINT);
  remote.wait(5s);
}

// A bounded menu of hostile inputs: random, truncated, oversize length, wrong magic, wrong
// version, a well-formed message of a foreign session.
std::vector<std::uint8_t> junk(int kind, std::mt19937& rng, bool stream) {
  std::vector<std::uint8_t> m;
  proto::Header h;
  h.session_id = 0xBADBAD;
  h.seq = static_cast<std::uint32_t>(rng());
  switch (kind % 6) {
    case 0:
      m.resize(1 + rng() % 1500);
      for (auto& b : m) b = static_cast<std::uint8_t>(rng());
      return m;
    case 1:
      m = proto::encode_stream(h, proto::Heartbeat{1, 2, 3, 4});
      m.resize(rng() % m.size());
      return m;
    case 2:
      m = {0xFF, 0xFF, 0xFF, 0x7F};  // a 2 GiB length prefix
      return m;
    case 3:
      h.magic = 0x58585858u;
      break;
    case 4:
      h.version = 99;
      break;
    default:
      break;  // valid bytes, wrong session
  }
  return stream ? proto::encode_stream(h, proto::Heartbeat{1, 2, 3, 4})
                : proto::encode(h, proto::Heartbeat{1, 2, 3, 4});
}

TEST(BadInput, DaemonsStayUpAndKeepServingTheRealSession) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("bad_input");
  const auto port = free_port(), udp_port = free_port();
  Process remote = start_remote(port, dir, "");
  ASSERT_TRUE(eventually(10s, [&] {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port);
    const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(fd);
    return ok;
  }));
  std::atomic<bool> stop{false};
  std::atomic<int> sent{0};
  // Junk to the remote's TCP and UDP port and the station's UDP port, bounded in count and rate.
  std::thread attacker([&] {
    std::mt19937 rng(1234);
    for (int i = 0; i < 3000 && !stop; ++i) {
      tcp_blurt(port, junk(i, rng, true));
      udp_blurt(port, junk(i, rng, false));
      udp_blurt(udp_port, junk(i, rng, false));
      ++sent;
      if (i % 20 == 19) std::this_thread::sleep_for(10ms);
    }
  });
  Process local(local_argv(port, {"--udp-port", std::to_string(udp_port), "--hand", "script:press",
                                  "--duration", "5"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(45s);
  stop = true;
  attacker.join();
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_GT(sent.load(), 100);
  const auto s = last_json_line(local.stdout_text());
  ASSERT_TRUE(s.is_object()) << local.stdout_text();
  EXPECT_GT(s["surfaces"].get<int>(), 30);
  EXPECT_TRUE(remote.running()) << remote.stderr_text();
  remote.signal(SIGINT);
  const auto rrc = remote.wait(10s);
  ASSERT_TRUE(rrc.has_value());
  EXPECT_EQ(*rrc, 0) << remote.stderr_text();
}

TEST(RemoteConfig, BadConfigurationExitsTwo) {
  TELEX_REQUIRE_REMOTE();
  const auto dir = scratch_dir("remote_bad_config");
  // A TCP listener holding a port makes --listen on it fail.
  const int busy = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(busy, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(listen(busy, 1), 0);
  socklen_t len = sizeof a;
  getsockname(busy, reinterpret_cast<sockaddr*>(&a), &len);
  const std::string busy_port = std::to_string(ntohs(a.sin_port));
  const std::vector<std::vector<std::string>> runs{
      {"--no-such-flag"},
      {"--listen", "127.0.0.1:99999"},
      {"--listen", "127.0.0.1:" + busy_port, "--source", "synthetic:plane"},
      {"--transport", "carrier-pigeon"},
  };
  for (std::size_t i = 0; i < runs.size(); ++i) {
    std::vector<std::string> argv{built_binary("telex-remote").string()};
    argv.insert(argv.end(), runs[i].begin(), runs[i].end());
    Process p(argv, dir / ("out" + std::to_string(i)), dir / ("err" + std::to_string(i)));
    const auto rc = p.wait(10s);
    ASSERT_TRUE(rc.has_value()) << "run " << i << " did not exit";
    EXPECT_EQ(*rc, 2) << "run " << i << ": " << p.stderr_text();
    EXPECT_FALSE(p.stderr_text().empty()) << "run " << i << " gave no message";
  }
  close(busy);
}

}  // namespace
}  // namespace telex::test
