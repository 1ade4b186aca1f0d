// SPDX-License-Identifier: MIT
// Temporal hole filling from a per-pixel history of the last valid depth and its age.
#include "telex/common/temporal_fill.h"

#include <stdexcept>
#include <string>

#include "telex/base/demand.h"

namespace telex {

TemporalFill::TemporalFill(const TemporalFillOptions& options) : options_(options) {
  if (options.max_age_frames < 1)
    throw std::invalid_argument("TemporalFill: max_age_frames must be >= 1, got " +
                                std::to_string(options.max_age_frames));
  if (options.max_age_ms < 0.0)
    throw std::invalid_argument("TemporalFill: max_age_ms must be >= 0, got " +
                                std::to_string(options.max_age_ms));
}

void TemporalFill::reset() {
  last_mm_.release();
  last_frame_.release();
  last_time_ms_.release();
  frame_ = 0;
  prev_time_ms_ = 0.0;
}

bool TemporalFill::begin_frame(cv::Size size, double time_ms) {
  bool reset_history = false;
  if (last_mm_.size() != size || (frame_ > 0 && time_ms < prev_time_ms_)) {
    reset_history = frame_ > 0;
    last_mm_.create(size);
    last_mm_.setTo(0);
    last_frame_.create(size);
    last_time_ms_.create(size);
    frame_ = 0;
  }
  ++frame_;
  prev_time_ms_ = time_ms;
  return reset_history;
}

TemporalFillResult TemporalFill::apply(const cv::Mat1w& depth_mm, double time_ms,
                                       cv::Mat1w& out_mm) {
  return apply(depth_mm, depth_mm, time_ms, out_mm);
}

TemporalFillResult TemporalFill::apply(const cv::Mat1w& measured_mm, const cv::Mat1w& filled_mm,
                                       double time_ms, cv::Mat1w& out_mm) {
  const bool reset_history = begin_frame(filled_mm.size(), time_ms);
  out_mm.create(filled_mm.size());
  TemporalFillResult r =
      apply_rect(measured_mm, filled_mm, cv::Rect(0, 0, filled_mm.cols, filled_mm.rows), out_mm);
  r.history_reset = reset_history;
  return r;
}

TemporalFillResult TemporalFill::apply_rect(const cv::Mat1w& depth_mm, const cv::Rect& rect,
                                            cv::Mat1w& out_mm) {
  return apply_rect(depth_mm, depth_mm, rect, out_mm);
}

TemporalFillResult TemporalFill::apply_rect(const cv::Mat1w& measured_mm,
                                            const cv::Mat1w& filled_mm, const cv::Rect& rect,
                                            cv::Mat1w& out_mm) {
  // begin_frame with the frame size first, an output of that size, a rectangle inside the frame.
  TELEX_DEMAND(frame_ != 0 && filled_mm.size() == last_mm_.size() &&
               measured_mm.size() == filled_mm.size() && out_mm.size() == filled_mm.size());
  TELEX_DEMAND(!rect.empty() && (rect & cv::Rect(0, 0, filled_mm.cols, filled_mm.rows)) == rect);
  TemporalFillResult r;
  const int frame = static_cast<int>(frame_);
  const double time_ms = prev_time_ms_;
  const int max_age = options_.max_age_frames;
  const double max_age_ms = options_.max_age_ms;
  for (int y = rect.y; y < rect.y + rect.height; ++y) {
    const std::uint16_t* measured = measured_mm[y];
    const std::uint16_t* in = filled_mm[y];
    std::uint16_t* out = out_mm[y];
    std::uint16_t* last = last_mm_[y];
    int* last_frame = last_frame_[y];
    double* last_time = last_time_ms_[y];
    for (int x = rect.x; x < rect.x + rect.width; ++x) {
      if (measured[x] != 0) {  // only a measurement enters the history
        last[x] = measured[x];
        last_frame[x] = frame;
        last_time[x] = time_ms;
      }
      const std::uint16_t v = in[x];
      if (v != 0) {
        out[x] = v;
        continue;
      }
      ++r.holes_in;
      const std::uint16_t h = last[x];
      const bool young = h != 0 && frame - last_frame[x] <= max_age &&
                         (max_age_ms <= 0.0 || time_ms - last_time[x] <= max_age_ms);
      out[x] = young ? h : std::uint16_t{0};
      r.filled += young ? 1 : 0;
    }
  }
  r.holes_out = r.holes_in - r.filled;
  return r;
}

}  // namespace telex
