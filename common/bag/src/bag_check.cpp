// SPDX-License-Identifier: MIT
// Checks a bag's framing before rosbag_storage reads it. Debian's rosbag_storage 1.15 trusts the
// lengths and positions in the file: libFuzzer found a heap overflow in Bag::readHeader and
// multi-gigabyte allocations from a 60 KB file. So every length, position and count the library
// will follow is checked here first, against the file and against each other (ROS bag format 2.0,
// wiki.ros.org/Bags/Format/2.0); the library still does all the reading.
#include <bzlib.h>
#include <roslz4/lz4s.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "telex/bag/bag.h"

namespace telex::bag {

namespace {

constexpr std::uint8_t kOpMessage = 0x02, kOpBagHeader = 0x03, kOpIndex = 0x04, kOpChunk = 0x05,
                       kOpChunkInfo = 0x06, kOpConnection = 0x07;
// A decompressed chunk larger than this is refused (telex writes 768 KB chunks; rosbag's default
// threshold is the same).
constexpr std::uint64_t kMaxChunkBytes = 256u << 20;

struct Fail : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::uint32_t u32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
std::uint64_t u64(const std::uint8_t* p) {
  return static_cast<std::uint64_t>(u32(p)) | static_cast<std::uint64_t>(u32(p + 4)) << 32;
}

// The name=value fields of a record header (or of a connection record's data), every length in
// bounds. rosbag parses them with ros::Header::parse.
std::map<std::string, std::string> fields_of(const std::uint8_t* p, std::uint64_t n,
                                             const std::string& where) {
  std::map<std::string, std::string> out;
  std::uint64_t at = 0;
  while (at < n) {
    if (n - at < 4) throw Fail(where + ": a header field length is cut off");
    const std::uint32_t len = u32(p + at);
    at += 4;
    if (len > n - at)
      throw Fail(where + ": a header field of " + std::to_string(len) +
                 " bytes runs past its header");
    const auto* f = reinterpret_cast<const char*>(p + at);
    const void* eq = std::memchr(f, '=', len);
    if (eq == nullptr) throw Fail(where + ": a header field has no '='");
    const auto name_len = static_cast<std::size_t>(static_cast<const char*>(eq) - f);
    out[std::string(f, name_len)] = std::string(f + name_len + 1, len - name_len - 1);
    at += len;
  }
  return out;
}

std::uint64_t field_uint(const std::map<std::string, std::string>& f, const char* name,
                         std::size_t bytes, const std::string& where) {
  const auto it = f.find(name);
  if (it == f.end()) throw Fail(where + ": no '" + name + "' field");
  if (it->second.size() != bytes)
    throw Fail(where + ": field '" + name + "' has " + std::to_string(it->second.size()) +
               " bytes, not " + std::to_string(bytes));
  const auto* p = reinterpret_cast<const std::uint8_t*>(it->second.data());
  return bytes == 8 ? u64(p) : bytes == 4 ? u32(p) : p[0];
}

struct Record {
  std::uint64_t pos = 0;  // of header_len
  std::uint8_t op = 0;
  std::map<std::string, std::string> fields;
  std::uint64_t data_pos = 0, data_len = 0;
  std::uint64_t end = 0;  // the next record's position
};

// One record at `pos` of a buffer of `size` bytes (a whole file read by parts, or a chunk).
template <typename Read>
Record record_at(std::uint64_t pos, std::uint64_t size, Read&& read, const std::string& where) {
  Record r;
  r.pos = pos;
  std::uint8_t len[4];
  if (size - pos < 4) throw Fail(where + ": a record is cut off at byte " + std::to_string(pos));
  read(pos, len, 4);
  const std::uint32_t header_len = u32(len);
  if (header_len > size - pos - 4 || size - pos - 4 - header_len < 4)
    throw Fail(where + ": the record at byte " + std::to_string(pos) + " claims a " +
               std::to_string(header_len) + "-byte header, past the end");
  std::vector<std::uint8_t> header(header_len);
  read(pos + 4, header.data(), header_len);
  r.fields = fields_of(header.data(), header_len, where + " record at byte " + std::to_string(pos));
  r.op = static_cast<std::uint8_t>(field_uint(r.fields, "op", 1, where));
  read(pos + 4 + header_len, len, 4);
  r.data_len = u32(len);
  r.data_pos = pos + 8 + header_len;
  if (r.data_len > size - r.data_pos)
    throw Fail(where + ": the record at byte " + std::to_string(pos) + " claims " +
               std::to_string(r.data_len) + " data bytes, past the end");
  r.end = r.data_pos + r.data_len;
  return r;
}

// The file, read by parts; a short read is a Fail naming the position.
struct FileReader {
  std::ifstream& in;
  void operator()(std::uint64_t pos, std::uint8_t* out, std::uint64_t n) const {
    in.seekg(static_cast<std::streamoff>(pos));
    in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
    if (!in) throw Fail("read error at byte " + std::to_string(pos));
  }
};

// Every top-level record, in order, and where each starts.
struct TopLevel {
  std::vector<Record> records;
  std::map<std::uint64_t, std::size_t> at;  // position -> index in records
};

// Where the index is: rosbag reads conn_count connection records, then chunk_count chunk infos,
// from the bag header's index_pos.
struct IndexSpan {
  std::size_t first = 0;  // index in TopLevel::records of the record at index_pos
  std::uint64_t conn_count = 0, chunk_count = 0;
};

void check_magic(std::uint64_t file_size, const FileReader& read) {
  const char kMagic[] = "#ROSBAG V2.0\n";
  std::uint8_t magic[13] = {};
  if (file_size < 13)
    throw Fail("too short for a ROS bag (" + std::to_string(file_size) + " bytes)");
  read(0, magic, 13);
  if (std::memcmp(magic, kMagic, 13) != 0)
    throw Fail("not a ROS bag of format 2.0 (no '#ROSBAG V2.0' line)");
}

TopLevel read_top_level(std::uint64_t file_size, const FileReader& read) {
  TopLevel top;
  for (std::uint64_t pos = 13; pos < file_size;) {
    Record r = record_at(pos, file_size, read, "top level");
    top.at[pos] = top.records.size();
    pos = r.end;
    top.records.push_back(std::move(r));
  }
  return top;
}

// The bag header's counts and index position, checked against the records there.
IndexSpan locate_index(const TopLevel& top) {
  if (top.records.empty() || top.records[0].op != kOpBagHeader)
    throw Fail("the first record is not the bag header");
  const Record& head = top.records[0];
  const std::uint64_t index_pos = field_uint(head.fields, "index_pos", 8, "bag header");
  IndexSpan span;
  span.conn_count = field_uint(head.fields, "conn_count", 4, "bag header");
  span.chunk_count = field_uint(head.fields, "chunk_count", 4, "bag header");
  if (index_pos == 0)
    throw Fail("the bag has no index (its recording did not finish; `rosbag reindex` repairs it)");
  const auto index = top.at.find(index_pos);
  if (index == top.at.end())
    throw Fail("the index position " + std::to_string(index_pos) + " is not the start of a record");
  span.first = index->second;
  if (top.records.size() - span.first < span.conn_count + span.chunk_count)
    throw Fail("the index holds fewer records than the header counts");
  return span;
}

// The index's connection records; returns their connection ids.
std::set<std::uint32_t> check_index_connections(const TopLevel& top, const IndexSpan& span,
                                                const FileReader& read) {
  std::set<std::uint32_t> connections;
  for (std::uint64_t i = 0; i < span.conn_count; ++i) {
    const Record& c = top.records[span.first + i];
    const std::string where = "connection record at byte " + std::to_string(c.pos);
    if (c.op != kOpConnection) throw Fail(where + " is not a connection");
    connections.insert(static_cast<std::uint32_t>(field_uint(c.fields, "conn", 4, where)));
    std::vector<std::uint8_t> data(c.data_len);
    read(c.data_pos, data.data(), c.data_len);
    fields_of(data.data(), c.data_len, where);
  }
  return connections;
}

// A chunk info's fields, and the chunk it points at.
struct ChunkRef {
  std::size_t chunk = 0;    // index in TopLevel::records
  std::uint64_t count = 0;  // connections in the chunk, each with an index record after it
};

ChunkRef check_chunk_info(const TopLevel& top, const Record& info) {
  const std::string where = "chunk info at byte " + std::to_string(info.pos);
  if (info.op != kOpChunkInfo) throw Fail(where + " is not a chunk info");
  if (field_uint(info.fields, "ver", 4, where) != 1) throw Fail(where + ": version is not 1");
  const std::uint64_t chunk_pos = field_uint(info.fields, "chunk_pos", 8, where);
  field_uint(info.fields, "start_time", 8, where);
  field_uint(info.fields, "end_time", 8, where);
  ChunkRef ref;
  ref.count = field_uint(info.fields, "count", 4, where);
  if (info.data_len != ref.count * 8) throw Fail(where + ": its data does not hold its count");
  const auto chunk_at = top.at.find(chunk_pos);
  if (chunk_at == top.at.end() || top.records[chunk_at->second].op != kOpChunk)
    throw Fail(where + ": chunk position " + std::to_string(chunk_pos) +
               " is not the start of a chunk");
  ref.chunk = chunk_at->second;
  return ref;
}

// The chunk's records as rosbag will see them: its data, decompressed within kMaxChunkBytes.
std::vector<std::uint8_t> unpack_chunk(const Record& chunk, const FileReader& read,
                                       const std::string& cw) {
  const std::string compression =
      chunk.fields.count("compression") ? chunk.fields.at("compression") : "";
  const std::uint64_t size = field_uint(chunk.fields, "size", 4, cw);
  if (size > kMaxChunkBytes) throw Fail(cw + ": " + std::to_string(size) + " bytes unpacked");
  std::vector<std::uint8_t> packed(chunk.data_len), data;
  read(chunk.data_pos, packed.data(), chunk.data_len);
  if (compression == "none") {
    if (size != chunk.data_len) throw Fail(cw + ": its size field disagrees with its data");
    return packed;
  }
  if (compression != "lz4" && compression != "bz2")
    throw Fail(cw + ": unknown compression '" + compression + "'");
  data.resize(size);
  unsigned int out_len = static_cast<unsigned int>(size);
  const int rc = compression == "lz4"
                     ? roslz4_buffToBuffDecompress(reinterpret_cast<char*>(packed.data()),
                                                   static_cast<unsigned int>(packed.size()),
                                                   reinterpret_cast<char*>(data.data()), &out_len)
                     : BZ2_bzBuffToBuffDecompress(reinterpret_cast<char*>(data.data()), &out_len,
                                                  reinterpret_cast<char*>(packed.data()),
                                                  static_cast<unsigned int>(packed.size()), 0, 0);
  const int ok = compression == "lz4" ? ROSLZ4_OK : BZ_OK;
  if (rc != ok || out_len != size)
    throw Fail(cw + ": its " + compression + " data does not unpack to its " +
               std::to_string(size) + " bytes");
  return data;
}

// The records inside an unpacked chunk: messages and connections (added to `connections`).
// Returns its messages: offset -> connection.
std::map<std::uint64_t, std::uint32_t> check_chunk_records(const std::vector<std::uint8_t>& data,
                                                           const std::string& cw,
                                                           std::set<std::uint32_t>& connections) {
  std::map<std::uint64_t, std::uint32_t> messages;
  auto read_chunk = [&](std::uint64_t pos, std::uint8_t* out, std::uint64_t n) {
    std::memcpy(out, data.data() + pos, n);
  };
  for (std::uint64_t pos = 0; pos < data.size();) {
    const Record r = record_at(pos, data.size(), read_chunk, cw);
    const std::string rw = cw + ", record at " + std::to_string(pos);
    if (r.op == kOpMessage) {
      messages[pos] = static_cast<std::uint32_t>(field_uint(r.fields, "conn", 4, rw));
      field_uint(r.fields, "time", 8, rw);
    } else if (r.op == kOpConnection) {
      connections.insert(static_cast<std::uint32_t>(field_uint(r.fields, "conn", 4, rw)));
      fields_of(data.data() + r.data_pos, r.data_len, rw);
    } else {
      throw Fail(rw + " is neither a message nor a connection");
    }
    pos = r.end;
  }
  return messages;
}

// rosbag reads one index record per connection of the chunk, right after it; each entry must
// point at a message of that connection.
void check_chunk_index(const TopLevel& top, const ChunkRef& ref, const FileReader& read,
                       const std::set<std::uint32_t>& connections,
                       const std::map<std::uint64_t, std::uint32_t>& messages,
                       const std::string& cw) {
  for (std::uint64_t k = 0; k < ref.count; ++k) {
    if (ref.chunk + 1 + k >= top.records.size())
      throw Fail(cw + ": fewer index records follow it than its chunk info counts");
    const Record& idx = top.records[ref.chunk + 1 + k];
    const std::string iw = "index record at byte " + std::to_string(idx.pos);
    if (idx.op != kOpIndex) throw Fail(iw + " is not an index record");
    if (field_uint(idx.fields, "ver", 4, iw) != 1) throw Fail(iw + ": version is not 1");
    const auto conn = static_cast<std::uint32_t>(field_uint(idx.fields, "conn", 4, iw));
    const std::uint64_t n = field_uint(idx.fields, "count", 4, iw);
    if (idx.data_len != n * 12) throw Fail(iw + ": its data does not hold its count");
    if (!connections.count(conn))
      throw Fail(iw + ": connection " + std::to_string(conn) + " is not defined");
    std::vector<std::uint8_t> entries(idx.data_len);
    read(idx.data_pos, entries.data(), idx.data_len);
    for (std::uint64_t e = 0; e < n; ++e) {
      const std::uint32_t offset = u32(entries.data() + e * 12 + 8);
      const auto m = messages.find(offset);
      if (m == messages.end() || m->second != conn)
        throw Fail(iw + ": entry " + std::to_string(e) + " points at byte " +
                   std::to_string(offset) + " of its chunk, not at a message of connection " +
                   std::to_string(conn));
    }
  }
}

// One chunk info, its chunk, the chunk's records and the index records after it.
void check_chunk(const TopLevel& top, const Record& info, const FileReader& read,
                 std::set<std::uint32_t>& connections) {
  const ChunkRef ref = check_chunk_info(top, info);
  const Record& chunk = top.records[ref.chunk];
  const std::string cw = "chunk at byte " + std::to_string(chunk.pos);
  const std::vector<std::uint8_t> data = unpack_chunk(chunk, read, cw);
  const auto messages = check_chunk_records(data, cw, connections);
  // The chunk info's own (connection, count) pairs: rosbag reads them, so they must be readable.
  std::vector<std::uint8_t> pairs(info.data_len);
  read(info.data_pos, pairs.data(), info.data_len);
  check_chunk_index(top, ref, read, connections, messages, cw);
}

}  // namespace

void check_bag_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read bag " + path + ": cannot open the file");
  in.seekg(0, std::ios::end);
  const auto file_size = static_cast<std::uint64_t>(in.tellg());
  const FileReader read{in};
  try {
    check_magic(file_size, read);
    const TopLevel top = read_top_level(file_size, read);
    const IndexSpan span = locate_index(top);
    std::set<std::uint32_t> connections = check_index_connections(top, span, read);
    for (std::uint64_t i = 0; i < span.chunk_count; ++i)
      check_chunk(top, top.records[span.first + span.conn_count + i], read, connections);
  } catch (const Fail& e) {
    throw std::runtime_error("cannot read bag " + path + ": " + e.what());
  }
}

}  // namespace telex::bag
