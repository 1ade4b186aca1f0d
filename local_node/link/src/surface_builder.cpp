// SPDX-License-Identifier: MIT
// Surface snapshot construction (full frame or fingertip windows).
#include "telex/local/link/surface_builder.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <stdexcept>
#include <string>

namespace telex::local {

std::vector<cv::Rect> fingertip_windows(const HandState& hand, const cv::Mat1w& depth_mm,
                                        const Intrinsics& k, const SurfaceOptions& o) {
  std::vector<cv::Rect> out;
  const cv::Rect image(0, 0, depth_mm.cols, depth_mm.rows);
  for (const auto& tip : hand.tips) {
    if (!tip.valid) continue;
    const glm::dvec3& p = tip.p_CameraFingertip;
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || p.z <= 0.05) continue;
    const double u = k.fx * p.x / p.z + k.cx;
    const double v = k.fy * p.y / p.z + k.cy;
    const double speed = std::isfinite(glm::length(tip.v_CameraFingertip))
                             ? glm::length(tip.v_CameraFingertip)
                             : 0.0;
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

void PooledSurface::Free::operator()(void* p) const { std::free(p); }

PooledSurface::PooledSurface(cv::Size size) {
  const auto n = static_cast<std::size_t>(size.area());
  depth_buf_.reset(std::calloc(n, sizeof(float)));
  normal_buf_.reset(std::calloc(n, 3 * sizeof(float)));
  if (!depth_buf_ || !normal_buf_) throw std::bad_alloc();
  depth_m = cv::Mat1f(size.height, size.width, static_cast<float*>(depth_buf_.get()));
  normals = cv::Mat3f(size.height, size.width, static_cast<cv::Vec3f*>(normal_buf_.get()));
}

void PooledSurface::recycle(bool zero) {
  const cv::Size size = this->size();
  if (depth_m.data != depth_buf_.get() || normals.data != normal_buf_.get()) {
    depth_m = cv::Mat1f(size.height, size.width, static_cast<float*>(depth_buf_.get()));
    normals = cv::Mat3f(size.height, size.width, static_cast<cv::Vec3f*>(normal_buf_.get()));
  }
  if (!zero) {
    // The caller writes every pixel; until it has, assume all of them may hold data.
    written.clear();
    written_all = true;
    return;
  }
  if (written_all) {
    depth_m.setTo(0.0f);
    normals.setTo(cv::Vec3f(0.0f, 0.0f, 0.0f));
  } else {
    for (const auto& r : written) {
      depth_m(r).setTo(0.0f);
      normals(r).setTo(cv::Vec3f(0.0f, 0.0f, 0.0f));
    }
  }
  written.clear();
  written_all = false;
}

SurfacePool::SurfacePool(std::size_t capacity) : capacity_(capacity) {
  if (capacity_ < 1) throw std::invalid_argument("SurfacePool: capacity must be at least 1");
  entries_.reserve(capacity_);
}

SurfacePool::~SurfacePool() = default;

void SurfacePool::warm(cv::Size size) {
  if (size.width <= 0 || size.height <= 0)
    throw std::invalid_argument("SurfacePool: empty snapshot size");
  while (entries_.size() < capacity_) {
    auto s = std::make_shared<PooledSurface>(size);
    ++allocations_;
    // calloc'd pages are mapped on first write: write the zeros they already read as.
    s->depth_m.setTo(0.0f);
    s->normals.setTo(cv::Vec3f(0.0f, 0.0f, 0.0f));
    entries_.push_back(std::move(s));
  }
}

std::shared_ptr<PooledSurface> SurfacePool::acquire(cv::Size size, bool zeroed) {
  if (size.width <= 0 || size.height <= 0)
    throw std::invalid_argument("SurfacePool: empty snapshot size");
  std::shared_ptr<PooledSurface> found;
  for (std::size_t i = 0; i < entries_.size();) {
    // Only the pool can make new references to an entry it alone holds, and only this thread
    // uses the pool: a use count of 1 cannot rise behind our back.
    if (entries_[i].use_count() != 1) {
      ++i;
      continue;
    }
    if (entries_[i]->size() != size) {  // the stream changed resolution: drop the old size
      entries_.erase(entries_.begin() + static_cast<std::ptrdiff_t>(i));
      continue;
    }
    found = entries_[i];
    break;
  }
  if (found) {
    // use_count() is a relaxed load; the other owners released with acq_rel decrements. The fence
    // orders their last reads of the pixels before our writes.
    std::atomic_thread_fence(std::memory_order_acquire);
    ++recycled_;
  } else {
    found = std::make_shared<PooledSurface>(size);
    ++allocations_;
    if (entries_.size() < capacity_) entries_.push_back(found);
  }
  found->recycle(zeroed);
  found->intrinsics = {};
  found->capture_ns = 0;
  found->frame_id = 0;
  return found;
}

std::shared_ptr<Surface> build_surface(const AssembledFrame& frame, const SurfaceOptions& o,
                                       std::span<const cv::Rect> windows, SurfaceBuildStats* stats,
                                       SurfacePool* pool) {
  SurfaceBuildStats local;
  const cv::Size size = frame.depth_mm.size();
  if (o.roi)
    for (const auto& r : windows)
      if (r.empty() || (r & cv::Rect(cv::Point(0, 0), size)) != r)
        throw std::invalid_argument("build_surface: window " + std::to_string(r.width) + "x" +
                                    std::to_string(r.height) + " at (" + std::to_string(r.x) +
                                    ", " + std::to_string(r.y) + ") is empty or outside the frame");
  const StageClock now_ms = o.clock_ms;
  double t0 = now_ms();
  // A full-frame build writes every pixel; a region-of-interest one needs zeros outside its
  // windows (a fingertip that far from the surface cannot touch it before the next frame). Without
  // a pool, a region-of-interest snapshot gets fresh calloc'd buffers and a full-frame one lets the
  // kernels allocate.
  std::shared_ptr<PooledSurface> pooled;
  std::shared_ptr<Surface> s;
  if (pool)
    s = pooled = pool->acquire(size, o.roi);
  else if (o.roi)
    s = pooled = std::make_shared<PooledSurface>(size);
  else
    s = std::make_shared<Surface>();
  s->intrinsics = frame.intrinsics;
  s->capture_ns = frame.capture_ns;
  s->frame_id = frame.frame_id;
  s->head_valid = frame.head.valid;
  for (std::size_t j = 0; j < 3; ++j) s->head_joint_rad[j] = frame.head.joint_rad[j];
  local.snapshot_ms = now_ms() - t0;
  // Station-side fill: what the filter reads (the windows plus the bilateral radius) is filled
  // from the depth as it arrived. The scratch image is this thread's, reused frame to frame; in
  // ROI mode only the widened windows of it are written, and only they are read.
  const cv::Mat1w* depth = &frame.depth_mm;
  if (o.fill_here) {
    thread_local cv::Mat1w filled;
    t0 = now_ms();
    if (!o.roi) {
      fill_holes_mode_into(frame.depth_mm, filled, o.fill_options);
    } else {
      // What the filter reads: the windows plus the bilateral radius.
      const int margin = o.bilateral ? o.bilateral_options.radius_px : 0;
      fill_holes_mode_rois_into(frame.depth_mm, windows, RoiWidening{margin, {1, 1}}, filled,
                                o.fill_options);
    }
    depth = &filled;
    local.fill_ms = now_ms() - t0;
  }
  // The kernels write straight into the snapshot's buffers (their outputs are valid by
  // construction: finite metres or 0, unit or zero normals): no copy, no re-check.
  if (!o.roi) {
    if (pooled) pooled->written_all = true;
    t0 = now_ms();
    if (o.bilateral)
      bilateral_filter_depth(*depth, s->depth_m, o.bilateral_options);
    else
      depth->convertTo(s->depth_m, CV_32F, 1e-3);  // as depth_m_from_mm, in place
    local.filter_ms = now_ms() - t0;
    t0 = now_ms();
    compute_normals(s->depth_m, frame.intrinsics, s->normals, o.normal_options);
    local.normals_ms = now_ms() - t0;
    local.pixels_processed = frame.depth_mm.total();
    if (stats) *stats = local;
    return s;
  }
  pooled->written.assign(windows.begin(), windows.end());
  t0 = now_ms();
  for (const auto& r : windows) {
    cv::Mat1f dst = s->depth_m(r);  // the kernel writes through this view (same size: no realloc)
    if (o.bilateral)
      bilateral_filter_depth_roi(*depth, r, dst, o.bilateral_options);
    else
      (*depth)(r).convertTo(dst, CV_32F, 1e-3);
  }
  local.filter_ms = now_ms() - t0;
  t0 = now_ms();
  for (const auto& r : windows) {
    // Normals need a one-pixel-plus-stencil margin of depth around the window; the window edges
    // see the margin as holes and fall back to one-sided differences.
    cv::Mat3f dst = s->normals(r);
    compute_normals_roi(s->depth_m, frame.intrinsics, r, dst, o.normal_options);
    local.pixels_processed += static_cast<std::size_t>(r.area());
  }
  local.normals_ms = now_ms() - t0;
  if (stats) *stats = local;
  return s;
}

}  // namespace telex::local
