// SPDX-License-Identifier: MIT
// Depth stabiliser kernel and its per-stream state.
#include "telex/common/stabilise.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "telex/base/demand.h"
#include "telex/common/synthetic.h"

namespace telex {

StabiliseThresholds::StabiliseThresholds(double k, double immediate_factor)
    : k_sigma(k), tolerance_mm(65536, 0), jump_mm(65536, 0) {
  if (!(k >= 0.0) || !std::isfinite(k))
    throw std::invalid_argument("stabiliser k (sigmas) must be a finite number >= 0");
  if (!(immediate_factor >= 1.0))
    throw std::invalid_argument("stabiliser immediate factor must be >= 1");
  if (k > 0.0)
    for (std::size_t d = 1; d < tolerance_mm.size(); ++d) {
      const double tol = k * synth::axial_sigma_m(static_cast<double>(d) * 1e-3, 0.0) * 1e3;
      tolerance_mm[d] = static_cast<std::uint16_t>(std::min(65535.0, std::floor(tol)));
      jump_mm[d] = static_cast<std::uint32_t>(std::floor(tol * immediate_factor));
    }
}

void stabilise_rect(const cv::Mat1w& in_mm, const cv::Rect& rect, const StabiliseThresholds& t,
                    int confirm_frames, cv::Mat1w& held_mm, cv::Mat1b& outside_frames,
                    cv::Mat1w& out_mm) {
  const auto confirm = static_cast<std::uint8_t>(confirm_frames);
  for (int y = rect.y; y < rect.y + rect.height; ++y) {
    const std::uint16_t* in = in_mm.ptr<std::uint16_t>(y);
    std::uint16_t* held = held_mm.ptr<std::uint16_t>(y);
    std::uint8_t* outside = outside_frames.ptr<std::uint8_t>(y);
    std::uint16_t* out = out_mm.ptr<std::uint16_t>(y);
    for (int x = rect.x; x < rect.x + rect.width; ++x) {
      const std::uint16_t v = in[x], s = held[x];
      const std::uint32_t diff = v > s ? v - s : s - v;
      bool take = v == 0 || s == 0;
      if (!take && diff > t.tolerance_mm[s]) {
        take = diff > t.jump_mm[s] || ++outside[x] >= confirm;
      } else if (!take) {
        outside[x] = 0;
      }
      if (take) {
        held[x] = v;
        outside[x] = 0;
      }
      out[x] = held[x];
    }
  }
}

Stabiliser::Stabiliser(double k_sigma, int confirm_frames, double immediate_factor)
    : thresholds_(k_sigma, immediate_factor), confirm_frames_(confirm_frames) {
  if (confirm_frames < 1 || confirm_frames > 255)
    throw std::invalid_argument("stabiliser confirm frames must be 1..255");
}

void Stabiliser::apply(const cv::Mat1w& in_mm, cv::Mat1w& out_mm) {
  if (thresholds_.k_sigma == 0.0) {
    in_mm.copyTo(out_mm);
    return;
  }
  if (held_mm_.size() != in_mm.size()) {
    begin(in_mm.size());
    in_mm.copyTo(out_mm);
    in_mm.copyTo(held_mm_);
    return;
  }
  out_mm.create(in_mm.size());
  apply_rect(in_mm, cv::Rect(0, 0, in_mm.cols, in_mm.rows), out_mm);
}

void Stabiliser::begin(cv::Size size) {
  if (thresholds_.k_sigma == 0.0 || held_mm_.size() == size) return;
  // An empty history takes every pixel as it comes (a held 0 is always replaced), which is what
  // the first frame of a full-frame apply() does.
  held_mm_ = cv::Mat1w(size, std::uint16_t(0));
  outside_ = cv::Mat1b(size, std::uint8_t(0));
}

void Stabiliser::apply_rect(const cv::Mat1w& in_mm, const cv::Rect& rect, cv::Mat1w& out_mm) {
  TELEX_DEMAND(out_mm.size() == in_mm.size());
  if (thresholds_.k_sigma == 0.0) {
    in_mm(rect).copyTo(out_mm(rect));
    return;
  }
  TELEX_DEMAND(held_mm_.size() == in_mm.size());  // begin() with the frame size first
  stabilise_rect(in_mm, rect, thresholds_, confirm_frames_, held_mm_, outside_, out_mm);
}

}  // namespace telex
