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

void MessageAuth::set_key(std::optional<AuthKey> key) {
  key_ = std::move(key);
  window_ = ReplayWindow{};
}

Result MessageAuth::open(std::span<const std::uint8_t> message, const DecodeLimits& limits) {
  const auto failure = [](ErrorReason reason, const char* detail) {
    Result r;
    r.error = reason;
    r.detail = detail;
    return r;
  };
  // Too short to hold flags: the decoder names what is wrong.
  if (message.size() < kHeaderSize) return decode(message, limits);
  const auto flags = static_cast<std::uint16_t>(message[6] | (message[7] << 8));
  const bool tagged = (flags & kFlagAuth) != 0;
  if (!key_) {
    if (tagged) return failure(ErrorReason::UnexpectedTag, "tagged message but no key configured");
    return decode(message, limits);
  }
  if (!tagged) return failure(ErrorReason::AuthFailed, "message has no tag");
  const auto body = verify_and_strip(message, *key_);
  if (!body) return failure(ErrorReason::AuthFailed, "tag does not verify");
  Result r = decode(*body, limits);
  if (!r.ok()) return r;
  const std::uint64_t seq = extend_seq(r.envelope->header.seq, window_.highest());
  switch (window_.check_and_update(seq)) {
    case ReplayWindow::Verdict::Accepted:
      return r;
    case ReplayWindow::Verdict::Replayed:
      return failure(ErrorReason::Replayed, "sequence number already received");
    case ReplayWindow::Verdict::TooOld:
      return failure(ErrorReason::Replayed, "sequence number older than the replay window");
  }
  return failure(ErrorReason::Replayed, "sequence number");
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
  if (len < kHeaderSize || len > limits_.max_message_bytes + kAuthTagBytes)
    return fail(ErrorReason::BadLength, "stream length prefix out of bounds", true);
  // Check the header as soon as it is here, so garbage is rejected before a long wait.
  if (avail >= 4 + kHeaderSize) {
    Header h;
    if (auto e = decode_header({p + 4, kHeaderSize}, h, limits_))
      return fail(e->reason, e->detail, true);
    const std::size_t tag = (h.flags & kFlagAuth) != 0 ? kAuthTagBytes : 0;
    if (h.payload_len + kHeaderSize + tag != len)
      return fail(ErrorReason::BadLength, "length prefix disagrees with header payload_len", true);
  }
  if (avail < 4 + static_cast<std::size_t>(len)) return std::nullopt;
  Result r = auth_.open({p + 4, len}, limits_);
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
  Result r = auth_.open(datagram, limits_);
  if (r.ok()) {
    ++messages_;
  } else {
    drops_.by_reason[static_cast<std::size_t>(r.error)]++;
  }
  return r;
}

}  // namespace telex::proto
