// SPDX-License-Identifier: MIT
// The one little-endian byte cursor: a bounds-checked reader and an appending writer, for the
// project's wire format (proto/) and NatNet (local_node/natnet.cpp). Values are assembled from
// bytes, never copied in host order, so the code is right on any host.
#pragma once

#include <bit>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace telex {

namespace detail {
template <std::size_t N>
struct UintOfSize;
template <>
struct UintOfSize<1> {
  using type = std::uint8_t;
};
template <>
struct UintOfSize<2> {
  using type = std::uint16_t;
};
template <>
struct UintOfSize<4> {
  using type = std::uint32_t;
};
template <>
struct UintOfSize<8> {
  using type = std::uint64_t;
};
}  // namespace detail

template <typename T>
concept WireScalar = std::is_arithmetic_v<T> && !std::same_as<T, bool> &&
                     (sizeof(T) == 1 || sizeof(T) == 2 || sizeof(T) == 4 || sizeof(T) == 8);

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}
  template <WireScalar T>
  void put(T v) {
    using U = typename detail::UintOfSize<sizeof(T)>::type;
    const U u = std::bit_cast<U>(v);
    for (std::size_t i = 0; i < sizeof(T); ++i)
      out_.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
  }
  void u8(std::uint8_t v) { put(v); }
  void u16(std::uint16_t v) { put(v); }
  void u32(std::uint32_t v) { put(v); }
  void u64(std::uint64_t v) { put(v); }
  void f32(float v) { put(v); }
  void f64(double v) { put(v); }
  void bytes(std::span<const std::uint8_t> b) { out_.insert(out_.end(), b.begin(), b.end()); }
  void cstring(const std::string& s) {
    out_.insert(out_.end(), s.begin(), s.end());
    out_.push_back(0);
  }
  // Overwrites 4 bytes written earlier at `offset` (a length known only later).
  void patch_u32(std::size_t offset, std::uint32_t v) {
    for (std::size_t i = 0; i < 4; ++i)
      out_.at(offset + i) = static_cast<std::uint8_t>(v >> (8 * i));
  }
  std::size_t size() const { return out_.size(); }

 private:
  std::vector<std::uint8_t>& out_;
};

// Every read checks the remaining length; after the first short read ok() stays false and reads
// return zero (or false), so a decoder may check once at the end of a group of fields.
class ByteReader {
 public:
  explicit ByteReader(std::span<const std::uint8_t> in) : in_(in) {}
  bool ok() const { return ok_; }
  std::size_t offset() const { return pos_; }
  std::size_t remaining() const { return in_.size() - pos_; }
  bool need(std::size_t n) {
    if (!ok_ || remaining() < n) ok_ = false;
    return ok_;
  }
  // Reads one value; false (and `v` untouched) when fewer than sizeof(T) bytes are left.
  template <WireScalar T>
  bool get(T& v) {
    if (!need(sizeof(T))) return false;
    using U = typename detail::UintOfSize<sizeof(T)>::type;
    U u = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i)
      u |= static_cast<U>(static_cast<U>(in_[pos_ + i]) << (8 * i));
    pos_ += sizeof(T);
    v = std::bit_cast<T>(u);
    return true;
  }
  template <WireScalar T>
  T read() {
    T v{};
    get(v);
    return v;
  }
  std::uint8_t u8() { return read<std::uint8_t>(); }
  std::uint16_t u16() { return read<std::uint16_t>(); }
  std::uint32_t u32() { return read<std::uint32_t>(); }
  std::uint64_t u64() { return read<std::uint64_t>(); }
  float f32() { return read<float>(); }
  double f64() { return read<double>(); }
  std::span<const std::uint8_t> bytes(std::size_t n) {
    if (!need(n)) return {};
    auto s = in_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  bool skip(std::size_t n) { return !bytes(n).empty() || (n == 0 && ok_); }
  // A NUL-terminated string; false when no NUL is left in the input.
  bool cstring(std::string& s) {
    if (!ok_) return false;
    const auto* start = in_.data() + pos_;
    const void* nul = std::memchr(start, 0, remaining());
    if (nul == nullptr) {
      ok_ = false;
      return false;
    }
    const auto n = static_cast<std::size_t>(static_cast<const std::uint8_t*>(nul) - start);
    s.assign(reinterpret_cast<const char*>(start), n);
    pos_ += n + 1;
    return true;
  }

 private:
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
  bool ok_ = true;
};

// A little-endian u32 at `p` (which must hold 4 bytes), for hot loops that checked the length.
inline std::uint32_t load_le_u32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

}  // namespace telex
