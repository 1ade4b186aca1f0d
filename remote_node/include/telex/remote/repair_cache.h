// SPDX-License-Identifier: MIT
// The tiles the remote sent in its last few frames, kept encoded so that a TileNack is answered by
// resending them (RFC 4588's retransmission, by tile; docs/PROTOCOL.md 2.5).
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "telex/proto/depth_codec.h"
#include "telex/proto/messages.h"

namespace telex::remote {

// One cached tile: what goes out again, with its frame's id and capture time.
struct CachedTile {
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;
  proto::Codec codec = proto::Codec::Zip;
  std::shared_ptr<const proto::EncodedTile> tile;
};

// What one TileNack was answered with.
struct NackAnswer {
  std::vector<CachedTile> resend;          // one per requested tile found, in the request's order
  std::vector<std::uint16_t> unavailable;  // requested tiles no cached frame at or after holds
};

// Bounded by frames: the tiles of the newest `max_frames` frames (both parts of a frame go into
// the same entry). Not thread-safe: the server guards it.
class RepairCache {
 public:
  explicit RepairCache(std::size_t max_frames = 8) : max_frames_(max_frames) {}

  // Records tiles sent for `frame_id` (a newer frame evicts the oldest beyond the bound).
  void add(std::uint32_t frame_id, std::int64_t capture_ns, proto::Codec codec,
           const std::vector<proto::EncodedTile>& tiles);
  // For each tile of the NACK: the newest cached copy from frame nack.frame_id or a newer frame
  // (serial order, RFC 1982), so a tile changed again since comes back in its newest version.
  // A tile no cached frame at or after nack.frame_id holds is unavailable.
  NackAnswer answer(const proto::TileNack& nack) const;
  void clear() { frames_.clear(); }
  std::size_t frames() const { return frames_.size(); }

 private:
  struct Frame {
    std::uint32_t frame_id = 0;
    std::int64_t capture_ns = 0;
    proto::Codec codec = proto::Codec::Zip;
    std::vector<std::shared_ptr<const proto::EncodedTile>> tiles;  // sorted by index
  };
  std::size_t max_frames_;
  std::deque<Frame> frames_;  // oldest first
};

}  // namespace telex::remote
