// SPDX-License-Identifier: MIT
// The remote node's per-frame processing: register, fill, stabilise, select changed tiles, encode.
#include "telex/remote/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iterator>
#include <numbers>
#include <stdexcept>
#include <string>

#include "telex/common/synthetic.h"

namespace telex::remote {

namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool same_tile(const cv::Mat1w& a, const cv::Mat1w& b, const cv::Rect& r) {
  for (int y = r.y; y < r.y + r.height; ++y)
    if (std::memcmp(a.ptr<std::uint16_t>(y) + r.x, b.ptr<std::uint16_t>(y) + r.x,
                    sizeof(std::uint16_t) * r.width) != 0)
      return false;
  return true;
}

}  // namespace

Stabiliser::Stabiliser(double k_sigma, int confirm_frames, double immediate_factor)
    : k_(k_sigma), confirm_frames_(confirm_frames), tol_mm_(65536, 0), jump_mm_(65536, 0) {
  if (!(k_sigma >= 0.0) || !std::isfinite(k_sigma))
    throw std::invalid_argument("stabiliser k (sigmas) must be a finite number >= 0");
  if (confirm_frames < 1 || confirm_frames > 255)
    throw std::invalid_argument("stabiliser confirm frames must be 1..255");
  if (!(immediate_factor >= 1.0))
    throw std::invalid_argument("stabiliser immediate factor must be >= 1");
  if (k_ > 0.0)
    for (std::size_t d = 1; d < tol_mm_.size(); ++d) {
      const double tol = k_ * synth::axial_sigma_m(static_cast<double>(d) * 1e-3, 0.0) * 1e3;
      tol_mm_[d] = static_cast<std::uint16_t>(std::min(65535.0, std::floor(tol)));
      jump_mm_[d] = static_cast<std::uint32_t>(std::floor(tol * immediate_factor));
    }
}

void Stabiliser::apply(const cv::Mat1w& in_mm, cv::Mat1w& out_mm) {
  if (k_ == 0.0) {
    in_mm.copyTo(out_mm);
    return;
  }
  if (last_mm_.size() != in_mm.size()) {
    begin(in_mm.size());
    in_mm.copyTo(out_mm);
    in_mm.copyTo(last_mm_);
    return;
  }
  out_mm.create(in_mm.size());
  apply_rect(in_mm, cv::Rect(0, 0, in_mm.cols, in_mm.rows), out_mm);
}

void Stabiliser::begin(cv::Size size) {
  if (k_ == 0.0 || last_mm_.size() == size) return;
  // An empty history takes every pixel as it comes (a held 0 is always replaced), which is what
  // the first frame of a full-frame apply() does.
  last_mm_ = cv::Mat1w(size, std::uint16_t(0));
  outside_ = cv::Mat1b(size, std::uint8_t(0));
}

void Stabiliser::apply_rect(const cv::Mat1w& in_mm, const cv::Rect& rect, cv::Mat1w& out_mm) {
  if (out_mm.size() != in_mm.size())
    throw std::invalid_argument("stabiliser: output must have the input's size");
  if (k_ == 0.0) {
    in_mm(rect).copyTo(out_mm(rect));
    return;
  }
  if (last_mm_.size() != in_mm.size())
    throw std::invalid_argument("stabiliser: begin() with the frame size before apply_rect()");
  const auto confirm = static_cast<std::uint8_t>(confirm_frames_);
  for (int y = rect.y; y < rect.y + rect.height; ++y) {
    const std::uint16_t* in = in_mm.ptr<std::uint16_t>(y);
    std::uint16_t* last = last_mm_.ptr<std::uint16_t>(y);
    std::uint8_t* outside = outside_.ptr<std::uint8_t>(y);
    std::uint16_t* out = out_mm.ptr<std::uint16_t>(y);
    for (int x = rect.x; x < rect.x + rect.width; ++x) {
      const std::uint16_t v = in[x], s = last[x];
      const std::uint32_t diff = v > s ? v - s : s - v;
      bool take = v == 0 || s == 0;
      if (!take && diff > tol_mm_[s]) {
        take = diff > jump_mm_[s] || ++outside[x] >= confirm;
      } else if (!take) {
        outside[x] = 0;
      }
      if (take) {
        last[x] = v;
        outside[x] = 0;
      }
      out[x] = last[x];
    }
  }
}

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

RegisterMode parse_register_mode(std::string_view text) {
  if (text == "none") return RegisterMode::None;
  if (text == "shift") return RegisterMode::Shift;
  if (text == "full") return RegisterMode::Full;
  throw std::invalid_argument("registration mode '" + std::string(text) +
                              "' is not one of none, shift, full");
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

namespace {

std::vector<double> parse_numbers(std::string_view text, std::size_t count, const char* flag,
                                  const char* form) {
  std::vector<double> out;
  std::string item;
  const std::string all(text);
  std::size_t start = 0;
  while (start <= all.size()) {
    const std::size_t comma = std::min(all.find(',', start), all.size());
    item = all.substr(start, comma - start);
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || !std::isfinite(v))
      throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
    out.push_back(v);
    start = comma + 1;
  }
  if (out.size() != count)
    throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
  return out;
}

}  // namespace

RegistrationConfig parse_registration(std::string_view mode, std::string_view eye_centre_m,
                                      std::string_view rotation_deg, std::string_view eye,
                                      double nominal_depth_m) {
  RegistrationConfig c;
  c.mode = parse_register_mode(mode);
  const auto centre = parse_numbers(eye_centre_m, 3, "--register-baseline", "X,Y,Z in metres");
  const auto rot = parse_numbers(rotation_deg, 3, "--register-rotation", "RX,RY,RZ in degrees");
  const double k = std::numbers::pi / 180.0;
  const glm::dmat3 rx(1, 0, 0, 0, std::cos(rot[0] * k), std::sin(rot[0] * k), 0,
                      -std::sin(rot[0] * k), std::cos(rot[0] * k));
  const glm::dmat3 ry(std::cos(rot[1] * k), 0, -std::sin(rot[1] * k), 0, 1, 0, std::sin(rot[1] * k),
                      0, std::cos(rot[1] * k));
  const glm::dmat3 rz(std::cos(rot[2] * k), std::sin(rot[2] * k), 0, -std::sin(rot[2] * k),
                      std::cos(rot[2] * k), 0, 0, 0, 1);
  // The eye's axes, seen from the depth camera, are the depth camera's turned by R; a depth-frame
  // point p is at R^T (p - C) in the eye's frame.
  const glm::dmat3 r = rz * ry * rx;
  const glm::dvec3 c_m(centre[0], centre[1], centre[2]);
  c.eye_from_depth.rotation = glm::transpose(r);
  c.eye_from_depth.translation_m = -(glm::transpose(r) * c_m);
  if (!eye.empty()) {
    const auto e = parse_numbers(eye, 6, "--register-eye", "FX,FY,CX,CY,W,H in pixels");
    if (!(e[0] > 0 && e[1] > 0 && e[4] >= 1 && e[5] >= 1 && e[4] <= 8192 && e[5] <= 8192 &&
          e[4] == std::floor(e[4]) && e[5] == std::floor(e[5])))
      throw std::invalid_argument("--register-eye '" + std::string(eye) +
                                  "': FX, FY must be > 0 and W, H whole numbers 1..8192");
    c.eye = Intrinsics{e[0], e[1], e[2], e[3], static_cast<int>(e[4]), static_cast<int>(e[5])};
  }
  if (!(nominal_depth_m > 0) || !std::isfinite(nominal_depth_m))
    throw std::invalid_argument("--register-nominal must be > 0 m");
  c.nominal_depth_m = nominal_depth_m;
  return c;
}

FramePipeline::FramePipeline(PipelineConfig config)
    : config_(std::move(config)),
      temporal_(config_.temporal),
      stabiliser_(config_.stabilise_k_sigma, config_.stabilise_confirm_frames) {
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
    const glm::dvec3& t = reg.eye_from_depth.translation_m;
    if (!std::isfinite(t.x) || !std::isfinite(t.y) || !std::isfinite(t.z))
      throw std::invalid_argument("registration baseline must be finite");
  }
}

const DepthImage& FramePipeline::register_frame(const DepthImage& in) {
  const RegistrationConfig& reg = config_.registration;
  if (reg.mode == RegisterMode::None) return in;
  const Intrinsics eye = reg.eye.width == 0 ? in.intrinsics : reg.eye;
  if (reg.mode == RegisterMode::Full) {
    registered_ = reproject_depth(in, eye, reg.eye_from_depth, /*fill_cracks=*/true);
  } else {
    // Shift+scale models a translated camera: the rotation is ignored.
    if (shift_scale_for_ != in.intrinsics) {
      shift_scale_ = shift_scale_from_calibration(
          in.intrinsics, eye, reg.eye_from_depth.translation_m, reg.nominal_depth_m);
      shift_scale_for_ = in.intrinsics;
    }
    registered_ = register_shift_scale(in, shift_scale_, eye);
  }
  return registered_;
}

ProcessedFrame FramePipeline::process(const DepthFrame& frame, const FrameRequest& request) {
  ProcessedFrame out = process_roi(frame, request);
  if (!rest_pending()) return out;
  ProcessedFrame rest = process_rest(frame);
  // One message set: every tile of the frame in index order, closed by the rest's manifest.
  std::vector<proto::EncodedTile> tiles;
  tiles.reserve(out.tiles.size() + rest.tiles.size());
  std::merge(
      std::make_move_iterator(out.tiles.begin()), std::make_move_iterator(out.tiles.end()),
      std::make_move_iterator(rest.tiles.begin()), std::make_move_iterator(rest.tiles.end()),
      std::back_inserter(tiles),
      [](const proto::EncodedTile& a, const proto::EncodedTile& b) { return a.index < b.index; });
  rest.tiles = std::move(tiles);
  rest.part = FramePart::Whole;
  rest.tiles_skipped += out.tiles_skipped;
  rest.holes_in += out.holes_in;
  rest.holes_out += out.holes_out;
  rest.pixels_processed += out.pixels_processed;
  rest.times += out.times;
  return rest;
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
  return out;
}

ProcessedFrame FramePipeline::process_roi(const DepthFrame& frame, const FrameRequest& request) {
  pending_.active = false;
  if (!request.select_tiles || request.rois.empty()) return process_whole(frame, request);
  const auto t_start = std::chrono::steady_clock::now();
  const auto t_register = std::chrono::steady_clock::now();
  const DepthImage& image = register_frame(frame.image);
  const double register_ms = ms_since(t_register);
  ProcessedFrame out = start_frame(frame, request, image);
  out.times.register_ms = register_ms;
  const cv::Mat1w& in = image.depth_mm;
  const proto::TileGrid& grid = out.grid;

  const bool size_changed = sent_view_.size() != in.size();
  ++frames_;
  const bool key = size_changed || request.force_key_frame || key_owed_ ||
                   since_key_ + 1 >= static_cast<std::uint64_t>(config_.key_frame_every) ||
                   frames_ == 1;
  since_key_ = key ? 0 : since_key_ + 1;
  if (size_changed) sent_view_ = cv::Mat1w(in.size(), std::uint16_t(0));
  const bool background_due =
      rest_owed_ || (frames_ % static_cast<std::uint64_t>(config_.background_every)) == 0;
  key_owed_ = rest_owed_ = false;
  const std::vector<bool> in_roi = tiles_in_rois(grid, request.rois);
  std::vector<int> roi_tiles;
  for (int i = 0; i < grid.count(); ++i)
    if (in_roi[static_cast<std::size_t>(i)]) roi_tiles.push_back(i);
  const bool has_rest =
      (key || background_due) && roi_tiles.size() < static_cast<std::size_t>(grid.count());

  // Fill, temporal fill and stabilise the ROI tiles only. The spatial fill runs per requested
  // rectangle widened to whole tiles (with the fill's own margin, so its result equals a
  // full-frame fill there); the stateful stages run once per tile.
  auto t0 = std::chrono::steady_clock::now();
  const cv::Mat1w* current = &in;
  filled_.create(in.size());
  temporal_out_.create(in.size());
  stabilised_.create(in.size());
  if (config_.fill) {
    const cv::Rect image(0, 0, in.cols, in.rows);
    for (const auto& roi : request.rois) {
      const cv::Rect r = cv::Rect(roi.x, roi.y, roi.w, roi.h) & image;
      if (r.empty()) continue;
      const int x0 = r.x / grid.tile_width * grid.tile_width;
      const int y0 = r.y / grid.tile_height * grid.tile_height;
      const int x1 = (r.x + r.width + grid.tile_width - 1) / grid.tile_width * grid.tile_width;
      const int y1 = (r.y + r.height + grid.tile_height - 1) / grid.tile_height * grid.tile_height;
      fill_holes_mode_roi_into(in, cv::Rect(x0, y0, x1 - x0, y1 - y0) & image, filled_,
                               config_.hole_fill);
    }
    current = &filled_;
    if (config_.temporal_fill) {
      temporal_.begin_frame(in.size(), static_cast<double>(frame.capture_ns) * 1e-6);
      for (int i : roi_tiles) temporal_.apply_rect(filled_, grid.rect(i), temporal_out_);
      current = &temporal_out_;
    }
  }
  for (int i : roi_tiles) {
    const cv::Rect r = grid.rect(i);
    out.holes_in += count_holes(in(r));
    out.holes_out += count_holes((*current)(r));
    out.pixels_processed += static_cast<std::size_t>(r.area());
  }
  out.times.fill_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  stabiliser_.begin(in.size());
  for (int i : roi_tiles) stabiliser_.apply_rect(*current, grid.rect(i), stabilised_);
  out.times.stabilise_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  std::vector<int> send;
  for (int i : roi_tiles) {
    if (key || !same_tile(stabilised_, sent_view_, grid.rect(i)))
      send.push_back(i);
    else
      ++out.tiles_skipped;
  }
  if (!has_rest) out.tiles_skipped += static_cast<std::size_t>(grid.count()) - roi_tiles.size();
  for (int i : send) stabilised_(grid.rect(i)).copyTo(sent_view_(grid.rect(i)));
  out.times.tile_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  encode_tiles(send, out);
  out.times.encode_ms = ms_since(t0);

  out.key_frame = key;
  out.manifest.frame_id = out.frame_id;
  out.manifest.tile_count = static_cast<std::uint16_t>(grid.count());
  if (has_rest) {
    // The ROI part lists the tiles it carries, even on a key frame; the rest's manifest closes
    // the frame as a one-part frame's manifest would.
    out.part = FramePart::RoiPart;
    out.manifest.key_frame = false;
    for (int i : send) out.manifest.changed_tiles.push_back(static_cast<std::uint16_t>(i));
    pending_.active = true;
    pending_.frame_id = frame.frame_id;
    pending_.key = key;
    pending_.in_roi = in_roi;
    pending_.roi_sent = out.manifest.changed_tiles;
    pending_.codec = out.codec;
  } else {
    out.part = FramePart::Whole;
    out.manifest.key_frame = key;
    if (!key)
      for (int i : send) out.manifest.changed_tiles.push_back(static_cast<std::uint16_t>(i));
  }
  out.sent_view_mm = sent_view_.clone();
  out.times.total_ms = ms_since(t_start);
  return out;
}

ProcessedFrame FramePipeline::process_rest(const DepthFrame& frame,
                                           const std::function<bool()>& preempt) {
  if (!pending_.active || pending_.frame_id != frame.frame_id)
    throw std::logic_error("process_rest: no ROI part of this frame is waiting for its rest");
  pending_.active = false;
  const auto t_start = std::chrono::steady_clock::now();
  FrameRequest request;
  request.codec = pending_.codec;
  // The rest uses the image the ROI part registered (registered_ is untouched until the next
  // frame).
  const DepthImage& image =
      config_.registration.mode == RegisterMode::None ? frame.image : registered_;
  ProcessedFrame out = start_frame(frame, request, image);
  const cv::Mat1w& in = image.depth_mm;
  const proto::TileGrid& grid = out.grid;
  std::vector<int> rest_tiles;
  for (int i = 0; i < grid.count(); ++i)
    if (!pending_.in_roi[static_cast<std::size_t>(i)]) rest_tiles.push_back(i);

  // The spatial fill needs the whole frame (holes reach across tiles); inside the ROI tiles it
  // rewrites the values the ROI part computed, bit for bit.
  auto t0 = std::chrono::steady_clock::now();
  const cv::Mat1w* current = &in;
  if (config_.fill) {
    fill_holes_mode_into(in, filled_, config_.hole_fill);
    current = &filled_;
    if (config_.temporal_fill) {
      for (int i : rest_tiles) temporal_.apply_rect(filled_, grid.rect(i), temporal_out_);
      current = &temporal_out_;
    }
  }
  for (int i : rest_tiles) {
    const cv::Rect r = grid.rect(i);
    out.holes_in += count_holes(in(r));
    out.holes_out += count_holes((*current)(r));
    out.pixels_processed += static_cast<std::size_t>(r.area());
  }
  out.times.fill_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  for (int i : rest_tiles) stabiliser_.apply_rect(*current, grid.rect(i), stabilised_);
  out.times.stabilise_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  std::vector<int> send;
  for (int i : rest_tiles) {
    if (pending_.key || !same_tile(stabilised_, sent_view_, grid.rect(i)))
      send.push_back(i);
    else
      ++out.tiles_skipped;
  }
  out.times.tile_ms = ms_since(t0);

  // Encode tile by tile; a newer frame waiting cuts the rest here (its ROI part must not wait for
  // this frame's background). What the receiver holds (sent_view_) moves only with sent tiles, so
  // the unsent ones compare as changed and go out with the next rest.
  t0 = std::chrono::steady_clock::now();
  const bool may_cut = preempt && !last_rest_cut_;
  std::vector<int> sent;
  sent.reserve(send.size());
  out.tiles.reserve(send.size());
  for (int i : send) {
    if (may_cut && preempt()) {
      out.rest_cut = true;
      break;
    }
    stabilised_(grid.rect(i)).copyTo(sent_view_(grid.rect(i)));
    sent.push_back(i);
    proto::EncodedTile t;
    t.index = static_cast<std::uint16_t>(i);
    t.rect = grid.rect(i);
    t.bytes = proto::encode_depth(stabilised_(t.rect), out.codec, config_.zip_level);
    out.tiles.push_back(std::move(t));
  }
  out.times.encode_ms = ms_since(t0);
  last_rest_cut_ = out.rest_cut;
  if (out.rest_cut) {
    out.tiles_skipped += send.size() - sent.size();
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
  out.times.total_ms = ms_since(t_start);
  return out;
}

void FramePipeline::encode_tiles(const std::vector<int>& send, ProcessedFrame& out) const {
  out.tiles.reserve(send.size());
  for (int i : send) {
    proto::EncodedTile t;
    t.index = static_cast<std::uint16_t>(i);
    t.rect = out.grid.rect(i);
    t.bytes = proto::encode_depth(stabilised_(t.rect), out.codec, config_.zip_level);
    out.tiles.push_back(std::move(t));
  }
}

ProcessedFrame FramePipeline::process_whole(const DepthFrame& frame, const FrameRequest& request) {
  const auto t_start = std::chrono::steady_clock::now();
  const auto t_register = std::chrono::steady_clock::now();
  const DepthImage& image = register_frame(frame.image);
  const double register_ms = ms_since(t_register);
  ProcessedFrame out = start_frame(frame, request, image);
  out.times.register_ms = register_ms;
  const cv::Mat1w& in = image.depth_mm;
  out.holes_in = count_holes(in);
  out.pixels_processed = in.total();

  // Fill: windowed mode for small holes, then the per-pixel history for what the window missed.
  auto t0 = std::chrono::steady_clock::now();
  const cv::Mat1w* current = &in;
  if (config_.fill) {
    fill_holes_mode_into(in, filled_, config_.hole_fill);
    current = &filled_;
    if (config_.temporal_fill) {
      const double time_ms = static_cast<double>(frame.capture_ns) * 1e-6;
      temporal_.apply(filled_, time_ms, temporal_out_);
      current = &temporal_out_;
    }
  }
  out.holes_out = count_holes(*current);
  out.times.fill_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  stabiliser_.apply(*current, stabilised_);
  out.times.stabilise_ms = ms_since(t0);

  // Tile selection against what the receiver holds.
  t0 = std::chrono::steady_clock::now();
  const proto::TileGrid& grid = out.grid;
  if (!request.select_tiles) {
    // Nobody holds anything: the next receiver starts with a key frame.
    sent_view_.release();
    out.times.total_ms = ms_since(t_start);
    return out;
  }
  const bool size_changed = sent_view_.size() != stabilised_.size();
  ++frames_;
  const bool key = size_changed || request.force_key_frame ||
                   since_key_ + 1 >= static_cast<std::uint64_t>(config_.key_frame_every) ||
                   frames_ == 1;
  since_key_ = key ? 0 : since_key_ + 1;
  if (size_changed) sent_view_ = cv::Mat1w(stabilised_.size(), std::uint16_t(0));
  std::vector<int> send;
  for (int i = 0; i < grid.count(); ++i) {
    const cv::Rect r = grid.rect(i);
    if (key || !same_tile(stabilised_, sent_view_, r))
      send.push_back(i);
    else
      ++out.tiles_skipped;
  }
  for (int i : send) stabilised_(grid.rect(i)).copyTo(sent_view_(grid.rect(i)));
  out.times.tile_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  encode_tiles(send, out);
  out.times.encode_ms = ms_since(t0);

  out.key_frame = key;
  out.manifest.frame_id = out.frame_id;
  out.manifest.tile_count = static_cast<std::uint16_t>(grid.count());
  out.manifest.key_frame = key;
  if (!key)
    for (int i : send) out.manifest.changed_tiles.push_back(static_cast<std::uint16_t>(i));
  out.sent_view_mm = sent_view_.clone();
  out.times.total_ms = ms_since(t_start);
  return out;
}

}  // namespace telex::remote
