// SPDX-License-Identifier: MIT
// The remote node's per-frame processing: register, fill, stabilise, select changed tiles, encode.
#include "telex/remote/pipeline.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iterator>
#include <numeric>
#include <stdexcept>
#include <string>

#include "telex/base/demand.h"

namespace telex::remote {

namespace {

bool same_tile(const cv::Mat1w& a, const cv::Mat1w& b, const cv::Rect& r) {
  for (int y = r.y; y < r.y + r.height; ++y)
    if (std::memcmp(a.ptr<std::uint16_t>(y) + r.x, b.ptr<std::uint16_t>(y) + r.x,
                    sizeof(std::uint16_t) * r.width) != 0)
      return false;
  return true;
}

// The manifest that closes a frame sent in one part: a key frame's lists no tiles (it holds them
// all), any other lists the tiles sent.
void close_one_part(ProcessedFrame& out, bool key, const std::vector<int>& sent) {
  out.part = FramePart::Whole;
  out.key_frame = key;
  out.manifest.frame_id = out.frame_id;
  out.manifest.tile_count = static_cast<std::uint16_t>(out.grid.count());
  out.manifest.key_frame = key;
  if (!key)
    for (int i : sent) out.manifest.changed_tiles.push_back(static_cast<std::uint16_t>(i));
}

}  // namespace

std::vector<bool> tiles_in_rois(const proto::TileGrid& grid,
                                const std::vector<proto::RoiRect>& rois) {
  std::vector<bool> mask(static_cast<std::size_t>(grid.count()), false);
  for (const auto& roi : rois) {
    const cv::Rect r(roi.x, roi.y, roi.w, roi.h);
    for (int i = 0; i < grid.count(); ++i)
      if ((grid.rect(i) & r).area() > 0) mask[static_cast<std::size_t>(i)] = true;
  }
  return mask;
}

std::string_view depth_registration_name(DepthRegistration registration) {
  switch (registration) {
    case DepthRegistration::Hardware:
      return "hardware";
    case DepthRegistration::Rig:
      return "rig";
    case DepthRegistration::None:
      break;
  }
  return "none";
}

std::string_view register_mode_name(RegisterMode mode) {
  switch (mode) {
    case RegisterMode::Shift:
      return "shift";
    case RegisterMode::Full:
      return "full";
    case RegisterMode::None:
      break;
  }
  return "none";
}

FramePipeline::FramePipeline(PipelineConfig config)
    : config_(std::move(config)),
      temporal_(config_.temporal),
      stabiliser_(config_.stabilise_k_sigma, config_.stabilise_confirm_frames) {
  if (config_.clock_ms == nullptr) throw std::invalid_argument("pipeline stage clock must be set");
  if (config_.tile_width <= 0 || config_.tile_height <= 0)
    throw std::invalid_argument("tile width and height must be positive");
  if (config_.key_frame_every < 1)
    throw std::invalid_argument("key frame interval must be >= 1 frame");
  if (config_.background_every < 1)
    throw std::invalid_argument("background rate divider must be >= 1");
  if (config_.zip_level < 0 || config_.zip_level > 9)
    throw std::invalid_argument("zip level must be 0..9");
  const RegistrationConfig& reg = config_.registration;
  if (reg.mode != RegisterMode::None) {
    if (reg.eye.width != 0 &&
        !(reg.eye.width > 0 && reg.eye.height > 0 && reg.eye.fx > 0 && reg.eye.fy > 0))
      throw std::invalid_argument("registration eye intrinsics need fx, fy, width, height > 0");
    if (!(reg.nominal_depth_m > 0) || !std::isfinite(reg.nominal_depth_m))
      throw std::invalid_argument("registration nominal depth must be > 0 m");
    const glm::dvec3& t = reg.X_EyeDepth.translation_m;
    if (!std::isfinite(t.x) || !std::isfinite(t.y) || !std::isfinite(t.z))
      throw std::invalid_argument("registration baseline must be finite");
  }
}

const DepthImage& FramePipeline::register_frame(const DepthImage& in) {
  const RegistrationConfig& reg = config_.registration;
  if (reg.mode == RegisterMode::None) return in;
  // A calibrated depth camera replaces the source's nominal intrinsics (a header copy: the pixels
  // are shared).
  DepthImage calibrated = in;
  if (reg.depth)
    calibrated.intrinsics =
        reg.depth->width == in.intrinsics.width && reg.depth->height == in.intrinsics.height
            ? *reg.depth
            : reg.depth->scaled(in.intrinsics.width, in.intrinsics.height);
  const DepthImage& src = calibrated;
  const Intrinsics eye = reg.eye.width == 0 ? src.intrinsics : reg.eye;
  if (reg.mode == RegisterMode::Full) {
    registered_ = reproject_depth(src, eye, reg.X_EyeDepth, /*fill_cracks=*/true);
  } else {
    // Shift+scale models a translated camera: the rotation is ignored.
    if (shift_scale_for_ != src.intrinsics) {
      shift_scale_ = shift_scale_from_calibration(src.intrinsics, eye, reg.X_EyeDepth.translation_m,
                                                  reg.nominal_depth_m);
      shift_scale_for_ = src.intrinsics;
    }
    registered_ = register_shift_scale(src, shift_scale_, eye);
  }
  return registered_;
}

ProcessedFrame FramePipeline::process(const DepthFrame& frame, const FrameRequest& request,
                                      const PartHandler& on_part,
                                      const std::function<bool()>& preempt) {
  // Parts stream to the tile sink only when they go out as parts; one message set streams nothing.
  stream_parts_ = request.frame_parts;
  ProcessedFrame out = first_part(frame, request);
  out.first_part_ms = out.times.total_ms;
  if (!pending_.active) {
    if (on_part) on_part(out);
    return out;
  }
  if (request.frame_parts && on_part) on_part(out);
  ProcessedFrame rest = rest_part(frame, request.frame_parts ? preempt : std::function<bool()>{});
  if (request.frame_parts && on_part) on_part(rest);
  merge_into_rest(std::move(out), rest);
  if (!request.frame_parts && on_part) on_part(rest);
  return rest;
}

void FramePipeline::merge_into_rest(ProcessedFrame&& roi, ProcessedFrame& rest) {
  // The rest's manifest already closes the frame and lists both parts' tiles.
  std::vector<proto::EncodedTile> tiles;
  tiles.reserve(roi.tiles.size() + rest.tiles.size());
  std::merge(
      std::make_move_iterator(roi.tiles.begin()), std::make_move_iterator(roi.tiles.end()),
      std::make_move_iterator(rest.tiles.begin()), std::make_move_iterator(rest.tiles.end()),
      std::back_inserter(tiles),
      [](const proto::EncodedTile& a, const proto::EncodedTile& b) { return a.index < b.index; });
  rest.tiles = std::move(tiles);
  rest.tiles_streamed = 0;  // the parts streamed, not this set
  rest.part = FramePart::Whole;
  rest.tiles_skipped += roi.tiles_skipped;
  rest.holes_in += roi.holes_in;
  rest.holes_out += roi.holes_out;
  rest.pixels_processed += roi.pixels_processed;
  rest.times += roi.times;
  rest.first_part_ms = roi.first_part_ms;
}

ProcessedFrame FramePipeline::start_frame(const DepthFrame& frame, const FrameRequest& request,
                                          const DepthImage& image) {
  ProcessedFrame out;
  out.frame_id = static_cast<std::uint32_t>(frame.frame_id);
  out.capture_ns = frame.capture_ns;
  out.intrinsics = image.intrinsics;
  out.codec = request.codec.value_or(config_.codec);
  const cv::Mat1w& in = image.depth_mm;
  out.grid = proto::TileGrid{in.cols, in.rows, config_.tile_width, config_.tile_height};
  out.manifest.head = frame.head;
  return out;
}

bool FramePipeline::next_frame_is_key(cv::Size size, const FrameRequest& request) {
  const bool size_changed = sent_view_.size() != size;
  ++frames_;
  const bool key = size_changed || request.force_key_frame || key_owed_ ||
                   since_key_ + 1 >= static_cast<std::uint64_t>(config_.key_frame_every) ||
                   frames_ == 1;
  since_key_ = key ? 0 : since_key_ + 1;
  if (size_changed) sent_view_ = cv::Mat1w(size, std::uint16_t(0));
  return key;
}

// The one path every part of a frame takes: spatial fill, temporal fill, hole counting, stabilise,
// select against what the receiver holds, encode.
std::vector<int> FramePipeline::process_tiles(const DepthFrame& frame, const cv::Mat1w& in,
                                              const TileJob& job, ProcessedFrame& out) {
  const StageClock now_ms = config_.clock_ms;
  const proto::TileGrid& grid = out.grid;
  const std::vector<int>& tiles = *job.tiles;

  // Fill: windowed mode for small holes, then the per-pixel history for what the window missed.
  double t0 = now_ms();
  const cv::Mat1w* current = &in;
  if (config_.fill) {
    if (job.fill_rois != nullptr) {
      // Per requested rectangle widened to whole tiles, with the fill's own margin, so its result
      // there equals a full-frame fill bit for bit.
      fill_holes_mode_rois_into(in, *job.fill_rois,
                                RoiWidening{0, cv::Size(grid.tile_width, grid.tile_height)},
                                filled_, config_.hole_fill);
    } else {
      // Holes reach across tiles: the whole frame (inside tiles an ROI part already filled it
      // rewrites the same values, bit for bit).
      fill_holes_mode_into(in, filled_, config_.hole_fill);
    }
    current = &filled_;
    if (config_.temporal_fill) {
      const double t1 = now_ms();
      if (job.new_frame)
        temporal_.begin_frame(in.size(), static_cast<double>(frame.capture_ns) * 1e-6);
      temporal_out_.create(in.size());
      // The history learns from the measured frame only; it fills what the spatial fill left.
      for (int i : tiles) temporal_.apply_rect(in, filled_, grid.rect(i), temporal_out_);
      current = &temporal_out_;
      out.times.temporal_ms += now_ms() - t1;
    }
  }
  for (int i : tiles) {
    const cv::Rect r = grid.rect(i);
    out.holes_in += count_holes(in(r));
    out.holes_out += count_holes((*current)(r));
    out.pixels_processed += static_cast<std::size_t>(r.area());
  }
  out.times.fill_ms += now_ms() - t0;

  t0 = now_ms();
  stabilised_.create(in.size());
  stabiliser_.begin(in.size());
  for (int i : tiles) stabiliser_.apply_rect(*current, grid.rect(i), stabilised_);
  out.times.stabilise_ms += now_ms() - t0;
  if (!job.select) return {};

  t0 = now_ms();
  std::vector<int> send;
  for (int i : tiles) {
    if (job.key || !same_tile(stabilised_, sent_view_, grid.rect(i)))
      send.push_back(i);
    else
      ++out.tiles_skipped;
  }
  out.times.tile_ms += now_ms() - t0;

  // Encode tile by tile. A preempting caller (a newer frame is waiting) cuts the list short; what
  // the receiver holds (sent_view_) moves only with sent tiles, so the unsent ones still compare
  // as changed and go out with a later part.
  t0 = now_ms();
  std::vector<int> sent;
  sent.reserve(send.size());
  out.tiles.reserve(out.tiles.size() + send.size());
  for (int i : send) {
    if (job.preempt != nullptr && (*job.preempt)()) {
      out.rest_cut = true;
      out.tiles_skipped += send.size() - sent.size();
      break;
    }
    const cv::Rect r = grid.rect(i);
    stabilised_(r).copyTo(sent_view_(r));
    sent.push_back(i);
    proto::EncodedTile t;
    t.index = static_cast<std::uint16_t>(i);
    t.rect = r;
    t.bytes = proto::encode_depth(stabilised_(r), out.codec, config_.zip_level);
    out.tiles.push_back(std::move(t));
    // Hand a batch on while the next ones are encoded; the last batch goes with the manifest.
    if (sink_ && stream_parts_ && config_.stream_tiles > 0 && sent.size() < send.size() &&
        out.tiles.size() - out.tiles_streamed >= static_cast<std::size_t>(config_.stream_tiles)) {
      sink_(out, out.tiles_streamed);
      out.tiles_streamed = out.tiles.size();
    }
  }
  out.times.encode_ms += now_ms() - t0;
  return sent;
}

ProcessedFrame FramePipeline::first_part(const DepthFrame& frame, const FrameRequest& request) {
  pending_.active = false;
  if (!request.select_tiles || request.rois.empty()) return whole_frame(frame, request);
  const double t_start = config_.clock_ms();
  const DepthImage& image = register_frame(frame.image);
  ProcessedFrame out = start_frame(frame, request, image);
  out.times.register_ms = config_.clock_ms() - t_start;
  const cv::Mat1w& in = image.depth_mm;
  const proto::TileGrid& grid = out.grid;

  const bool key = next_frame_is_key(in.size(), request);
  const bool background_due =
      rest_owed_ || (frames_ % static_cast<std::uint64_t>(config_.background_every)) == 0;
  key_owed_ = rest_owed_ = false;
  const std::vector<bool> in_roi = tiles_in_rois(grid, request.rois);
  std::vector<int> roi_tiles;
  for (int i = 0; i < grid.count(); ++i)
    if (in_roi[static_cast<std::size_t>(i)]) roi_tiles.push_back(i);
  const bool has_rest =
      (key || background_due) && roi_tiles.size() < static_cast<std::size_t>(grid.count());

  TileJob job;
  job.tiles = &roi_tiles;
  std::vector<cv::Rect> fill_rois;
  fill_rois.reserve(request.rois.size());
  for (const auto& roi : request.rois) fill_rois.emplace_back(roi.x, roi.y, roi.w, roi.h);
  job.fill_rois = &fill_rois;
  job.key = key;
  out.part = has_rest ? FramePart::RoiPart : FramePart::Whole;  // what streamed tiles carry
  out.key_frame = key;
  const std::vector<int> sent = process_tiles(frame, in, job, out);
  if (!has_rest) out.tiles_skipped += static_cast<std::size_t>(grid.count()) - roi_tiles.size();

  if (has_rest) {
    // The ROI part lists the tiles it carries, even on a key frame; the rest's manifest closes
    // the frame as a one-part frame's manifest would.
    out.part = FramePart::RoiPart;
    out.key_frame = key;
    out.manifest.frame_id = out.frame_id;
    out.manifest.tile_count = static_cast<std::uint16_t>(grid.count());
    out.manifest.key_frame = false;
    for (int i : sent) out.manifest.changed_tiles.push_back(static_cast<std::uint16_t>(i));
    pending_.active = true;
    pending_.frame_id = frame.frame_id;
    pending_.key = key;
    pending_.in_roi = in_roi;
    pending_.roi_sent = out.manifest.changed_tiles;
    pending_.codec = out.codec;
  } else {
    close_one_part(out, key, sent);
  }
  out.sent_view_mm = sent_view_.clone();
  out.times.total_ms = config_.clock_ms() - t_start;
  return out;
}

ProcessedFrame FramePipeline::rest_part(const DepthFrame& frame,
                                        const std::function<bool()>& preempt) {
  // Only the frame whose ROI part first_part() just returned has a rest.
  TELEX_DEMAND(pending_.active && pending_.frame_id == frame.frame_id);
  pending_.active = false;
  const double t_start = config_.clock_ms();
  FrameRequest request;
  request.codec = pending_.codec;
  // The rest uses the image the ROI part registered (registered_ is untouched until the next
  // frame).
  const DepthImage& image =
      config_.registration.mode == RegisterMode::None ? frame.image : registered_;
  ProcessedFrame out = start_frame(frame, request, image);
  const proto::TileGrid& grid = out.grid;
  std::vector<int> rest_tiles;
  for (int i = 0; i < grid.count(); ++i)
    if (!pending_.in_roi[static_cast<std::size_t>(i)]) rest_tiles.push_back(i);

  TileJob job;
  job.tiles = &rest_tiles;
  job.new_frame = false;  // the ROI part began this frame's temporal fill
  job.key = pending_.key;
  // Two rests in a row are never cut, so the background always progresses.
  if (preempt && !last_rest_cut_) job.preempt = &preempt;
  // Tiles streamed before a cut carry the key flag the rest began with; the manifest decides.
  out.part = FramePart::Rest;
  out.key_frame = pending_.key;
  const std::vector<int> sent = process_tiles(frame, image.depth_mm, job, out);
  last_rest_cut_ = out.rest_cut;
  if (out.rest_cut) {
    rest_owed_ = true;
    key_owed_ = pending_.key;
  }
  const bool key = pending_.key && !out.rest_cut;

  out.part = FramePart::Rest;
  out.key_frame = key;
  out.manifest.frame_id = out.frame_id;
  out.manifest.tile_count = static_cast<std::uint16_t>(grid.count());
  out.manifest.key_frame = key;
  if (!key) {
    std::vector<std::uint16_t> rest_sent;
    for (int i : sent) rest_sent.push_back(static_cast<std::uint16_t>(i));
    std::merge(pending_.roi_sent.begin(), pending_.roi_sent.end(), rest_sent.begin(),
               rest_sent.end(), std::back_inserter(out.manifest.changed_tiles));
  }
  out.sent_view_mm = sent_view_.clone();
  out.times.total_ms = config_.clock_ms() - t_start;
  return out;
}

ProcessedFrame FramePipeline::whole_frame(const DepthFrame& frame, const FrameRequest& request) {
  const double t_start = config_.clock_ms();
  const DepthImage& image = register_frame(frame.image);
  ProcessedFrame out = start_frame(frame, request, image);
  out.times.register_ms = config_.clock_ms() - t_start;
  const cv::Mat1w& in = image.depth_mm;
  std::vector<int> all(static_cast<std::size_t>(out.grid.count()));
  std::iota(all.begin(), all.end(), 0);

  TileJob job;
  job.tiles = &all;
  if (!request.select_tiles) {
    // Nobody holds anything: keep the histories going, encode nothing, and start the next
    // receiver with a key frame.
    job.select = false;
    process_tiles(frame, in, job, out);
    sent_view_.release();
    out.times.total_ms = config_.clock_ms() - t_start;
    return out;
  }
  const bool key = next_frame_is_key(in.size(), request);
  key_owed_ = rest_owed_ = false;  // a whole frame sends every tile that differs
  job.key = key;
  out.key_frame = key;
  close_one_part(out, key, process_tiles(frame, in, job, out));
  out.sent_view_mm = sent_view_.clone();
  out.times.total_ms = config_.clock_ms() - t_start;
  return out;
}

}  // namespace telex::remote
