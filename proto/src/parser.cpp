// SPDX-License-Identifier: MIT
// TCP stream parser (u32 length prefix) and datagram parser over the message decoder.
#include "telex/proto/parser.h"

#include <algorithm>
#include <cstring>
#include <numeric>

#include "byte_io.h"

namespace telex::proto {

std::uint64_t DropCounters::total() const {
  return std::accumulate(by_reason.begin(), by_reason.end(), std::uint64_t{0});
}

void ParserCore::set_frame_size(std::uint16_t width, std::uint16_t height) {
  limits_.frame_width = width;
  limits_.frame_height = height;
}

StreamParser::StreamParser(DecodeLimits limits) : ParserCore(limits) {}

std::size_t StreamParser::feed(std::span<const std::uint8_t> bytes) {
  if (failed_) return 0;
  // Compact lazily: consumed bytes at the front are reclaimed before growing.
  if (begin_ > 0 && (end_ + bytes.size() > buf_.size())) {
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  const std::size_t room = capacity() - end_;
  const std::size_t take = std::min(room, bytes.size());
  if (take == 0) return 0;  // also keeps memcpy away from a null pointer
  if (end_ + take > buf_.size())
    buf_.resize(std::min(capacity(), std::max(end_ + take, buf_.size() * 2)));
  std::memcpy(buf_.data() + end_, bytes.data(), take);
  end_ += take;
  return take;
}

Result StreamParser::fail(ErrorReason reason, const char* detail, bool fatal) {
  drops_.by_reason[static_cast<std::size_t>(reason)]++;
  if (fatal) {
    failed_ = true;
    begin_ = end_ = 0;
    buf_.clear();
    buf_.shrink_to_fit();
  }
  Result r;
  r.error = reason;
  r.detail = detail;
  return r;
}

std::optional<Result> StreamParser::next() {
  if (failed_) return std::nullopt;
  const std::size_t avail = end_ - begin_;
  if (avail < 4) return std::nullopt;
  const std::uint8_t* p = buf_.data() + begin_;
  const std::uint32_t len = detail::load_u32(p);
  if (len < kHeaderSize || len > limits_.max_message_bytes)
    return fail(ErrorReason::BadLength, "stream length prefix out of bounds", true);
  // Check the header as soon as it is here, so garbage is rejected before a long wait.
  if (avail >= 4 + kHeaderSize) {
    Header h;
    if (auto e = decode_header({p + 4, kHeaderSize}, h, limits_))
      return fail(e->reason, e->detail, true);
    if (h.payload_len + kHeaderSize != len)
      return fail(ErrorReason::BadLength, "length prefix disagrees with header payload_len", true);
  }
  if (avail < 4 + static_cast<std::size_t>(len)) return std::nullopt;
  Result r = decode({p + 4, len}, limits_);
  begin_ += 4 + static_cast<std::size_t>(len);
  if (begin_ == end_) begin_ = end_ = 0;
  if (r.ok()) {
    ++messages_;
    return r;
  }
  // Framing was verified above; only a CRC mismatch leaves the byte stream untrustworthy.
  const bool fatal = r.error == ErrorReason::BadChecksum || r.error == ErrorReason::BadMagic ||
                     r.error == ErrorReason::BadLength || r.error == ErrorReason::Truncated;
  return fail(r.error, r.detail, fatal);
}

std::optional<Result> StreamParser::finish() {
  if (failed_ || end_ == begin_) return std::nullopt;
  return fail(ErrorReason::Truncated, "stream ended inside a message", true);
}

DatagramParser::DatagramParser(DecodeLimits limits) : ParserCore(limits) {}

Result DatagramParser::parse(std::span<const std::uint8_t> datagram) {
  Result r = decode(datagram, limits_);
  if (r.ok()) {
    ++messages_;
  } else {
    drops_.by_reason[static_cast<std::size_t>(r.error)]++;
  }
  return r;
}

}  // namespace telex::proto
