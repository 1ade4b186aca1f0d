// SPDX-License-Identifier: MIT
// DYNAMIXEL Protocol 2.0 packets byte for byte against ROBOTIS's examples, stuffing, the parser.
#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "telex/dynamixel/protocol.h"

namespace telex::dynamixel {
namespace {

using Bytes = std::vector<std::uint8_t>;

// The examples of the ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0" (emanual.robotis.com/docs/en/dxl/
// protocol2/, source ROBOTIS-GIT/emanual docs/en/dxl/protocol2.md), recorded as printed there:
// XM430-W210 servos, model 1030, firmware 38.
const Bytes kPingId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E};
const Bytes kPingBroadcast = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x03, 0x00, 0x01, 0x31, 0x42};
const Bytes kPingStatusId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00,
                              0x55, 0x00, 0x06, 0x04, 0x26, 0x65, 0x5D};
const Bytes kPingStatusId2 = {0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x07, 0x00,
                              0x55, 0x00, 0x06, 0x04, 0x26, 0x6F, 0x6D};
// Read Present Position (132, 4 bytes) of id 1 = 166.
const Bytes kReadId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00,
                        0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15};
const Bytes kReadStatusId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55,
                              0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C, 0xC0};
// Write 512 to Goal Position (116, 4 bytes) of id 1.
const Bytes kWriteId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x03,
                         0x74, 0x00, 0x00, 0x02, 0x00, 0x00, 0xCA, 0x89};
const Bytes kEmptyStatusId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x55, 0x00, 0xA1, 0x0C};
// Sync Read of Present Position from ids 1 (166) and 2 (2079).
const Bytes kSyncRead = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x09, 0x00, 0x82,
                         0x84, 0x00, 0x04, 0x00, 0x01, 0x02, 0xCE, 0xFA};
const Bytes kSyncReadStatusId2 = {0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x08, 0x00, 0x55,
                                  0x00, 0x1F, 0x08, 0x00, 0x00, 0xBA, 0xBE};
// Sync Write of Goal Position: id 1 = 150, id 2 = 170.
const Bytes kSyncWrite = {0xFF, 0xFF, 0xFD, 0x00, 0xFE, 0x11, 0x00, 0x83, 0x74, 0x00, 0x04, 0x00,
                          0x01, 0x96, 0x00, 0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00, 0x82, 0x87};
// The other instructions' examples, for the CRC: Reg Write, Action, Factory Reset, Reboot, Clear,
// and the Bulk Read's two answers.
const Bytes kRegWrite = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x09, 0x00, 0x04,
                         0x68, 0x00, 0xC8, 0x00, 0x00, 0x00, 0xAE, 0x8E};
const Bytes kAction = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x05, 0x02, 0xCE};
const Bytes kFactoryReset = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x04, 0x00, 0x06, 0x01, 0xA1, 0xE6};
const Bytes kReboot = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x08, 0x2F, 0x4E};
const Bytes kClear = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x10,
                      0x01, 0x44, 0x58, 0x4C, 0x22, 0xB1, 0xDC};
const Bytes kBulkReadStatusId1 = {0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x06, 0x00,
                                  0x55, 0x00, 0x77, 0x00, 0xC3, 0x69};
const Bytes kBulkReadStatusId2 = {0xFF, 0xFF, 0xFD, 0x00, 0x02, 0x05,
                                  0x00, 0x55, 0x00, 0x24, 0x8B, 0xA9};

Bytes cat(std::initializer_list<Bytes> parts) {
  Bytes out;
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

std::vector<ParseResult> parse_all(PacketParser& parser, std::span<const std::uint8_t> bytes) {
  std::vector<ParseResult> out;
  while (!bytes.empty()) {
    bytes = bytes.subspan(parser.feed(bytes));
    while (auto r = parser.next()) out.push_back(*r);
  }
  return out;
}

std::vector<ParseResult> parse_all(PacketKind kind, std::span<const std::uint8_t> bytes) {
  PacketParser parser(kind);
  return parse_all(parser, bytes);
}

TEST(DynamixelCrc, MatchesTheSdkTable) {
  // With crc = 0 one byte b gives table[b]: values from the DynamixelSDK's updateCRC table.
  const std::pair<std::uint8_t, std::uint16_t> entries[] = {
      {0x00, 0x0000}, {0x01, 0x8005}, {0x02, 0x800F}, {0x03, 0x000A},
      {0x08, 0x8033}, {0x10, 0x8063}, {0xFE, 0x8207}, {0xFF, 0x0202}};
  for (const auto& [b, value] : entries) {
    const std::uint8_t one[] = {b};
    EXPECT_EQ(crc16(one), value) << "table entry " << int(b);
  }
}

TEST(DynamixelCrc, EveryRecordedPacketsCrcMatches) {
  for (const Bytes* p :
       {&kPingId1, &kPingBroadcast, &kPingStatusId1, &kPingStatusId2, &kReadId1, &kReadStatusId1,
        &kWriteId1, &kEmptyStatusId1, &kSyncRead, &kSyncReadStatusId2, &kSyncWrite, &kRegWrite,
        &kAction, &kFactoryReset, &kReboot, &kClear, &kBulkReadStatusId1, &kBulkReadStatusId2}) {
    const std::uint16_t crc = crc16(std::span(*p).first(p->size() - 2));
    EXPECT_EQ(crc & 0xFF, p->at(p->size() - 2));
    EXPECT_EQ(crc >> 8, p->at(p->size() - 1));
  }
}

TEST(DynamixelEncode, InstructionsAreTheEmanualsBytes) {
  EXPECT_EQ(ping_packet(1), kPingId1);
  EXPECT_EQ(ping_packet(kBroadcastId), kPingBroadcast);
  EXPECT_EQ(read_packet(1, xseries::kPresentPosition, 4), kReadId1);
  EXPECT_EQ(write_packet(1, xseries::kGoalPosition, le_bytes(512, 4)), kWriteId1);
  const std::uint8_t ids[] = {1, 2};
  EXPECT_EQ(sync_read_packet(xseries::kPresentPosition, 4, ids), kSyncRead);
  const Bytes goals = cat({le_bytes(150, 4), le_bytes(170, 4)});
  EXPECT_EQ(sync_write_packet(xseries::kGoalPosition, 4, ids, goals), kSyncWrite);
  const std::uint8_t reg[] = {0x68, 0x00, 0xC8, 0x00, 0x00, 0x00};
  EXPECT_EQ(encode_packet(1, 0x04, reg), kRegWrite);
  EXPECT_EQ(encode_packet(1, 0x05, {}), kAction);
  const std::uint8_t reset_option[] = {0x01};
  EXPECT_EQ(encode_packet(1, 0x06, reset_option), kFactoryReset);
  EXPECT_EQ(encode_packet(1, 0x08, {}), kReboot);
  const std::uint8_t clear[] = {0x01, 0x44, 0x58, 0x4C, 0x22};
  EXPECT_EQ(encode_packet(1, 0x10, clear), kClear);
}

TEST(DynamixelEncode, StatusPacketsAreTheEmanualsBytes) {
  const std::uint8_t info[] = {0x06, 0x04, 0x26};
  EXPECT_EQ(status_packet(1, 0, info), kPingStatusId1);
  EXPECT_EQ(status_packet(2, 0, info), kPingStatusId2);
  EXPECT_EQ(status_packet(1, 0, le_bytes(166, 4)), kReadStatusId1);
  EXPECT_EQ(status_packet(2, 0, le_bytes(2079, 4)), kSyncReadStatusId2);
  EXPECT_EQ(status_packet(1, 0, {}), kEmptyStatusId1);
  EXPECT_EQ(status_packet(1, 0, le_bytes(119, 2)), kBulkReadStatusId1);
  EXPECT_EQ(status_packet(2, 0, le_bytes(36, 1)), kBulkReadStatusId2);
}

TEST(DynamixelParse, StatusPacketsDecodeToTheirValues) {
  const Bytes stream = cat({kPingStatusId1, kReadStatusId1, kSyncReadStatusId2, kEmptyStatusId1});
  const auto r = parse_all(PacketKind::Status, stream);
  ASSERT_EQ(r.size(), 4u);
  for (const auto& x : r) EXPECT_EQ(x.error, ParseError::None);
  EXPECT_EQ(r[0].packet.id, 1);
  EXPECT_EQ(r[0].packet.instruction, 0x55);
  EXPECT_EQ(r[0].packet.error, 0);
  EXPECT_EQ(le_value(std::span(r[0].packet.params).first(2)), 1030u);  // XM430-W210
  EXPECT_EQ(r[0].packet.params[2], 38);
  EXPECT_EQ(le_value(r[1].packet.params), 166u);
  EXPECT_EQ(r[2].packet.id, 2);
  EXPECT_EQ(le_value(r[2].packet.params), 2079u);
  EXPECT_TRUE(r[3].packet.params.empty());
}

TEST(DynamixelParse, InstructionPacketsDecodeForADevice) {
  const auto r = parse_all(PacketKind::Instruction, cat({kSyncWrite, kPingId1, kSyncRead}));
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0].packet.id, kBroadcastId);
  EXPECT_EQ(r[0].packet.instruction, static_cast<std::uint8_t>(Instruction::SyncWrite));
  EXPECT_EQ(r[0].packet.params, Bytes(kSyncWrite.begin() + 8, kSyncWrite.end() - 2));
  EXPECT_EQ(r[1].packet.instruction, static_cast<std::uint8_t>(Instruction::Ping));
  EXPECT_TRUE(r[1].packet.params.empty());
  EXPECT_EQ(r[2].packet.params, (Bytes{0x84, 0x00, 0x04, 0x00, 0x01, 0x02}));
}

// The protocol is an incremental parser over bytes: the same packets whatever the split.
TEST(DynamixelParse, SameResultAtEverySplitPoint) {
  const Bytes stream =
      cat({kPingStatusId1, kReadStatusId1, kSyncReadStatusId2, kBulkReadStatusId2});
  const auto whole = parse_all(PacketKind::Status, stream);
  ASSERT_EQ(whole.size(), 4u);
  for (std::size_t cut = 0; cut <= stream.size(); ++cut) {
    PacketParser parser(PacketKind::Status);
    auto a = parse_all(parser, std::span(stream).first(cut));
    const auto b = parse_all(parser, std::span(stream).subspan(cut));
    a.insert(a.end(), b.begin(), b.end());
    ASSERT_EQ(a.size(), whole.size()) << "split at " << cut;
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].packet.id, whole[i].packet.id);
      EXPECT_EQ(a[i].packet.params, whole[i].packet.params);
    }
  }
  PacketParser bytewise(PacketKind::Status);
  std::size_t n = 0;
  for (const std::uint8_t b : stream) n += parse_all(bytewise, std::span(&b, 1)).size();
  EXPECT_EQ(n, 4u);
}

TEST(DynamixelStuffing, PatternsGetAnFd) {
  EXPECT_EQ(add_stuffing(Bytes{0xFF, 0xFF, 0xFD}), (Bytes{0xFF, 0xFF, 0xFD, 0xFD}));
  EXPECT_EQ(add_stuffing(Bytes{0x01, 0xFF, 0xFF, 0xFD, 0x02}),
            (Bytes{0x01, 0xFF, 0xFF, 0xFD, 0xFD, 0x02}));
  EXPECT_EQ(add_stuffing(Bytes{0xFF, 0xFF, 0xFD, 0xFD}), (Bytes{0xFF, 0xFF, 0xFD, 0xFD, 0xFD}));
  EXPECT_EQ(add_stuffing(Bytes{0xFF, 0xFF, 0xFF, 0xFD}), (Bytes{0xFF, 0xFF, 0xFF, 0xFD, 0xFD}));
  EXPECT_EQ(add_stuffing(Bytes{0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFD}),
            (Bytes{0xFF, 0xFF, 0xFD, 0xFD, 0xFF, 0xFF, 0xFD, 0xFD}));
  for (const Bytes& unchanged :
       {Bytes{0xFF, 0xFF, 0xFC}, Bytes{0xFF, 0xFD, 0xFD}, Bytes{0xFD, 0xFF, 0xFF}, Bytes{}})
    EXPECT_EQ(add_stuffing(unchanged), unchanged);
  EXPECT_EQ(remove_stuffing(Bytes{0xFF, 0xFF, 0xFD, 0xFD, 0xFD}), (Bytes{0xFF, 0xFF, 0xFD, 0xFD}));
}

TEST(DynamixelStuffing, RoundTripsRandomBodiesRichInFfAndFd) {
  std::mt19937 rng(13);
  const std::uint8_t alphabet[] = {0xFF, 0xFF, 0xFD, 0xFD, 0x00, 0x55};
  for (int i = 0; i < 20000; ++i) {
    Bytes body(rng() % 24);
    for (auto& b : body) b = alphabet[rng() % std::size(alphabet)];
    const Bytes stuffed = add_stuffing(body);
    ASSERT_EQ(remove_stuffing(stuffed), body);
    // No header pattern FF FF FD 00 survives stuffing, so no packet can start inside another.
    for (std::size_t k = 0; k + 3 < stuffed.size(); ++k)
      ASSERT_FALSE(stuffed[k] == 0xFF && stuffed[k + 1] == 0xFF && stuffed[k + 2] == 0xFD &&
                   stuffed[k + 3] == 0x00);
  }
}

TEST(DynamixelStuffing, StuffedPacketCountsTheFdInLenAndCrc) {
  // WRITE of FF FF FD 00 at address 116: params 74 00 FF FF FD 00 become 74 00 FF FF FD FD 00.
  const Bytes data = {0xFF, 0xFF, 0xFD, 0x00};
  const Bytes p = write_packet(3, xseries::kGoalPosition, data);
  ASSERT_EQ(p.size(), 7u + 1 + 7 + 2);
  EXPECT_EQ(p[5], 1 + 7 + 2);  // LEN after stuffing
  EXPECT_EQ(p[6], 0);
  EXPECT_EQ(Bytes(p.begin() + 7, p.end() - 2),
            (Bytes{0x03, 0x74, 0x00, 0xFF, 0xFF, 0xFD, 0xFD, 0x00}));
  const std::uint16_t crc = crc16(std::span(p).first(p.size() - 2));
  EXPECT_EQ(p[p.size() - 2], crc & 0xFF);
  const auto r = parse_all(PacketKind::Instruction, p);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].packet.params, (Bytes{0x74, 0x00, 0xFF, 0xFF, 0xFD, 0x00}));
  // And in a status packet: data FF FF FD read back.
  const auto s = parse_all(PacketKind::Status, status_packet(4, 0, Bytes{0xFF, 0xFF, 0xFD}));
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0].packet.params, (Bytes{0xFF, 0xFF, 0xFD}));
}

TEST(DynamixelParse, ResyncsAfterGarbageBadCrcAndBadHeaders) {
  Bytes corrupt = kReadStatusId1;
  corrupt[10] ^= 0x01;  // a data bit: the CRC no longer matches
  Bytes bad_id = kPingStatusId1;
  bad_id[4] = 0xFE;  // a status packet cannot come from the broadcast id
  const Bytes garbage = {0x00, 0x13, 0xFF, 0x42, 0xFF, 0xFF, 0xFD, 0xFD, 0x07};  // stuffed data
  const Bytes stream = cat(
      {garbage, corrupt, kPingStatusId2, bad_id, kSyncReadStatusId2, kReadId1, kEmptyStatusId1});
  PacketParser parser(PacketKind::Status);
  const auto r = parse_all(parser, stream);
  std::vector<ParseError> errors;
  std::vector<int> ids;
  for (const auto& x : r) {
    errors.push_back(x.error);
    if (x.error == ParseError::None) ids.push_back(x.packet.id);
  }
  EXPECT_EQ(errors,
            (std::vector<ParseError>{ParseError::Crc, ParseError::None, ParseError::BadHeader,
                                     ParseError::None, ParseError::None}));
  EXPECT_EQ(ids, (std::vector<int>{2, 2, 1}));
  EXPECT_EQ(parser.counters().crc_errors, 1u);
  EXPECT_EQ(parser.counters().bad_headers, 1u);
  EXPECT_EQ(parser.counters().other_kind, 1u);  // the READ instruction, as a half-duplex echo
  EXPECT_EQ(parser.counters().packets, 3u);
  EXPECT_GE(parser.counters().garbage_bytes, garbage.size());
  EXPECT_EQ(parser.buffered(), 0u);
}

TEST(DynamixelParse, ATruncatedAnswerDoesNotHideTheNextOne) {
  // A status packet cut after 9 bytes: its LEN swallows the next packet's start, the CRC fails,
  // and the parser finds the next packet one byte on.
  const Bytes stream = cat({Bytes(kReadStatusId1.begin(), kReadStatusId1.begin() + 9),
                            kSyncReadStatusId2, kPingStatusId1});
  const auto r = parse_all(PacketKind::Status, stream);
  ASSERT_GE(r.size(), 2u);
  EXPECT_EQ(r.front().error, ParseError::Crc);
  std::vector<int> ids;
  for (const auto& x : r)
    if (x.error == ParseError::None) ids.push_back(x.packet.id);
  EXPECT_EQ(ids, (std::vector<int>{2, 1}));
}

TEST(DynamixelParse, BufferStaysWithinItsBoundOnNoise) {
  std::mt19937 rng(7);
  PacketParser parser(PacketKind::Status, 64);
  ASSERT_EQ(parser.capacity(), 2u * (kHeaderBytes + 64));
  Bytes chunk(300);
  std::uint64_t taken_total = 0;
  for (int round = 0; round < 300; ++round) {
    // Noise rich in header bytes, with a real packet now and then.
    for (auto& b : chunk) b = (rng() % 3 == 0) ? 0xFF : static_cast<std::uint8_t>(rng());
    Bytes input = round % 5 == 0 ? cat({chunk, kPingStatusId1}) : chunk;
    std::span<const std::uint8_t> in(input);
    while (!in.empty()) {
      const std::size_t took = parser.feed(in);
      taken_total += took;
      in = in.subspan(took);
      ASSERT_LE(parser.buffered(), parser.capacity());
      while (auto r = parser.next()) {
        if (r->error == ParseError::None) {
          ASSERT_LE(r->packet.params.size(), 64u);
        }
      }
    }
  }
  EXPECT_GT(taken_total, 0u);
  EXPECT_GE(parser.counters().packets, 50u);  // the 60 real packets, less any a false header ate
}

TEST(DynamixelXSeries, PositionAndVelocityUnits) {
  EXPECT_EQ(xseries::counts_from_rad(0.0), 2048);
  EXPECT_EQ(xseries::counts_from_rad(std::numbers::pi / 2), 3072);
  EXPECT_EQ(xseries::counts_from_rad(-std::numbers::pi), 0);
  EXPECT_DOUBLE_EQ(xseries::rad_from_counts(1024), -std::numbers::pi / 2);
  EXPECT_EQ(xseries::counts_from_rad(xseries::rad_from_counts(2999)), 2999);
  // 180 deg/s = 30 rev/min = 131 units of 0.229 rev/min.
  EXPECT_EQ(xseries::profile_velocity_from_rad_s(std::numbers::pi), 131u);
  EXPECT_EQ(xseries::profile_velocity_from_rad_s(1e-6), 1u);  // never 0, which means no limit
  EXPECT_EQ(describe_error(0x07), "access error");
  EXPECT_NE(describe_error(0x80).find("hardware alert"), std::string::npos);
}

}  // namespace
}  // namespace telex::dynamixel
