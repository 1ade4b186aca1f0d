// SPDX-License-Identifier: MIT
// Depth bilateral filter: padded float copy, precomputed disc taps, range LUT, AVX2 gather kernel.
#include "telex/common/bilateral.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define TELEX_HAVE_X86 1
#endif

namespace telex {
namespace {

// Neighbours with (difference / sigma)^2 above this (3 sigma, with float slack so the LUT and the
// computed weights keep the same integer-mm neighbours) do not vote.
constexpr float kCutoffU2 = 9.0f * (1.0f + 1e-6f);

struct Tap {
  int offset;  // element offset in the padded buffer
  float weight;
};

struct Plan {
  std::vector<Tap> taps;
  std::vector<float> lut;  // fixed sigma: weight per integer mm of difference; last entry 0
  float lut_last = 0.0f;   // index of that last entry, as float for the clamp
  bool per_pixel_sigma = false;
  float inv_sigma_mm = 0.0f;     // fixed sigma
  double noise_factor_mm = 0.0;  // per-pixel sigma = this * Nguyen sigma (m)
};

struct Padded {
  std::vector<float> data;  // depth in mm, 0 = hole or outside the image
  int stride = 0;
  int radius = 0;
  const float* row(int y) const {  // y in ROI coordinates, x = 0 at the ROI's left edge
    return data.data() + static_cast<std::size_t>(y + radius) * stride + radius;
  }
};

void validate(const cv::Mat1w& depth_mm, const BilateralOptions& o) {
  if (depth_mm.empty()) throw std::invalid_argument("bilateral_filter_depth: depth image is empty");
  if (o.radius_px < 1 || o.radius_px > 15)
    throw std::invalid_argument("bilateral_filter_depth: radius_px must be in 1..15, got " +
                                std::to_string(o.radius_px));
  if (!(o.sigma_space_px > 0.0))
    throw std::invalid_argument("bilateral_filter_depth: sigma_space_px must be > 0");
  if (!o.sigma_from_noise_model && !(o.sigma_depth_mm > 0.0 && o.sigma_depth_mm <= 10000.0))
    throw std::invalid_argument("bilateral_filter_depth: sigma_depth_mm must be in (0, 10000]");
  if (o.sigma_from_noise_model && !(o.noise_sigma_factor > 0.0 && o.noise_sigma_factor < 1000.0))
    throw std::invalid_argument("bilateral_filter_depth: noise_sigma_factor must be in (0, 1000)");
}

Plan make_plan(const BilateralOptions& o, int stride) {
  Plan p;
  const int r = o.radius_px;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const int d2 = dx * dx + dy * dy;
      if (d2 > r * r) continue;
      p.taps.push_back({dy * stride + dx, static_cast<float>(std::exp(
                                              -d2 / (2.0 * o.sigma_space_px * o.sigma_space_px)))});
    }
  p.per_pixel_sigma = o.sigma_from_noise_model;
  if (p.per_pixel_sigma) {
    p.noise_factor_mm = o.noise_sigma_factor * 1000.0;
  } else {
    p.inv_sigma_mm = static_cast<float>(1.0 / o.sigma_depth_mm);
    // Integer-mm differences index the LUT directly: exact weights, no per-tap scaling error.
    const int n = static_cast<int>(std::floor(3.0 * o.sigma_depth_mm));
    for (int i = 0; i <= n; ++i)
      p.lut.push_back(
          static_cast<float>(std::exp(-0.5 * i * i / (o.sigma_depth_mm * o.sigma_depth_mm))));
  }
  p.lut.push_back(0.0f);
  p.lut_last = static_cast<float>(p.lut.size() - 1);
  return p;
}

// Depth of `roi` grown by `radius` as float mm; zeros beyond the image make border taps holes.
// Rows carry 8 spare floats so vector loads past the last pixel stay inside the buffer.
Padded make_padded(const cv::Mat1w& depth_mm, const cv::Rect& roi, int radius) {
  Padded p;
  p.radius = radius;
  p.stride = roi.width + 2 * radius + 8;
  p.data.assign(static_cast<std::size_t>(p.stride) * (roi.height + 2 * radius), 0.0f);
  const cv::Rect grown(roi.x - radius, roi.y - radius, roi.width + 2 * radius,
                       roi.height + 2 * radius);
  const cv::Rect src = grown & cv::Rect(0, 0, depth_mm.cols, depth_mm.rows);
  for (int y = src.y; y < src.y + src.height; ++y) {
    const std::uint16_t* in = depth_mm[y] + src.x;
    float* out =
        p.data.data() + static_cast<std::size_t>(y - grown.y) * p.stride + (src.x - grown.x);
    for (int x = 0; x < src.width; ++x) out[x] = static_cast<float>(in[x]);
  }
  return p;
}

inline float pixel_inv_sigma(const Plan& plan, float c_mm) {
  return static_cast<float>(1.0 / (plan.noise_factor_mm * nguyen_axial_sigma_m(c_mm * 1e-3)));
}

// One output pixel; also the tail of each row of the vector kernel. Fixed sigma: range weights
// from the LUT indexed by the integer-mm difference; per-pixel sigma: computed.
inline float filter_pixel(const Plan& plan, const float* centre) {
  const float c = *centre;
  float sum_w = 0.0f, sum_wd = 0.0f;
  if (!plan.per_pixel_sigma) {
    for (const Tap& t : plan.taps) {
      const float n = centre[t.offset];
      if (n == 0.0f) continue;
      const float idx = std::min(std::fabs(n - c), plan.lut_last);
      const float w = t.weight * plan.lut[static_cast<int>(idx)];
      sum_w += w;
      sum_wd += w * n;
    }
  } else {
    const float inv_sigma = pixel_inv_sigma(plan, c);
    for (const Tap& t : plan.taps) {
      const float n = centre[t.offset];
      if (n == 0.0f) continue;
      const float u = std::fabs(n - c) * inv_sigma;
      if (u * u > kCutoffU2) continue;
      const float w = t.weight * std::exp(-0.5f * u * u);
      sum_w += w;
      sum_wd += w * n;
    }
  }
  return sum_wd / sum_w * 1e-3f;
}

void filter_rows_scalar(const Plan& plan, const Padded& pad, int x_begin, int width, int rows,
                        cv::Mat1f& out) {
  for (int y = 0; y < rows; ++y) {
    const float* row = pad.row(y);
    float* o = out[y];
    for (int x = x_begin; x < width; ++x) {
      const float c = row[x];
      o[x] = c == 0.0f ? 0.0f : filter_pixel(plan, row + x);
    }
  }
}

#ifdef TELEX_HAVE_X86
// exp(x) for x in [-4.6, 0]: x = n ln2 + r, |r| <= ln2/2, e^r by its degree-5 Taylor polynomial
// (relative error <= r^6/720 = 2.4e-6, far below what a depth weight needs), 2^n via the exponent.
// On the EPYC test box (d=5, desk frame, one thread) a gather from the range LUT took 3.75 ms CPU
// against 3.03 ms for a polynomial exp.
__attribute__((target("avx2,fma"))) inline __m256 exp_neg_avx2(__m256 x) {
  const __m256 log2e = _mm256_set1_ps(1.44269504088896341f);
  const __m256 c1 = _mm256_set1_ps(0.693359375f), c2 = _mm256_set1_ps(-2.12194440e-4f);
  const __m256 n =
      _mm256_round_ps(_mm256_mul_ps(x, log2e), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m256 r = _mm256_fnmadd_ps(n, c1, x);
  r = _mm256_fnmadd_ps(n, c2, r);
  __m256 p = _mm256_set1_ps(1.0f / 120.0f);
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f / 24.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(1.0f / 6.0f));
  p = _mm256_fmadd_ps(p, r, _mm256_set1_ps(0.5f));
  p = _mm256_fmadd_ps(p, _mm256_mul_ps(r, r), _mm256_add_ps(r, _mm256_set1_ps(1.0f)));
  const __m256i e =
      _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(p, _mm256_castsi256_ps(e));
}

// Eight output pixels starting at `centre` (c: their depths, c_valid: depth > 0).
__attribute__((target("avx2,fma"))) inline __m256 filter8_avx2(const Plan& plan,
                                                               const float* centre, __m256 c,
                                                               __m256 c_valid) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 cutoff = _mm256_set1_ps(kCutoffU2);
  __m256 inv_sigma;
  if (plan.per_pixel_sigma) {
    alignas(32) float buf[8];
    for (int i = 0; i < 8; ++i) buf[i] = centre[i] > 0.0f ? pixel_inv_sigma(plan, centre[i]) : 0.0f;
    inv_sigma = _mm256_load_ps(buf);
  } else {
    inv_sigma = _mm256_set1_ps(plan.inv_sigma_mm);
  }
  __m256 sum_w = zero, sum_wd = zero;
  for (const Tap& t : plan.taps) {
    const __m256 n = _mm256_loadu_ps(centre + t.offset);
    const __m256 u = _mm256_mul_ps(_mm256_and_ps(_mm256_sub_ps(n, c), abs_mask), inv_sigma);
    const __m256 u2 = _mm256_mul_ps(u, u);
    // Beyond 3 sigma and holes do not vote.
    const __m256 keep =
        _mm256_and_ps(_mm256_cmp_ps(u2, cutoff, _CMP_LE_OQ), _mm256_cmp_ps(n, zero, _CMP_GT_OQ));
    const __m256 range_w = exp_neg_avx2(_mm256_mul_ps(u2, _mm256_set1_ps(-0.5f)));
    const __m256 w = _mm256_and_ps(_mm256_mul_ps(range_w, _mm256_set1_ps(t.weight)), keep);
    sum_w = _mm256_add_ps(sum_w, w);
    sum_wd = _mm256_fmadd_ps(w, n, sum_wd);
  }
  // Hole centres may have sum_w 0 (0/0); the mask writes 0 there instead of NaN.
  const __m256 v = _mm256_mul_ps(_mm256_div_ps(sum_wd, sum_w), _mm256_set1_ps(1e-3f));
  return _mm256_and_ps(v, c_valid);
}

__attribute__((target("avx2,fma"))) void filter_rows_avx2(const Plan& plan, const Padded& pad,
                                                          int width, int rows, cv::Mat1f& out) {
  const __m256 zero = _mm256_setzero_ps();
  alignas(32) float tail[8];
  for (int y = 0; y < rows; ++y) {
    const float* row = pad.row(y);
    // Every pixel, the last partial block included, goes through the same lanes, so an ROI gives
    // bit-identical results to the full frame; the padded rows have room for the extra reads.
    for (int x = 0; x < width; x += 8) {
      float* o = x + 8 <= width ? out[y] + x : tail;
      const __m256 c = _mm256_loadu_ps(row + x);
      const __m256 c_valid = _mm256_cmp_ps(c, zero, _CMP_GT_OQ);
      // A run of holes has nothing to filter.
      _mm256_storeu_ps(
          o, _mm256_movemask_ps(c_valid) == 0 ? zero : filter8_avx2(plan, row + x, c, c_valid));
      if (o == tail) std::copy(tail, tail + (width - x), out[y] + x);
    }
  }
}

// Fixed sigma: the range weight of a pair of pixels is symmetric, so each unordered pair within
// the disc is weighed once and credited to both ends. Rows of p are processed top to bottom with
// a ring of r+1 accumulator rows; row y is final once p-row y is done. Blocks of 8 p-pixels start
// at image columns that are multiples of 8, so every pixel sees its contributions in the same
// order whatever the ROI: ROI results are bit-identical to the full frame.
__attribute__((target("avx2,fma"))) void filter_pairs_avx2(const BilateralOptions& o,
                                                           const cv::Mat1w& depth_mm,
                                                           const cv::Rect& roi, cv::Mat1f& out) {
  const int r = o.radius_px;
  struct Half {
    int dy, dx;
    float weight;
  };
  std::vector<Half> half;
  for (int dy = 0; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      if (dy == 0 && dx <= 0) continue;
      const int d2 = dx * dx + dy * dy;
      if (d2 > r * r) continue;
      half.push_back(
          {dy, dx,
           static_cast<float>(std::exp(-d2 / (2.0 * o.sigma_space_px * o.sigma_space_px)))});
    }
  // Columns in image coordinates: p from p0 (a multiple of 8) to p_end (rounded up to 8).
  const int p0 = static_cast<int>(std::floor((roi.x - r) / 8.0)) * 8;
  const int p_end = p0 + ((roi.x + roi.width + r - p0 + 7) / 8) * 8;
  const int bx0 = p0 - r;  // buffer column 0
  const int stride = p_end + r + 8 - bx0;
  const int by0 = roi.y - r;  // buffer row 0
  const int rows = roi.height + 2 * r;
  thread_local std::vector<float> z_store, acc_store;
  z_store.resize(static_cast<std::size_t>(stride) * rows);
  for (int by = 0; by < rows; ++by) {
    const int y = by0 + by;
    float* zr = z_store.data() + static_cast<std::size_t>(by) * stride;  // buffer column 0
    if (y < 0 || y >= depth_mm.rows) {
      std::fill(zr, zr + stride, 0.0f);
      continue;
    }
    // Zeros beyond the image make the outside holes; inside, 8 pixels per conversion.
    const int x_from = std::max(0, bx0), x_to = std::min(depth_mm.cols, bx0 + stride);
    std::fill(zr, zr + (x_from - bx0), 0.0f);
    std::fill(zr + (x_to - bx0), zr + stride, 0.0f);
    const std::uint16_t* in = depth_mm[y];
    float* out = zr - bx0;
    int x = x_from;
    for (; x + 8 <= x_to; x += 8)
      _mm256_storeu_ps(out + x, _mm256_cvtepi32_ps(_mm256_cvtepu16_epi32(
                                    _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + x)))));
    for (; x < x_to; ++x) out[x] = static_cast<float>(in[x]);
  }
  const auto z_row = [&](int y) {
    return z_store.data() + static_cast<std::size_t>(y - by0) * stride - bx0;
  };
  // Ring of r+1 rows, each sum_w then sum_wd.
  acc_store.assign(static_cast<std::size_t>(2 * stride) * (r + 1), 0.0f);
  const auto acc_row = [&](int y) {
    return acc_store.data() + static_cast<std::size_t>(2 * stride) * ((y - by0) % (r + 1)) - bx0;
  };
  const float k = static_cast<float>(-0.5 / (o.sigma_depth_mm * o.sigma_depth_mm));
  const __m256 kk = _mm256_set1_ps(k);
  // (3 sigma)^2 in mm^2, with the same float slack as the LUT path.
  const __m256 cutoff_d2 =
      _mm256_set1_ps(static_cast<float>(kCutoffU2 * o.sigma_depth_mm * o.sigma_depth_mm));
  const __m256 zero = _mm256_setzero_ps();
  thread_local std::vector<float> self_store;
  self_store.assign(static_cast<std::size_t>(2 * stride), 0.0f);
  float* self_w = self_store.data() - bx0;  // contributions to p from its own pairs
  float* self_wd = self_w + stride;
  for (int py = roi.y - r; py < roi.y + roi.height; ++py) {
    if (py > roi.y - r) {  // the slot of row py + r held row py - 1, already written out
      float* a = acc_row(py + r) + bx0;
      std::fill(a, a + 2 * stride, 0.0f);
    }
    const float* zp_row = z_row(py);
    for (int x = p0; x < p_end; x += 8) {  // the centre tap
      const __m256 zp = _mm256_loadu_ps(zp_row + x);
      const __m256 pv = _mm256_cmp_ps(zp, zero, _CMP_GT_OQ);
      _mm256_storeu_ps(self_w + x, _mm256_and_ps(pv, _mm256_set1_ps(1.0f)));
      _mm256_storeu_ps(self_wd + x, _mm256_and_ps(pv, zp));
    }
    // Offset-major: within one offset the blocks touch disjoint accumulator ranges, so no load
    // waits on a partially overlapping store; p-side and q-side sums live in separate rows.
    for (const Half& h : half) {
      const float* zq_row = z_row(py + h.dy);
      float* other_w = acc_row(py + h.dy) + h.dx;
      float* other_wd = other_w + stride;
      // ws * exp(e) = exp(e + ln ws): one fused multiply-add instead of two multiplies.
      const __m256 log_weight = _mm256_set1_ps(std::log(h.weight));
      for (int x = p0; x < p_end; x += 8) {
        const __m256 zp = _mm256_loadu_ps(zp_row + x);
        const __m256 pv = _mm256_cmp_ps(zp, zero, _CMP_GT_OQ);
        if (_mm256_movemask_ps(pv) == 0) continue;
        const __m256 zq = _mm256_loadu_ps(zq_row + x + h.dx);
        const __m256 d = _mm256_sub_ps(zq, zp);
        const __m256 d2 = _mm256_mul_ps(d, d);
        const __m256 keep = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(d2, cutoff_d2, _CMP_LE_OQ),
                                                        _mm256_cmp_ps(zq, zero, _CMP_GT_OQ)),
                                          pv);
        const __m256 w = _mm256_and_ps(exp_neg_avx2(_mm256_fmadd_ps(d2, kk, log_weight)), keep);
        _mm256_storeu_ps(self_w + x, _mm256_add_ps(_mm256_loadu_ps(self_w + x), w));
        _mm256_storeu_ps(self_wd + x, _mm256_fmadd_ps(w, zq, _mm256_loadu_ps(self_wd + x)));
        _mm256_storeu_ps(other_w + x, _mm256_add_ps(_mm256_loadu_ps(other_w + x), w));
        _mm256_storeu_ps(other_wd + x, _mm256_fmadd_ps(w, zp, _mm256_loadu_ps(other_wd + x)));
      }
    }
    if (py < roi.y) continue;
    // Row py has all its contributions now.
    const float* aw = acc_row(py);
    const float* awd = aw + stride;
    float* o_row = out[py - roi.y] - roi.x;
    for (int x = roi.x; x < roi.x + roi.width; ++x)
      o_row[x] = zp_row[x] > 0.0f ? (self_wd[x] + awd[x]) / (self_w[x] + aw[x]) * 1e-3f : 0.0f;
  }
}

bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return has;
}
#endif

void run(const cv::Mat1w& depth_mm, const cv::Rect& roi, cv::Mat1f& out,
         const BilateralOptions& o) {
  validate(depth_mm, o);
  if (roi.empty() || (roi & cv::Rect(0, 0, depth_mm.cols, depth_mm.rows)) != roi)
    throw std::invalid_argument("bilateral_filter_depth: ROI is empty or outside the image");
  const Padded pad = make_padded(depth_mm, roi, o.radius_px);
  const Plan plan = make_plan(o, pad.stride);
  out.create(roi.size());
#ifdef TELEX_HAVE_X86
  if (o.allow_simd && cpu_has_avx2()) {
    if (o.sigma_from_noise_model) {
      filter_rows_avx2(plan, pad, roi.width, roi.height, out);
    } else {
      filter_pairs_avx2(o, depth_mm, roi, out);
    }
    return;
  }
#endif
  filter_rows_scalar(plan, pad, 0, roi.width, roi.height, out);
}

}  // namespace

void bilateral_filter_depth(const cv::Mat1w& depth_mm, cv::Mat1f& depth_m_out,
                            const BilateralOptions& options) {
  run(depth_mm, cv::Rect(0, 0, depth_mm.cols, depth_mm.rows), depth_m_out, options);
}

cv::Mat1f bilateral_filter_depth(const cv::Mat1w& depth_mm, const BilateralOptions& options) {
  cv::Mat1f out;
  bilateral_filter_depth(depth_mm, out, options);
  return out;
}

void bilateral_filter_depth_roi(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                cv::Mat1f& depth_m_out, const BilateralOptions& options) {
  run(depth_mm, roi, depth_m_out, options);
}

}  // namespace telex
