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

// The encoded pairs the remote sent last, kept so that a VideoNack is answered by sending a pair
// again (PROTOCOL.md 2.7). Bounded by pairs; not thread-safe: the server guards it.
class VideoRepairCache {
 public:
  struct Pair {
    std::uint32_t encode_seq = 0;
    std::uint32_t frame_id = 0;
    std::int64_t capture_ns = 0;
    bool is_intra = false;
    std::shared_ptr<const std::vector<std::uint8_t>> frame;  // header + payload, as sent
  };
  explicit VideoRepairCache(std::size_t max_pairs = 16) : max_pairs_(max_pairs) {}
  void add(Pair pair);
  // The cached pair with this encode_seq, or nullopt.
  std::optional<Pair> find(std::uint32_t encode_seq) const;
  void clear() { pairs_.clear(); }
  std::size_t pairs() const { return pairs_.size(); }

 private:
  std::size_t max_pairs_;
  std::deque<Pair> pairs_;  // oldest first
};

// Bounds what TileNacks can make the remote send (issue 27): a NACK of ~150 bytes could otherwise
// queue a key frame of resends. A tile already resent from the same cached frame within
// `dedup_ns` is not sent again (the station asks again only after its retry interval, at least
// 25 ms: a repeat sooner is a duplicate or a storm), and resends draw on a token bucket of bytes
// that refills at `bytes_per_s` up to `burst_bytes`. Pure: time comes in as an argument; one per
// session, on the network thread.
class RepairLimiter {
 public:
  struct Config {
    std::int64_t dedup_ns = 10'000'000;
    double bytes_per_s = 1.25e6;  // 10 Mbit/s: the whole stream's goal, so repair never outgrows it
    double burst_bytes = 256.0 * 1024.0;
  };
  enum class Verdict { Send, Duplicate, OverBudget };

  explicit RepairLimiter(Config config) : cfg_(config), tokens_(config.burst_bytes) {}
  RepairLimiter() : RepairLimiter(Config{}) {}
  Verdict admit(std::uint16_t tile, std::uint32_t frame_id, std::size_t bytes, std::int64_t now_ns);
  const Config& config() const { return cfg_; }

 private:
  struct Sent {
    std::uint32_t frame_id = 0;
    std::int64_t at_ns = 0;
    bool valid = false;
  };
  Config cfg_;
  double tokens_;
  std::int64_t last_ns_ = 0;
  bool started_ = false;
  std::vector<Sent> sent_;  // by tile index, grown on demand (at most kMaxManifestTiles)
};

}  // namespace telex::remote
