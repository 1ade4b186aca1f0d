// SPDX-License-Identifier: MIT
// The remote's cache of recently sent tiles, answering TileNack.
#include "telex/remote/repair_cache.h"

#include <algorithm>

namespace telex::remote {
namespace {
// Serial-number order (RFC 1982): a is at or after b.
bool at_or_after(std::uint32_t a, std::uint32_t b) { return static_cast<std::int32_t>(a - b) >= 0; }
}  // namespace

void RepairCache::add(std::uint32_t frame_id, std::int64_t capture_ns, proto::Codec codec,
                      const std::vector<proto::EncodedTile>& tiles) {
  if (max_frames_ == 0 || tiles.empty()) return;
  // The rest of a frame joins its ROI part's entry.
  Frame* f = nullptr;
  if (!frames_.empty() && frames_.back().frame_id == frame_id && frames_.back().codec == codec)
    f = &frames_.back();
  if (f == nullptr) {
    frames_.push_back(Frame{frame_id, capture_ns, codec, {}});
    while (frames_.size() > max_frames_) frames_.pop_front();
    f = &frames_.back();
  }
  for (const auto& t : tiles) {
    auto copy = std::make_shared<const proto::EncodedTile>(t);
    auto it = std::lower_bound(f->tiles.begin(), f->tiles.end(), t.index,
                               [](const std::shared_ptr<const proto::EncodedTile>& a,
                                  std::uint16_t i) { return a->index < i; });
    if (it != f->tiles.end() && (*it)->index == t.index)
      *it = std::move(copy);
    else
      f->tiles.insert(it, std::move(copy));
  }
}

NackAnswer RepairCache::answer(const proto::TileNack& nack) const {
  NackAnswer out;
  for (std::uint16_t index : nack.tiles) {
    bool found = false;
    for (auto f = frames_.rbegin(); f != frames_.rend() && !found; ++f) {
      if (!at_or_after(f->frame_id, nack.frame_id)) break;
      auto it = std::lower_bound(f->tiles.begin(), f->tiles.end(), index,
                                 [](const std::shared_ptr<const proto::EncodedTile>& a,
                                    std::uint16_t i) { return a->index < i; });
      if (it != f->tiles.end() && (*it)->index == index) {
        out.resend.push_back(CachedTile{f->frame_id, f->capture_ns, f->codec, *it});
        found = true;
      }
    }
    if (!found) out.unavailable.push_back(index);
  }
  return out;
}

void VideoRepairCache::add(Pair pair) {
  if (max_pairs_ == 0 || !pair.frame) return;
  pairs_.push_back(std::move(pair));
  while (pairs_.size() > max_pairs_) pairs_.pop_front();
}

std::optional<VideoRepairCache::Pair> VideoRepairCache::find(std::uint32_t encode_seq) const {
  for (auto it = pairs_.rbegin(); it != pairs_.rend(); ++it)
    if (it->encode_seq == encode_seq) return *it;
  return std::nullopt;
}

RepairLimiter::Verdict RepairLimiter::admit(std::uint16_t tile, std::uint32_t frame_id,
                                            std::size_t bytes, std::int64_t now_ns) {
  if (!started_) {
    started_ = true;
    last_ns_ = now_ns;
  }
  if (now_ns > last_ns_) {
    tokens_ = std::min(cfg_.burst_bytes,
                       tokens_ + cfg_.bytes_per_s * static_cast<double>(now_ns - last_ns_) * 1e-9);
    last_ns_ = now_ns;
  }
  if (tile >= sent_.size()) sent_.resize(static_cast<std::size_t>(tile) + 1);
  Sent& s = sent_[tile];
  if (s.valid && s.frame_id == frame_id && now_ns - s.at_ns < cfg_.dedup_ns)
    return Verdict::Duplicate;
  const double cost = static_cast<double>(bytes);
  if (cost > tokens_) return Verdict::OverBudget;
  tokens_ -= cost;
  s = Sent{frame_id, now_ns, true};
  return Verdict::Send;
}

}  // namespace telex::remote
