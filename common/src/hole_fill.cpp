// SPDX-License-Identifier: MIT
// Windowed-mode hole filling: visits only holes, one small key/count table per hole.
#include "telex/common/hole_fill.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace telex {
namespace {

constexpr int kMaxWindow = 15;
constexpr int kMaxNeighbours = kMaxWindow * kMaxWindow;

void validate(const cv::Mat1w& depth_mm, const HoleFillOptions& o) {
  if (depth_mm.empty()) throw std::invalid_argument("fill_holes_mode: depth image is empty");
  if (o.window_px < 3 || o.window_px > kMaxWindow || o.window_px % 2 == 0)
    throw std::invalid_argument("fill_holes_mode: window_px must be odd in 3..15, got " +
                                std::to_string(o.window_px));
  if (o.bin_mm < 1 || o.bin_mm > 65535)
    throw std::invalid_argument("fill_holes_mode: bin_mm must be in 1..65535, got " +
                                std::to_string(o.bin_mm));
  if (o.max_passes < 0 || o.max_passes > 255)
    throw std::invalid_argument("fill_holes_mode: max_passes must be in 0..255, got " +
                                std::to_string(o.max_passes));
  if (o.min_valid < 1 || o.min_valid >= o.window_px * o.window_px)
    throw std::invalid_argument("fill_holes_mode: min_valid must be in 1..window_px^2-1, got " +
                                std::to_string(o.min_valid));
}

struct Fill {
  std::int32_t x, y;
  std::uint16_t value;
};

// Mode of the window around (x, y) in `img`; 0 when fewer than min_valid valid neighbours.
// Bins are v * mul >> 16 with mul ~ 65536 / bin_mm: a multiply instead of a divide per sample.
// R > 0 fixes the radius at compile time (unrolled rows); R == 0 reads it from `radius`.
template <int R>
inline std::uint16_t window_mode(const cv::Mat1w& img, int x, int y, int radius, std::uint32_t mul,
                                 int min_valid) {
  if constexpr (R > 0) radius = R;
  const int y0 = std::max(0, y - radius), y1 = std::min(img.rows - 1, y + radius);
  const int x0 = std::max(0, x - radius), x1 = std::min(img.cols - 1, x + radius);
  // Holes deep inside a hole region are the common case in a big gap: reject them with one OR
  // over the window before any binning. For radius 2 away from the border that is two loads per
  // row (four pixels as one 64-bit word plus the fifth).
  std::uint64_t any = 0;
  if (R == 2 && x1 - x0 == 4 && y1 - y0 == 4) {
    for (int yy = y0; yy <= y1; ++yy) {
      const std::uint16_t* row = img[yy] + x0;
      std::uint64_t q;
      std::memcpy(&q, row, sizeof q);
      any |= q | row[4];
    }
  } else {
    for (int yy = y0; yy <= y1; ++yy) {
      const std::uint16_t* row = img[yy];
      for (int xx = x0; xx <= x1; ++xx) any |= row[xx];
    }
  }
  if (any == 0) return 0;
  std::array<std::uint32_t, kMaxNeighbours> key;
  std::array<std::uint32_t, kMaxNeighbours> count;
  std::array<std::uint32_t, kMaxNeighbours> sum;
  key[0] = count[0] = sum[0] = 0;  // keeps -Wmaybe-uninitialized quiet; total guards the use
  int distinct = 0;
  int last = 0;
  int total = 0;
  // Valid neighbours first, compacted without a branch per pixel (holes and values interleave
  // unpredictably at a hole's rim), then binned.
  std::array<std::uint16_t, kMaxNeighbours + 1> vals;
  for (int yy = y0; yy <= y1; ++yy) {
    const std::uint16_t* row = img[yy];
    for (int xx = x0; xx <= x1; ++xx) {
      const std::uint16_t v = row[xx];
      vals[total] = v;
      total += v != 0;
    }
  }
  for (int i = 0; i < total; ++i) {
    {
      const std::uint32_t v = vals[i];
      const std::uint32_t k = (v * mul) >> 16;
      // Neighbours mostly share the previous sample's bin: try it before searching.
      if (key[last] != k || distinct == 0) {
        int j = 0;
        while (j < distinct && key[j] != k) ++j;
        if (j == distinct) {
          key[j] = k;
          count[j] = 0;
          sum[j] = 0;
          ++distinct;
        }
        last = j;
      }
      ++count[last];
      sum[last] += v;
    }
  }
  if (total < min_valid) return 0;
  int best = 0;
  for (int j = 1; j < distinct; ++j) {
    // Ties go to the nearer surface: an occluder's depth is safer than the background's for a
    // fingertip that must not sink into an object.
    if (count[j] > count[best] || (count[j] == count[best] && key[j] < key[best])) best = j;
  }
  return static_cast<std::uint16_t>((sum[best] + count[best] / 2) / count[best]);
}

// Writes fills for the candidates that have enough valid neighbours; returns how many.
// `fills` has room for all candidates.
template <int R>
std::size_t evaluate(const cv::Mat1w& work, const Fill* candidates, std::size_t n_candidates,
                     int radius, std::uint32_t mul, int min_valid, Fill* fills) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < n_candidates; ++i) {
    const Fill& h = candidates[i];
    const std::uint16_t v = window_mode<R>(work, h.x, h.y, radius, mul, min_valid);
    fills[n] = {h.x, h.y, v};
    n += v != 0;
  }
  return n;
}

// Appends the hole pixels of `region` to `holes`, skipping runs of valid pixels four at a time.
void collect_holes(const cv::Mat1w& img, const cv::Rect& region, std::vector<Fill>& holes) {
  constexpr std::uint64_t kLow = 0x0001000100010001ULL;
  constexpr std::uint64_t kHigh = 0x8000800080008000ULL;
  for (int y = region.y; y < region.y + region.height; ++y) {
    const std::uint16_t* row = img[y];
    int x = region.x;
    const int x_end = region.x + region.width;
    for (; x + 4 <= x_end; x += 4) {
      std::uint64_t q;
      std::memcpy(&q, row + x, sizeof q);
      // Classic has-zero-lane test: no 16-bit lane is zero -> nothing to do in these 4 pixels.
      if (((q - kLow) & ~q & kHigh) == 0) continue;
      for (int i = 0; i < 4; ++i)
        if (row[x + i] == 0) holes.push_back({x + i, y, 0});
    }
    for (; x < x_end; ++x)
      if (row[x] == 0) holes.push_back({x, y, 0});
  }
}

// Scratch lists reused per thread; they only grow. Fresh multi-100 kB allocations would fault
// pages on every frame.
struct Scratch {
  std::vector<Fill> candidates, fills, next;
  std::vector<std::uint8_t> stamp;  // pass a hole was last queued for (region-relative)
  static void ensure(std::vector<Fill>& v, std::size_t n) {
    if (v.size() < n) v.resize(n);
  }
};

// Fills holes of `region` in `work` (a copy of the input). Returns {fills inside roi, passes}.
std::pair<std::size_t, int> fill_region(cv::Mat1w& work, const cv::Rect& region,
                                        const cv::Rect& roi, const HoleFillOptions& o,
                                        std::size_t& holes_in_region) {
  const int radius = o.window_px / 2;
  const std::uint32_t mul = static_cast<std::uint32_t>((65536 + o.bin_mm / 2) / o.bin_mm);
  thread_local Scratch s;
  thread_local std::vector<Fill> hole_list;
  hole_list.clear();
  collect_holes(work, region, hole_list);
  const std::size_t total = hole_list.size();
  holes_in_region = total;
  Scratch::ensure(s.candidates, total + 1);
  Scratch::ensure(s.fills, total + 1);
  Scratch::ensure(s.next, total + 1);
  std::copy(hole_list.begin(), hole_list.end(), s.candidates.begin());
  std::size_t n_candidates = total;
  bool stamp_ready = false;
  std::size_t filled_in_roi = 0;
  int passes = 0;
  for (int pass = 1; pass <= o.max_passes && n_candidates > 0; ++pass) {
    std::size_t n_fills = 0;
    const Fill* cand = s.candidates.data();
    Fill* fills = s.fills.data();
    switch (radius) {
      case 1:
        n_fills = evaluate<1>(work, cand, n_candidates, radius, mul, o.min_valid, fills);
        break;
      case 2:
        n_fills = evaluate<2>(work, cand, n_candidates, radius, mul, o.min_valid, fills);
        break;
      case 3:
        n_fills = evaluate<3>(work, cand, n_candidates, radius, mul, o.min_valid, fills);
        break;
      default:
        n_fills = evaluate<0>(work, cand, n_candidates, radius, mul, o.min_valid, fills);
        break;
    }
    if (n_fills == 0) break;
    ++passes;
    // Writes are deferred to the end of the pass so every decision saw the same image.
    for (std::size_t i = 0; i < n_fills; ++i) {
      const Fill& f = fills[i];
      work(f.y, f.x) = f.value;
      filled_in_roi += roi.contains({f.x, f.y});
    }
    if (pass == o.max_passes) break;
    // Only holes near a fresh fill can have changed windows: queue exactly those.
    if (!stamp_ready) {
      s.stamp.assign(static_cast<std::size_t>(region.area()), 0);
      stamp_ready = true;
    }
    // Locals and __restrict let the compiler keep the loop state in registers (the stores into
    // `next` could otherwise alias everything).
    Fill* __restrict next = s.next.data();
    std::uint8_t* __restrict stamp = s.stamp.data();
    const std::uint8_t pass8 = static_cast<std::uint8_t>(pass);
    const int rx0 = region.x, ry0 = region.y, rx1 = region.x + region.width - 1,
              ry1 = region.y + region.height - 1, rw = region.width;
    std::size_t n_next = 0;
    for (std::size_t i = 0; i < n_fills; ++i) {
      const int fx = fills[i].x, fy = fills[i].y;
      const int y0 = std::max(ry0, fy - radius), y1 = std::min(ry1, fy + radius);
      const int x0 = std::max(rx0, fx - radius), x1 = std::min(rx1, fx + radius);
      for (int yy = y0; yy <= y1; ++yy) {
        const std::uint16_t* __restrict row = work[yy];
        std::uint8_t* __restrict st = stamp + static_cast<std::ptrdiff_t>(yy - ry0) * rw - rx0;
        for (int xx = x0; xx <= x1; ++xx) {
          if (row[xx] != 0 || st[xx] == pass8) continue;
          st[xx] = pass8;
          next[n_next++] = {xx, yy, 0};
        }
      }
    }
    std::swap(s.candidates, s.next);
    n_candidates = n_next;
  }
  return {filled_in_roi, passes};
}

std::size_t count_zero(const cv::Mat1w& m) {
  return m.total() - static_cast<std::size_t>(cv::countNonZero(m));
}

void check_roi(const cv::Mat1w& depth_mm, const cv::Rect& roi) {
  const cv::Rect image(0, 0, depth_mm.cols, depth_mm.rows);
  if (roi.empty() || (roi & image) != roi)
    throw std::invalid_argument(
        "fill_holes_mode: ROI " + std::to_string(roi.width) + "x" + std::to_string(roi.height) +
        "+" + std::to_string(roi.x) + "+" + std::to_string(roi.y) + " is empty or outside the " +
        std::to_string(image.width) + "x" + std::to_string(image.height) + " image");
}

HoleFillResult run(const cv::Mat1w& depth_mm, cv::Mat1w& out, const cv::Rect& roi,
                   const HoleFillOptions& o) {
  validate(depth_mm, o);
  const cv::Rect image(0, 0, depth_mm.cols, depth_mm.rows);
  check_roi(depth_mm, roi);
  depth_mm.copyTo(out);
  HoleFillResult r;
  const int margin = (o.window_px / 2) * std::max(0, o.max_passes - 1);
  const cv::Rect region =
      cv::Rect(roi.x - margin, roi.y - margin, roi.width + 2 * margin, roi.height + 2 * margin) &
      image;
  std::size_t holes_in_region = 0;
  auto [filled, passes] = fill_region(out, region, roi, o, holes_in_region);
  r.holes_in = region == roi ? holes_in_region : count_zero(depth_mm(roi));
  r.holes_out = r.holes_in - filled;
  r.passes_run = passes;
  if (region != roi) {
    // The margin was processed only so the ROI sees the same earlier fills as a full frame.
    cv::Mat1w roi_result = out(roi).clone();
    depth_mm.copyTo(out);
    roi_result.copyTo(out(roi));
  }
  return r;
}

}  // namespace

HoleFillResult fill_holes_mode(const cv::Mat1w& depth_mm, const HoleFillOptions& options) {
  HoleFillResult r;
  cv::Mat1w out;
  r = fill_holes_mode_into(depth_mm, out, options);
  r.depth_mm = out;
  return r;
}

HoleFillResult fill_holes_mode_into(const cv::Mat1w& depth_mm, cv::Mat1w& out_mm,
                                    const HoleFillOptions& options) {
  return run(depth_mm, out_mm, cv::Rect(0, 0, depth_mm.cols, depth_mm.rows), options);
}

HoleFillResult fill_holes_mode_roi(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                   const HoleFillOptions& options) {
  HoleFillResult r;
  cv::Mat1w out;
  r = run(depth_mm, out, roi, options);
  r.depth_mm = out;
  return r;
}

HoleFillResult fill_holes_mode_roi_into(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                        cv::Mat1w& out_mm, const HoleFillOptions& options) {
  validate(depth_mm, options);
  check_roi(depth_mm, roi);
  out_mm.create(depth_mm.size());
  const cv::Rect image(0, 0, depth_mm.cols, depth_mm.rows);
  const int radius = options.window_px / 2;
  const int margin = radius * std::max(0, options.max_passes - 1);
  const auto grow = [&](const cv::Rect& r, int m) {
    return cv::Rect(r.x - m, r.y - m, r.width + 2 * m, r.height + 2 * m) & image;
  };
  // The margin is filled too (as in fill_holes_mode_roi) so the ROI sees the same earlier fills as
  // a full frame; windows around the margin's holes read one radius further.
  const cv::Rect region = grow(roi, margin);
  const cv::Rect readable = grow(region, radius);
  thread_local cv::Mat1w work;
  work.create(depth_mm.size());
  depth_mm(readable).copyTo(work(readable));
  std::size_t holes_in_region = 0;
  auto [filled, passes] = fill_region(work, region, roi, options, holes_in_region);
  HoleFillResult r;
  r.holes_in = count_zero(depth_mm(roi));
  r.holes_out = r.holes_in - filled;
  r.passes_run = passes;
  work(roi).copyTo(out_mm(roi));
  return r;
}

cv::Rect widen_roi(const cv::Rect& roi, cv::Size image, const RoiWidening& widening) {
  if (widening.margin_px < 0)
    throw std::invalid_argument("widen_roi: margin must be >= 0 px, got " +
                                std::to_string(widening.margin_px));
  if (widening.align_px.width < 1 || widening.align_px.height < 1)
    throw std::invalid_argument("widen_roi: alignment must be >= 1x1 px");
  const cv::Rect whole(cv::Point(0, 0), image);
  const cv::Rect r = roi & whole;
  if (r.empty()) return {};
  const int m = widening.margin_px;
  const int ax = widening.align_px.width, ay = widening.align_px.height;
  // Floor and ceiling to the grid (coordinates may be negative after the margin).
  const auto floor_to = [](int v, int a) { return (v >= 0 ? v : v - a + 1) / a * a; };
  const auto ceil_to = [&](int v, int a) { return floor_to(v + a - 1, a); };
  const int x0 = floor_to(r.x - m, ax), y0 = floor_to(r.y - m, ay);
  const int x1 = ceil_to(r.x + r.width + m, ax), y1 = ceil_to(r.y + r.height + m, ay);
  return cv::Rect(x0, y0, x1 - x0, y1 - y0) & whole;
}

void fill_holes_mode_rois_into(const cv::Mat1w& depth_mm, std::span<const cv::Rect> rois,
                               const RoiWidening& widening, cv::Mat1w& out_mm,
                               const HoleFillOptions& options) {
  out_mm.create(depth_mm.size());
  for (const cv::Rect& roi : rois) {
    const cv::Rect wide = widen_roi(roi, depth_mm.size(), widening);
    if (!wide.empty()) fill_holes_mode_roi_into(depth_mm, wide, out_mm, options);
  }
}

}  // namespace telex
