// SPDX-License-Identifier: MIT
// Pairs the frames of two free-running eye cameras by capture time: one instant per stereo pair.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <utility>

#include "telex/base/demand.h"

namespace telex::video {

enum class Eye : std::uint8_t { Left = 0, Right = 1 };

struct EyePairerCounters {
  std::uint64_t pairs = 0;
  std::uint64_t unpaired_left = 0;   // left frames no right frame came within tolerance of
  std::uint64_t unpaired_right = 0;  //
  std::uint64_t out_of_order = 0;    // a frame older than the last one of its eye: dropped
};

// A pure class (no clock, no thread): push each eye's frames with their capture times; a pair is
// emitted when the oldest waiting left and right frames lie within `tolerance_ns` of each other.
// The older of two unmatched frames can never pair later (the other eye's frames only get newer),
// so it is dropped and counted. A stalled eye costs at most `max_waiting` frames of the other.
// `Image` is what the caller carries along: a cv::Mat3b, or camera JPEG bytes for pass-through.
template <typename Image>
class EyePairer {
 public:
  struct Frame {
    Image image;
    std::int64_t capture_ns = 0;
  };
  struct Pair {
    Image left;
    Image right;
    // The older eye's capture time: latency measured from the first light in the pair.
    std::int64_t capture_ns = 0;
    std::int64_t skew_ns = 0;  // right capture minus left capture
  };

  // Default tolerance: half a frame period, so each frame can match at most one of the other's.
  explicit EyePairer(std::int64_t frame_period_ns, std::int64_t tolerance_ns = -1,
                     std::size_t max_waiting = 4)
      : tolerance_ns_(tolerance_ns >= 0 ? tolerance_ns : frame_period_ns / 2),
        max_waiting_(max_waiting) {
    TELEX_DEMAND(frame_period_ns > 0);
    TELEX_DEMAND(max_waiting >= 1);
  }

  // Takes one frame of one eye; returns the pair it completes, if any (at most one per push).
  std::optional<Pair> push(Eye eye, Image image, std::int64_t capture_ns) {
    auto& queue = eye == Eye::Left ? left_ : right_;
    auto& last_ns = eye == Eye::Left ? last_left_ns_ : last_right_ns_;
    if (last_ns && capture_ns <= *last_ns) {
      ++counters_.out_of_order;
      return std::nullopt;
    }
    last_ns = capture_ns;
    if (queue.size() >= max_waiting_) {
      queue.pop_front();
      ++(eye == Eye::Left ? counters_.unpaired_left : counters_.unpaired_right);
    }
    queue.push_back(Frame{std::move(image), capture_ns});
    while (!left_.empty() && !right_.empty()) {
      const std::int64_t skew_ns = right_.front().capture_ns - left_.front().capture_ns;
      if (skew_ns > tolerance_ns_) {
        left_.pop_front();
        ++counters_.unpaired_left;
      } else if (-skew_ns > tolerance_ns_) {
        right_.pop_front();
        ++counters_.unpaired_right;
      } else {
        Pair pair{std::move(left_.front().image), std::move(right_.front().image),
                  std::min(left_.front().capture_ns, right_.front().capture_ns), skew_ns};
        left_.pop_front();
        right_.pop_front();
        ++counters_.pairs;
        return pair;
      }
    }
    return std::nullopt;
  }

  const EyePairerCounters& counters() const { return counters_; }
  std::int64_t tolerance_ns() const { return tolerance_ns_; }
  std::size_t waiting(Eye eye) const { return eye == Eye::Left ? left_.size() : right_.size(); }

 private:
  std::int64_t tolerance_ns_;
  std::size_t max_waiting_;
  std::deque<Frame> left_, right_;
  std::optional<std::int64_t> last_left_ns_, last_right_ns_;
  EyePairerCounters counters_;
};

}  // namespace telex::video
