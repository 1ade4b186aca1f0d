// SPDX-License-Identifier: MIT
// Spatial hole filling by the windowed statistical mode of the valid depths around each hole.
#pragma once

#include <cstddef>
#include <opencv2/core.hpp>
#include <span>

namespace telex {

struct HoleFillOptions {
  // Odd side of the square window around each hole, 3..15.
  int window_px = 5;
  // Width of a depth bin in mm: neighbours within one bin count as the same surface.
  int bin_mm = 20;
  // Passes over the still-missing pixels; each pass sees the previous passes' fills, so a hole
  // region of width w closes after about w / window_px * 2 passes. 16 passes close the 30 px
  // registration border of a PrimeSense frame with a 5 px window.
  int max_passes = 16;
  // A hole is filled only when its window holds at least this many valid depths.
  int min_valid = 1;
};

struct HoleFillResult {
  cv::Mat1w depth_mm;         // filled image (same size as the input)
  std::size_t holes_in = 0;   // missing pixels before (inside the ROI when one is given)
  std::size_t holes_out = 0;  // missing pixels after
  int passes_run = 0;         // passes that filled at least one pixel
};

// Fills each missing pixel (0) with the most frequent depth bin among the valid pixels of its
// window; ties go to the nearer bin. The value written is the rounded mean of the winning bin's
// members, so it always lies inside the range of the input's valid depths. Within one pass all
// decisions read the image as it was before the pass (order independent). One scan (four pixels
// per test) lists the holes; after it, work is proportional to the holes: pass 1 visits each
// hole once, later passes only the holes near the previous pass's fills.
// Throws std::invalid_argument on bad options.
HoleFillResult fill_holes_mode(const cv::Mat1w& depth_mm, const HoleFillOptions& options = {});

// Same, writing into caller-owned `out_mm` (reallocated only when its size differs). Returns the
// result with an empty `depth_mm`.
HoleFillResult fill_holes_mode_into(const cv::Mat1w& depth_mm, cv::Mat1w& out_mm,
                                    const HoleFillOptions& options = {});

// Only the holes inside `roi` are filled; pixels outside `roi` are copied unchanged. Inside the
// ROI the result equals the full-frame result (holes within (max_passes-1)*radius of the ROI are
// processed internally so that later passes see the same earlier fills). Counts are for the ROI.
// Throws std::invalid_argument when `roi` is empty or not inside the image.
HoleFillResult fill_holes_mode_roi(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                   const HoleFillOptions& options = {});

// Same, but touches only `roi` of caller-owned `out_mm` (reallocated when its size differs; its
// pixels outside `roi` are then undefined): work proportional to the ROI plus its margin, for
// pipelines that process a few regions of a frame before (or instead of) the rest. Inside `roi`
// the result equals fill_holes_mode's, bit for bit. Returns the result with an empty `depth_mm`.
HoleFillResult fill_holes_mode_roi_into(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                        cv::Mat1w& out_mm, const HoleFillOptions& options = {});

// How a requested region of interest grows before it is filled: by `margin_px` on every side (what
// a later stage reads around it, e.g. a bilateral filter's radius), then out to whole cells of
// `align_px` (a tile grid anchored at (0, 0)), always clipped to the image.
struct RoiWidening {
  int margin_px = 0;
  cv::Size align_px{1, 1};
};

// `roi` clipped to `image`, widened by `widening` and clipped again; empty when `roi` lies outside
// the image. Throws std::invalid_argument on a negative margin or a non-positive alignment.
cv::Rect widen_roi(const cv::Rect& roi, cv::Size image, const RoiWidening& widening);

// The ROI fill of the remote's pipeline and the station's surface builder: every one of `rois`,
// widened (widen_roi), filled by fill_holes_mode_roi_into into `out_mm` (allocated to the input's
// size; pixels outside every widened ROI are undefined). Inside them the result equals
// fill_holes_mode's bit for bit. ROIs outside the image are skipped.
void fill_holes_mode_rois_into(const cv::Mat1w& depth_mm, std::span<const cv::Rect> rois,
                               const RoiWidening& widening, cv::Mat1w& out_mm,
                               const HoleFillOptions& options = {});

}  // namespace telex
