// SPDX-License-Identifier: MIT
// .oni repair: adds the per-node cropping record that OpenNI2's file driver needs to play frames.
// Layout from OpenNI2's Source/Drivers/OniFile/DataRecords.h (64-bit positions, file format
// 1.0.1.0 and newer): a 24-byte file header, then records of a 28-byte header (magic "NIR\0",
// type, node id, fields size including the header, payload size, undo position) + fields +
// payload.
#include <fmt/format.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <stdexcept>
#include <vector>

#include "telex/remote/openni_record.h"

namespace telex::remote {

namespace {

constexpr std::size_t kFileHeaderSize = 24;
constexpr std::size_t kRecordHeaderSize = 28;
constexpr std::uint32_t kGeneralProperty = 0x06;
constexpr std::uint32_t kEnd = 0x0B;
constexpr std::uint32_t kNodeAdded = 0x0D;
constexpr std::uint32_t kSeekTable = 0x0E;
constexpr std::size_t kSeekEntrySize = 20;  // u64 timestamp, u32 configuration, u64 position
// XnProductionNodeType values of the image generators (OpenNI 1.x XnTypes.h).
const std::set<std::uint32_t> kImageNodeTypes = {2, 3, 4};  // depth, image, IR
const char kCroppingName[] = "xnCropping";

template <typename T>
T get(const std::vector<std::uint8_t>& b, std::size_t at) {
  T v;
  std::memcpy(&v, b.data() + at, sizeof(T));
  return v;
}
template <typename T>
void put(std::vector<std::uint8_t>& b, std::size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof(T));
}

struct Record {
  std::size_t pos = 0;
  std::uint32_t type = 0, node = 0, fields = 0, payload = 0;
  std::uint64_t undo = 0;
  std::string name;  // node name (NodeAdded) or property name (General property)
  std::uint32_t node_type = 0;
  std::size_t seek_table_field = 0;  // NodeAdded: where its seek-table position is stored
};

struct Parsed {
  std::vector<std::uint8_t> bytes;
  std::vector<Record> records;
};

Parsed parse(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(fmt::format("cannot read oni recording '{}'", path.string()));
  Parsed p;
  p.bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  const auto& b = p.bytes;
  auto bad = [&](const std::string& why) {
    return std::runtime_error(
        fmt::format("'{}' is not an .oni recording this code can repair: {}", path.string(), why));
  };
  if (b.size() < kFileHeaderSize || std::memcmp(b.data(), "NI10", 4) != 0)
    throw bad("no NI10 file header");
  // XnVersion {u8 major, u8 minor, u16 maintenance, u32 build}; 64-bit positions since 1.0.1.0.
  const int major = b[4], minor = b[5];
  const int maintenance = get<std::uint16_t>(b, 6);
  if (major != 1 || minor != 0 || maintenance < 1)
    throw bad(fmt::format("file format {}.{}.{} (need 1.0.1 or newer)", major, minor, maintenance));
  std::size_t pos = kFileHeaderSize;
  bool ended = false;
  while (!ended) {
    if (pos + kRecordHeaderSize > b.size()) throw bad(fmt::format("record at {} truncated", pos));
    if (std::memcmp(b.data() + pos, "NIR\0", 4) != 0)
      throw bad(fmt::format("no record magic at {}", pos));
    Record r;
    r.pos = pos;
    r.type = get<std::uint32_t>(b, pos + 4);
    r.node = get<std::uint32_t>(b, pos + 8);
    r.fields = get<std::uint32_t>(b, pos + 12);
    r.payload = get<std::uint32_t>(b, pos + 16);
    r.undo = get<std::uint64_t>(b, pos + 20);
    if (r.fields < kRecordHeaderSize || pos + r.fields + r.payload > b.size())
      throw bad(fmt::format("record at {} runs past the end of the file", pos));
    const std::size_t f0 = pos + kRecordHeaderSize;
    const std::size_t fend = pos + r.fields;
    auto read_string = [&](std::size_t at, std::size_t& after) {
      if (at + 4 > fend) throw bad(fmt::format("record at {} has a truncated name", pos));
      const auto len = get<std::uint32_t>(b, at);
      if (len == 0 || at + 4 + len > fend)
        throw bad(fmt::format("record at {} has a bad name length", pos));
      after = at + 4 + len;
      return std::string(reinterpret_cast<const char*>(b.data() + at + 4), len - 1);
    };
    if (r.type == kNodeAdded) {
      std::size_t at = 0;
      r.name = read_string(f0, at);
      // type u32, codec u32, frames u32, min timestamp u64, max timestamp u64, seek table u64
      if (at + 36 > fend) throw bad(fmt::format("NodeAdded record at {} truncated", pos));
      r.node_type = get<std::uint32_t>(b, at);
      r.seek_table_field = at + 28;
    } else if (r.type == kGeneralProperty) {
      std::size_t at = 0;
      r.name = read_string(f0, at);
    } else if (r.type == 0x02 || r.type == 0x0C) {
      throw bad("it uses an old NodeAdded record (format 1.0.0.4/1.0.0.5)");
    } else if (r.type == kSeekTable && r.payload % kSeekEntrySize != 0) {
      throw bad(fmt::format("seek table at {} has a partial entry", pos));
    }
    ended = r.type == kEnd;
    pos += r.fields + r.payload;
    p.records.push_back(std::move(r));
  }
  return p;
}

// Image nodes (by NodeAdded record index) that lack a cropping record.
std::vector<std::size_t> nodes_missing_cropping(const Parsed& p) {
  std::set<std::uint32_t> with_cropping;
  for (const auto& r : p.records)
    if (r.type == kGeneralProperty && r.name == kCroppingName) with_cropping.insert(r.node);
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < p.records.size(); ++i) {
    const auto& r = p.records[i];
    if (r.type == kNodeAdded && kImageNodeTypes.count(r.node_type) != 0 &&
        with_cropping.count(r.node) == 0)
      out.push_back(i);
  }
  return out;
}

std::vector<std::uint8_t> cropping_record(std::uint32_t node) {
  // OpenNI 1.x XnCropping: XnBool (int) enabled, then u16 x, y, width, height: 12 bytes.
  std::uint8_t cropping[12] = {};
  const std::uint32_t name_len = sizeof(kCroppingName);  // with the terminating NUL
  const std::uint32_t data_len = sizeof(cropping);
  const std::uint32_t fields =
      static_cast<std::uint32_t>(kRecordHeaderSize + 4 + name_len + 4 + data_len);
  std::vector<std::uint8_t> rec(fields, 0);
  std::memcpy(rec.data(), "NIR\0", 4);
  put<std::uint32_t>(rec, 4, kGeneralProperty);
  put<std::uint32_t>(rec, 8, node);
  put<std::uint32_t>(rec, 12, fields);
  put<std::uint32_t>(rec, 16, 0);
  put<std::uint64_t>(rec, 20, 0);  // no earlier value to undo to
  std::size_t at = kRecordHeaderSize;
  put<std::uint32_t>(rec, at, name_len);
  std::memcpy(rec.data() + at + 4, kCroppingName, name_len);
  at += 4 + name_len;
  put<std::uint32_t>(rec, at, data_len);
  std::memcpy(rec.data() + at + 4, cropping, data_len);
  return rec;
}

}  // namespace

int oni_nodes_missing_cropping(const std::filesystem::path& path) {
  return static_cast<int>(nodes_missing_cropping(parse(path)).size());
}

int repair_oni_for_playback(const std::filesystem::path& in, const std::filesystem::path& out) {
  Parsed p = parse(in);
  const auto missing = nodes_missing_cropping(p);
  // Insertions, by file offset, each right after its node's NodeAdded record.
  std::map<std::size_t, std::vector<std::uint8_t>> inserts;
  for (std::size_t i : missing) {
    const auto& r = p.records[i];
    inserts[r.pos + r.fields + r.payload] = cropping_record(r.node);
  }
  // New offset of an old file offset: shifted by every insertion at or before it.
  auto moved = [&](std::uint64_t old) {
    std::uint64_t shift = 0;
    for (const auto& [at, rec] : inserts)
      if (old >= at) shift += rec.size();
    return old + shift;
  };
  std::vector<std::uint8_t> fixed = p.bytes;
  // Patch positions in place (old offsets), then splice.
  for (const auto& r : p.records) {
    if (r.undo != 0) put<std::uint64_t>(fixed, r.pos + 20, moved(r.undo));
    if (r.type == kNodeAdded) {
      const auto seek_table = get<std::uint64_t>(fixed, r.seek_table_field);
      if (seek_table != 0) put<std::uint64_t>(fixed, r.seek_table_field, moved(seek_table));
    }
    if (r.type == kSeekTable) {
      const std::size_t entries = r.payload / kSeekEntrySize;
      for (std::size_t e = 0; e < entries; ++e) {
        const std::size_t at = r.pos + r.fields + e * kSeekEntrySize + 12;
        const auto seek = get<std::uint64_t>(fixed, at);
        if (seek != 0) put<std::uint64_t>(fixed, at, moved(seek));
      }
    }
  }
  std::vector<std::uint8_t> result;
  result.reserve(fixed.size() + inserts.size() * 64);
  std::size_t from = 0;
  for (const auto& [at, rec] : inserts) {
    result.insert(result.end(), fixed.begin() + static_cast<std::ptrdiff_t>(from),
                  fixed.begin() + static_cast<std::ptrdiff_t>(at));
    result.insert(result.end(), rec.begin(), rec.end());
    from = at;
  }
  result.insert(result.end(), fixed.begin() + static_cast<std::ptrdiff_t>(from), fixed.end());
  const auto tmp = out.string() + ".tmp";
  {
    std::ofstream o(tmp, std::ios::binary | std::ios::trunc);
    o.write(reinterpret_cast<const char*>(result.data()),
            static_cast<std::streamsize>(result.size()));
    if (!o) throw std::runtime_error(fmt::format("cannot write '{}'", tmp));
  }
  std::filesystem::rename(tmp, out);
  return static_cast<int>(inserts.size());
}

}  // namespace telex::remote
