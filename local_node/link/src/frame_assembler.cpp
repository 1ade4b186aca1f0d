// SPDX-License-Identifier: MIT
// Tile reassembly into whole depth frames with per-tile ageing.
#include "telex/local/link/frame_assembler.h"

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
  const auto n = static_cast<std::size_t>(grid_.count());
  tile_listed_frame_id_.assign(n, 0);
  tile_listed_.assign(n, false);
  tile_current_capture_ns_.assign(n, 0);
  tile_nacked_ns_.assign(n, 0);
  repaired_.clear();
  have_frame_ = false;
  roi_part_open_ = false;
  open_frame_ = false;
  unclosed_pending_ = false;
}

// A tile a closed frame changed whose data is older than that frame (or gone).
bool FrameAssembler::stale(std::size_t i) const {
  return tile_listed_[i] && (!tile_valid_[i] || newer(tile_listed_frame_id_[i], tile_frame_id_[i]));
}

bool FrameAssembler::apply_tile(const proto::Header& header, const proto::DepthTile& tile,
                                std::int64_t now_ns) {
  if (!configured() || tile.tile_index >= grid_.count()) {
    ++counters_.tiles_rejected;
    return false;
  }
  const auto idx = static_cast<std::size_t>(tile.tile_index);
  const bool repair = (header.flags & proto::kFlagRepair) != 0;
  const bool rest_of_open_part = roi_part_open_ && header.frame_id == last_frame_id_;
  if (repair) {
    // A resent copy is of use only when it is newer than what the tile holds.
    if (tile_valid_[idx] && !newer(header.frame_id, tile_frame_id_[idx])) {
      ++counters_.repairs_useless;
      return false;
    }
  } else if (have_frame_ && !newer(header.frame_id, last_frame_id_) && !rest_of_open_part) {
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
  tile_updated_ns_[idx] = now_ns;
  tile_valid_[idx] = true;
  tile_frame_id_[idx] = header.frame_id;
  if (rest_of_open_part) arrived_since_part_[idx] = true;
  ++counters_.tiles;
  const bool of_a_closed_frame = have_frame_ && !newer(header.frame_id, last_frame_id_);
  if (repair && rest_of_open_part) {
    ++counters_.tiles_repaired;  // the rest's manifest publishes it with the frame
    return true;
  }
  if (repair && of_a_closed_frame) {
    // Current again unless a closed frame changed the tile after the copy's frame.
    if (!stale(idx)) {
      tile_current_capture_ns_[idx] = last_capture_ns_;
      ++counters_.tiles_repaired;
      // Only a fingertip window's tile is worth republishing the frame for; the others go out
      // with the next frame.
      if (idx < watched_.size() && watched_[idx]) repaired_.push_back(tile.tile_index);
    }
    return true;
  }
  if (!of_a_closed_frame && !repair) {
    // Tiles of a newer frame: if another unclosed frame is open, its manifest was lost.
    if (open_frame_ && newer(header.frame_id, open_frame_id_)) {
      ++counters_.frames_unclosed;
      unclosed_pending_ = true;
    }
    open_frame_ = true;
    open_frame_id_ = header.frame_id;
  }
  return true;
}

void FrameAssembler::set_watched(const std::vector<cv::Rect>& rects) {
  watched_.assign(tile_valid_.size(), false);
  for (int i = 0; i < grid_.count(); ++i)
    for (const auto& r : rects)
      if ((grid_.rect(i) & r).area() > 0) watched_[static_cast<std::size_t>(i)] = true;
}

std::optional<AssembledFrame> FrameAssembler::take_repaired(std::int64_t now_ns) {
  if (repaired_.empty() || !have_frame_) return std::nullopt;
  AssembledFrame out;
  out.part = AssembledPart::Repair;
  out.frame_id = last_frame_id_;
  out.capture_ns = last_capture_ns_;
  out.head = last_head_;
  out.received_ns = now_ns;
  out.intrinsics =
      Intrinsics{config_.fx, config_.fy, config_.cx, config_.cy, config_.width, config_.height};
  frame_.copyTo(out.depth_mm);
  for (int i = 0; i < grid_.count(); ++i)
    if (!tile_valid_[static_cast<std::size_t>(i)]) out.depth_mm(grid_.rect(i)).setTo(0);
  std::sort(repaired_.begin(), repaired_.end());
  repaired_.erase(std::unique(repaired_.begin(), repaired_.end()), repaired_.end());
  for (int i : repaired_) out.changed_since_roi_part.push_back(grid_.rect(i));
  out.complete = true;
  for (std::size_t i = 0; i < tile_listed_.size(); ++i) out.complete = out.complete && !stale(i);
  repaired_.clear();
  return out;
}

RepairRequest FrameAssembler::repair_request(std::int64_t now_ns, std::int64_t retry_ns,
                                             std::int64_t key_interval_ns) {
  RepairRequest out;
  if (!configured() || !have_frame_) return out;
  proto::TileNack nack;
  bool first = true;
  // Every tile a closed frame changed that has not arrived: the fingertip windows' tiles are the
  // reason, but a window that moves onto a tile lost earlier needs it as well.
  for (std::size_t i = 0; i < tile_valid_.size(); ++i) {
    if (!stale(i)) continue;
    if (tile_nacked_ns_[i] != 0 && now_ns - tile_nacked_ns_[i] < retry_ns) continue;
    tile_nacked_ns_[i] = now_ns;
    nack.tiles.push_back(static_cast<std::uint16_t>(i));
    if (i < watched_.size() && watched_[i]) ++counters_.watched_tiles_nacked;
    // The oldest frame asked for: the remote sends each tile's newest copy from there on.
    if (first || newer(nack.frame_id, tile_listed_frame_id_[i]))
      nack.frame_id = tile_listed_frame_id_[i];
    first = false;
  }
  if (!nack.tiles.empty()) {
    ++counters_.nacks;
    counters_.tiles_nacked += nack.tiles.size();
    out.nack = std::move(nack);
  }
  if (unclosed_pending_ &&
      (last_key_request_ns_ == 0 || now_ns - last_key_request_ns_ >= key_interval_ns)) {
    last_key_request_ns_ = now_ns;
    ++counters_.key_frame_requests;
    out.key_frame = true;
  }
  return out;
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
  if (!closes_part) {
    // A new frame while an earlier one is still open (tiles seen, or an ROI part published, and
    // no closing manifest): what that frame changed is unknown.
    const bool skipped_open = open_frame_ && newer(manifest.frame_id, open_frame_id_);
    if (skipped_open || (roi_part_open_ && have_frame_)) {
      ++counters_.frames_unclosed;
      unclosed_pending_ = true;
    }
  }
  if (open_frame_ && !newer(open_frame_id_, manifest.frame_id)) open_frame_ = false;
  AssembledFrame out;
  out.part = roi_part ? AssembledPart::RoiPart
                      : (closes_part ? AssembledPart::Rest : AssembledPart::Whole);
  out.frame_id = manifest.frame_id;
  out.capture_ns = static_cast<std::int64_t>(header.capture_ns);
  out.head = manifest.head;
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
  const bool closes = !roi_part;
  if (closes && manifest.key_frame) unclosed_pending_ = false;  // a key frame holds everything
  for (int i = 0; i < grid_.count(); ++i) {
    const auto idx = static_cast<std::size_t>(i);
    // Arrived: the tile holds this frame's data or a newer frame's (a repair can run ahead).
    const bool arrived = tile_valid_[idx] && !newer(manifest.frame_id, tile_frame_id_[idx]);
    if (listed[idx] && !arrived) ++missing;
    if (listed[idx] &&
        (!tile_listed_[idx] || newer(manifest.frame_id, tile_listed_frame_id_[idx]))) {
      tile_listed_[idx] = true;
      tile_listed_frame_id_[idx] = manifest.frame_id;
    }
    // An ROI part confirms only what it carries: the tiles it does not list are the rest's to
    // confirm (or send). A tile a closed frame changed and that never arrived is not confirmed by
    // later frames leaving it out: it is repaired, or it expires.
    const bool confirmed = (arrived || (!listed[idx] && !roi_part)) && !stale(idx);
    if (tile_valid_[idx] && confirmed) {
      tile_updated_ns_[idx] = now_ns;
      tile_current_capture_ns_[idx] = out.capture_ns;
    }
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
  last_capture_ns_ = out.capture_ns;
  last_head_ = out.head;
  roi_part_open_ = roi_part;
  repaired_.clear();  // this frame carries them
  if (closes && config_.fps > 0) {
    // Tile ages at this frame, in frame periods.
    const double period_ns = 1e9 / static_cast<double>(config_.fps);
    for (std::size_t i = 0; i < tile_current_capture_ns_.size(); ++i) {
      if (tile_current_capture_ns_[i] == 0) continue;  // never held data
      const double age =
          static_cast<double>(out.capture_ns - tile_current_capture_ns_[i]) / period_ns;
      ages_.all.add(std::max(age, 0.0));
      if (i < watched_.size() && watched_[i]) ages_.watched.add(std::max(age, 0.0));
    }
  }
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
