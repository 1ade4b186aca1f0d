// SPDX-License-Identifier: MIT
// Remote processing pipeline: fill, stabilise, tile, skip unchanged tiles, encode; each stage
// timed.
#pragma once

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "telex/common/hole_fill.h"
#include "telex/common/temporal_fill.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/messages.h"
#include "telex/remote/sources.h"

namespace telex::remote {

// Keeps each pixel's last sent depth while new measurements stay within k sensor-noise sigmas of it
// (Nguyen axial sigma at that depth, incidence unknown so the 10-60 deg term). Static surfaces then
// stop changing, so their tiles stop being sent. k = 0 turns it off: output == input, bit-exact.
// Holes (0) pass through and reset the pixel. A measurement outside the band replaces the held
// value at once when it is beyond `immediate_factor` bands (real motion), otherwise only when it
// stays outside for `confirm_frames` frames in a row: over 300k pixels a single-frame threshold
// meets the Gaussian tail somewhere in every tile, two frames in a row almost never.
class Stabiliser {
 public:
  explicit Stabiliser(double k_sigma = 0.0, int confirm_frames = 2, double immediate_factor = 3.0);
  // `out` receives the stabilised frame (reallocated when the size differs; history restarts).
  void apply(const cv::Mat1w& in_mm, cv::Mat1w& out_mm);
  void reset() { last_mm_.release(); }
  double k_sigma() const { return k_; }
  // Tolerance in mm around a held value of `depth_mm`.
  std::uint16_t tolerance_mm(std::uint16_t depth_mm) const { return tol_mm_[depth_mm]; }

 private:
  double k_;
  int confirm_frames_;
  std::vector<std::uint16_t> tol_mm_;   // per depth value 0..65535
  std::vector<std::uint32_t> jump_mm_;  // immediate-replacement threshold per depth value
  cv::Mat1w last_mm_;
  cv::Mat1b outside_;  // consecutive frames outside the band
};

struct PipelineConfig {
  bool fill = true;  // windowed-mode spatial fill, then temporal fill of what is left
  HoleFillOptions hole_fill;
  bool temporal_fill = true;
  TemporalFillOptions temporal;
  double stabilise_k_sigma = 0.0;  // 0 = off (bit-exact)
  int stabilise_confirm_frames = 2;
  int tile_width = 80;  // 640x480 -> 8x8 grid
  int tile_height = 60;
  int key_frame_every = 30;  // frames between key frames (1 = every frame)
  int background_every =
      2;  // tiles outside any ROI are considered every Nth frame while an ROI is set
  proto::Codec codec = proto::Codec::Zip;
  int zip_level = proto::kDefaultZipLevel;
};

// What the receiver asked for, sampled by the processing thread once per frame.
struct FrameRequest {
  bool force_key_frame = false;       // new receiver or explicit request
  std::vector<proto::RoiRect> rois;   // in pixels of the frame as sent
  std::optional<proto::Codec> codec;  // negotiated codec (overrides the config)
  bool select_tiles = true;           // false: no receiver, stop after the stabiliser
};

struct StageTimes {
  double fill_ms = 0, stabilise_ms = 0, tile_ms = 0, encode_ms = 0, total_ms = 0;
};

struct ProcessedFrame {
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;
  bool key_frame = false;
  Intrinsics intrinsics;
  proto::TileGrid grid;
  proto::Codec codec = proto::Codec::Zip;
  cv::Mat1w sent_view_mm;  // what a receiver that got every message of every frame now holds
  std::vector<proto::EncodedTile> tiles;  // tiles to send, increasing index
  proto::FrameManifest manifest;
  std::size_t tiles_skipped = 0;  // unchanged, or not due (outside ROI on a background-skip frame)
  std::size_t holes_in = 0, holes_out = 0;
  StageTimes times;
};

// Tiles of `grid` that intersect any of `rois`, as a mask indexed by tile.
std::vector<bool> tiles_in_rois(const proto::TileGrid& grid,
                                const std::vector<proto::RoiRect>& rois);

// Single-threaded: owned by the processing thread. Reads no clock except to time its own stages.
class FramePipeline {
 public:
  explicit FramePipeline(PipelineConfig config);
  ProcessedFrame process(const DepthFrame& frame, const FrameRequest& request);
  const PipelineConfig& config() const { return config_; }

 private:
  PipelineConfig config_;
  TemporalFill temporal_;
  Stabiliser stabiliser_;
  cv::Mat1w filled_, temporal_out_, stabilised_, sent_view_;
  std::uint64_t frames_ = 0;
  std::uint64_t since_key_ = 0;
};

}  // namespace telex::remote
