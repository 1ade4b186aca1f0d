// SPDX-License-Identifier: MIT
// Normal maps from box-averaged central differences with per-pixel fallback near holes and edges.
#include "telex/common/normals.h"

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

void validate(const cv::Mat1f& depth_m, const Intrinsics& k, const NormalOptions& o) {
  if (depth_m.empty()) throw std::invalid_argument("compute_normals: depth image is empty");
  if (o.smooth_radius_px < 0 || o.smooth_radius_px > 7)
    throw std::invalid_argument("compute_normals: smooth_radius_px must be in 0..7, got " +
                                std::to_string(o.smooth_radius_px));
  if (!(o.discontinuity_ratio > 0.0))
    throw std::invalid_argument("compute_normals: discontinuity_ratio must be > 0");
  if (!(k.fx > 0.0 && k.fy > 0.0))
    throw std::invalid_argument("compute_normals: intrinsics need positive fx and fy");
}

// Depth of the ROI grown by `pad` pixels, 0 where missing, non-finite or outside the image, plus a
// flag per pixel (1.0f): hole, or a jump to its right or lower neighbour. Flags are floats so the
// window counts run in the same vector lanes as the depths (small integers are exact in float).
struct Grid {
  int pad = 0, stride = 0, rows = 0;
  // Reused per thread: a fresh 2.5 MB allocation per frame costs page faults on every call.
  std::vector<float>& z;
  std::vector<float>& bad;
  const float* z_row(int y) const { return z.data() + static_cast<std::size_t>(y + pad) * stride; }
  const float* bad_row(int y) const {
    return bad.data() + static_cast<std::size_t>(y + pad) * stride;
  }
};

inline bool jump(float a, float b, float ratio) {
  return std::fabs(a - b) > ratio * std::min(a, b);
}

// Scalar flag of one pixel; `right`/`below` are 0 when absent.
inline float bad_flag(float c, float right, float below, float ratio) {
  if (c == 0.0f) return 1.0f;
  if (right != 0.0f && jump(c, right, ratio)) return 1.0f;
  if (below != 0.0f && jump(c, below, ratio)) return 1.0f;
  return 0.0f;
}

// One row's inputs to wide_normals_avx2 (a stub without x86): wide-stencil normals of 8 pixels at
// a time into planar rows; `wide` marks the pixels it covered (the rest need the scalar
// fallback). Operation order matches the scalar code exactly.
struct WideRow {
  const float* z;
  const float* win_bad;
  const float* col_z;
  const float* d_rows;
  int k;
  float inv, fx, fy, u0, v_c;
  const float* z_up;
  const float* z_down;
  float ratio;
  cv::Vec3f* out;
};

#ifdef TELEX_HAVE_X86
__attribute__((target("avx2"))) int clean_avx2(const float* in, float* out, int n) {
  const __m256 zero = _mm256_setzero_ps(), big = _mm256_set1_ps(1e6f);
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256 v = _mm256_loadu_ps(in + x);
    const __m256 ok =
        _mm256_and_ps(_mm256_cmp_ps(v, zero, _CMP_GT_OQ), _mm256_cmp_ps(v, big, _CMP_LT_OQ));
    _mm256_storeu_ps(out + x, _mm256_and_ps(v, ok));
  }
  return x;
}

__attribute__((target("avx2"))) inline __m256 jump8(__m256 c, __m256 o, __m256 ratio) {
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 d = _mm256_and_ps(_mm256_sub_ps(c, o), abs_mask);
  const __m256 present = _mm256_cmp_ps(o, _mm256_setzero_ps(), _CMP_NEQ_OQ);
  return _mm256_and_ps(present,
                       _mm256_cmp_ps(d, _mm256_mul_ps(ratio, _mm256_min_ps(c, o)), _CMP_GT_OQ));
}

// Flags for x in [0, n) where x + 1 exists in the row and `below` is a full row (or null).
__attribute__((target("avx2"))) int flags_avx2(const float* z, const float* below, float* bad,
                                               int n, float ratio_f) {
  if (!below) return 0;
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f),
               ratio = _mm256_set1_ps(ratio_f);
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256 c = _mm256_loadu_ps(z + x);
    __m256 b = _mm256_cmp_ps(c, zero, _CMP_EQ_OQ);
    b = _mm256_or_ps(b, jump8(c, _mm256_loadu_ps(z + x + 1), ratio));
    b = _mm256_or_ps(b, jump8(c, _mm256_loadu_ps(below + x), ratio));
    _mm256_storeu_ps(bad + x, _mm256_and_ps(b, one));
  }
  return x;
}

// Per-row sums: col_bad += add - sub; win_bad = sum of col_bad over 2m+1 columns; col_z = sum of
// 2k+1 depth rows; d_rows = (z[y+k+1] + z[y+k]) - (z[y-k] + z[y-k-1]). Same summation order as the
// scalar code, so both give bit-identical results.
__attribute__((target("avx2"))) int col_update_avx2(float* col_bad, const float* add,
                                                    const float* sub, int n) {
  int x = 0;
  for (; x + 8 <= n; x += 8)
    _mm256_storeu_ps(col_bad + x, _mm256_add_ps(_mm256_loadu_ps(col_bad + x),
                                                _mm256_sub_ps(_mm256_loadu_ps(add + x),
                                                              _mm256_loadu_ps(sub + x))));
  return x;
}

__attribute__((target("avx2"))) int win_sum_avx2(const float* col, float* win, int m, int x_begin,
                                                 int x_end) {
  int x = x_begin;
  for (; x + 8 <= x_end; x += 8) {
    __m256 s = _mm256_loadu_ps(col + x - m);
    for (int i = -m + 1; i <= m; ++i) s = _mm256_add_ps(s, _mm256_loadu_ps(col + x + i));
    _mm256_storeu_ps(win + x, s);
  }
  return x;
}

__attribute__((target("avx2"))) int rows_sum_avx2(const float* const* rows, int count, float* out,
                                                  int n) {
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    __m256 s = _mm256_loadu_ps(rows[0] + x);
    for (int i = 1; i < count; ++i) s = _mm256_add_ps(s, _mm256_loadu_ps(rows[i] + x));
    _mm256_storeu_ps(out + x, s);
  }
  return x;
}

__attribute__((target("avx2"))) int diff_rows_avx2(const float* a, const float* b, const float* c,
                                                   const float* d, float* out, int n) {
  int x = 0;
  for (; x + 8 <= n; x += 8) {
    const __m256 p = _mm256_add_ps(_mm256_loadu_ps(a + x), _mm256_loadu_ps(b + x));
    const __m256 q = _mm256_add_ps(_mm256_loadu_ps(c + x), _mm256_loadu_ps(d + x));
    _mm256_storeu_ps(out + x, _mm256_sub_ps(p, q));
  }
  return x;
}

// Lanes where neighbour `o` exists and is on the same surface as `c`.
__attribute__((target("avx2"))) inline __m256 usable8(__m256 c, __m256 o, __m256 ratio) {
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 d = _mm256_and_ps(_mm256_sub_ps(c, o), abs_mask);
  const __m256 jumps = _mm256_cmp_ps(d, _mm256_mul_ps(ratio, _mm256_min_ps(c, o)), _CMP_GT_OQ);
  return _mm256_andnot_ps(jumps, _mm256_cmp_ps(o, _mm256_setzero_ps(), _CMP_NEQ_OQ));
}

// The small-stencil derivative of the scalar small_derivative() in lanes: central where both
// neighbours are usable, else one-sided, `ok` false where neither is.
__attribute__((target("avx2"))) inline __m256 small_derivative8(__m256 c, __m256 before,
                                                                __m256 after, __m256 ratio,
                                                                __m256& ok) {
  const __m256 ok_before = usable8(c, before, ratio), ok_after = usable8(c, after, ratio);
  ok = _mm256_or_ps(ok_before, ok_after);
  const __m256 one_sided =
      _mm256_blendv_ps(_mm256_sub_ps(c, before), _mm256_sub_ps(after, c), ok_after);
  const __m256 central = _mm256_mul_ps(_mm256_set1_ps(0.5f), _mm256_sub_ps(after, before));
  return _mm256_blendv_ps(one_sided, central, _mm256_and_ps(ok_before, ok_after));
}

// Normals of 8 pixels at a time: the wide stencil where its window is clean, else the small
// stencil, else the zero vector; the same operations in the same order as the scalar loop, so the
// results are bit-identical. Returns how many pixels it did (a multiple of 8).
__attribute__((target("avx2"))) int wide_normals_avx2(const WideRow& r, int xs, int w) {
  const __m256 zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
  const __m256 inv = _mm256_set1_ps(r.inv), fx = _mm256_set1_ps(r.fx), fy = _mm256_set1_ps(r.fy);
  const __m256 v_c = _mm256_set1_ps(r.v_c), ratio = _mm256_set1_ps(r.ratio);
  const __m256 iota = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  const int k = r.k;
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const int gx = xs + x;
    const __m256 zc = _mm256_loadu_ps(r.z + gx);
    const __m256 present = _mm256_cmp_ps(zc, zero, _CMP_NEQ_OQ);
    const __m256 wide =
        _mm256_and_ps(present, _mm256_cmp_ps(_mm256_loadu_ps(r.win_bad + gx), zero, _CMP_EQ_OQ));
    float* o = reinterpret_cast<float*>(r.out + x);
    if (_mm256_movemask_ps(present) == 0) {
      _mm256_storeu_ps(o, zero);
      _mm256_storeu_ps(o + 8, zero);
      _mm256_storeu_ps(o + 16, zero);
      continue;
    }
    const float* cz = r.col_z + gx;
    __m256 du = _mm256_mul_ps(
        _mm256_sub_ps(_mm256_add_ps(_mm256_loadu_ps(cz + k + 1), _mm256_loadu_ps(cz + k)),
                      _mm256_add_ps(_mm256_loadu_ps(cz - k), _mm256_loadu_ps(cz - k - 1))),
        inv);
    const float* dr = r.d_rows + gx;
    __m256 s = _mm256_loadu_ps(dr - k);
    for (int i = -k + 1; i <= k; ++i) s = _mm256_add_ps(s, _mm256_loadu_ps(dr + i));
    __m256 dv = _mm256_mul_ps(s, inv);
    __m256 ok = wide;
    if (_mm256_movemask_ps(wide) != _mm256_movemask_ps(present)) {
      __m256 ok_u, ok_v;
      const __m256 du_s = small_derivative8(zc, _mm256_loadu_ps(r.z + gx - 1),
                                            _mm256_loadu_ps(r.z + gx + 1), ratio, ok_u);
      const __m256 dv_s = small_derivative8(zc, _mm256_loadu_ps(r.z_up + gx),
                                            _mm256_loadu_ps(r.z_down + gx), ratio, ok_v);
      du = _mm256_blendv_ps(du_s, du, wide);
      dv = _mm256_blendv_ps(dv_s, dv, wide);
      ok = _mm256_or_ps(wide, _mm256_and_ps(present, _mm256_and_ps(ok_u, ok_v)));
    }
    // u_c is computed in float per lane exactly as the scalar (roi.x + x - cx) in float.
    const __m256 u_c = _mm256_add_ps(_mm256_set1_ps(r.u0 + static_cast<float>(x)), iota);
    const __m256 nx = _mm256_mul_ps(fx, du);
    const __m256 ny = _mm256_mul_ps(fy, dv);
    const __m256 nz = _mm256_sub_ps(
        zero, _mm256_add_ps(_mm256_add_ps(zc, _mm256_mul_ps(u_c, du)), _mm256_mul_ps(v_c, dv)));
    const __m256 len2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(nx, nx), _mm256_mul_ps(ny, ny)),
                                      _mm256_mul_ps(nz, nz));
    const __m256 inv_len = _mm256_div_ps(one, _mm256_sqrt_ps(len2));
    // Invalid lanes become +0 (the masks also clear any 0/0 of hole lanes).
    const __m256 a = _mm256_and_ps(_mm256_mul_ps(nx, inv_len), ok);
    const __m256 b = _mm256_and_ps(_mm256_mul_ps(ny, inv_len), ok);
    const __m256 c = _mm256_and_ps(_mm256_mul_ps(nz, inv_len), ok);
    // 3-way interleave of the planar results into x y z triples.
    const __m256 ab = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0));
    const __m256 bc = _mm256_shuffle_ps(b, c, _MM_SHUFFLE(3, 1, 3, 1));
    const __m256 ca = _mm256_shuffle_ps(c, a, _MM_SHUFFLE(3, 1, 2, 0));
    const __m256 r03 = _mm256_shuffle_ps(ab, ca, _MM_SHUFFLE(2, 0, 2, 0));
    const __m256 r14 = _mm256_shuffle_ps(bc, ab, _MM_SHUFFLE(3, 1, 2, 0));
    const __m256 r25 = _mm256_shuffle_ps(ca, bc, _MM_SHUFFLE(3, 1, 3, 1));
    _mm256_storeu_ps(o, _mm256_permute2f128_ps(r03, r14, 0x20));
    _mm256_storeu_ps(o + 8, _mm256_permute2f128_ps(r25, r03, 0x30));
    _mm256_storeu_ps(o + 16, _mm256_permute2f128_ps(r14, r25, 0x31));
  }
  return x;
}

bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}
#else
int wide_normals_avx2(const WideRow&, int, int) { return 0; }
int clean_avx2(const float*, float*, int) { return 0; }
int flags_avx2(const float*, const float*, float*, int, float) { return 0; }
int col_update_avx2(float*, const float*, const float*, int) { return 0; }
int win_sum_avx2(const float*, float*, int, int x_begin, int) { return x_begin; }
int rows_sum_avx2(const float* const*, int, float*, int) { return 0; }
int diff_rows_avx2(const float*, const float*, const float*, const float*, float*, int) {
  return 0;
}
bool cpu_has_avx2() { return false; }
#endif

Grid make_grid(const cv::Mat1f& depth_m, const cv::Rect& roi, int pad, float ratio, bool simd) {
  thread_local std::vector<float> z_storage, bad_storage;
  Grid g{pad, roi.width + 2 * pad, roi.height + 2 * pad, z_storage, bad_storage};
  g.z.resize(static_cast<std::size_t>(g.stride) * g.rows);
  g.bad.resize(g.z.size());
  const cv::Rect grown(roi.x - pad, roi.y - pad, g.stride, g.rows);
  const cv::Rect src = grown & cv::Rect(0, 0, depth_m.cols, depth_m.rows);
  for (int gy = 0; gy < g.rows; ++gy) {
    float* row = g.z.data() + static_cast<std::size_t>(gy) * g.stride;
    const int y = grown.y + gy;
    if (y < src.y || y >= src.y + src.height) {
      std::fill(row, row + g.stride, 0.0f);
      continue;
    }
    const int left = src.x - grown.x;
    std::fill(row, row + left, 0.0f);
    std::fill(row + left + src.width, row + g.stride, 0.0f);
    const float* in = depth_m[y] + src.x;
    float* out = row + left;
    int x = simd ? clean_avx2(in, out, src.width) : 0;
    for (; x < src.width; ++x) {
      const float v = in[x];
      out[x] = (v > 0.0f && v < 1e6f) ? v : 0.0f;  // NaN fails both comparisons
    }
  }
  for (int y = 0; y < g.rows; ++y) {
    const float* z = g.z.data() + static_cast<std::size_t>(y) * g.stride;
    const float* below = y + 1 < g.rows ? z + g.stride : nullptr;
    float* b = g.bad.data() + static_cast<std::size_t>(y) * g.stride;
    int x = simd ? flags_avx2(z, below, b, g.stride - 1, ratio) : 0;
    for (; x < g.stride; ++x)
      b[x] = bad_flag(z[x], x + 1 < g.stride ? z[x + 1] : 0.0f, below ? below[x] : 0.0f, ratio);
  }
  return g;
}

// Derivative along one axis from the immediate neighbours: central, else one-sided, else none.
inline bool small_derivative(float c, float before, float after, float ratio, float& d) {
  const bool ok_before = before != 0.0f && !jump(c, before, ratio);
  const bool ok_after = after != 0.0f && !jump(c, after, ratio);
  if (ok_before && ok_after) {
    d = 0.5f * (after - before);
  } else if (ok_after) {
    d = after - c;
  } else if (ok_before) {
    d = c - before;
  } else {
    return false;
  }
  return true;
}

void run(const cv::Mat1f& depth_m, const Intrinsics& intr, const cv::Rect& roi, cv::Mat3f& out,
         const NormalOptions& o) {
  validate(depth_m, intr, o);
  if (roi.empty() || (roi & cv::Rect(0, 0, depth_m.cols, depth_m.rows)) != roi)
    throw std::invalid_argument("compute_normals: ROI is empty or outside the image");
  const bool simd = o.allow_simd && cpu_has_avx2();
  const int k = o.smooth_radius_px;
  const int m = k + 1;  // half-size of the stencil whose cleanliness the wide estimate needs
  const float ratio = static_cast<float>(o.discontinuity_ratio);
  // One extra ring so the flags of the window's outer pixels see their real neighbours.
  const Grid g = make_grid(depth_m, roi, m + 1, ratio, simd);
  out.create(roi.size());

  const float fx = static_cast<float>(intr.fx), fy = static_cast<float>(intr.fy);
  const float inv = 1.0f / (2.0f * (2 * k + 1) * (2 * k + 1));
  const int w = roi.width;
  const int n = g.stride;
  const int xs = g.pad;                 // grid column of ROI x = 0
  std::vector<float> col_bad(n, 0.0f);  // flags summed over rows y-m..y+m
  std::vector<float> win_bad(n, 0.0f);  // col_bad summed over columns x-m..x+m
  std::vector<float> col_z(n, 0.0f);    // z summed over rows y-k..y+k
  std::vector<float> d_rows(n, 0.0f);   // z(y+k+1) + z(y+k) - z(y-k) - z(y-k-1)
  std::vector<const float*> rows(2 * k + 1);
  for (int dy = -m; dy <= m; ++dy) {
    const float* b = g.bad_row(dy);
    for (int x = 0; x < n; ++x) col_bad[x] += b[x];
  }
  for (int y = 0; y < roi.height; ++y) {
    if (y > 0) {
      const float* add = g.bad_row(y + m);
      const float* sub = g.bad_row(y - m - 1);
      int x = simd ? col_update_avx2(col_bad.data(), add, sub, n) : 0;
      for (; x < n; ++x) col_bad[x] = col_bad[x] + (add[x] - sub[x]);
    }
    {
      int x = simd ? win_sum_avx2(col_bad.data(), win_bad.data(), m, xs, xs + w) : xs;
      for (; x < xs + w; ++x) {
        float s = col_bad[x - m];
        for (int i = -m + 1; i <= m; ++i) s += col_bad[x + i];
        win_bad[x] = s;
      }
    }
    for (int dy = -k; dy <= k; ++dy) rows[dy + k] = g.z_row(y + dy);
    {
      int x = simd ? rows_sum_avx2(rows.data(), 2 * k + 1, col_z.data(), n) : 0;
      for (; x < n; ++x) {
        float s = rows[0][x];
        for (int i = 1; i <= 2 * k; ++i) s += rows[i][x];
        col_z[x] = s;
      }
    }
    {
      const float* a = g.z_row(y + k + 1);
      const float* b = g.z_row(y + k);
      const float* c = g.z_row(y - k);
      const float* d = g.z_row(y - k - 1);
      int x = simd ? diff_rows_avx2(a, b, c, d, d_rows.data(), n) : 0;
      for (; x < n; ++x) d_rows[x] = (a[x] + b[x]) - (c[x] + d[x]);
    }
    const float* z = g.z_row(y);
    const float* z_up = g.z_row(y - 1);
    const float* z_down = g.z_row(y + 1);
    const float v_c = static_cast<float>(roi.y + y - intr.cy);
    const float u0 = static_cast<float>(roi.x - intr.cx);
    cv::Vec3f* n_out = out[y];
    int vec_done = 0;
    if (simd) {
      const WideRow wr{z,   win_bad.data(), col_z.data(), d_rows.data(), k,    inv, fx, fy, u0,
                       v_c, z_up,           z_down,       ratio,         n_out};
      vec_done = wide_normals_avx2(wr, xs, w);
    }
    for (int x = vec_done; x < w; ++x) {
      const int gx = xs + x;
      const float zc = z[gx];
      float du = 0.0f, dv = 0.0f;
      bool ok = zc != 0.0f;
      if (ok && win_bad[gx] == 0.0f) {
        const float* cz = col_z.data() + gx;
        du = ((cz[k + 1] + cz[k]) - (cz[-k] + cz[-k - 1])) * inv;
        const float* dr = d_rows.data() + gx;
        float s = dr[-k];
        for (int i = -k + 1; i <= k; ++i) s += dr[i];
        dv = s * inv;
      } else if (ok) {
        ok = small_derivative(zc, z[gx - 1], z[gx + 1], ratio, du) &&
             small_derivative(zc, z_up[gx], z_down[gx], ratio, dv);
      }
      if (!ok) {
        n_out[x] = cv::Vec3f(0.0f, 0.0f, 0.0f);
        continue;
      }
      const float u_c = u0 + static_cast<float>(x);
      // Cross product of the back-projected tangents, scaled by fx fy / z; it faces the camera
      // for any visible surface (its dot product with the viewing ray is -z).
      const float nx = fx * du;
      const float ny = fy * dv;
      const float nz = -((zc + u_c * du) + v_c * dv);
      const float inv_len = 1.0f / std::sqrt((nx * nx + ny * ny) + nz * nz);
      n_out[x] = cv::Vec3f(nx * inv_len, ny * inv_len, nz * inv_len);
    }
  }
}

}  // namespace

void compute_normals(const cv::Mat1f& depth_m, const Intrinsics& intrinsics, cv::Mat3f& normals_out,
                     const NormalOptions& options) {
  run(depth_m, intrinsics, cv::Rect(0, 0, depth_m.cols, depth_m.rows), normals_out, options);
}

cv::Mat3f compute_normals(const cv::Mat1f& depth_m, const Intrinsics& intrinsics,
                          const NormalOptions& options) {
  cv::Mat3f out;
  compute_normals(depth_m, intrinsics, out, options);
  return out;
}

void compute_normals_roi(const cv::Mat1f& depth_m, const Intrinsics& intrinsics,
                         const cv::Rect& roi, cv::Mat3f& normals_out,
                         const NormalOptions& options) {
  run(depth_m, intrinsics, roi, normals_out, options);
}

}  // namespace telex
