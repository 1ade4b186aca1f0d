// SPDX-License-Identifier: MIT
// The link against peers without the key (issue 49), both daemons as processes: a
// certificate-only TLS 1.3 impostor at the station and at the remote, an idle connection that
// must not hold the operator's slot, a crowd of idle and half-open connections under a
// descriptor limit, and an accept loop that backs off when the descriptors run out.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "daemons.h"
#include "process.h"
#include "telex/proto/auth.h"
#include "test_support.h"
#include "tls_peers.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

std::string new_key(const std::filesystem::path& dir) {
  const auto p = dir / "telex.key";
  proto::write_new_key_file(p);
  return p.string();
}

bool have_openssl() { return std::system("openssl version > /dev/null 2>&1") == 0; }

std::size_t open_descriptors(pid_t pid) {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e :
       std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/fd"))
    ++n;
  return n;
}

void limit_descriptors(pid_t pid, rlim_t limit) {
  const rlimit r{limit, limit};
  ASSERT_EQ(::prlimit(pid, RLIMIT_NOFILE, &r, nullptr), 0) << "prlimit failed";
}

// A station with the key against a TLS 1.3 server that has a throw-away certificate and no key
// (an impostor on the path): the handshake fails at the station, which counts it, builds no
// surface, exits non-zero naming the certificate, and never sends the impostor a byte (its Hello).
// Before issue 49 the handshake completed (no certificate was checked in --psk mode) and the
// impostor read the station's Hello.
TEST(PskImpostor, StationRefusesACertificateOnlyServerAndSendsItNothing) {
  TELEX_REQUIRE_BINARIES("telex-local");
  TELEX_SKIP_UNLESS(have_openssl(), "the openssl command line is not installed");
  const auto dir = scratch_dir("psk_impostor_station");
  const auto key = new_key(dir);
  CertOnlyTlsServer impostor(dir);
  Process local(local_args(impostor.port(), dir,
                           {"--quiet", "--psk", key, "--transport", "tcp", "--hand", "script:press",
                            "--first-surface-timeout", "3"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_NE(*rc, 0);
  const auto err = local.stderr_text();
  EXPECT_NE(err.find("[error] authentication failed"), std::string::npos) << err;
  EXPECT_EQ(err.find("remote streaming"), std::string::npos) << err;
  EXPECT_GE(impostor.connections(), 1);
  EXPECT_EQ(impostor.handshakes(), 0) << err;
  EXPECT_EQ(impostor.bytes_read(), 0) << "the station sent its Hello to an impostor";
  EXPECT_NE(err.find("certificate, not the shared key"), std::string::npos) << err;
}

// The same impostor as a client of a keyed remote: no session, counted as an auth failure.
TEST(PskImpostor, RemoteRefusesACertificateOnlyClient) {
  TELEX_REQUIRE_BINARIES("telex-remote");
  TELEX_SKIP_UNLESS(have_openssl(), "the openssl command line is not installed");
  const auto dir = scratch_dir("psk_impostor_remote");
  const auto key = new_key(dir);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key});
  EXPECT_FALSE(cert_only_client_gets_a_session(dir, remote.port));
  EXPECT_TRUE(eventually(10s, [&] {
    return last_counter(remote.proc.stderr_text(), "auth-failed") >= 1;
  })) << remote.proc.stderr_text();
  EXPECT_EQ(last_counter(remote.proc.stderr_text(), "accepted"), 0);
}

// Runs a keyed station for 3 s against `port`; returns its exit code and how long it ran.
struct StationRun {
  int rc = -1;
  nlohmann::json summary;
  std::string err;
  double seconds = 0;
};
StationRun run_keyed_station(const std::filesystem::path& dir, std::uint16_t port,
                             const std::string& key) {
  const auto t0 = std::chrono::steady_clock::now();
  Process local(local_args(port, dir,
                           {"--quiet", "--psk", key, "--hand", "script:press", "--duration", "3",
                            "--first-surface-timeout", "6"}),
                dir / "local.out", dir / "local.err");
  StationRun r;
  r.rc = local.wait(60s).value_or(-1);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.summary = summary_of(local);
  r.err = local.stderr_text();
  return r;
}

// Finding 2: one client that connects and never speaks took the operator's slot at accept and
// held it until the client timeout, again and again; the keyed station was told "another
// operator is connected" until it gave up. Now the slot goes to the first authenticated Hello.
TEST(PreAuth, AnIdleConnectionDoesNotHoldTheOperatorsSlot) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("preauth_idle");
  const auto key = new_key(dir);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key});
  ConnectionCrowd idle(remote.port, 1, ConnectionCrowd::Kind::Idle, {"127.0.0.1"});
  ASSERT_TRUE(eventually(5s, [&] { return idle.connects() >= 1; }));
  std::this_thread::sleep_for(200ms);  // the idle connection is accepted first
  const auto r = run_keyed_station(dir, remote.port, key);
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_GT(r.summary.value("surfaces", 0), 10) << r.summary.dump();
  EXPECT_EQ(r.err.find("another operator"), std::string::npos) << r.err;
}

// Finding 3 and the crowd: 150 idle connections from three addresses and 50 half-open ones (a
// TLS record header, then silence) from a fourth, reconnecting as they are closed, against a
// remote limited to 128 descriptors (before issue 49 the accept loop spun on EMFILE and the keyed
// station timed out). The keyed station streams; the crowd was held to its caps.
TEST(PreAuth, KeyedStationStreamsWhileACrowdHammersThePort) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("preauth_crowd");
  const auto key = new_key(dir);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key});
  limit_descriptors(remote.proc.pid(), 128);
  ConnectionCrowd idle(remote.port, 150, ConnectionCrowd::Kind::Idle,
                       {"127.0.0.2", "127.0.0.3", "127.0.0.4"});
  ConnectionCrowd half(remote.port, 50, ConnectionCrowd::Kind::HalfOpen, {"127.0.0.5"});
  ASSERT_TRUE(eventually(20s, [&] { return idle.connects() >= 150 && half.connects() >= 50; }));
  const auto r = run_keyed_station(dir, remote.port, key);
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_GT(r.summary.value("surfaces", 0), 10) << r.summary.dump();
  EXPECT_LE(open_descriptors(remote.proc.pid()), 128u);
  const auto log = remote.proc.stderr_text();
  EXPECT_GT(last_counter(log, "pre-auth-evicted"), 0) << log;
  EXPECT_EQ(last_counter(log, "accepted"), 1) << log;
  std::printf("station ran %.2f s for a 3 s session; crowd connects %ld idle, %ld half-open\n",
              r.seconds, idle.connects(), half.connects());
}

// Out of descriptors: the remote's limit is set just above what it holds, so accept fails with
// EMFILE while idle connections wait. Each failure is counted and followed by a 100 ms pause
// (kAcceptBackoff), so over any span the failures stay near ten a second; a spinning loop makes
// thousands. The bound allows for the stats line's one-second lag at both ends.
TEST(PreAuth, OutOfDescriptorsTheAcceptLoopBacksOff) {
  TELEX_REQUIRE_BINARIES("telex-remote");
  const auto dir = scratch_dir("preauth_emfile");
  const auto key = new_key(dir);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key});
  ASSERT_TRUE(eventually(10s, [&] {
    return last_counter(remote.proc.stderr_text(), "accept-errors") >= 0;
  })) << remote.proc.stderr_text();
  limit_descriptors(remote.proc.pid(), open_descriptors(remote.proc.pid()) + 4);
  std::vector<std::string> sources;
  for (int i = 1; i <= 20; ++i) sources.push_back("127.0.1." + std::to_string(i));
  ConnectionCrowd idle(remote.port, 100, ConnectionCrowd::Kind::Idle, sources);
  ASSERT_TRUE(eventually(20s, [&] {
    return last_counter(remote.proc.stderr_text(), "accept-errors") >= 1;
  })) << remote.proc.stderr_text();
  const long e1 = last_counter(remote.proc.stderr_text(), "accept-errors");
  const auto t1 = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(3s);
  const long e2 = last_counter(remote.proc.stderr_text(), "accept-errors");
  const double span_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count() + 2.0;
  EXPECT_LE(static_cast<double>(e2 - e1), 10.0 * span_s + 10.0)
      << e1 << " -> " << e2 << " accept errors in " << span_s << " s";
  std::printf("accept errors %ld -> %ld over about %.1f s\n", e1, e2, span_s - 2.0);
}

}  // namespace
}  // namespace telex::test
