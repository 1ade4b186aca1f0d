// SPDX-License-Identifier: MIT
// The link under TLS and sealed datagrams, both daemons as processes: what a recording proxy sees
// on the wire, datagrams reflected and replayed, forged and unkeyed HeadCommands against the sim
// head, certificates both ways, and --insecure off loopback.
#include "telex/proto/tls.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <thread>
#include <unordered_set>

#include "daemons.h"
#include "process.h"
#include "recording_proxy.h"
#include "telex/proto/fragment.h"
#include "telex/proto/messages.h"
#include "telex/proto/seal.h"
#include "test_support.h"
#include "tls_peers.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

std::filesystem::path write_key(const std::filesystem::path& dir, const std::string& name,
                                std::uint8_t seed) {
  const auto p = dir / name;
  {
    std::ofstream out(p, std::ios::binary);
    for (int i = 0; i < 32; ++i) out.put(static_cast<char>(seed * 37 + i * 11));
  }
  std::filesystem::permissions(
      p, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  return p;
}

bool contains(const Bytes& b, std::initializer_list<std::uint8_t> pattern) {
  return std::search(b.begin(), b.end(), pattern.begin(), pattern.end()) != b.end();
}

// 16-byte windows of `b` (at any offset) that occur twice or more.
std::size_t repeated_blocks(const Bytes& b) {
  if (b.size() < 32) return 0;
  std::unordered_set<std::string> seen;
  std::size_t repeats = 0;
  for (std::size_t i = 0; i + 16 <= b.size(); ++i)
    if (!seen.emplace(reinterpret_cast<const char*>(b.data() + i), 16).second) ++repeats;
  return repeats;
}

// A message header's first six bytes anywhere: "TLX1", this protocol's version, a known type.
// Four bytes alone would match random ciphertext once in 4 GB, about once in 400 runs of this
// test's ~10 MB; six, with the type's 15 values, once in ~10^7 runs.
bool contains_header(const Bytes& b) {
  for (std::size_t i = 0; i + 6 <= b.size(); ++i)
    if (b[i] == 0x54 && b[i + 1] == 0x4C && b[i + 2] == 0x58 && b[i + 3] == 0x31 &&
        b[i + 4] == proto::kProtocolVersion && b[i + 5] < proto::kMsgTypeCount)
      return true;
  return false;
}

struct WireFindings {
  std::size_t chunks = 0, bytes = 0, udp = 0;
  std::size_t message_magic = 0;   // a message header (contains_header) anywhere
  std::size_t fragment_magic = 0;  // a datagram starting "TF"
  // A JPEG's start: SOI, the APP0 marker and its "JFIF" identifier, as OpenCV's libjpeg writes
  // them (ten bytes: FF D8 FF alone occur by chance once in 16 MB of random bytes, about once per
  // run of this test's ciphertext).
  std::size_t jpeg = 0;
  std::size_t repeated = 0;  // chunks with a repeated 16-byte block
};

WireFindings inspect(const std::vector<RecordingProxy::Chunk>& chunks) {
  WireFindings f;
  for (const auto& c : chunks) {
    ++f.chunks;
    f.bytes += c.bytes.size();
    f.udp += c.udp;
    f.message_magic += contains_header(c.bytes);
    f.fragment_magic += c.udp && c.bytes.size() >= 2 && c.bytes[0] == 'T' && c.bytes[1] == 'F';
    f.jpeg += contains(c.bytes, {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 'J', 'F', 'I', 'F'});
    f.repeated += repeated_blocks(c.bytes) > 0;
  }
  return f;
}

class TlsCapture : public ::testing::TestWithParam<std::string> {};

// Depth, both eyes' JPEG video (--video-codec mjpeg: JPEG starts are easy to find, H.264's not)
// and the control messages through a recording proxy, keyed and
// then unkeyed: with the key not one datagram or TCP read shows the message magic, a fragment
// header, a JPEG start or a repeated 16-byte block (at any offset); without it all of them show
// (the inspection can fail).
TEST_P(TlsCapture, KeyedLinkShowsNoPlaintextOnTheWire) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const std::string transport = GetParam();
  WireFindings keyed, plain;
  for (const bool with_key : {true, false}) {
    const auto dir = scratch_dir("tls_capture_" + transport + (with_key ? "_keyed" : "_plain"));
    const auto key = write_key(dir, "key", 1);
    std::vector<std::string> remote_extra{
        "--source",    "synthetic:plane", "--stereo",      "synthetic:plane",
        "--transport", transport,         "--video-codec", "mjpeg"};
    // 6 s: the first surface must come within --duration too, through the recording proxy at
    // about 60 Mbit/s; on a loaded 2-core CI host 4 s once saw none.
    std::vector<std::string> local_extra{
        "--quiet", "--transport",  transport,
        "--hand",  "script:press", "--duration",
        "6",       "--view",       "png:" + (dir / "view").string()};
    if (with_key) {
      remote_extra.insert(remote_extra.end(), {"--psk", key.string()});
      local_extra.insert(local_extra.end(), {"--psk", key.string()});
    }
    RemoteProcess remote(dir, remote_extra);
    std::uint16_t station_udp = 0;
    ::close(bound_socket(SOCK_DGRAM, station_udp));
    RecordingProxy proxy(remote.port, station_udp);
    local_extra.insert(local_extra.end(), {"--udp-port", std::to_string(station_udp),
                                           "--udp-announce-port", std::to_string(proxy.udp_port)});
    Process local(local_args(proxy.tcp_port, dir, local_extra), dir / "local.out",
                  dir / "local.err");
    ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text() << remote.proc.stderr_text();
    const auto j = summary_of(local);
    EXPECT_GT(j["surfaces"].get<int>(), 20) << j.dump();
    (with_key ? keyed : plain) = inspect(proxy.chunks());
  }
  std::printf(
      "keyed %s: %zu chunks (%zu datagrams), %zu bytes: TLX1 %zu, TF %zu, JPEG %zu, "
      "repeated blocks %zu\n",
      transport.c_str(), keyed.chunks, keyed.udp, keyed.bytes, keyed.message_magic,
      keyed.fragment_magic, keyed.jpeg, keyed.repeated);
  std::printf(
      "plain %s: %zu chunks (%zu datagrams), %zu bytes: TLX1 %zu, TF %zu, JPEG %zu, "
      "repeated blocks %zu\n",
      transport.c_str(), plain.chunks, plain.udp, plain.bytes, plain.message_magic,
      plain.fragment_magic, plain.jpeg, plain.repeated);
  EXPECT_GT(keyed.bytes, 1'000'000u);  // depth and video went through the proxy
  if (transport == "udp") {
    EXPECT_GT(keyed.udp, 500u);
  }
  EXPECT_EQ(keyed.message_magic, 0u);
  EXPECT_EQ(keyed.fragment_magic, 0u);
  EXPECT_EQ(keyed.jpeg, 0u);
  EXPECT_EQ(keyed.repeated, 0u);
  EXPECT_GT(plain.message_magic, 0u);
  EXPECT_GT(plain.jpeg, 0u);
  EXPECT_GT(plain.repeated, 0u);
  if (transport == "udp") {
    EXPECT_GT(plain.fragment_magic, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Tls, TlsCapture, ::testing::Values("udp", "tcp"));

// Datagrams the remote sealed for the station, captured on the way: sent back to the remote's
// UDP socket they do not open (the station->remote key is another exporter output), and replayed
// to the station they are refused by its replay window. On TCP a reflected record cannot happen
// by construction: TLS 1.3 keys each direction with its own traffic secret (RFC 8446 7.1), so a
// record the remote sent fails the remote's decryption (bad_record_mac) and ends the connection
// instead of being read as the station's.
TEST(TlsReflection, ASealedDatagramReflectedToTheRemoteOrReplayedToTheStationIsRefused) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("tls_reflection");
  const auto key = write_key(dir, "key", 2);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key.string()});
  std::uint16_t station_udp = 0;
  ::close(bound_socket(SOCK_DGRAM, station_udp));
  RecordingProxy proxy(remote.port, station_udp);
  Process local(local_args(proxy.tcp_port, dir,
                           {"--quiet", "--psk", key.string(), "--hand", "script:press",
                            "--duration", "5", "--udp-port", std::to_string(station_udp),
                            "--udp-announce-port", std::to_string(proxy.udp_port)}),
                dir / "local.out", dir / "local.err");
  ASSERT_TRUE(eventually(20s, [&] {
    const auto c = proxy.chunks();
    return std::count_if(c.begin(), c.end(), [](const auto& x) { return x.udp; }) >= 20;
  })) << local.stderr_text();
  std::vector<RecordingProxy::Chunk> sealed;
  for (auto& c : proxy.chunks())
    if (c.udp && sealed.size() < 10) sealed.push_back(c);
  ASSERT_EQ(sealed.size(), 10u);
  const long before = std::max(0L, last_counter(remote.proc.stderr_text(), "auth-failed"));
  for (const auto& c : sealed) {
    EXPECT_EQ(c.bytes[0], 'T');
    EXPECT_EQ(c.bytes[1], 'S');
    udp_blurt(c.from_port, c.bytes);  // back to the remote's own UDP socket
    udp_blurt(station_udp, c.bytes);  // again to the station, which had it already
  }
  ASSERT_TRUE(eventually(5s, [&] {
    return last_counter(remote.proc.stderr_text(), "auth-failed") >= before + 10;
  })) << remote.proc.stderr_text();
  ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text();
  const auto j = summary_of(local);
  EXPECT_GE(j["replayed"].get<int>(), 10) << j.dump();
  EXPECT_EQ(j["auth_failed"].get<int>(), 0) << j.dump() << local.stderr_text();
  EXPECT_GT(j["surfaces"].get<int>(), 20) << j.dump();
  EXPECT_EQ(last_counter(remote.proc.stderr_text(), "udp-ignored"), 0);
  std::printf("remote auth-failed %ld (reflected 10), station replayed %d (replayed 10)\n",
              last_counter(remote.proc.stderr_text(), "auth-failed"), j["replayed"].get<int>());
}

// A forwarder (ssh -L, say) that accepts the station's connection while nothing listens behind it
// closes the connection with no TLS reply. The station retries, does not count an authentication
// failure and, once the remote is there, streams; the final message of a station that never got
// a surface would otherwise blame the keys.
TEST(TlsForwarder, AClosedHandshakeWithNothingBehindIsRetriedNotAnAuthenticationFailure) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("tls_forwarder");
  const auto key = write_key(dir, "key", 3);
  const auto remote_port = free_port();  // nothing listens there yet
  RecordingProxy proxy(remote_port, 0);
  Process local(local_args(proxy.tcp_port, dir,
                           {"--quiet", "--psk", key.string(), "--transport", "tcp", "--hand",
                            "script:press", "--duration", "8"}),
                dir / "local.out", dir / "local.err");
  ASSERT_TRUE(eventually(20s, [&] { return proxy.refused() >= 2; })) << local.stderr_text();
  RemoteProcess remote(dir,
                       {"--source", "synthetic:plane", "--psk", key.string(), "--transport", "tcp"},
                       remote_port);
  ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text() << remote.proc.stderr_text();
  const auto j = summary_of(local);
  const auto err = local.stderr_text();
  EXPECT_EQ(j["auth_failed"].get<int>(), 0) << j.dump() << err;
  EXPECT_GT(j["surfaces"].get<int>(), 10) << j.dump();
  EXPECT_NE(err.find("closed the connection during the TLS handshake"), std::string::npos) << err;
  EXPECT_EQ(err.find("authentication failed"), std::string::npos) << err;
  EXPECT_GE(proxy.accepted(), proxy.refused() + 1);
}

int tcp_connect(std::uint16_t port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// An operator's session opened the unkeyed way: Hello, then a HeadCommand turning the head.
Bytes unkeyed_hello_and_head_command() {
  proto::Hello hello;
  hello.codecs = {proto::Codec::Zip};
  proto::Header h;
  Bytes out = proto::encode_stream(h, hello);
  h.session_id = 1;
  h.seq = 1;
  const auto cmd = proto::encode_stream(h, proto::HeadCommand{1, 0.8f, 0.3f, 0.0f});
  out.insert(out.end(), cmd.begin(), cmd.end());
  return out;
}

// A TLS client under a key of its own: the handshake must fail (false) before any byte of a
// HeadCommand could be written; true would mean a session.
bool tls_handshake_with_wrong_key(std::uint16_t port) {
  proto::TlsConfig c;
  c.psk = proto::AuthKey(Bytes(32, 0x5A));
  SSL_CTX* ctx = proto::make_tls_context(c, proto::TlsRole::Client);
  SSL* ssl = SSL_new(ctx);
  const int fd = tcp_connect(port);
  bool ok = false;
  if (fd >= 0) {
    SSL_set_fd(ssl, fd);
    ok = SSL_connect(ssl) == 1;
    if (ok) {
      const Bytes cmd = unkeyed_hello_and_head_command();
      SSL_write(ssl, cmd.data(), static_cast<int>(cmd.size()));
    }
    ::close(fd);
  }
  ERR_clear_error();
  SSL_free(ssl);
  SSL_CTX_free(ctx);
  return ok;
}

// The remote with --psk and the sim head serves a real station (which sends no HeadCommand: its
// hand is scripted, its head untracked) while an attacker sends HeadCommands every way it can:
// in the clear on new TCP connections, through a TLS handshake under another key, and over UDP
// (where no HeadCommand is ever taken) plain and sealed under a key of its own. None reaches the
// head: head-in stays 0; the handshakes and datagrams are counted. The same clear-text bytes at a
// remote without a key on loopback do move it (head-in 1): the check can fail.
TEST(TlsHead, ForgedAndUnkeyedHeadCommandsNeverMoveTheSimHead) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("tls_head_forged");
  const auto key = write_key(dir, "key", 3);
  RemoteProcess remote(dir,
                       {"--source", "synthetic:plane", "--head", "sim", "--psk", key.string()});
  std::uint16_t station_udp = 0;
  ::close(bound_socket(SOCK_DGRAM, station_udp));
  RecordingProxy proxy(remote.port, station_udp);
  Process local(local_args(proxy.tcp_port, dir,
                           {"--quiet", "--psk", key.string(), "--hand", "script:press",
                            "--duration", "6", "--udp-port", std::to_string(station_udp),
                            "--udp-announce-port", std::to_string(proxy.udp_port)}),
                dir / "local.out", dir / "local.err");
  // The remote's UDP port, as an on-path attacker learns it: the source of its datagrams.
  std::uint16_t remote_udp = 0;
  ASSERT_TRUE(eventually(20s, [&] {
    for (const auto& c : proxy.chunks())
      if (c.udp) remote_udp = c.from_port;
    return remote_udp != 0;
  })) << local.stderr_text();
  const Bytes clear = unkeyed_hello_and_head_command();
  proto::Header h;
  h.session_id = 1;
  h.seq = 2;
  const Bytes plain_datagram =
      proto::fragment_message(proto::encode(h, proto::HeadCommand{2, 0.8f, 0.3f, 0.0f}), 7, 1)
          .front();
  proto::DirectionKey forger;
  forger.key.fill(0x77);
  forger.iv.fill(0x33);
  proto::DatagramSealer forger_sealer(forger);
  int handshakes_won = 0;
  for (int i = 0; i < 5; ++i) {
    tcp_blurt(remote.port, clear);
    handshakes_won += tls_handshake_with_wrong_key(remote.port);
    udp_blurt(remote_udp, plain_datagram);
    udp_blurt(remote_udp, forger_sealer.seal(plain_datagram));
  }
  EXPECT_EQ(handshakes_won, 0);
  ASSERT_TRUE(eventually(5s, [&] {
    const auto err = remote.proc.stderr_text();
    return last_counter(err, "auth-failed") >= 5 && last_counter(err, "unsealed") >= 5;
  })) << remote.proc.stderr_text();
  ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text();
  const std::string err = remote.proc.stderr_text();
  EXPECT_EQ(last_counter(err, "head-in"), 0) << err;
  EXPECT_EQ(last_counter(err, "accepted"), 1) << err;  // the real station only
  EXPECT_GE(last_counter(err, "rejected"), 5) << err;  // the attacker's connections
  EXPECT_EQ(summary_of(local)["head_commands"].get<int>(), 0);
  std::printf("keyed remote: head-in %ld, auth-failed %ld, unsealed %ld, rejected %ld\n",
              last_counter(err, "head-in"), last_counter(err, "auth-failed"),
              last_counter(err, "unsealed"), last_counter(err, "rejected"));

  // The control: the same clear-text bytes at a remote without a key (loopback) reach its head.
  const auto control_dir = scratch_dir("tls_head_control");
  RemoteProcess open_remote(control_dir, {"--source", "synthetic:plane", "--head", "sim"});
  ASSERT_TRUE(eventually(10s, [&] {
    const int fd = tcp_connect(open_remote.port);
    if (fd < 0) return false;
    ::send(fd, clear.data(), clear.size(), MSG_NOSIGNAL);
    std::this_thread::sleep_for(300ms);
    ::close(fd);
    return true;
  }));
  ASSERT_TRUE(eventually(5s, [&] {
    return last_counter(open_remote.proc.stderr_text(), "head-in") >= 1;
  })) << open_remote.proc.stderr_text();
}

// Certificates from one throwaway CA on both daemons give a session (and the press); a station
// whose certificate another CA signed, and a station with none, get none, and both sides say
// what is wrong.
TEST(TlsCertificates, MutualCertificatesServeAndOthersAreRefused) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  TELEX_SKIP_UNLESS(std::system("openssl version > /dev/null 2>&1") == 0,
                    "the openssl command line is not installed");
  const auto dir = scratch_dir("tls_certificates");
  ASSERT_TRUE(make_ca(dir, "ca") && make_cert(dir, "ca", "remote") &&
              make_cert(dir, "ca", "station") && make_ca(dir, "stranger_ca") &&
              make_cert(dir, "stranger_ca", "stranger"))
      << read_text(dir / "openssl.log");
  const auto f = [&](const std::string& n) { return (dir / n).string(); };
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--cert", f("remote.pem"), "--key",
                             f("remote.key"), "--ca", f("ca.pem")});
  {
    Process local(local_args(remote.port, dir,
                             {"--quiet", "--cert", f("station.pem"), "--key", f("station.key"),
                              "--ca", f("ca.pem"), "--hand", "script:press", "--duration", "3"}),
                  dir / "local.out", dir / "local.err");
    ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text();
    EXPECT_GT(summary_of(local)["surfaces"].get<int>(), 20);
  }
  EXPECT_NE(remote.proc.stderr_text().find("TLS 1.3 with certificates"), std::string::npos);
  {
    Process stranger(
        local_args(remote.port, dir,
                   {"--quiet", "--cert", f("stranger.pem"), "--key", f("stranger.key"), "--ca",
                    f("ca.pem"), "--hand", "script:press", "--first-surface-timeout", "2"}),
        dir / "stranger.out", dir / "stranger.err");
    const auto rc = stranger.wait(40s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_NE(*rc, 0);
    EXPECT_NE(stranger.stderr_text().find("certificate"), std::string::npos)
        << stranger.stderr_text();
    EXPECT_NE(stranger.stderr_text().find("authentication failed"), std::string::npos)
        << stranger.stderr_text();
  }
  {
    Process none(local_args(remote.port, dir,
                            {"--quiet", "--hand", "script:press", "--first-surface-timeout", "2"}),
                 dir / "none.out", dir / "none.err");
    const auto rc = none.wait(40s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_NE(*rc, 0);
    EXPECT_NE(none.stderr_text().find("requires TLS"), std::string::npos) << none.stderr_text();
  }
  const std::string log = remote.proc.stderr_text();
  EXPECT_NE(log.find("certificate"), std::string::npos) << log;
  EXPECT_NE(log.find("does not speak TLS"), std::string::npos) << log;
  EXPECT_EQ(last_counter(remote.proc.stderr_text(), "accepted"), 1);
  std::printf("remote: %ld accepted, %ld auth-failed\n",
              last_counter(remote.proc.stderr_text(), "accepted"),
              last_counter(remote.proc.stderr_text(), "auth-failed"));
}

// Both daemons load their certificates through one loader (telex/cli/link_security.h) that
// builds a TLS context while the flags are read: a key that does not match its certificate exits
// 2 naming the problem before anything listens or connects, at the remote as at the station.
TEST(TlsCertificates, AKeyThatDoesNotMatchItsCertificateExitsTwoAtStartOnBothSides) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  TELEX_SKIP_UNLESS(std::system("openssl version > /dev/null 2>&1") == 0,
                    "the openssl command line is not installed");
  const auto dir = scratch_dir("tls_mismatch");
  ASSERT_TRUE(make_ca(dir, "ca") && make_cert(dir, "ca", "remote") &&
              make_cert(dir, "ca", "station"))
      << read_text(dir / "openssl.log");
  const auto f = [&](const std::string& n) { return (dir / n).string(); };
  {
    Process p({built_binary("telex-remote").string(), "--source", "synthetic:plane", "--listen",
               "127.0.0.1:" + std::to_string(free_port()), "--cert", f("remote.pem"), "--key",
               f("station.key"), "--ca", f("ca.pem"), "--duration", "5"},
              dir / "r.out", dir / "r.err");
    const auto rc = p.wait(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 2) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("key"), std::string::npos) << p.stderr_text();
    EXPECT_EQ(p.stderr_text().find("listening"), std::string::npos) << p.stderr_text();
  }
  {
    Process p({built_binary("telex-local").string(), "--connect",
               "127.0.0.1:" + std::to_string(free_port()), "--cert", f("station.pem"), "--key",
               f("remote.key"), "--ca", f("ca.pem"), "--hand", "script:press"},
              dir / "l.out", dir / "l.err");
    const auto rc = p.wait(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 2) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("key"), std::string::npos) << p.stderr_text();
  }
}

// The IPv4 address of an interface that is up and not loopback, or "0.0.0.0" when there is none.
std::string non_loopback_address() {
  ifaddrs* list = nullptr;
  std::string found = "0.0.0.0";
  if (::getifaddrs(&list) != 0) return found;
  for (ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
    if (i->ifa_addr == nullptr || i->ifa_addr->sa_family != AF_INET) continue;
    if ((i->ifa_flags & IFF_UP) == 0 || (i->ifa_flags & IFF_LOOPBACK) != 0) continue;
    char buf[INET_ADDRSTRLEN];
    ::inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(i->ifa_addr)->sin_addr, buf, sizeof buf);
    found = buf;
    break;
  }
  ::freeifaddrs(list);
  return found;
}

// Off loopback without a key or certificates both daemons exit 2 naming the risk and --insecure;
// with --insecure (or `insecure = true` in --config) they start and warn. The station's address
// is this machine's own, so nothing leaves it.
TEST(Insecure, OffLoopbackWithoutAKeyExitsTwoUnlessInsecure) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("tls_insecure");
  const std::string address = non_loopback_address();
  const std::string remote_bin = built_binary("telex-remote").string();
  const std::string local_bin = built_binary("telex-local").string();
  std::printf("non-loopback address: %s\n", address.c_str());
  const auto says_risk = [](const std::string& text) {
    return text.find("--insecure") != std::string::npos &&
           text.find("move the robot head and watch its cameras") != std::string::npos;
  };
  {
    Process p({remote_bin, "--source", "synthetic:plane", "--listen", address + ":0"},
              dir / "r1.out", dir / "r1.err");
    const auto rc = p.wait(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 2) << p.stderr_text();
    EXPECT_TRUE(says_risk(p.stderr_text())) << p.stderr_text();
  }
  {
    Process p({local_bin, "--connect", address + ":7300", "--hand", "script:press"}, dir / "l1.out",
              dir / "l1.err");
    const auto rc = p.wait(20s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 2) << p.stderr_text();
    EXPECT_TRUE(says_risk(p.stderr_text())) << p.stderr_text();
  }
  {
    Process p({remote_bin, "--source", "synthetic:plane", "--listen", address + ":0", "--insecure",
               "--duration", "2"},
              dir / "r2.out", dir / "r2.err");
    const auto rc = p.wait(30s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 0) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("INSECURE (--insecure)"), std::string::npos) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("| INSECURE link (--insecure)"), std::string::npos)
        << p.stderr_text();
  }
  {
    const auto cfg = dir / "remote.ini";
    std::ofstream(cfg) << "listen = \"" << address << ":0\"\ninsecure = true\nduration = 1\n";
    Process p({remote_bin, "--source", "synthetic:plane", "--config", cfg.string()}, dir / "r3.out",
              dir / "r3.err");
    const auto rc = p.wait(30s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_EQ(*rc, 0) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("INSECURE"), std::string::npos) << p.stderr_text();
  }
  {
    // Nothing listens on this machine's own address at a fresh port: the station tries, warns and
    // gives up after its first-surface timeout.
    Process p({local_bin, "--connect", address + ":" + std::to_string(free_port()), "--insecure",
               "--hand", "script:press", "--first-surface-timeout", "1", "--haptics", "sim"},
              dir / "l2.out", dir / "l2.err");
    const auto rc = p.wait(30s);
    ASSERT_TRUE(rc.has_value());
    EXPECT_NE(*rc, 2) << p.stderr_text();
    EXPECT_NE(p.stderr_text().find("INSECURE (--insecure)"), std::string::npos) << p.stderr_text();
  }
}

}  // namespace
}  // namespace telex::test
