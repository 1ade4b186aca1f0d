// SPDX-License-Identifier: MIT
// Temporal hole filling: remembers each pixel's last measured depth and reuses it while young.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

namespace telex {

struct TemporalFillOptions {
  // A remembered depth is used while it is at most this many frames old (1 = previous frame).
  int max_age_frames = 4;
  // And, when > 0, at most this many milliseconds old (time comes in with each frame).
  double max_age_ms = 0.0;
};

struct TemporalFillResult {
  std::size_t holes_in = 0;   // holes in the frame handed in
  std::size_t filled = 0;     // holes filled from the history
  std::size_t holes_out = 0;  // holes left
  bool history_reset =
      false;  // the frame size changed (or the clock ran backwards): history dropped
};

// Per-pixel history of the last measured depth, the frame it came from and its time. All state is
// in this object; apply() reads no clock. Only measurements enter the history: pixels filled from
// it are not written back (a value ages out even while it keeps being reused), and with the
// two-image calls the depth a spatial fill guessed is used for this frame but never remembered.
class TemporalFill {
 public:
  explicit TemporalFill(const TemporalFillOptions& options = {});

  // Records the valid pixels of `depth_mm` (taken at `time_ms`) and fills its holes from the
  // history into `out_mm` (caller-owned, reallocated only when its size differs). Never throws on
  // a size change: the history restarts and the result says so.
  TemporalFillResult apply(const cv::Mat1w& depth_mm, double time_ms, cv::Mat1w& out_mm);

  // The same in two steps, for callers that process a frame region by region: begin_frame
  // advances the frame count and clock (returns true when the history was dropped, as
  // TemporalFillResult::history_reset); apply_rect then records and fills only `rect` of the frame
  // into `out_mm`, which must already have the frame's size. Each pixel at most once per frame;
  // pixels a frame does not visit keep their history (their age keeps growing with the frames).
  // A size mismatch or a rectangle outside the frame is a caller bug (TELEX_DEMAND aborts).
  bool begin_frame(cv::Size size, double time_ms);
  TemporalFillResult apply_rect(const cv::Mat1w& depth_mm, const cv::Rect& rect, cv::Mat1w& out_mm);

  // After a spatial fill: `measured_mm` is the frame as the sensor gave it (the only values the
  // history records) and `filled_mm` the same frame with some holes guessed; the holes still left
  // in `filled_mm` are filled from the history. Same size rules as above.
  TemporalFillResult apply(const cv::Mat1w& measured_mm, const cv::Mat1w& filled_mm, double time_ms,
                           cv::Mat1w& out_mm);
  TemporalFillResult apply_rect(const cv::Mat1w& measured_mm, const cv::Mat1w& filled_mm,
                                const cv::Rect& rect, cv::Mat1w& out_mm);

  void reset();
  std::uint32_t frames_seen() const { return frame_; }
  const TemporalFillOptions& options() const { return options_; }

 private:
  TemporalFillOptions options_;
  cv::Mat1w last_mm_;        // last valid depth per pixel (0 = never seen)
  cv::Mat1i last_frame_;     // frame number that depth came from
  cv::Mat1d last_time_ms_;   // capture time of that frame
  std::uint32_t frame_ = 0;  // frames applied since the last reset
  double prev_time_ms_ = 0.0;
};

}  // namespace telex
