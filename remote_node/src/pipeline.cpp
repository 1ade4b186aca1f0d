// SPDX-License-Identifier: MIT
// The remote node's per-frame processing: register, fill, stabilise, select changed tiles, encode.
#include "telex/remote/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
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
    in_mm.copyTo(last_mm_);
    outside_ = cv::Mat1b(in_mm.size(), std::uint8_t(0));
    in_mm.copyTo(out_mm);
    return;
  }
  out_mm.create(in_mm.size());
  const auto confirm = static_cast<std::uint8_t>(confirm_frames_);
  for (int y = 0; y < in_mm.rows; ++y) {
    const std::uint16_t* in = in_mm.ptr<std::uint16_t>(y);
    std::uint16_t* last = last_mm_.ptr<std::uint16_t>(y);
    std::uint8_t* outside = outside_.ptr<std::uint8_t>(y);
    std::uint16_t* out = out_mm.ptr<std::uint16_t>(y);
    for (int x = 0; x < in_mm.cols; ++x) {
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
  const auto t_start = std::chrono::steady_clock::now();
  ProcessedFrame out;
  out.frame_id = static_cast<std::uint32_t>(frame.frame_id);
  out.capture_ns = frame.capture_ns;
  out.codec = request.codec.value_or(config_.codec);
  auto t0 = std::chrono::steady_clock::now();
  const DepthImage& registered = register_frame(frame.image);
  out.times.register_ms = ms_since(t0);
  out.intrinsics = registered.intrinsics;
  const cv::Mat1w& in = registered.depth_mm;
  out.holes_in = count_holes(in);

  // Fill: windowed mode for small holes, then the per-pixel history for what the window missed.
  t0 = std::chrono::steady_clock::now();
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
  proto::TileGrid grid{in.cols, in.rows, config_.tile_width, config_.tile_height};
  out.grid = grid;
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
  const bool background_due =
      request.rois.empty() || (frames_ % static_cast<std::uint64_t>(config_.background_every)) == 0;
  const std::vector<bool> in_roi = tiles_in_rois(grid, request.rois);
  std::vector<int> send;
  for (int i = 0; i < grid.count(); ++i) {
    const cv::Rect r = grid.rect(i);
    const bool due = key || background_due || in_roi[static_cast<std::size_t>(i)];
    if (due && (key || !same_tile(stabilised_, sent_view_, r)))
      send.push_back(i);
    else
      ++out.tiles_skipped;
  }
  for (int i : send) stabilised_(grid.rect(i)).copyTo(sent_view_(grid.rect(i)));
  out.times.tile_ms = ms_since(t0);

  t0 = std::chrono::steady_clock::now();
  out.tiles.reserve(send.size());
  for (int i : send) {
    proto::EncodedTile t;
    t.index = static_cast<std::uint16_t>(i);
    t.rect = grid.rect(i);
    t.bytes = proto::encode_depth(stabilised_(t.rect), out.codec, config_.zip_level);
    out.tiles.push_back(std::move(t));
  }
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
