// SPDX-License-Identifier: MIT
// NatNet parser on byte arrays written out by hand per version, truncations, and mutations.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "telex/natnet/natnet.h"

namespace telex::local::natnet {
namespace {

// Deliberately separate from the library's writer, so that a layout mistake has to be made twice
// (once here by hand, once in natnet.cpp) to go unnoticed.
struct Bytes {
  std::vector<std::uint8_t> b;
  Bytes& i16(std::int16_t v) { return raw(&v, 2); }
  Bytes& u16(std::uint16_t v) { return raw(&v, 2); }
  Bytes& i32(std::int32_t v) { return raw(&v, 4); }
  Bytes& u32(std::uint32_t v) { return raw(&v, 4); }
  Bytes& u64(std::uint64_t v) { return raw(&v, 8); }
  Bytes& f32(float v) { return raw(&v, 4); }
  Bytes& f64(double v) { return raw(&v, 8); }
  Bytes& xyz(float x, float y, float z) { return f32(x).f32(y).f32(z); }
  Bytes& str(const char* s) { return raw(s, std::strlen(s) + 1); }
  Bytes& raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    b.insert(b.end(), c, c + n);
    return *this;
  }
  std::size_t size() const { return b.size(); }
  void patch_u32(std::size_t at, std::uint32_t v) { std::memcpy(b.data() + at, &v, 4); }
};

// One frame: a marker set "hand" with 2 markers, 1 unlabeled marker, 2 rigid bodies (id 1 head,
// id 2 hand, the hand not tracked), 1 skeleton with 1 bone, 1 labeled marker, 1 force plate with
// 2 channels, 1 device with 1 channel. Each field is written in the order, and under the version
// condition, of NaturalPoint's reference decoder: PacketClient.cpp's Unpack() of SDK 2.5 .. 3.1
// (mje-nz/natnet-sdk-mirror) and NatNetClient.py's __unpack_mocap_data() of SDK 4.x, whose
// __unpack_data_size() reads the 4.1 section byte counts.
std::vector<std::uint8_t> hand_built_frame(Version v, bool with_assets = true) {
  Bytes p;
  const bool sized = v.at_least(4, 1);
  auto section = [&](auto&& body) {
    std::size_t at = 0;
    if (sized) {
      at = p.size();
      p.u32(0);
    }
    const std::size_t start = p.size();
    body();
    if (sized) p.patch_u32(at, static_cast<std::uint32_t>(p.size() - start));
  };
  auto rigid_body = [&](std::int32_t id, float x, bool valid) {
    p.i32(id).xyz(x, 1.5f, -0.25f).f32(0.0f).f32(0.0f).f32(0.70710678f).f32(0.70710678f);
    if (v.major < 3) {                         // 3.0 dropped the rigid body's marker list
      p.i32(1).xyz(x + 0.01f, 1.5f, -0.25f);   // one marker
      if (v.major >= 2) p.i32(1).f32(0.014f);  // its id and size (2.0+)
    }
    if (v.major >= 2) p.f32(0.0004f);            // mean error (2.0+)
    if (v.at_least(2, 6)) p.i16(valid ? 1 : 0);  // params, bit 0 tracking valid (2.6+)
  };
  p.u32(4711);
  p.i32(1);
  section([&] { p.str("hand").i32(2).xyz(1, 2, 3).xyz(4, 5, 6); });
  p.i32(1);
  section([&] { p.xyz(-1, -2, -3); });
  p.i32(2);
  section([&] {
    rigid_body(1, 0.25f, true);
    rigid_body(2, 0.5f, false);
  });
  if (v.at_least(2, 1)) {  // skeletons
    p.i32(1);
    section([&] {
      p.i32(9).i32(1);
      rigid_body(0x90001, 0.75f, true);
    });
  }
  if (v.at_least(4, 1)) {  // assets (4.1+), skipped by byte count
    if (with_assets)
      p.i32(3).u32(5).raw("ABCDE", 5);
    else
      p.i32(0).u32(0);
  }
  if (v.at_least(2, 3)) {  // labeled markers
    p.i32(1);
    section([&] {
      p.i32((2 << 16) | 5).xyz(0.1f, 0.2f, 0.3f).f32(0.015f);
      if (v.at_least(2, 6)) p.i16(4);    // params
      if (v.major >= 3) p.f32(0.0002f);  // residual
    });
  }
  if (v.at_least(2, 9)) {  // force plates
    p.i32(1);
    section([&] { p.i32(31).i32(2).i32(1).f32(9.5f).i32(2).f32(1.0f).f32(2.0f); });
  }
  if (v.at_least(2, 11)) {  // devices
    p.i32(1);
    section([&] { p.i32(41).i32(1).i32(1).f32(-3.0f); });
  }
  if (v.major < 3) p.f32(0.0125f);                 // "software latency (removed in version 3.0)"
  if (v.at_least(2, 3)) p.u32(0x01020304).u32(5);  // timecode, sub-frame (2.3 change log)
  if (v.at_least(2, 7))
    p.f64(12.345);  // "2.7 and later - increased from single to double precision"
  else if (v.at_least(2, 6))
    p.f32(12.5f);                                  // timestamp added in 2.6 (its change log)
  if (v.major >= 3) p.u64(111).u64(222).u64(333);  // "high res timestamps (version 3.0 and later)"
  if (v.at_least(4, 1)) p.u32(44).u32(55);         // precision timestamp: NatNet 4.1 and later
  if (v.at_least(2, 6)) p.i16(2);                  // frame params (2.6)
  p.u32(0);                                        // end of data tag
  Bytes d;
  d.u16(7).u16(static_cast<std::uint16_t>(p.size())).raw(p.b.data(), p.size());
  return d.b;
}

// The versions of the SDKs whose decoders were read, and the boundaries between them.
const Version kVersions[] = {{2, 0},  {2, 3},  {2, 5}, {2, 6}, {2, 7}, {2, 9},
                             {2, 10}, {2, 11}, {3, 0}, {3, 1}, {4, 0}, {4, 1}};

class NatNetVersions : public ::testing::TestWithParam<Version> {};

TEST_P(NatNetVersions, ParsesHandBuiltFrame) {
  const Version v = GetParam();
  const auto bytes = hand_built_frame(v);
  PacketView pkt;
  ASSERT_TRUE(parse_packet(bytes, pkt).ok());
  EXPECT_EQ(pkt.message_id, kFrameOfData);
  Frame f;
  const ParseStatus st = parse_frame(pkt.payload, v, f);
  ASSERT_TRUE(st.ok()) << st.reason << " at " << st.offset;
  EXPECT_EQ(f.frame_number, 4711u);
  ASSERT_EQ(f.marker_sets.size(), 1u);
  EXPECT_EQ(f.marker_sets[0].name, "hand");
  ASSERT_EQ(f.marker_sets[0].markers.size(), 2u);
  EXPECT_EQ(f.marker_sets[0].markers[1], (Vec3f{4, 5, 6}));
  ASSERT_EQ(f.unlabeled_markers.size(), 1u);
  EXPECT_EQ(f.unlabeled_markers[0], (Vec3f{-1, -2, -3}));
  ASSERT_EQ(f.rigid_bodies.size(), 2u);
  const RigidBody* hand = f.find_body(2);
  ASSERT_NE(hand, nullptr);
  EXPECT_FLOAT_EQ(hand->p_m.x, 0.5f);
  EXPECT_FLOAT_EQ(hand->p_m.y, 1.5f);
  EXPECT_FLOAT_EQ(hand->qw, 0.70710678f);
  EXPECT_EQ(hand->markers.size(), v.major < 3 ? 1u : 0u);
  EXPECT_FLOAT_EQ(hand->mean_error_m, v.major >= 2 ? 0.0004f : 0.0f);
  // Tracking validity only exists from 2.6; older servers imply valid.
  EXPECT_EQ(hand->tracking_valid, !v.at_least(2, 6));
  EXPECT_TRUE(f.find_body(1)->tracking_valid);
  EXPECT_EQ(f.skeletons.size(), v.at_least(2, 1) ? 1u : 0u);
  if (v.at_least(2, 1)) {
    ASSERT_EQ(f.skeletons[0].bones.size(), 1u);
    EXPECT_EQ(f.skeletons[0].bones[0].id, 0x90001);
  }
  EXPECT_EQ(f.asset_count, v.at_least(4, 1) ? 3 : 0);
  ASSERT_EQ(f.labeled_markers.size(), v.at_least(2, 3) ? 1u : 0u);
  if (v.at_least(2, 3)) {
    EXPECT_EQ(f.labeled_markers[0].id, (2 << 16) | 5);
    EXPECT_EQ(f.labeled_markers[0].params, v.at_least(2, 6) ? 4 : 0);
    EXPECT_FLOAT_EQ(f.labeled_markers[0].residual_m, v.major >= 3 ? 0.0002f : 0.0f);
  }
  ASSERT_EQ(f.force_plates.size(), v.at_least(2, 9) ? 1u : 0u);
  if (v.at_least(2, 9)) {
    ASSERT_EQ(f.force_plates[0].channels.size(), 2u);
    EXPECT_FLOAT_EQ(f.force_plates[0].channels[1][1], 2.0f);
  }
  ASSERT_EQ(f.devices.size(), v.at_least(2, 11) ? 1u : 0u);
  EXPECT_FLOAT_EQ(f.software_latency_s, v.major < 3 ? 0.0125f : 0.0f);
  EXPECT_EQ(f.timecode, v.at_least(2, 3) ? 0x01020304u : 0u);
  EXPECT_EQ(f.timecode_sub, v.at_least(2, 3) ? 5u : 0u);
  EXPECT_DOUBLE_EQ(f.timestamp_s, v.at_least(2, 7) ? 12.345 : v.at_least(2, 6) ? 12.5 : 0.0);
  EXPECT_EQ(f.stamp_mid_exposure, v.major >= 3 ? 111u : 0u);
  EXPECT_EQ(f.stamp_transmit, v.major >= 3 ? 333u : 0u);
  EXPECT_EQ(f.precision_s, v.at_least(4, 1) ? 44u : 0u);
  EXPECT_EQ(f.precision_frac, v.at_least(4, 1) ? 55u : 0u);
  EXPECT_EQ(f.params, v.at_least(2, 6) ? 2 : 0);
}

// The library's writer (which the simulator and the fuzz seeds use) gives the reference layout
// byte for byte: the hand-built packet, parsed and written again, is the same bytes.
TEST_P(NatNetVersions, EncoderWritesTheReferenceLayoutByteForByte) {
  const Version v = GetParam();
  const auto bytes = hand_built_frame(v, /*with_assets=*/false);  // the writer sends no assets
  Frame f;
  const ParseStatus st = parse_frame(std::span<const std::uint8_t>(bytes).subspan(4), v, f);
  ASSERT_TRUE(st.ok()) << st.reason;
  EXPECT_EQ(encode_frame(f, v), bytes);
}

// Each version's layout is not another's: parsing the frame under the neighbouring version is an
// error (the tail no longer ends in the zero end-of-data tag), never a silently shifted frame.
TEST_P(NatNetVersions, NeighbouringVersionsDoNotParseEachOther) {
  const Version v = GetParam();
  const auto bytes = hand_built_frame(v);
  const auto payload = std::span<const std::uint8_t>(bytes).subspan(4);
  for (const Version other : kVersions) {
    if (other == v) continue;
    if (hand_built_frame(other) == bytes) continue;  // no layout change between them (3.0, 3.1)
    Frame f;
    EXPECT_FALSE(parse_frame(payload, other, f).ok())
        << v.major << "." << v.minor << " bytes parsed as " << other.major << "." << other.minor;
  }
}

TEST_P(NatNetVersions, EveryTruncationIsRejectedWithAReason) {
  const Version v = GetParam();
  const auto bytes = hand_built_frame(v);
  const std::span<const std::uint8_t> payload(bytes.data() + 4, bytes.size() - 4);
  Frame f;
  for (std::size_t n = 0; n < payload.size(); ++n) {
    // A fresh heap copy of exactly n bytes, so a read past the end is a real out-of-bounds read
    // under the sanitizer build.
    std::vector<std::uint8_t> cut(payload.begin(), payload.begin() + static_cast<long>(n));
    const ParseStatus st = parse_frame(cut, v, f);
    ASSERT_FALSE(st.ok()) << "accepted a frame cut to " << n << " bytes";
    EXPECT_LE(st.offset, n);
  }
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + static_cast<long>(n));
    PacketView pkt;
    EXPECT_FALSE(parse_packet(cut, pkt).ok()) << "datagram cut to " << n;
  }
}

TEST_P(NatNetVersions, EncoderRoundTripsThroughTheParser) {
  const Version v = GetParam();
  Frame in;
  in.frame_number = 99;
  in.marker_sets.push_back({"all", {{1, 2, 3}}});
  in.unlabeled_markers = {{7, 8, 9}, {1, 1, 1}};
  RigidBody rb;
  rb.id = 3;
  rb.p_m = {0.1f, 0.2f, 0.3f};
  rb.qx = 0.5f;
  rb.qy = 0.5f;
  rb.qz = 0.5f;
  rb.qw = 0.5f;
  rb.mean_error_m = 0.001f;
  in.rigid_bodies = {rb, rb};
  in.rigid_bodies[1].id = 4;
  in.skeletons.push_back({5, {rb}});
  in.labeled_markers.push_back({12, {3, 2, 1}, 0.01f, 0, 0});
  in.force_plates.push_back({1, {{1.0f, 2.0f}}});
  in.devices.push_back({2, {{3.0f}, {4.0f}}});
  in.timestamp_s = 3.25;
  in.params = 1;
  const auto bytes = encode_frame(in, v);
  PacketView pkt;
  ASSERT_TRUE(parse_packet(bytes, pkt).ok());
  Frame out;
  const ParseStatus st = parse_frame(pkt.payload, v, out);
  ASSERT_TRUE(st.ok()) << st.reason;
  EXPECT_EQ(out.frame_number, 99u);
  EXPECT_EQ(out.unlabeled_markers, in.unlabeled_markers);
  ASSERT_EQ(out.rigid_bodies.size(), 2u);
  EXPECT_EQ(out.rigid_bodies[1].id, 4);
  EXPECT_EQ(out.rigid_bodies[0].p_m, rb.p_m);
  EXPECT_FLOAT_EQ(out.rigid_bodies[0].qz, 0.5f);
  EXPECT_EQ(out.skeletons.size(), v.at_least(2, 1) ? 1u : 0u);
  EXPECT_EQ(out.devices.size(), v.at_least(2, 11) ? 1u : 0u);
  // Before 2.6 a frame carries neither its timestamp nor its params.
  EXPECT_DOUBLE_EQ(out.timestamp_s, v.at_least(2, 6) ? 3.25 : 0.0);
  EXPECT_EQ(out.params, v.at_least(2, 6) ? 1 : 0);
}

INSTANTIATE_TEST_SUITE_P(Layouts, NatNetVersions, ::testing::ValuesIn(kVersions),
                         [](const auto& info) {
                           return "v" + std::to_string(info.param.major) + "_" +
                                  std::to_string(info.param.minor);
                         });

std::span<const std::uint8_t> payload_of(const std::vector<std::uint8_t>& d) {
  return {d.data() + 4, d.size() - 4};
}

TEST(NatNetParser, RejectsCorruptCountsAndMarkers) {
  const Version v{3, 1};
  Frame f;
  auto bytes = hand_built_frame(v);
  // Marker set count (payload offset 4) claiming two billion sets.
  auto bad = bytes;
  const std::int32_t huge = 0x7FFFFFFF;
  std::memcpy(bad.data() + 4 + 4, &huge, 4);
  EXPECT_STREQ(parse_frame(payload_of(bad), v, f).reason,
               "count exceeds the bytes left in the packet");
  const std::int32_t negative = -1;
  std::memcpy(bad.data() + 4 + 4, &negative, 4);
  EXPECT_STREQ(parse_frame(payload_of(bad), v, f).reason, "negative count");
  // Non-zero end-of-data.
  bad = bytes;
  bad.back() = 1;
  EXPECT_STREQ(parse_frame(payload_of(bad), v, f).reason, "end-of-data marker is not zero");
  // Marker set name running to the end without a NUL.
  Bytes p;
  p.u32(1).i32(1).raw("abcdefgh", 8);
  EXPECT_STREQ(parse_frame(p.b, v, f).reason, "marker set name without terminating NUL");
  EXPECT_FALSE(parse_frame(payload_of(bytes), Version{5, 0}, f).ok());
}

// Up to 4.1 a frame ends at its end-of-data marker; a later 4.x may append fields we do not read.
TEST(NatNetParser, BytesAfterTheEndAreAnotherLayoutUpTo41) {
  for (const Version v : {Version{3, 1}, Version{4, 1}, Version{4, 2}}) {
    auto bytes = hand_built_frame(v == Version{4, 2} ? Version{4, 1} : v);
    bytes.push_back(0);
    Frame f;
    const ParseStatus st = parse_frame(payload_of(bytes), v, f);
    if (v == Version{4, 2}) {
      EXPECT_TRUE(st.ok()) << st.reason;
    } else {
      ASSERT_FALSE(st.ok());
      EXPECT_STREQ(st.reason, "bytes after the end-of-data marker");
    }
  }
}

TEST(NatNetParser, RejectsSectionByteCountMismatchIn41) {
  const Version v{4, 1};
  auto bytes = hand_built_frame(v);
  // The marker set section's byte count sits right after frame number and count.
  std::uint32_t n = 0;
  std::memcpy(&n, bytes.data() + 4 + 8, 4);
  ++n;
  std::memcpy(bytes.data() + 4 + 8, &n, 4);
  Frame f;
  EXPECT_STREQ(parse_frame(payload_of(bytes), v, f).reason,
               "section byte count does not match its contents");
}

TEST(NatNetParser, ServerInfoAndPing) {
  ServerInfo info;
  info.app_name = "Motive";
  info.app_version = {3, 0, 1, 0};
  info.natnet_version = {4, 1};
  const auto d = make_server_info(info);
  ASSERT_EQ(d.size(), 4u + 279u) << "3.0+: sSender_Server, as Motive 2.1 sends it";
  info.natnet_version = {2, 9};
  EXPECT_EQ(make_server_info(info).size(), 4u + 264u) << "2.x: sSender";
  info.natnet_version = {4, 1};
  EXPECT_EQ(d[0], 1);  // PINGRESPONSE
  PacketView pkt;
  ASSERT_TRUE(parse_packet(d, pkt).ok());
  ServerInfo got;
  ASSERT_TRUE(parse_server_info(pkt.payload, got).ok());
  EXPECT_EQ(got.app_name, "Motive");
  EXPECT_EQ(got.natnet_version, (Version{4, 1}));
  EXPECT_EQ(got.app_version[0], 3);
  EXPECT_STREQ(parse_server_info(pkt.payload.first(263), got).reason,
               "server info shorter than 264 bytes");

  const auto ping = make_ping("telex-local");
  ASSERT_EQ(ping.size(), 4u + 12u);
  EXPECT_EQ(ping[0], 0);
  EXPECT_EQ(ping[2], 12);
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(ping.data() + 4)), "telex-local");
}

TEST(NatNetParser, VersionText) {
  EXPECT_EQ(parse_version("3.1"), (Version{3, 1}));
  EXPECT_EQ(parse_version("4.1.0.0"), (Version{4, 1}));
  EXPECT_EQ(parse_version("2"), (Version{2, 0}));
  EXPECT_THROW(parse_version("1.4"), std::invalid_argument);
  EXPECT_THROW(parse_version("3.x"), std::invalid_argument);
  EXPECT_THROW(parse_version(""), std::invalid_argument);
}

// Random byte flips, insertions, deletions and count overwrites on valid frames of every layout:
// the parser must answer (accept or reject with an offset inside the input) and never crash.
TEST(NatNetParser, BoundedRandomMutations) {
  std::mt19937 rng(20261121);
  Frame f;
  std::size_t rejected = 0, total = 0;
  for (const Version v : kVersions) {
    const auto base = hand_built_frame(v);
    for (int iter = 0; iter < 3000; ++iter) {
      std::vector<std::uint8_t> m(base.begin() + 4, base.end());
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits && !m.empty(); ++e) {
        const std::size_t at = rng() % m.size();
        switch (rng() % 4) {
          case 0:
            m[at] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
            break;
          case 1:
            m.insert(m.begin() + static_cast<long>(at), static_cast<std::uint8_t>(rng()));
            break;
          case 2:
            m.erase(m.begin() + static_cast<long>(at));
            break;
          default:
            if (at + 4 <= m.size()) {
              const std::uint32_t c = rng();
              std::memcpy(m.data() + at, &c, 4);
            }
        }
      }
      const ParseStatus st = parse_frame(m, v, f);
      ++total;
      if (!st.ok()) {
        ++rejected;
        EXPECT_LE(st.offset, m.size());
      }
    }
  }
  // Most mutations break the layout; a parser that accepted everything would be checking nothing.
  EXPECT_GT(rejected, total / 2);
}

}  // namespace
}  // namespace telex::local::natnet
