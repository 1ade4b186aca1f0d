// SPDX-License-Identifier: MIT
// Rebuilds depth frames from independently decodable tiles; a missing tile keeps its last value
// up to a maximum age, then counts as no data.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

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
};

// What an assembled frame holds (docs/PROTOCOL.md 2.4, frame parts).
enum class AssembledPart : std::uint8_t {
  Whole,    // a frame sent in one part
  RoiPart,  // the ROI tiles of a frame are current; its other tiles still hold earlier frames'
            // data (unconfirmed) until the rest arrives
  Rest,     // the same frame again, completed by its rest
};

struct AssembledFrame {
  cv::Mat1w depth_mm;  // the whole frame, a private copy
  Intrinsics intrinsics;
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;   // sender clock
  std::int64_t received_ns = 0;  // receiver clock, when the manifest arrived
  bool complete = true;          // every tile the manifest named arrived
  AssembledPart part = AssembledPart::Whole;
  // Rest only: tiles whose pixels may differ from the RoiPart published for this frame (decoded
  // since, or expired). Empty: the ROI part's frame was already this frame.
  std::vector<cv::Rect> changed_since_roi_part;
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
  bool apply_tile(const proto::Header& header, const proto::DepthTile& tile, std::int64_t now_ns);

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
  bool have_frame_ = false;
  bool roi_part_open_ = false;  // last_frame_id_ was published as an ROI part; its rest may follow
  std::uint32_t last_frame_id_ = 0;
  AssemblerCounters counters_;
};

}  // namespace telex::local
