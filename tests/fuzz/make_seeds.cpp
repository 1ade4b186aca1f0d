// SPDX-License-Identifier: MIT
// Writes valid seed inputs for each fuzz target (in each target's own input layout) into
// OUT/<target>/, so the fuzzers start deep inside the formats. Built with TELEX_FUZZ; the kept
// corpus in corpus/ is these seeds after fuzzing, minimised with -merge=1 (docs/BENCHMARKS.md).
#include <openssl/bio.h>
#include <openssl/ssl.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stream_fixtures.h"
#include "telex/bag/bag.h"
#include "telex/dynamixel/protocol.h"
#include "telex/local/inputs/glove.h"
#include "telex/natnet/natnet.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/fragment.h"
#include "telex/proto/messages.h"
#include "telex/proto/seal.h"
#include "telex/proto/tls.h"
#include "telex/video/frame_header.h"

namespace {

using Bytes = std::vector<std::uint8_t>;
namespace fs = std::filesystem;

int g_written = 0;

void write(const fs::path& dir, const std::string& name, const Bytes& b) {
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  ++g_written;
}

// What `ssl` wrote into its output memory BIO so far.
Bytes drain(SSL* ssl) {
  Bytes out(1 << 16);
  const int n = BIO_read(SSL_get_wbio(ssl), out.data(), static_cast<int>(out.size()));
  out.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  return out;
}

// A real ClientHello and the server's first flight under the fuzz target's PSK (0x42 x 32).
std::pair<Bytes, Bytes> tls_first_flights() {
  using namespace telex::proto;
  TlsConfig c;
  c.psk = AuthKey(Bytes(32, 0x42));
  SSL_CTX* sctx = make_tls_context(c, TlsRole::Server);
  SSL_CTX* cctx = make_tls_context(c, TlsRole::Client);
  SSL* server = SSL_new(sctx);
  SSL* client = SSL_new(cctx);
  SSL_set_bio(server, BIO_new(BIO_s_mem()), BIO_new(BIO_s_mem()));
  SSL_set_bio(client, BIO_new(BIO_s_mem()), BIO_new(BIO_s_mem()));
  SSL_set_accept_state(server);
  SSL_set_connect_state(client);
  (void)SSL_do_handshake(client);
  const Bytes hello = drain(client);
  BIO_write(SSL_get_rbio(server), hello.data(), static_cast<int>(hello.size()));
  (void)SSL_do_handshake(server);
  const Bytes flight = drain(server);
  SSL_free(server);
  SSL_free(client);
  SSL_CTX_free(sctx);
  SSL_CTX_free(cctx);
  return {hello, flight};
}

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

cv::Mat1w tile(int w, int h, int seed, bool holes) {
  cv::Mat1w t(h, w);
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      t(y, x) = holes && rng.uniform(0, 5) == 0
                    ? 0
                    : static_cast<std::uint16_t>(800 + 3 * x + 2 * y + rng.uniform(0, 4));
  return t;
}

std::vector<telex::proto::Message> messages() {
  using namespace telex::proto;
  std::vector<Message> m;
  m.push_back(Hello{});
  m.push_back(Heartbeat{1, 2, 3, 4});
  m.push_back(telex::test::stream_config_2x2());
  for (const Codec c : {Codec::Raw, Codec::Zip, Codec::Fast}) {
    const cv::Mat1w t = tile(16, 12, static_cast<int>(c), true);
    m.push_back(DepthTile{3, 80, 60, 16, 12, c, encode_depth(t, c)});
  }
  FrameManifest fm;
  fm.frame_id = 7;
  fm.tile_count = 64;
  fm.changed_tiles = {0, 3, 9, 63};
  m.push_back(fm);
  fm.key_frame = true;
  fm.changed_tiles.clear();
  m.push_back(fm);
  m.push_back(Bye{});
  // The client's requests, repair among them (docs/PROTOCOL.md 2.5).
  m.push_back(RoiRequest{{{10, 20, 80, 60, 3}}});
  m.push_back(Stats{{{"key_frame_request", 1}}});
  m.push_back(TileNack{41, {9, 10, 17}});
  m.push_back(HeadCommand{123456789, {0.3f, -0.1f, 0.05f}, 77, 4500, DeadmanState::Pressed});
  // The eyes (docs/PROTOCOL.md 2.7): an encoded pair (and one with the robot head's joints at its
  // capture), a PLI, a receiver report.
  for (const bool posed : {false, true}) {
    telex::video::EncodedFrameHeader h;
    h.frame_id = 7;
    h.encode_seq = 3;
    h.capture_ns = 1'700'000'000'123'456'789;
    h.is_intra = true;
    h.eye_width_px = 64;
    h.eye_height_px = 48;
    const Bytes payload{0, 0, 0, 1, 0x65, 0x88, 0x84};
    h.payload_bytes = static_cast<std::uint32_t>(payload.size());
    if (posed) h.head_joint_rad = std::array<float, 3>{0.4f, -0.2f, 0.05f};
    Bytes frame;
    telex::video::serialize_header(h, frame);
    frame.insert(frame.end(), payload.begin(), payload.end());
    m.push_back(EncodedVideo{frame});
  }
  m.push_back(PictureLoss{2, PictureLossReason::MissingReference});
  m.push_back(ReceiverReport{250'000, 180'000, 120'000, 140, 3, 40, 21'500, 23'000, -35.5f});
  m.push_back(VideoNack{41, 2});
  return m;
}

// natnet_reply_fuzz: byte 0 = the client's configured version (index into 2.0 2.3 2.5 2.6 2.7
// 2.9 2.11 3.0 3.1 4.0 4.1; 11 = none), then records of u16 length, u8 ms since the last, datagram.
void natnet_reply_seeds(const fs::path& dir) {
  using namespace telex::local::natnet;
  const Version versions[] = {{2, 0},  {2, 3}, {2, 5}, {2, 6}, {2, 7}, {2, 9},
                              {2, 11}, {3, 0}, {3, 1}, {4, 0}, {4, 1}};
  const auto record = [](std::uint8_t dt_ms, const Bytes& datagram) {
    return cat({{static_cast<std::uint8_t>(datagram.size()),
                 static_cast<std::uint8_t>(datagram.size() >> 8), dt_ms},
                datagram});
  };
  ModelDefs defs;
  defs.rigid_bodies.push_back({"head", 1, -1, {0.0f, 0.1f, 0.0f}});
  defs.rigid_bodies.push_back({"hand", 2, 1, {0.02f, 0.0f, -0.01f}});
  const auto frame_at = [](std::uint32_t n, double t_s, float x_m) {
    Frame f;
    f.frame_number = n;
    f.timestamp_s = t_s;
    f.stamp_mid_exposure = 1'000'000 + n * 10'000;
    f.stamp_transmit = f.stamp_mid_exposure + 4'000;
    f.software_latency_s = 0.004f;
    RigidBody head;
    head.id = 1;
    head.p_m = {0.0f, 1.6f, 0.3f};
    RigidBody hand;
    hand.id = 2;
    hand.p_m = {x_m, 1.2f, 0.4f};
    hand.qx = 0.7071068f;
    hand.qw = 0.7071068f;
    hand.markers.push_back(hand.p_m);
    f.rigid_bodies = {head, hand};
    f.labeled_markers.push_back({65537, {0.5f, 0.5f, 0.5f}, 0.01f, 1, 0.001f});
    return f;
  };
  for (std::uint8_t i = 0; i < std::size(versions); ++i) {
    const Version v = versions[i];
    ServerInfo info;
    info.app_name = "Motive";
    info.app_version = {3, 0, 1, 0};
    info.natnet_version = v;
    info.high_res_clock_hz = 10'000'000;
    info.data_port = 1511;
    info.multicast = true;
    info.multicast_group = {239, 255, 42, 99};
    // As the client meets a server: its info, the model definitions, frames, the echo reply.
    const Bytes session =
        cat({record(0, make_server_info(info)), record(1, make_model_defs(defs, v)),
             record(8, encode_frame(frame_at(100, 1.000, 0.10f), v)),
             record(8, encode_frame(frame_at(101, 1.008, 0.11f), v)),
             record(1, make_echo_reply(12345, 67890, v)),
             record(9, encode_frame(frame_at(102, 1.016, 0.12f), v))});
    const std::string name = std::to_string(v.major) + "_" + std::to_string(v.minor);
    write(dir, "session_v" + name, cat({{11}, session}));
    // Configured with the version (version=X.Y): frames parse before any server info.
    write(dir, "configured_v" + name,
          cat({{i},
               record(8, encode_frame(frame_at(7, 0.5, 0.2f), v)),
               record(8, encode_frame(frame_at(8, 0.508, 0.2f), v))}));
  }
  // What the client reads nothing of but the framing: a message string, a command response, an
  // unrecognized request.
  const std::string text = "Motive: recording started";
  write(dir, "replies",
        cat({{11},
             record(0, make_packet(kMessageString, Bytes(text.begin(), text.end()))),
             record(0, make_packet(kResponse, Bytes{1, 0, 0, 0})),
             record(0, make_packet(kUnrecognizedRequest, {}))}));
}

// config_fuzz: byte 0 = the file's name (0 .toml, 1 .json, 2 .conf), then a telex-local config.
void config_seeds(const fs::path& dir) {
  const auto text = [](std::uint8_t kind, const std::string& t) {
    return cat({{kind}, Bytes(t.begin(), t.end())});
  };
  write(
      dir, "station.toml",
      text(0,
           "# telex-local at the desk\nconnect = \"192.168.1.20:7300\"\ntransport = \"udp\"\n"
           "hand = \"natnet:192.168.1.10,unicast,version=3.1\"\nhead-body = 1\nhand-body = 2\n"
           "max-force = 2.5\nstiffness = 400.0\nno-realtime = true\nrig = \"rig.json\"\n"
           "psk = \"telex.key\"\nlog-forces = \"logs/forces.csv\"\nhaptics = \"sim:display.csv\"\n"
           "view = \"png:view\"\nduration = 30\n"));
  write(dir, "station.json",
        text(1,
             "{\"connect\": \"127.0.0.1:7300\", \"transport\": \"tcp\", \"rate\": 1000, "
             "\"repeat\": true, \"elbow-bodies\": \"4,5\", \"udp-port\": 0, \"ramp\": 1.5, "
             "\"rig\": \"../rig/desk.json\", \"gg-config\": \"gg.json\", "
             "\"hand\": \"script:press\", \"quiet\": false}"));
  write(dir, "station_json.conf",
        text(2, "  {\"eye-size\": \"1280x720\", \"view-layout\": \"fig7\", \"warp\": \"off\"}"));
  write(dir, "lists.toml",
        text(0,
             "[default]\nduration = 0.5\nview = 'png:/tmp/v'\nhead-rate = 200.0\n"
             "deadman = \"evdev:/dev/input/event3\"\n"));
  write(dir, "typo.toml", text(0, "duraton = 1\n"));
  write(dir, "wrong_type.json", text(1, "{\"no-repair\": 3, \"max-force\": \"strong\"}"));
}

// parser_fuzz: byte 0 = flags (bit 0 frame size, bit 1 key, chunk size), then a TCP stream.
void stream_seeds(const fs::path& out, const std::vector<telex::proto::Message>& msgs) {
  using namespace telex::proto;
  for (std::size_t i = 0; i < msgs.size(); ++i) {
    Header h;
    h.seq = static_cast<std::uint32_t>(i);
    h.frame_id = 7;
    write(out / "parser_fuzz", "msg" + std::to_string(i),
          cat({{static_cast<std::uint8_t>(1 + 4 * i)}, encode_stream(h, msgs[i])}));
  }
  Bytes stream{0x11};
  for (std::size_t i = 0; i < msgs.size(); ++i) stream = cat({stream, encode_stream({}, msgs[i])});
  write(out / "parser_fuzz", "all", stream);

  // datagram_fuzz: one whole datagram message.
  for (std::size_t i = 0; i < msgs.size(); ++i)
    write(out / "datagram_fuzz", "msg" + std::to_string(i), encode({}, msgs[i]));
}

// tls_record_fuzz: byte 0 bit 0 picks the end (0 server, 1 client), then the peer's bytes; the
// same bytes go to the datagram opener (key 0x42 x 32, IV 0x24 x 12) and the stream parser.
void tls_record_seeds(const fs::path& out, const std::vector<telex::proto::Message>& msgs) {
  using namespace telex::proto;
  const auto [hello, flight] = tls_first_flights();
  write(out / "tls_record_fuzz", "client_hello", cat({{0x00}, hello}));
  write(out / "tls_record_fuzz", "server_flight", cat({{0x01}, flight}));
  DirectionKey key;
  key.key.fill(0x42);
  key.iv.fill(0x24);
  DatagramSealer sealer(key);
  for (std::size_t i = 0; i < msgs.size(); ++i)
    for (const auto& d : fragment_message(encode({}, msgs[i]), static_cast<std::uint32_t>(i), 7))
      write(out / "tls_record_fuzz", "sealed" + std::to_string(i), cat({{0x02}, sealer.seal(d)}));
  write(out / "tls_record_fuzz", "stream", cat({{0x00}, encode_stream({}, msgs[0])}));
}

// reassembler_fuzz: records of u16 length, u8 time step, datagram.
void reassembler_seeds(const fs::path& out, const std::vector<telex::proto::Message>& msgs) {
  using namespace telex::proto;
  Bytes seq;
  const Bytes big = encode(
      {}, DepthTile{1, 0, 0, 40, 30, Codec::Raw, encode_depth(tile(40, 30, 1, false), Codec::Raw)});
  const auto frags = fragment_message(big, 5, 9);
  for (const auto& f : frags)
    seq = cat({seq,
               {static_cast<std::uint8_t>(f.size()), static_cast<std::uint8_t>(f.size() >> 8), 1},
               f});
  write(out / "reassembler_fuzz", "fragments", seq);
  const auto one = fragment_message(encode({}, msgs[1]), 6, 9);
  write(out / "reassembler_fuzz", "single",
        cat({{static_cast<std::uint8_t>(one[0].size()), 0, 2}, one[0]}));
}

// depth_decode_fuzz: bytes w - 1, h - 1, codec (0 raw, 1 zip, 2 fast, 3 rvl-ref), bitstream.
void depth_decode_seeds(const fs::path& out) {
  using namespace telex::proto;
  for (int k = 0; k < 12; ++k) {
    const int w = 4 + 7 * k % 36, h = 3 + 5 * k % 28;
    const cv::Mat1w t = tile(w, h, k, k % 2 == 0);
    for (int c = 0; c < 4; ++c) {
      const Bytes bits = c == 3 ? rvl_ref_encode(t) : encode_depth(t, static_cast<Codec>(c));
      if (bits.size() > 500) continue;
      write(out / "depth_decode_fuzz", "t" + std::to_string(k) + "c" + std::to_string(c),
            cat({{static_cast<std::uint8_t>(w - 1), static_cast<std::uint8_t>(h - 1),
                  static_cast<std::uint8_t>(c)},
                 bits}));
    }
  }
}

// natnet_fuzz: byte 0 picks the version (index into 2.0 2.5 2.7 2.9 2.11 3.0 3.1 4.0 4.1 2.3
// 2.6), then a datagram.
void natnet_seeds(const fs::path& out) {
  using namespace telex::local::natnet;
  const Version versions[] = {{2, 0}, {2, 5}, {2, 7}, {2, 9}, {2, 11}, {3, 0},
                              {3, 1}, {4, 0}, {4, 1}, {2, 3}, {2, 6}};
  Frame f;
  f.frame_number = 42;
  f.marker_sets.push_back({"hand", {{0.1f, 0.2f, 0.3f}}});
  f.unlabeled_markers.push_back({1, 2, 3});
  RigidBody b;
  b.id = 2;
  b.p_m = {0.1f, 1.2f, 0.4f};
  b.markers.push_back({0.1f, 1.2f, 0.4f});
  f.rigid_bodies.push_back(b);
  f.skeletons.push_back({7, {b}});
  f.labeled_markers.push_back({65537, {0.5f, 0.5f, 0.5f}, 0.01f, 1, 0.001f});
  f.force_plates.push_back({1, {{1.0f, 2.0f}}});
  f.devices.push_back({2, {{3.0f}}});
  for (std::uint8_t i = 0; i < std::size(versions); ++i) {
    write(out / "natnet_fuzz",
          "frame_v" + std::to_string(versions[i].major) + "_" + std::to_string(versions[i].minor),
          cat({{i}, encode_frame(f, versions[i])}));
  }
  ServerInfo info;
  info.app_name = "Motive";
  info.natnet_version = {4, 1};
  info.natnet_version_bytes = {4, 1, 0, 0};
  write(out / "natnet_fuzz", "server_info", cat({{8}, make_server_info(info)}));
  write(out / "natnet_fuzz", "ping", cat({{8}, make_ping("telex")}));
}

// device_fuzz: byte 0 picks the parser (0 USB report, 1 wired serial, 2 wireless serial, 3 info
// reply, 4 Gravity Grabber device text), byte 1 the glove model for a USB report.
void device_seeds(const fs::path& out) {
  Bytes usb(64, 0);
  for (std::size_t i = 0; i < 16; ++i) usb[2 * i] = static_cast<std::uint8_t>(i);  // 256 i
  for (std::uint8_t m = 0; m < 3; ++m)
    write(out / "device_fuzz", "usb" + std::to_string(m), cat({{0, m}, usb}));
  const Bytes report{0x80, 10, 20, 30, 40, 50, 60, 70, 24};
  write(out / "device_fuzz", "serial", cat({{1, 0}, {0x12}, report, report}));
  Bytes wireless = report;
  wireless.push_back(0x01);
  write(out / "device_fuzz", "wireless", cat({{2, 0}, wireless, wireless}));
  Bytes info(32, 0);
  info[0] = 'B';
  info[1] = 'R';
  info[2] = 2;
  info[4] = 1;
  info[5] = 0x10;
  for (std::size_t i = 0; i < 6; ++i) info[16 + i] = static_cast<std::uint8_t>("DG5 R "[i]);
  write(out / "device_fuzz", "info", cat({{3, 0}, info}));
  for (const std::string t : {"/dev/hidraw3", "16c0:05df", "16c0:05df:GG-0042"})
    write(out / "device_fuzz", "target_" + std::to_string(t.size()),
          cat({{4, 0}, Bytes(t.begin(), t.end())}));
}

// bag_fuzz: small bags of every message type the adapter decodes, uncompressed (so mutations
// reach the message fields: an image's width, height, step and encoding) and LZ4.
void bag_seeds(const fs::path& out) {
  for (const auto compression : {telex::bag::Compression::None, telex::bag::Compression::Lz4}) {
    const bool lz4 = compression == telex::bag::Compression::Lz4;
    fs::create_directories(out / "bag_fuzz");
    const fs::path file = out / "bag_fuzz" / (lz4 ? "session_lz4.bag" : "session.bag");
    {
      telex::bag::Writer w(file.string(), compression);
      const std::int64_t t0 = 1'700'000'000'000'000'000;
      const telex::bag::CameraIntrinsics k{5.0, 5.0, 1.5, 1.0, 4, 3};
      cv::Mat1w mm(3, 4);
      for (int i = 0; i < 12; ++i) mm(i / 4, i % 4) = static_cast<std::uint16_t>(400 + 37 * i);
      w.depth_mm("/d", "/camera_info", t0, 1, "c", mm, k);
      cv::Mat1f m(3, 4, 0.8f);
      m(1, 1) = std::numeric_limits<float>::quiet_NaN();
      w.depth_m("/f", "/f_info", t0 + 1, 2, "c", m, k);
      w.colour("/rgb", t0 + 2, "c", cv::Mat3b(3, 4, cv::Vec3b(1, 2, 3)));
      w.tf(t0 + 3, {{"a", "b", {{0.1, 0.2, 0.3}, {0, 0, 0, 1}}}});
      w.poses("/p", t0 + 4, 3, "c", {{{1, 2, 3}, {0, 0, 0, 1}}, {{4, 5, 6}, {0, 0, 0, 0}}});
      w.wrench("/w", t0 + 5, "c", {1, 2, 3}, {0, 0, 0});
      w.text("/s", t0 + 6, "{\"rate_hz\": 1000}");
    }
    ++g_written;
  }
  // One small uncompressed bag per message type: a mutation costs less to run.
  const std::int64_t t0 = 1'700'000'000'000'000'000;
  auto one = [&](const char* name, auto&& write_into) {
    telex::bag::Writer w((out / "bag_fuzz" / name).string(), telex::bag::Compression::None);
    write_into(w);
    ++g_written;
  };
  one("image_16uc1.bag", [&](telex::bag::Writer& w) {
    w.depth_mm("/d", "", t0, 1, "c", cv::Mat1w(2, 3, std::uint16_t(900)), {});
  });
  one("image_32fc1.bag",
      [&](telex::bag::Writer& w) { w.depth_m("/d", "", t0, 1, "c", cv::Mat1f(2, 3, 0.9f), {}); });
  one("image_bgr8.bag", [&](telex::bag::Writer& w) {
    w.colour("/rgb", t0, "c", cv::Mat3b(2, 3, cv::Vec3b(1, 2, 3)));
  });
  one("wrench.bag", [&](telex::bag::Writer& w) { w.wrench("/w", t0, "c", {1, 2, 3}, {4, 5, 6}); });
  one("poses.bag", [&](telex::bag::Writer& w) {
    w.poses("/p", t0, 2, "c", {{{1, 2, 3}, {0, 0, 0, 1}}});
  });
  one("tf.bag", [&](telex::bag::Writer& w) { w.tf(t0, {{"a", "b", {{1, 2, 3}, {0, 0, 0, 1}}}}); });
  one("text.bag", [&](telex::bag::Writer& w) { w.text("/s", t0, "{}"); });
}

// dynamixel_fuzz: byte 0 = bit 0 kind (0 status, 1 instruction), bit 1 small bound, bits 2..7
// chunk size - 1; then a byte stream of packets, one with stuffing.
void dynamixel_seeds(const fs::path& out) {
  namespace dxl = telex::dynamixel;
  const std::uint8_t ids[] = {1, 2, 3};
  const Bytes goals = cat({dxl::le_bytes(2048, 4), dxl::le_bytes(3072, 4), dxl::le_bytes(1024, 4)});
  const Bytes status = cat({dxl::status_packet(1, 0, Bytes{0x06, 0x04, 0x26}),
                            dxl::status_packet(2, 0, dxl::le_bytes(2079, 4)),
                            dxl::status_packet(3, 0x80, Bytes{0xFF, 0xFF, 0xFD, 0x00}),
                            dxl::status_packet(1, 0x07, {})});
  const Bytes instructions =
      cat({dxl::ping_packet(1), dxl::read_packet(2, 132, 4),
           dxl::write_packet(3, 116, Bytes{0xFF, 0xFF, 0xFD, 0x00}),
           dxl::sync_read_packet(132, 4, ids), dxl::sync_write_packet(116, 4, ids, goals)});
  write(out / "dynamixel_fuzz", "status", cat({{0x00}, status}));
  write(out / "dynamixel_fuzz", "status_chunks", cat({{0x0E}, status}));
  write(out / "dynamixel_fuzz", "instructions", cat({{0x01}, instructions}));
  write(out / "dynamixel_fuzz", "instructions_small", cat({{0x23}, instructions}));
  write(out / "dynamixel_fuzz", "mixed_with_garbage",
        cat({{0x40}, Bytes{0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x13}, instructions, status}));
}

// video_header_fuzz: one whole encoded pair (header + payload).
void video_seeds(const fs::path& out) {
  namespace video = telex::video;
  const auto pair = [](video::VideoCodec codec, bool intra, const Bytes& payload) {
    video::EncodedFrameHeader h;
    h.frame_id = 41;
    h.encode_seq = 7;
    h.capture_ns = 1'700'000'000'123'456'789;
    h.codec = codec;
    h.is_intra = intra;
    h.eye_width_px = 1280;
    h.eye_height_px = 720;
    h.payload_bytes = static_cast<std::uint32_t>(payload.size());
    Bytes b;
    video::serialize_header(h, b);
    return cat({b, payload});
  };
  write(out / "video_header_fuzz", "h264_idr",
        pair(video::VideoCodec::H264, true, Bytes{0, 0, 0, 1, 0x65, 0x88, 0x84}));
  write(out / "video_header_fuzz", "h264_p",
        pair(video::VideoCodec::H264, false, Bytes{0, 0, 0, 1, 0x41, 0x9a}));
  write(out / "video_header_fuzz", "mjpeg",
        pair(video::VideoCodec::Mjpeg, true, Bytes{2, 0, 0, 0, 0xff, 0xd8, 0xff, 0xd8}));
  write(out / "video_header_fuzz", "empty_payload", pair(video::VideoCodec::H264, false, {}));
  // With the robot head's joints at capture (flag bit 1, three f32 before the payload).
  Bytes posed = pair(video::VideoCodec::H264, false, Bytes{0, 0, 0, 1, 0x41, 0x9a});
  video::stamp_head_pose(posed, {0.5f, -0.25f, 0.0f});
  write(out / "video_header_fuzz", "h264_head_pose", posed);
  // Protocol 7's posed pairs: intra MJPEG, joints at the bounds (+-pi), no payload, widest eyes.
  Bytes mjpeg = pair(video::VideoCodec::Mjpeg, true, Bytes{2, 0, 0, 0, 0xff, 0xd8, 0xff, 0xd8});
  video::stamp_head_pose(mjpeg, {-0.1f, 0.2f, -0.3f});
  write(out / "video_header_fuzz", "mjpeg_head_pose", mjpeg);
  const float pi = 3.14159265358979323846f;
  Bytes bounds = pair(video::VideoCodec::H264, true, Bytes{0, 0, 0, 1, 0x65});
  video::stamp_head_pose(bounds, {pi, -pi, 0.0f});
  write(out / "video_header_fuzz", "h264_head_pose_pi", bounds);
  Bytes empty = pair(video::VideoCodec::H264, false, {});
  video::stamp_head_pose(empty, {0.0f, 0.0f, 0.0f});
  write(out / "video_header_fuzz", "empty_payload_head_pose", empty);
  video::EncodedFrameHeader wide;
  wide.codec = video::VideoCodec::Mjpeg;
  wide.eye_width_px = video::kMaxEyeSidePx;
  wide.eye_height_px = 1;
  wide.head_joint_rad = std::array<float, 3>{1.0f, 1.0f, 1.0f};
  Bytes w;
  video::serialize_header(wide, w);
  write(out / "video_header_fuzz", "mjpeg_widest_head_pose", w);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  using namespace telex::proto;
  const fs::path out = argv[1];
  const auto msgs = messages();

  stream_seeds(out, msgs);
  tls_record_seeds(out, msgs);
  reassembler_seeds(out, msgs);
  depth_decode_seeds(out);
  natnet_seeds(out);
  device_seeds(out);
  bag_seeds(out);
  dynamixel_seeds(out);
  video_seeds(out);
  natnet_reply_seeds(out / "natnet_reply_fuzz");
  config_seeds(out / "config_fuzz");
  std::printf("wrote %d seeds under %s\n", g_written, out.c_str());
  return 0;
}
