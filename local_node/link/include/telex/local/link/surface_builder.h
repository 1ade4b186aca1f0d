// SPDX-License-Identifier: MIT
// Turns an assembled depth frame into the haptic loop's surface snapshot: bilateral smoothing and
// normals, over the whole frame or only in windows around the fingertips.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "telex/common/bilateral.h"
#include "telex/common/hole_fill.h"
#include "telex/common/normals.h"
#include "telex/common/stage_clock.h"
#include "telex/haptics/haptic_surface.h"
#include "telex/local/inputs/tracker.h"
#include "telex/local/link/frame_assembler.h"

namespace telex::local {

// The defaults are the bench's Pareto point of lowest force error (issue 16, docs/BENCHMARKS.md
// "Defaults"): radius 6 in fingertip windows, 4.07 % force error for 0.25 ms per 640x480 frame,
// against 9.24 % at radius 2 over the whole frame for 2.98 ms.
struct SurfaceOptions {
  bool bilateral = true;
  BilateralOptions bilateral_options{.radius_px = 6};
  NormalOptions normal_options{};
  // Region of interest: filter and build normals only near the fingertips. Elsewhere the snapshot
  // holds no depth (holes) and no normals: a fingertip there cannot touch anything before the
  // next frame. `telex-local --full-frame` turns it off.
  bool roi = true;
  // Station-side hole fill (issue 16's study of where to fill): the remote's spatial fill
  // (fill_holes_mode, with these options) run here on the depth as it arrived, in the windows
  // widened by the bilateral radius (bit-identical there to a full-frame fill) or on the whole
  // frame. On by default: the remote sends its depth unfilled (same force error, 18 % fewer
  // bytes on the real desk frames, 3.5 ms less remote work, 0.06 ms more here).
  bool fill_here = true;
  HoleFillOptions fill_options{};
  double roi_radius_m = 0.04;    // around each fingertip, at its depth
  double roi_lookahead_s = 0.1;  // plus the distance the fingertip may travel in this time
  int roi_min_half_px = 16;
  double roi_max_distance_m = 0.25;  // fingertips farther than this from the surface need nothing
  StageClock clock_ms = steady_clock_ms;  // SurfaceBuildStats' times (the bench: thread_cpu_ms)
};

// Windows (in pixels, clipped to the image) that the fingertips may touch before the next frame.
// Empty when no tracked fingertip is within roi_max_distance_m of the surface.
std::vector<cv::Rect> fingertip_windows(const HandState& hand, const cv::Mat1w& depth_mm,
                                        const Intrinsics& k, const SurfaceOptions& options);

struct SurfaceBuildStats {
  double snapshot_ms = 0;  // getting the snapshot's buffers: allocation, or recycling and clearing
  double fill_ms = 0;      // SurfaceOptions::fill_here
  double filter_ms = 0;
  double normals_ms = 0;
  std::size_t pixels_processed = 0;  // pixels filtered (== pixels with normals computed)
};

// A snapshot with its own calloc'd buffers (the kernel hands out zero pages lazily, so a fresh one
// only pays for the pages written), which a SurfacePool recycles. depth_m and normals view those
// buffers without an OpenCV reference count: a copied Mat header is valid only while the snapshot
// itself is held (clone() to keep pixels longer).
struct PooledSurface : Surface {
  explicit PooledSurface(cv::Size size);
  cv::Size size() const { return depth_m.size(); }
  // Where the current or last use may have left non-zero pixels: the writer records them.
  std::vector<cv::Rect> written;
  bool written_all = false;
  // Makes depth_m / normals view the own buffers again. With `zero`, clears what `written` marks
  // (all of it with written_all) so every pixel is 0; without, marks the whole frame as written
  // (the caller is to write every pixel).
  void recycle(bool zero);

 private:
  struct Free {
    void operator()(void* p) const;
  };
  std::unique_ptr<void, Free> depth_buf_, normal_buf_;
};

// Recycles snapshots, so a frame pays neither for allocating two full-frame buffers (~4.9 MB at
// 640x480) nor for zeroing them: a region-of-interest snapshot taken from the pool only clears the
// windows its previous use wrote. Owned and used by one thread (the surface thread). A pooled
// snapshot is reused only once the pool holds its last reference (shared_ptr use count 1, read
// with acquire ordering), so a snapshot the haptic loop, the triple buffer or anyone else still
// holds is never touched; and since the pool keeps one reference to each, the last release on
// another thread never frees memory. Do not make weak_ptrs to pooled snapshots (a weak_ptr could
// revive one the pool has judged free). When every pooled snapshot is in use and the pool is full,
// build_surface allocates an unpooled one.
class SurfacePool {
 public:
  explicit SurfacePool(std::size_t capacity = 16);
  ~SurfacePool();
  SurfacePool(const SurfacePool&) = delete;
  SurfacePool& operator=(const SurfacePool&) = delete;

  std::size_t capacity() const { return capacity_; }
  std::size_t pooled() const { return entries_.size(); }    // snapshots the pool owns
  std::size_t allocations() const { return allocations_; }  // snapshots allocated (incl. unpooled)
  std::size_t recycled() const { return recycled_; }        // snapshots handed out again

  // A snapshot of `size` that nobody else references. With `zeroed`, every depth and normal is 0
  // (a recycled one has the windows its previous use wrote cleared; a whole-frame one is cleared
  // in full); without, its pixels are unspecified and the caller must write all of them.
  std::shared_ptr<PooledSurface> acquire(cv::Size size, bool zeroed);
  // Fills the pool to capacity with snapshots of `size` whose pages are resident (written once),
  // so the first frames do not pay for page faults: the station calls it before its first frame.
  void warm(cv::Size size);

 private:
  std::size_t capacity_;
  std::vector<std::shared_ptr<PooledSurface>> entries_;
  std::size_t allocations_ = 0, recycled_ = 0;
};

// Builds the snapshot. With options.roi, only `windows` are filtered and get normals; elsewhere
// depth and normals are 0. With a pool, the snapshot's buffers are recycled (see SurfacePool);
// the result is the same with or without one.
std::shared_ptr<Surface> build_surface(const AssembledFrame& frame, const SurfaceOptions& options,
                                       std::span<const cv::Rect> windows,
                                       SurfaceBuildStats* stats = nullptr,
                                       SurfacePool* pool = nullptr);

}  // namespace telex::local
