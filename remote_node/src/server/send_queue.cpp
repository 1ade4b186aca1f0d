// SPDX-License-Identifier: MIT
// The remote's two-lane send queue: depth first, video bounded apart and dropped first.
#include "telex/remote/send_queue.h"

#include <algorithm>

namespace telex::remote {
namespace {

// Drops the oldest trimmable frames nobody has started sending so that at most `bound` remain,
// counting the one on the wire when `count_started` (depth, as the single queue did) or not
// (video: a newcomer must not be dropped for the frame already going).
std::size_t trim(std::deque<OutFrame>& q, std::size_t bound, bool count_started) {
  std::size_t dropped = 0;
  auto counted = static_cast<std::size_t>(std::count_if(q.begin(), q.end(), [&](const OutFrame& f) {
    return f.trimmable && (count_started || f.next == 0);
  }));
  while (counted > bound) {
    auto it = std::find_if(q.begin(), q.end(), [](const OutFrame& f) {
      return f.trimmable && f.next == 0;  // the frame on the wire finishes
    });
    if (it == q.end()) break;
    q.erase(it);
    --counted;
    ++dropped;
  }
  return dropped;
}

}  // namespace

SendQueue::SendQueue(SendQueueLimits limits) : limits_(limits) {}

std::size_t SendQueue::push(Lane lane, OutFrame frame) {
  if (lane == Lane::Depth) {
    depth_.push_back(std::move(frame));
    const std::size_t dropped = trim(depth_, limits_.max_depth_frames, true);
    counters_.depth_frames_dropped += dropped;
    return dropped;
  }
  if (!frame.trimmable) {
    // A resent pair goes before the pairs not started: the station holds them until it arrives.
    auto at = std::find_if(video_.begin(), video_.end(),
                           [](const OutFrame& f) { return f.next == 0 && f.trimmable; });
    video_.insert(at, std::move(frame));
    return 0;
  }
  video_.push_back(std::move(frame));
  const std::size_t dropped = trim(video_, limits_.max_video_frames, false);
  counters_.video_frames_dropped += dropped;
  return dropped;
}

Buffer SendQueue::take(std::deque<OutFrame>& q, bool& frame_done, bool& counts) {
  while (!q.empty()) {
    OutFrame& f = q.front();
    if (f.next == 0 && f.pack) {
      f.items = f.pack();
      f.pack = nullptr;
    }
    if (f.next < f.items.size()) break;
    q.pop_front();  // nothing (left) to send in it
  }
  if (q.empty()) return nullptr;
  OutFrame& f = q.front();
  Buffer b = f.items[f.next++];
  frame_done = f.next == f.items.size();
  counts = f.counts_as_frame;
  if (frame_done) q.pop_front();
  return b;
}

Buffer SendQueue::next_item(bool& frame_done, bool& counts, Lane& lane) {
  const bool video_started = !video_.empty() && video_.front().next > 0;
  if (!video_started) {
    if (Buffer b = take(depth_, frame_done, counts)) {
      lane = Lane::Depth;
      return b;
    }
  }
  lane = Lane::Video;
  return take(video_, frame_done, counts);
}

std::size_t SendQueue::queued_repair_bytes() const {
  std::size_t bytes = 0;
  for (const auto* q : {&depth_, &video_})
    for (const OutFrame& f : *q) {
      if (f.trimmable) continue;
      if (f.pack) {
        bytes += f.unpacked_bytes;
        continue;
      }
      for (std::size_t i = f.next; i < f.items.size(); ++i) bytes += f.items[i]->size();
    }
  return bytes;
}

}  // namespace telex::remote
