// SPDX-License-Identifier: MIT
// NatNet packet parsing and building: bounds-checked little-endian cursor over one datagram.
#include "telex/natnet/natnet.h"

#include <charconv>
#include <cstring>
#include <stdexcept>

#include "telex/base/byte_cursor.h"

namespace telex::local::natnet {

void Frame::clear() {
  frame_number = 0;
  marker_sets.clear();
  unlabeled_markers.clear();
  rigid_bodies.clear();
  skeletons.clear();
  asset_section_bytes = 0;
  asset_count = 0;
  labeled_markers.clear();
  force_plates.clear();
  devices.clear();
  software_latency_s = 0;
  timecode = timecode_sub = 0;
  timestamp_s = 0;
  stamp_mid_exposure = stamp_data_received = stamp_transmit = 0;
  precision_s = precision_frac = 0;
  params = 0;
}

const RigidBody* Frame::find_body(std::int32_t id) const {
  for (const auto& b : rigid_bodies)
    if (b.id == id) return &b;
  return nullptr;
}

bool supported(Version v) { return v.major >= 2 && v.major <= 4 && v.minor >= 0; }

Version parse_version(std::string_view text) {
  Version v{0, 0};
  const char* p = text.data();
  const char* end = text.data() + text.size();
  auto r = std::from_chars(p, end, v.major);
  if (r.ec == std::errc{} && r.ptr != end && *r.ptr == '.') {
    r = std::from_chars(r.ptr + 1, end, v.minor);
    // Build and revision numbers do not change the layout: accept and ignore them.
    while (r.ec == std::errc{} && r.ptr != end && *r.ptr == '.') {
      int ignored = 0;
      r = std::from_chars(r.ptr + 1, end, ignored);
    }
  }
  if (r.ec != std::errc{} || r.ptr != end || !supported(v))
    throw std::invalid_argument("NatNet version '" + std::string(text) +
                                "' is not one this client parses (2.0 .. 4.x, e.g. 3.1)");
  return v;
}

namespace {

// NatNet's reads over the project's one byte cursor (telex/base/byte_cursor.h): little-endian
// values assembled from bytes, bounds-checked.
class Reader : public ByteReader {
 public:
  using ByteReader::ByteReader;
  std::size_t left() const { return remaining(); }
  bool vec3(Vec3f& v) { return get(v.x) && get(v.y) && get(v.z); }
};

#define TELEX_NN_FAIL(why) \
  return ParseStatus { why, r.offset() }
#define TELEX_NN_NEED(expr, why)     \
  do {                               \
    if (!(expr)) TELEX_NN_FAIL(why); \
  } while (0)

// Reads a count and checks it against the bytes left, so a corrupt count cannot make us loop or
// allocate far beyond the datagram.
ParseStatus read_count(Reader& r, std::size_t min_item_bytes, std::int32_t& n, const char* what) {
  TELEX_NN_NEED(r.get(n), what);
  TELEX_NN_NEED(n >= 0, "negative count");
  TELEX_NN_NEED(static_cast<std::size_t>(n) <= r.left() / min_item_bytes,
                "count exceeds the bytes left in the packet");
  return {};
}

// NatNet 4.1+ prefixes every section's items with their byte count.
struct Section {
  bool sized = false;
  std::uint32_t bytes = 0;
  std::size_t start = 0;
};

ParseStatus open_section(Reader& r, Version v, Section& s) {
  s.sized = v.at_least(4, 1);
  if (s.sized) {
    TELEX_NN_NEED(r.get(s.bytes), "truncated section byte count");
    TELEX_NN_NEED(s.bytes <= r.left(), "section byte count exceeds the packet");
  }
  s.start = r.offset();
  return {};
}

ParseStatus close_section(const Reader& r, const Section& s) {
  if (s.sized && r.offset() - s.start != s.bytes)
    return ParseStatus{"section byte count does not match its contents", r.offset()};
  return {};
}

ParseStatus read_rigid_body(Reader& r, Version v, RigidBody& b) {
  TELEX_NN_NEED(r.get(b.id) && r.vec3(b.p_m), "truncated rigid body");
  TELEX_NN_NEED(r.get(b.qx) && r.get(b.qy) && r.get(b.qz) && r.get(b.qw), "truncated rigid body");
  b.markers.clear();
  if (v.major < 3) {
    std::int32_t n = 0;
    const std::size_t per_marker = v.major >= 2 ? 20 : 12;
    if (auto s = read_count(r, per_marker, n, "truncated rigid body marker count"); !s.ok())
      return s;
    b.markers.resize(static_cast<std::size_t>(n));
    for (auto& m : b.markers) TELEX_NN_NEED(r.vec3(m), "truncated rigid body marker");
    if (v.major >= 2)  // marker ids (i32) and sizes (f32): not used by the hand model
      TELEX_NN_NEED(r.skip(static_cast<std::size_t>(n) * 8), "truncated rigid body marker ids");
  }
  b.mean_error_m = 0;
  if (v.major >= 2) TELEX_NN_NEED(r.get(b.mean_error_m), "truncated rigid body mean error");
  b.tracking_valid = true;
  if (v.at_least(2, 6)) {
    std::int16_t params = 0;
    TELEX_NN_NEED(r.get(params), "truncated rigid body params");
    b.tracking_valid = (params & 1) != 0;
  }
  return {};
}

ParseStatus read_analog(Reader& r, std::vector<AnalogDevice>& out, Version v, const char* what) {
  std::int32_t n = 0;
  if (auto s = read_count(r, 8, n, what); !s.ok()) return s;
  Section sec;
  if (auto s = open_section(r, v, sec); !s.ok()) return s;
  out.resize(static_cast<std::size_t>(n));
  for (auto& d : out) {
    std::int32_t channels = 0;
    TELEX_NN_NEED(r.get(d.id), "truncated analog device id");
    if (auto s = read_count(r, 4, channels, "truncated analog channel count"); !s.ok()) return s;
    d.channels.resize(static_cast<std::size_t>(channels));
    for (auto& ch : d.channels) {
      std::int32_t frames = 0;
      if (auto s = read_count(r, 4, frames, "truncated analog frame count"); !s.ok()) return s;
      ch.resize(static_cast<std::size_t>(frames));
      for (auto& f : ch) TELEX_NN_NEED(r.get(f), "truncated analog sample");
    }
  }
  return close_section(r, sec);
}

}  // namespace

ParseStatus parse_packet(std::span<const std::uint8_t> datagram, PacketView& out) {
  Reader r(datagram);
  std::uint16_t id = 0, n = 0;
  TELEX_NN_NEED(r.get(id) && r.get(n), "datagram shorter than the 4-byte NatNet header");
  TELEX_NN_NEED(r.left() >= n, "datagram shorter than its header's byte count");
  out.message_id = id;
  out.payload = datagram.subspan(4, n);
  return {};
}

ParseStatus parse_frame(std::span<const std::uint8_t> payload, Version v, Frame& out) {
  Reader r(payload);
  if (!supported(v)) TELEX_NN_FAIL("unsupported NatNet version (2.0 .. 4.x parsed)");
  out.clear();
  TELEX_NN_NEED(r.get(out.frame_number), "truncated frame number");

  std::int32_t n = 0;
  // Marker sets: name, count, xyz each.
  if (auto s = read_count(r, 5, n, "truncated marker set count"); !s.ok()) return s;
  {
    Section sec;
    if (auto s = open_section(r, v, sec); !s.ok()) return s;
    out.marker_sets.resize(static_cast<std::size_t>(n));
    for (auto& ms : out.marker_sets) {
      TELEX_NN_NEED(r.cstring(ms.name), "marker set name without terminating NUL");
      std::int32_t m = 0;
      if (auto s = read_count(r, 12, m, "truncated marker set size"); !s.ok()) return s;
      ms.markers.resize(static_cast<std::size_t>(m));
      for (auto& p : ms.markers) TELEX_NN_NEED(r.vec3(p), "truncated marker");
    }
    if (auto s = close_section(r, sec); !s.ok()) return s;
  }
  // Unlabeled ("other") markers.
  if (auto s = read_count(r, 12, n, "truncated unlabeled marker count"); !s.ok()) return s;
  {
    Section sec;
    if (auto s = open_section(r, v, sec); !s.ok()) return s;
    out.unlabeled_markers.resize(static_cast<std::size_t>(n));
    for (auto& p : out.unlabeled_markers) TELEX_NN_NEED(r.vec3(p), "truncated unlabeled marker");
    if (auto s = close_section(r, sec); !s.ok()) return s;
  }
  // Rigid bodies.
  if (auto s = read_count(r, 32, n, "truncated rigid body count"); !s.ok()) return s;
  {
    Section sec;
    if (auto s = open_section(r, v, sec); !s.ok()) return s;
    out.rigid_bodies.resize(static_cast<std::size_t>(n));
    for (auto& b : out.rigid_bodies)
      if (auto s = read_rigid_body(r, v, b); !s.ok()) return s;
    if (auto s = close_section(r, sec); !s.ok()) return s;
  }
  // Skeletons: id, bone count, bones laid out as rigid bodies.
  if (v.at_least(2, 1)) {
    if (auto s = read_count(r, 8, n, "truncated skeleton count"); !s.ok()) return s;
    Section sec;
    if (auto s = open_section(r, v, sec); !s.ok()) return s;
    out.skeletons.resize(static_cast<std::size_t>(n));
    for (auto& sk : out.skeletons) {
      std::int32_t bones = 0;
      TELEX_NN_NEED(r.get(sk.id), "truncated skeleton id");
      if (auto s = read_count(r, 32, bones, "truncated skeleton bone count"); !s.ok()) return s;
      sk.bones.resize(static_cast<std::size_t>(bones));
      for (auto& b : sk.bones)
        if (auto s = read_rigid_body(r, v, b); !s.ok()) return s;
    }
    if (auto s = close_section(r, sec); !s.ok()) return s;
  }
  // Assets (Motive 3.1 / NatNet 4.1+): the byte count lets us step over them unparsed.
  if (v.at_least(4, 1)) {
    TELEX_NN_NEED(r.get(out.asset_count), "truncated asset count");
    TELEX_NN_NEED(out.asset_count >= 0, "negative count");
    TELEX_NN_NEED(r.get(out.asset_section_bytes), "truncated section byte count");
    TELEX_NN_NEED(r.skip(out.asset_section_bytes), "section byte count exceeds the packet");
  }
  // Labeled markers.
  if (v.at_least(2, 3)) {
    if (auto s = read_count(r, 20, n, "truncated labeled marker count"); !s.ok()) return s;
    Section sec;
    if (auto s = open_section(r, v, sec); !s.ok()) return s;
    out.labeled_markers.resize(static_cast<std::size_t>(n));
    for (auto& m : out.labeled_markers) {
      TELEX_NN_NEED(r.get(m.id) && r.vec3(m.p_m) && r.get(m.size_m), "truncated labeled marker");
      m.params = 0;
      m.residual_m = 0;
      if (v.at_least(2, 6)) TELEX_NN_NEED(r.get(m.params), "truncated labeled marker params");
      if (v.major >= 3) TELEX_NN_NEED(r.get(m.residual_m), "truncated labeled marker residual");
    }
    if (auto s = close_section(r, sec); !s.ok()) return s;
  }
  if (v.at_least(2, 9))
    if (auto s = read_analog(r, out.force_plates, v, "truncated force plate count"); !s.ok())
      return s;
  if (v.at_least(2, 11))
    if (auto s = read_analog(r, out.devices, v, "truncated device count"); !s.ok()) return s;

  // The frame's tail. SDK 2.5's PacketClient: latency, timecode (2.3+, its change log), end. SDK
  // 2.6 added the timestamp and the frame params; 2.7 widened the timestamp to f64; 3.0 removed the
  // latency and added three u64 stamps; 4.1 (not 4.0) added the precision timestamp.
  if (v.major < 3) TELEX_NN_NEED(r.get(out.software_latency_s), "truncated software latency");
  if (v.at_least(2, 3))
    TELEX_NN_NEED(r.get(out.timecode) && r.get(out.timecode_sub), "truncated timecode");
  if (v.at_least(2, 7)) {
    TELEX_NN_NEED(r.get(out.timestamp_s), "truncated timestamp");
  } else if (v.at_least(2, 6)) {
    float ts = 0;
    TELEX_NN_NEED(r.get(ts), "truncated timestamp");
    out.timestamp_s = ts;
  }
  if (v.major >= 3)
    TELEX_NN_NEED(r.get(out.stamp_mid_exposure) && r.get(out.stamp_data_received) &&
                      r.get(out.stamp_transmit),
                  "truncated high-resolution stamps");
  if (v.at_least(4, 1))
    TELEX_NN_NEED(r.get(out.precision_s) && r.get(out.precision_frac),
                  "truncated precision timestamp");
  if (v.at_least(2, 6)) TELEX_NN_NEED(r.get(out.params), "truncated frame params");
  std::uint32_t eod = 0;
  TELEX_NN_NEED(r.get(eod), "missing end-of-data marker");
  TELEX_NN_NEED(eod == 0, "end-of-data marker is not zero");
  // Up to 4.1 the layout is known to the byte, so anything after the marker means the frame was
  // read in another version's layout; a later 4.x may append fields, which are left unread.
  if (!v.at_least(4, 2)) TELEX_NN_NEED(r.left() == 0, "bytes after the end-of-data marker");
  return {};
}

#undef TELEX_NN_NEED
#undef TELEX_NN_FAIL

namespace {

class Writer {
 public:
  template <WireScalar T>
  void put(T v) {
    w_.put(v);
  }
  void vec3(const Vec3f& v) {
    put(v.x);
    put(v.y);
    put(v.z);
  }
  void cstring(const std::string& s) { w_.cstring(s); }
  // 4.1+: reserve a byte count and fill it in when the section ends.
  std::size_t open_section(Version v) {
    if (!v.at_least(4, 1)) return 0;
    put(std::uint32_t{0});
    return b.size();
  }
  void close_section(Version v, std::size_t start) {
    if (!v.at_least(4, 1)) return;
    w_.patch_u32(start - 4, static_cast<std::uint32_t>(b.size() - start));
  }
  std::vector<std::uint8_t> b;

 private:
  ByteWriter w_{b};
};

void write_rigid_body(Writer& w, const RigidBody& rb, Version v) {
  w.put(rb.id);
  w.vec3(rb.p_m);
  w.put(rb.qx);
  w.put(rb.qy);
  w.put(rb.qz);
  w.put(rb.qw);
  if (v.major < 3) {
    w.put(static_cast<std::int32_t>(rb.markers.size()));
    for (const auto& m : rb.markers) w.vec3(m);
    if (v.major >= 2) {
      for (std::size_t i = 0; i < rb.markers.size(); ++i) w.put(static_cast<std::int32_t>(i + 1));
      for (std::size_t i = 0; i < rb.markers.size(); ++i) w.put(0.014f);
    }
  }
  if (v.major >= 2) w.put(rb.mean_error_m);
  if (v.at_least(2, 6)) w.put(static_cast<std::int16_t>(rb.tracking_valid ? 1 : 0));
}

void write_analog(Writer& w, const std::vector<AnalogDevice>& devs, Version v) {
  w.put(static_cast<std::int32_t>(devs.size()));
  const auto sec = w.open_section(v);
  for (const auto& d : devs) {
    w.put(d.id);
    w.put(static_cast<std::int32_t>(d.channels.size()));
    for (const auto& ch : d.channels) {
      w.put(static_cast<std::int32_t>(ch.size()));
      for (float f : ch) w.put(f);
    }
  }
  w.close_section(v, sec);
}

}  // namespace

std::vector<std::uint8_t> make_packet(std::uint16_t message_id,
                                      std::span<const std::uint8_t> payload) {
  if (payload.size() > 0xFFFF) throw std::length_error("NatNet payload exceeds 65535 bytes");
  const auto n = static_cast<std::uint16_t>(payload.size());
  std::vector<std::uint8_t> out;
  out.reserve(4 + payload.size());
  ByteWriter w(out);
  w.u16(message_id);
  w.u16(n);
  w.bytes(payload);
  return out;
}

std::vector<std::uint8_t> make_ping(std::string_view app_name) {
  std::vector<std::uint8_t> p(app_name.begin(), app_name.end());
  p.push_back(0);
  return make_packet(kPing, p);
}

std::vector<std::uint8_t> encode_frame(const Frame& f, Version v) {
  if (!supported(v)) throw std::invalid_argument("encode_frame: NatNet version outside 2.0 .. 4.x");
  Writer w;
  w.put(f.frame_number);
  w.put(static_cast<std::int32_t>(f.marker_sets.size()));
  auto sec = w.open_section(v);
  for (const auto& ms : f.marker_sets) {
    w.cstring(ms.name);
    w.put(static_cast<std::int32_t>(ms.markers.size()));
    for (const auto& m : ms.markers) w.vec3(m);
  }
  w.close_section(v, sec);
  w.put(static_cast<std::int32_t>(f.unlabeled_markers.size()));
  sec = w.open_section(v);
  for (const auto& m : f.unlabeled_markers) w.vec3(m);
  w.close_section(v, sec);
  w.put(static_cast<std::int32_t>(f.rigid_bodies.size()));
  sec = w.open_section(v);
  for (const auto& rb : f.rigid_bodies) write_rigid_body(w, rb, v);
  w.close_section(v, sec);
  if (v.at_least(2, 1)) {
    w.put(static_cast<std::int32_t>(f.skeletons.size()));
    sec = w.open_section(v);
    for (const auto& sk : f.skeletons) {
      w.put(sk.id);
      w.put(static_cast<std::int32_t>(sk.bones.size()));
      for (const auto& b : sk.bones) write_rigid_body(w, b, v);
    }
    w.close_section(v, sec);
  }
  if (v.at_least(4, 1)) {
    w.put(std::int32_t{0});  // no assets
    w.put(std::uint32_t{0});
  }
  if (v.at_least(2, 3)) {
    w.put(static_cast<std::int32_t>(f.labeled_markers.size()));
    sec = w.open_section(v);
    for (const auto& m : f.labeled_markers) {
      w.put(m.id);
      w.vec3(m.p_m);
      w.put(m.size_m);
      if (v.at_least(2, 6)) w.put(m.params);
      if (v.major >= 3) w.put(m.residual_m);
    }
    w.close_section(v, sec);
  }
  if (v.at_least(2, 9)) write_analog(w, f.force_plates, v);
  if (v.at_least(2, 11)) write_analog(w, f.devices, v);
  if (v.major < 3) w.put(f.software_latency_s);
  if (v.at_least(2, 3)) {
    w.put(f.timecode);
    w.put(f.timecode_sub);
  }
  if (v.at_least(2, 7))
    w.put(f.timestamp_s);
  else if (v.at_least(2, 6))
    w.put(static_cast<float>(f.timestamp_s));
  if (v.major >= 3) {
    w.put(f.stamp_mid_exposure);
    w.put(f.stamp_data_received);
    w.put(f.stamp_transmit);
  }
  if (v.at_least(4, 1)) {
    w.put(f.precision_s);
    w.put(f.precision_frac);
  }
  if (v.at_least(2, 6)) w.put(f.params);
  w.put(std::uint32_t{0});
  return make_packet(kFrameOfData, w.b);
}

}  // namespace telex::local::natnet
