// SPDX-License-Identifier: MIT
// Tile reassembly into whole depth frames with per-tile ageing.
#include "telex/local/frame_assembler.h"

#include <algorithm>

namespace telex::local {
namespace {
// Serial-number comparison (RFC 1982) so frame ids may wrap.
bool newer(std::uint32_t a, std::uint32_t b) { return static_cast<std::int32_t>(a - b) > 0; }
}  // namespace

void FrameAssembler::configure(const proto::StreamConfig& config) {
  config_ = config;
  grid_ = proto::TileGrid{config.width, config.height, config.tile_width, config.tile_height};
  frame_ = cv::Mat1w(config.height, config.width, std::uint16_t{0});
  tile_updated_ns_.assign(static_cast<std::size_t>(grid_.count()), 0);
  tile_valid_.assign(static_cast<std::size_t>(grid_.count()), false);
  tile_frame_id_.assign(static_cast<std::size_t>(grid_.count()), 0);
  arrived_since_part_.assign(static_cast<std::size_t>(grid_.count()), false);
  have_frame_ = false;
  roi_part_open_ = false;
}

bool FrameAssembler::apply_tile(const proto::Header& header, const proto::DepthTile& tile,
                                std::int64_t now_ns) {
  if (!configured() || tile.tile_index >= grid_.count()) {
    ++counters_.tiles_rejected;
    return false;
  }
  const bool rest_of_open_part = roi_part_open_ && header.frame_id == last_frame_id_;
  if (have_frame_ && !newer(header.frame_id, last_frame_id_) && !rest_of_open_part) {
    ++counters_.tiles_stale;
    return false;
  }
  const cv::Rect r = grid_.rect(tile.tile_index);
  if (r != cv::Rect(tile.x, tile.y, tile.w, tile.h)) {
    ++counters_.tiles_rejected;
    return false;
  }
  if (proto::decode_tile_into(tile.payload, grid_, tile.tile_index, tile.codec, frame_) !=
      proto::DecodeStatus::Ok) {
    ++counters_.tiles_rejected;
    return false;
  }
  tile_updated_ns_[tile.tile_index] = now_ns;
  tile_valid_[tile.tile_index] = true;
  tile_frame_id_[tile.tile_index] = header.frame_id;
  if (rest_of_open_part) arrived_since_part_[tile.tile_index] = true;
  ++counters_.tiles;
  return true;
}

std::optional<AssembledFrame> FrameAssembler::finish(const proto::Header& header,
                                                     const proto::FrameManifest& manifest,
                                                     std::int64_t now_ns) {
  if (!configured() || manifest.tile_count != grid_.count()) {
    ++counters_.manifests_rejected;
    return std::nullopt;
  }
  const bool roi_part = (header.flags & proto::kFlagRoiPart) != 0;
  const bool closes_part =
      !roi_part && roi_part_open_ && have_frame_ && manifest.frame_id == last_frame_id_;
  if (have_frame_ && !newer(manifest.frame_id, last_frame_id_) && !closes_part) {
    ++counters_.manifests_rejected;
    return std::nullopt;
  }
  // An ROI part claiming a key frame would confirm tiles it does not carry.
  if (roi_part && manifest.key_frame) {
    ++counters_.manifests_rejected;
    return std::nullopt;
  }
  AssembledFrame out;
  out.part = roi_part ? AssembledPart::RoiPart
                      : (closes_part ? AssembledPart::Rest : AssembledPart::Whole);
  out.frame_id = manifest.frame_id;
  out.capture_ns = static_cast<std::int64_t>(header.capture_ns);
  out.received_ns = now_ns;
  out.intrinsics =
      Intrinsics{config_.fx, config_.fy, config_.cx, config_.cy, config_.width, config_.height};
  // A tile is confirmed current when it arrived for this frame, or when the manifest says it did
  // not change (unchanged tiles are not resent). Missing tiles keep their last value until they
  // grow older than the maximum age.
  std::vector<bool>& listed = listed_scratch_;
  listed.assign(static_cast<std::size_t>(grid_.count()), manifest.key_frame);
  for (auto i : manifest.changed_tiles) {
    if (i < grid_.count()) listed[i] = true;
  }
  std::uint64_t missing = 0;
  frame_.copyTo(out.depth_mm);
  for (int i = 0; i < grid_.count(); ++i) {
    const auto idx = static_cast<std::size_t>(i);
    const bool arrived = tile_frame_id_[idx] == manifest.frame_id && tile_valid_[idx];
    if (listed[idx] && !arrived) ++missing;
    // An ROI part confirms only what it carries: the tiles it does not list are the rest's to
    // confirm (or send).
    const bool confirmed = arrived || (!listed[idx] && !roi_part);
    if (tile_valid_[idx] && confirmed) tile_updated_ns_[idx] = now_ns;
    bool changed = closes_part && arrived_since_part_[idx];
    if (tile_valid_[idx] && now_ns - tile_updated_ns_[idx] > max_age_ns_) {
      // Too old to trust: no data rather than a surface that may no longer be there.
      frame_(grid_.rect(i)).setTo(0);
      tile_valid_[idx] = false;
      ++counters_.tiles_expired;
      changed = closes_part;
    }
    if (!tile_valid_[idx]) out.depth_mm(grid_.rect(i)).setTo(0);
    if (changed) out.changed_since_roi_part.push_back(grid_.rect(i));
  }
  out.complete = missing == 0;
  std::fill(arrived_since_part_.begin(), arrived_since_part_.end(), false);
  have_frame_ = true;
  last_frame_id_ = manifest.frame_id;
  roi_part_open_ = roi_part;
  if (roi_part) {
    // Counted once, when the frame closes (its closing manifest lists these tiles again).
    ++counters_.roi_parts;
    return out;
  }
  counters_.tiles_missing += missing;
  if (missing) ++counters_.frames_incomplete;
  ++counters_.frames;
  return out;
}

}  // namespace telex::local
