// SPDX-License-Identifier: MIT
// Surface snapshot construction (full frame or fingertip windows).
#include "telex/local/surface_builder.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <new>

namespace telex::local {
namespace {
double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

std::vector<cv::Rect> fingertip_windows(const HandState& hand, const cv::Mat1w& depth_mm,
                                        const Intrinsics& k, const SurfaceOptions& o) {
  std::vector<cv::Rect> out;
  const cv::Rect image(0, 0, depth_mm.cols, depth_mm.rows);
  for (const auto& tip : hand.tips) {
    if (!tip.valid) continue;
    const glm::dvec3& p = tip.p_camera_m;
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.z <= 0.05) continue;
    const double u = k.fx * p.x / p.z + k.cx;
    const double v = k.fy * p.y / p.z + k.cy;
    const double speed =
        std::isfinite(glm::length(tip.v_camera_mps)) ? glm::length(tip.v_camera_mps) : 0.0;
    const double reach_m = o.roi_radius_m + speed * o.roi_lookahead_s;
    // A fingertip far in front of whatever lies under it needs no surface yet.
    const int ui = static_cast<int>(std::lround(u)), vi = static_cast<int>(std::lround(v));
    if (ui >= 0 && vi >= 0 && ui < depth_mm.cols && vi < depth_mm.rows) {
      const double z_surface = depth_mm(vi, ui) * 1e-3;
      if (z_surface > 0 && z_surface - p.z > o.roi_max_distance_m + speed * o.roi_lookahead_s)
        continue;
    }
    const int half = std::max(o.roi_min_half_px, static_cast<int>(std::ceil(k.fx * reach_m / p.z)));
    const cv::Rect r = cv::Rect(static_cast<int>(u) - half, static_cast<int>(v) - half,
                                2 * half + 1, 2 * half + 1) &
                       image;
    if (r.area() > 0) out.push_back(r);
  }
  // Overlapping windows merge so no pixel is processed twice.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t i = 0; i < out.size() && !merged; ++i)
      for (std::size_t j = i + 1; j < out.size() && !merged; ++j)
        if ((out[i] & out[j]).area() > 0) {
          out[i] = out[i] | out[j];
          out.erase(out.begin() + static_cast<std::ptrdiff_t>(j));
          merged = true;
        }
  }
  return out;
}

namespace {

// A snapshot whose pixel buffers come from calloc: the kernel hands out zero pages lazily, so a
// region-of-interest snapshot only pays for the windows it writes, not for the whole frame.
struct WindowedSurface : Surface {
  struct Free {
    void operator()(void* p) const { std::free(p); }
  };
  std::unique_ptr<void, Free> depth_buf, normal_buf;

  WindowedSurface(cv::Size size) {
    const auto n = static_cast<std::size_t>(size.area());
    depth_buf.reset(std::calloc(n, sizeof(float)));
    normal_buf.reset(std::calloc(n, 3 * sizeof(float)));
    if (!depth_buf || !normal_buf) throw std::bad_alloc();
    depth_m = cv::Mat1f(size.height, size.width, static_cast<float*>(depth_buf.get()));
    normals = cv::Mat3f(size.height, size.width, static_cast<cv::Vec3f*>(normal_buf.get()));
  }
};

}  // namespace

std::shared_ptr<Surface> build_surface(const AssembledFrame& frame, const SurfaceOptions& o,
                                       std::span<const cv::Rect> windows,
                                       SurfaceBuildStats* stats) {
  SurfaceBuildStats local;
  // The kernels' outputs are valid by construction (finite metres or 0, unit or zero normals) and
  // freshly allocated per frame, so the snapshot takes them as they are: no copy, no re-check.
  if (!o.roi) {
    auto s = std::make_shared<Surface>();
    auto t0 = std::chrono::steady_clock::now();
    if (o.bilateral)
      bilateral_filter_depth(frame.depth_mm, s->depth_m, o.bilateral_options);
    else
      s->depth_m = depth_m_from_mm(frame.depth_mm);
    local.filter_ms = ms_since(t0);
    t0 = std::chrono::steady_clock::now();
    compute_normals(s->depth_m, frame.intrinsics, s->normals, o.normal_options);
    local.normals_ms = ms_since(t0);
    local.pixels_processed = frame.depth_mm.total();
    s->intrinsics = frame.intrinsics;
    s->capture_ns = frame.capture_ns;
    s->frame_id = frame.frame_id;
    if (stats) *stats = local;
    return s;
  }
  // Region of interest: outside the windows the snapshot holds no data (a fingertip that far
  // from the surface cannot touch it before the next frame).
  auto s = std::make_shared<WindowedSurface>(frame.depth_mm.size());
  s->intrinsics = frame.intrinsics;
  s->capture_ns = frame.capture_ns;
  s->frame_id = frame.frame_id;
  auto t0 = std::chrono::steady_clock::now();
  cv::Mat1f filtered;
  for (const auto& r : windows) {
    if (o.bilateral) {
      bilateral_filter_depth_roi(frame.depth_mm, r, filtered, o.bilateral_options);
      filtered.copyTo(s->depth_m(r));
    } else {
      depth_m_from_mm(frame.depth_mm(r)).copyTo(s->depth_m(r));
    }
  }
  local.filter_ms = ms_since(t0);
  t0 = std::chrono::steady_clock::now();
  cv::Mat3f n_roi;
  for (const auto& r : windows) {
    // Normals need a one-pixel-plus-stencil margin of depth around the window; the window edges
    // see the margin as holes and fall back to one-sided differences.
    compute_normals_roi(s->depth_m, frame.intrinsics, r, n_roi, o.normal_options);
    n_roi.copyTo(s->normals(r));
    local.pixels_processed += static_cast<std::size_t>(r.area());
  }
  local.normals_ms = ms_since(t0);
  if (stats) *stats = local;
  return s;
}

}  // namespace telex::local
