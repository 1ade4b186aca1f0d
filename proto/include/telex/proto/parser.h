// SPDX-License-Identifier: MIT
// Incremental parsers: a TCP stream parser (u32 length prefix + message) and a datagram parser.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "telex/proto/messages.h"

namespace telex::proto {

// Messages rejected, per reason (indexed by ErrorReason).
struct DropCounters {
  std::array<std::uint64_t, kErrorReasonCount> by_reason{};
  std::uint64_t of(ErrorReason r) const { return by_reason[static_cast<std::size_t>(r)]; }
  std::uint64_t total() const;
};

// What both parsers keep: the decode limits (with the frame size once known) and the counters.
// Authenticity lives below them: TLS on the stream, the seal (seal.h) on datagrams.
class ParserCore {
 public:
  const DropCounters& drops() const { return drops_; }
  std::uint64_t messages() const { return messages_; }
  // Lets tile rectangles be checked against the frame once StreamConfig is known.
  void set_frame_size(std::uint16_t width, std::uint16_t height);

 protected:
  explicit ParserCore(DecodeLimits limits) : limits_(limits) {}
  DecodeLimits limits_;
  DropCounters drops_;
  std::uint64_t messages_ = 0;
};

// TCP stream parser. Bytes in: feed(); messages out: next(). Never touches a socket.
//
// Memory: the internal buffer never holds more than 4 + limits.max_message_bytes bytes; feed()
// accepts only what fits and returns how many bytes it took, so a caller drains with next() and
// feeds the rest.
//
// Errors: TCP delivers bytes intact and in order, so two classes exist.
//  - Framing errors (length prefix out of bound or disagreeing with the header's payload_len,
//    BadMagic, BadChecksum): the byte boundary of the next message can no longer be trusted. The
//    parser reports the error once, then stays failed() (feed takes nothing, next() returns
//    nullopt): THE CALLER CLOSES THE CONNECTION. No resynchronisation is attempted.
//  - Content errors in a correctly framed message whose CRC verified (BadVersion, UnknownType,
//    BadPayload, BadTileGeometry, DecompressionBomb): the message is skipped, the error returned,
//    and parsing continues with the next message.
class StreamParser : public ParserCore {
 public:
  explicit StreamParser(DecodeLimits limits = {});

  [[nodiscard]] std::size_t feed(std::span<const std::uint8_t> bytes);
  std::optional<Result> next();
  // At end of stream: Truncated when a partial message is buffered (also counted), else nullopt.
  std::optional<Result> finish();

  bool failed() const { return failed_; }
  std::size_t buffered() const { return end_ - begin_; }
  std::size_t capacity() const { return 4 + limits_.max_message_bytes; }

 private:
  Result fail(ErrorReason reason, const char* detail, bool fatal);

  std::vector<std::uint8_t> buf_;
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  bool failed_ = false;
};

// One message per datagram (or per reassembled UDP message); no length prefix. Stateless apart
// from counters, so every datagram stands alone.
class DatagramParser : public ParserCore {
 public:
  explicit DatagramParser(DecodeLimits limits = {});
  Result parse(std::span<const std::uint8_t> datagram);
};

}  // namespace telex::proto
