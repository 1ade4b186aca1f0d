// SPDX-License-Identifier: MIT
// Depth stabiliser: keeps each pixel's last sent depth while new measurements stay within the
// sensor's noise of it, so static surfaces stop changing and their tiles stop being sent.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace telex {

// Thresholds per depth value (0..65535 mm), derived once from k and the Nguyen axial sigma at that
// depth (incidence unknown, so the 10-60 deg term).
struct StabiliseThresholds {
  StabiliseThresholds(double k_sigma, double immediate_factor);
  double k_sigma;
  std::vector<std::uint16_t> tolerance_mm;  // |new - held| within this keeps the held value
  std::vector<std::uint32_t> jump_mm;       // beyond this the new value replaces it at once
};

// The kernel, pure apart from the caller-owned per-pixel state: over `rect`, each pixel of
// `held_mm` (the value last sent, 0 = none) takes the new measurement in `in_mm` when either is a
// hole, when it is more than `jump_mm` away, or when it has been outside `tolerance_mm` for
// `confirm_frames` frames in a row (`outside` counts them); `out_mm` receives the held values.
// Over 300k pixels a single-frame threshold meets the Gaussian tail somewhere in every tile; two
// frames in a row almost never. All four images have one size; `rect` lies inside it.
void stabilise_rect(const cv::Mat1w& in_mm, const cv::Rect& rect, const StabiliseThresholds& t,
                    int confirm_frames, cv::Mat1w& held_mm, cv::Mat1b& outside, cv::Mat1w& out_mm);

// The state around the kernel for a stream of frames. k = 0 turns it off: output == input,
// bit-exact. Holes pass through and reset the pixel.
class Stabiliser {
 public:
  explicit Stabiliser(double k_sigma = 0.0, int confirm_frames = 2, double immediate_factor = 3.0);
  // `out` receives the stabilised frame (reallocated when the size differs; history restarts).
  void apply(const cv::Mat1w& in_mm, cv::Mat1w& out_mm);
  // Region by region: begin() (re)starts the history when the frame size differs; apply_rect()
  // then stabilises only `rect` of `in_mm` into `out_mm` (already of the input's size). Pixels a
  // frame does not visit keep their held value and their outside-band count. Visiting every pixel
  // once per frame equals apply(), bit for bit. Sizes that differ are a caller bug (TELEX_DEMAND).
  void begin(cv::Size size);
  void apply_rect(const cv::Mat1w& in_mm, const cv::Rect& rect, cv::Mat1w& out_mm);
  void reset() { held_mm_.release(); }
  double k_sigma() const { return thresholds_.k_sigma; }
  // Tolerance in mm around a held value of `depth_mm`.
  std::uint16_t tolerance_mm(std::uint16_t depth_mm) const {
    return thresholds_.tolerance_mm[depth_mm];
  }

 private:
  StabiliseThresholds thresholds_;
  int confirm_frames_;
  cv::Mat1w held_mm_;
  cv::Mat1b outside_;  // consecutive frames outside the band
};

}  // namespace telex
