// SPDX-License-Identifier: MIT
// Rebuilds depth frames from independently decodable tiles; a missing tile keeps its last value
// up to a maximum age, then counts as no data.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "telex/base/periodic.h"
#include "telex/common/depth_image.h"
#include "telex/proto/messages.h"

namespace telex::local {

struct AssemblerCounters {
  std::uint64_t tiles = 0;              // tiles decoded into the frame
  std::uint64_t tiles_rejected = 0;     // bad geometry, codec mismatch or decode failure
  std::uint64_t tiles_stale = 0;        // tiles of a frame older than the newest manifest
  std::uint64_t frames = 0;             // manifests that produced a frame
  std::uint64_t roi_parts = 0;          // ROI-part manifests published before their frame's rest
  std::uint64_t frames_incomplete = 0;  // manifests naming tiles that never arrived
  std::uint64_t tiles_missing = 0;      // tiles a manifest named but we did not get
  std::uint64_t tiles_expired = 0;      // tiles zeroed because they grew older than max age
  std::uint64_t manifests_rejected = 0;
  // Repair (docs/PROTOCOL.md 2.5).
  std::uint64_t frames_unclosed = 0;  // tiles of a frame arrived, then a newer frame before its
                                      // closing manifest: what that frame changed is unknown
  std::uint64_t tiles_repaired = 0;   // resent tiles (kFlagRepair) that made a tile current
  std::uint64_t repairs_useless = 0;  // resent tiles that arrived after a newer copy
  std::uint64_t nacks = 0;            // TileNacks asked for
  std::uint64_t tiles_nacked = 0;
  std::uint64_t watched_tiles_nacked = 0;  // of those, tiles of the watched (fingertip) windows
  std::uint64_t key_frame_requests = 0;
};

// What the assembler wants from the remote now (FrameAssembler::repair_request).
struct RepairRequest {
  std::optional<proto::TileNack> nack;  // tiles that are not current
  bool key_frame = false;               // a frame could not be completed
};

// How old the tiles are, sampled at every closed frame: the capture time of that frame less the
// capture time of the newest frame at which each tile was known current, in frame periods.
struct TileAges {
  Histogram watched{0.1, 2000};  // tiles of the watched (fingertip) windows
  Histogram all{0.1, 2000};      // every tile that ever held data
};

// What an assembled frame holds (docs/PROTOCOL.md 2.4, frame parts).
enum class AssembledPart : std::uint8_t {
  Whole,    // a frame sent in one part
  RoiPart,  // the ROI tiles of a frame are current; its other tiles still hold earlier frames'
            // data (unconfirmed) until the rest arrives
  Rest,     // the same frame again, completed by its rest
  Repair,   // the last frame again, with tiles a TileNack brought back
};

struct AssembledFrame {
  cv::Mat1w depth_mm;  // the whole frame, a private copy
  Intrinsics intrinsics;
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;   // sender clock
  std::int64_t received_ns = 0;  // receiver clock, when the manifest arrived
  bool complete = true;          // every tile the manifest named arrived
  AssembledPart part = AssembledPart::Whole;
  // Rest and Repair: tiles whose pixels may differ from the frame published before with the same
  // capture (decoded since, repaired, or expired). Empty: nothing changed.
  std::vector<cv::Rect> changed_since_roi_part;
  proto::HeadJoints head;  // the robot head at capture (from the manifest)
};

// Not thread-safe: the network thread owns it. Time comes in as arguments.
class FrameAssembler {
 public:
  explicit FrameAssembler(std::int64_t max_tile_age_ns = 500'000'000)
      : max_age_ns_(max_tile_age_ns) {}

  // (Re)configures the frame; resets all tiles to no data.
  void configure(const proto::StreamConfig& config);
  bool configured() const { return !frame_.empty(); }
  const proto::StreamConfig& config() const { return config_; }

  // Decodes a tile into the frame. Returns false (counted) when it does not fit the configuration.
  // A tile flagged kFlagRepair is the copy of an earlier (or the newest) frame's tile: it is taken
  // when it is newer than what the tile holds, and makes the tile current when no closed frame
  // changed the tile after it.
  bool apply_tile(const proto::Header& header, const proto::DepthTile& tile, std::int64_t now_ns);

  // The watched tiles repairs made current since the last call, as the last frame republished
  // (part Repair, the same capture); nothing when no repair made a watched tile current.
  std::optional<AssembledFrame> take_repaired(std::int64_t now_ns);

  // Tiles whose age is sampled as `watched` (the fingertip windows' tiles): those that intersect
  // any of these rectangles (pixels of the frame).
  void set_watched(const std::vector<cv::Rect>& rects);
  // After a manifest: a TileNack for the tiles a closed frame changed that have not arrived (each
  // tile asked again only after retry_ns), and a key frame when a frame went unclosed (what it
  // changed is unknown; at most once per key_interval_ns until a key frame closes).
  RepairRequest repair_request(std::int64_t now_ns, std::int64_t retry_ns,
                               std::int64_t key_interval_ns);
  const TileAges& ages() const { return ages_; }

  // Closes a frame: the tiles it names should all have arrived. Returns the assembled frame (tiles
  // older than the maximum age zeroed) or nothing when the manifest is stale or malformed.
  // A manifest flagged kFlagRoiPart publishes the frame early: its listed tiles are confirmed, the
  // others are neither confirmed nor expected yet. Tiles of that frame id and then its closing
  // manifest (same frame id, no flag) are still accepted until a newer frame arrives.
  std::optional<AssembledFrame> finish(const proto::Header& header,
                                       const proto::FrameManifest& manifest, std::int64_t now_ns);

  const AssemblerCounters& counters() const { return counters_; }

 private:
  proto::StreamConfig config_;
  proto::TileGrid grid_;
  cv::Mat1w frame_;
  std::vector<std::int64_t> tile_updated_ns_;  // receiver time a tile was last confirmed
  std::vector<std::uint32_t> tile_frame_id_;   // frame id of each tile's last update
  std::vector<bool> tile_valid_;               // tile holds data that has not expired
  std::vector<bool> listed_scratch_;
  std::int64_t max_age_ns_;
  std::vector<bool> arrived_since_part_;  // tiles decoded after the open ROI part
  // Repair: the newest closed frame that changed each tile (its data is current when its own
  // frame is not older), the capture time at which each tile was last known current, when each
  // was last asked for, and the tiles repaired since the last take_repaired().
  std::vector<std::uint32_t> tile_listed_frame_id_;
  std::vector<bool> tile_listed_;
  std::vector<std::int64_t> tile_current_capture_ns_;
  std::vector<std::int64_t> tile_nacked_ns_;
  std::vector<int> repaired_;
  std::vector<bool> watched_;
  TileAges ages_;
  bool open_frame_ = false;  // tiles of open_frame_id_ (newer than the last closed) have arrived
  std::uint32_t open_frame_id_ = 0;
  bool unclosed_pending_ = false;  // a frame went unclosed since the last key frame
  std::int64_t last_key_request_ns_ = 0;
  std::int64_t last_capture_ns_ = 0;  // of the last published frame
  proto::HeadJoints last_head_;       // of the last published frame
  bool stale(std::size_t i) const;
  bool have_frame_ = false;
  bool roi_part_open_ = false;  // last_frame_id_ was published as an ROI part; its rest may follow
  std::uint32_t last_frame_id_ = 0;
  AssemblerCounters counters_;
};

}  // namespace telex::local
