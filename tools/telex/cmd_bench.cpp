// SPDX-License-Identifier: MIT
// `telex bench`: error against run time of the depth-to-force chain over a grid of configurations.
#include <time.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_plot.h"
#include "command.h"
#include "telex/common/bilateral.h"
#include "telex/common/depth_io.h"
#include "telex/common/haptic_model.h"
#include "telex/common/haptic_surface.h"
#include "telex/common/hole_fill.h"
#include "telex/common/normals.h"
#include "telex/common/synthetic.h"
#include "telex/common/temporal_fill.h"
#include "telex/local/surface_builder.h"
#include "telex/proto/depth_codec.h"

namespace telex::tool {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kFrameRateHz = 30.0;

// Thread CPU time: the machine is shared by several builds, and wall-clock medians would mostly
// measure the other processes' share of the cores.
double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

double mean_finite(const std::vector<double>& v) {
  double sum = 0.0;
  std::size_t n = 0;
  for (double x : v)
    if (std::isfinite(x)) {
      sum += x;
      ++n;
    }
  return n ? sum / static_cast<double>(n) : kNaN;
}

// ---- configurations ----------------------------------------------------------------------------

enum class NormalMethod { Smoothed, Plain };

struct Config {
  std::string name;
  std::string group;  // the factor this configuration varies from the default
  int width = 640, height = 480;
  bool temporal = true;
  TemporalFillOptions temporal_options{};
  bool fill = true;
  HoleFillOptions fill_options{};
  bool bilateral = true;
  BilateralOptions bilateral_options{};
  NormalMethod normal_method = NormalMethod::Smoothed;
  NormalOptions normal_options{};
  proto::Codec codec = proto::Codec::Zip;
  int zip_level = proto::kDefaultZipLevel;
  bool roi = false;
};

const std::vector<std::string> kGroups = {"default", "resolution", "fill", "temporal", "bilateral",
                                          "normals", "codec",      "roi",  "combo"};

int group_index(const std::string& g) {
  const auto it = std::find(kGroups.begin(), kGroups.end(), g);
  return static_cast<int>(it - kGroups.begin());
}

// One factor at a time around the default (the library defaults at 640x480), plus a few
// combinations: a full Cartesian grid would be thousands of chains for little extra insight.
std::vector<Config> make_grid(bool quick) {
  std::vector<Config> out;
  const Config base{.name = "default", .group = "default"};
  auto add = [&](const std::string& group, const std::string& name, auto mutate, bool in_quick) {
    if (quick && !in_quick) return;
    Config c = base;
    c.group = group;
    c.name = name;
    mutate(c);
    out.push_back(c);
  };
  add(
      "default", "default", [](Config&) {}, true);
  add(
      "resolution", "res160", [](Config& c) { c.width = 160, c.height = 120; }, true);
  add(
      "resolution", "res320", [](Config& c) { c.width = 320, c.height = 240; }, false);
  add(
      "fill", "fill_off", [](Config& c) { c.fill = false; }, true);
  for (int w : {3, 7, 9})
    add(
        "fill", "fill_w" + std::to_string(w), [w](Config& c) { c.fill_options.window_px = w; },
        w == 9);
  for (int b : {5, 10, 40})
    add(
        "fill", "fill_bin" + std::to_string(b), [b](Config& c) { c.fill_options.bin_mm = b; },
        false);
  add(
      "temporal", "temporal_off", [](Config& c) { c.temporal = false; }, true);
  add(
      "bilateral", "bil_off", [](Config& c) { c.bilateral = false; }, true);
  for (int r : {1, 3, 6})
    add(
        "bilateral", "bil_r" + std::to_string(r),
        [r](Config& c) { c.bilateral_options.radius_px = r; }, r == 6);
  for (double sd : {10.0, 60.0})
    add(
        "bilateral", "bil_sd" + std::to_string(static_cast<int>(sd)),
        [sd](Config& c) { c.bilateral_options.sigma_depth_mm = sd; }, false);
  add(
      "bilateral", "bil_ss1.5", [](Config& c) { c.bilateral_options.sigma_space_px = 1.5; }, false);
  add(
      "bilateral", "bil_noise3",
      [](Config& c) { c.bilateral_options.sigma_from_noise_model = true; }, false);
  for (int k : {0, 1})
    add(
        "normals", "n_smooth" + std::to_string(k),
        [k](Config& c) { c.normal_options.smooth_radius_px = k; }, k == 0);
  add(
      "normals", "n_plain", [](Config& c) { c.normal_method = NormalMethod::Plain; }, true);
  for (int lv : {1, 6, 9})
    add(
        "codec", "zip" + std::to_string(lv), [lv](Config& c) { c.zip_level = lv; }, lv == 6);
  add(
      "codec", "fast", [](Config& c) { c.codec = proto::Codec::Fast; }, true);
  add(
      "codec", "raw", [](Config& c) { c.codec = proto::Codec::Raw; }, true);
  add(
      "roi", "roi", [](Config& c) { c.roi = true; }, true);
  add(
      "roi", "roi320", [](Config& c) { c.roi = true, c.width = 320, c.height = 240; }, false);
  add(
      "roi", "roi160", [](Config& c) { c.roi = true, c.width = 160, c.height = 120; }, true);
  add(
      "combo", "cheap320",
      [](Config& c) {
        c.width = 320, c.height = 240, c.bilateral = false, c.codec = proto::Codec::Fast;
        c.normal_options.smooth_radius_px = 1;
      },
      false);
  add(
      "combo", "kinfu_r6_roi", [](Config& c) { c.bilateral_options.radius_px = 6, c.roi = true; },
      false);
  add(
      "combo", "smooth1_r1",
      [](Config& c) { c.bilateral_options.radius_px = 1, c.normal_options.smooth_radius_px = 1; },
      false);
  return out;
}

// ---- metrics -----------------------------------------------------------------------------------

enum Metric {
  kDepthRmse,
  kFillRmse,
  kFillRate,
  kRangeOk,
  kNormalMean,
  kNormalP95,
  kForceErr,
  kBytes,
  kTemporalMs,
  kFillMs,
  kEncodeMs,
  kDecodeMs,
  kFilterMs,
  kNormalsMs,
  kSurfaceMs,
  kTotalMs,
  kPixels,
  kMetricCount
};
// Errors are averaged over frames, scenes and seeds; costs are medians.
constexpr std::array<const char*, kMetricCount> kMetricNames = {
    "depth_rmse_mm", "fill_rmse_mm",        "fill_rate",
    "range_ok",      "normal_err_mean_deg", "normal_err_p95_deg",
    "force_err_rel", "bytes_per_frame",     "temporal_ms",
    "fill_ms",       "encode_ms",           "decode_ms",
    "filter_ms",     "normals_ms",          "surface_ms",
    "total_ms",      "pixels_processed"};
bool is_cost(int m) { return m >= kBytes; }
using Sample = std::array<double, kMetricCount>;

// ---- scripted fingertip ------------------------------------------------------------------------

struct Script {
  std::vector<glm::dvec3> path_camera;  // one position per 1 kHz tick
  local::HandState hand;                // the fingertip where the press starts (for ROI windows)
};

// Approach from 1 cm in front of p0 along the free-side normal, press 5 mm in, stroke +-1.5 cm
// along the tangent (so friction sticks, slips and reverses), then release: 1.5 s at 1 kHz.
Script make_script(const glm::dvec3& p0, const glm::dvec3& n_free) {
  glm::dvec3 t = glm::cross(n_free, glm::dvec3(0, 1, 0));
  if (glm::length(t) < 1e-6) t = glm::cross(n_free, glm::dvec3(1, 0, 0));
  t = glm::normalize(t);
  Script s;
  auto push = [&](double off_m, double along_m) {
    s.path_camera.push_back(p0 + off_m * n_free + along_m * t);
  };
  auto lerp = [](double a, double b, int i, int n) { return a + (b - a) * i / n; };
  for (int i = 0; i < 200; ++i) push(lerp(0.01, 0.0, i, 200), 0.0);
  for (int i = 0; i < 300; ++i) push(lerp(0.0, -0.005, i, 300), 0.0);
  for (int i = 0; i < 200; ++i) push(-0.005, lerp(0.0, 0.015, i, 200));
  for (int i = 0; i < 400; ++i) push(-0.005, lerp(0.015, -0.015, i, 400));
  for (int i = 0; i < 200; ++i) push(-0.005, lerp(-0.015, 0.0, i, 200));
  for (int i = 0; i < 200; ++i) push(lerp(-0.005, 0.01, i, 200), 0.0);
  auto& tip = s.hand.tips[1];
  tip.finger = 1;
  tip.p_camera_m = p0 + 0.01 * n_free;
  tip.axis_camera = t;
  tip.valid = true;
  return s;
}

HapticParams bench_haptics() {
  HapticParams p;
  // The comparison is about the surface, not the safety layer: no start-up ramp, and the one
  // snapshot never goes stale during the 1.5 s script.
  p.startup_ramp_s = 0.0;
  p.stale_limit_s = 10.0;
  return p;
}

std::vector<glm::dvec3> run_script(const std::shared_ptr<const Surface>& surface,
                                   const Script& script) {
  HapticModel model(bench_haptics(), 1);
  std::array<FingertipInput, 1> in{};
  std::array<FingertipForce, 1> out{};
  std::vector<glm::dvec3> forces;
  forces.reserve(script.path_camera.size());
  for (std::size_t i = 0; i < script.path_camera.size(); ++i) {
    in[0].p_camera = script.path_camera[i];
    in[0].axis_camera = script.hand.tips[1].axis_camera;
    model.tick(static_cast<std::int64_t>(i) * 1'000'000, surface, in, out);
    forces.push_back(out[0].force_N);
  }
  return forces;
}

// RMS of the force difference relative to the peak of the reference force.
double force_error(const std::vector<glm::dvec3>& got, const std::vector<glm::dvec3>& ref) {
  double sum = 0.0, peak = 0.0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const glm::dvec3 d = got[i] - ref[i];
    sum += glm::dot(d, d);
    peak = std::max(peak, glm::length(ref[i]));
  }
  if (peak <= 0.0) return kNaN;
  return std::sqrt(sum / static_cast<double>(ref.size())) / peak;
}

// Nearest pixel to the image centre with a positive value, as (u, v).
cv::Point nearest_valid_to_centre(const cv::Mat& positive) {
  const cv::Point c(positive.cols / 2, positive.rows / 2);
  for (int r = 0; r < std::max(positive.cols, positive.rows); ++r)
    for (int dv = -r; dv <= r; ++dv)
      for (int du = -r; du <= r; ++du) {
        if (std::max(std::abs(du), std::abs(dv)) != r) continue;
        const cv::Point p(c.x + du, c.y + dv);
        if (p.x < 0 || p.y < 0 || p.x >= positive.cols || p.y >= positive.rows) continue;
        const bool ok = positive.depth() == CV_32F ? positive.at<float>(p) > 0.0f
                                                   : positive.at<std::uint16_t>(p) > 0;
        if (ok) return p;
      }
  throw std::runtime_error("frame has no valid depth at all");
}

// ---- frames ------------------------------------------------------------------------------------

struct Frame {
  cv::Mat1w depth_mm;
  cv::Mat1f true_depth_m;  // empty for real frames
  cv::Mat3f true_normals;
  Intrinsics intr;
  double time_ms = 0.0;
  std::uint32_t id = 0;
  Script script;
  std::vector<glm::dvec3> ideal_force;  // force against the surface built from ground truth
  bool has_truth() const { return !true_depth_m.empty(); }
};

Frame synthetic_frame(const synth::Rendered& r, std::uint32_t id) {
  Frame f;
  f.depth_mm = r.depth.depth_mm;
  f.true_depth_m = r.true_depth_m;
  f.true_normals = r.true_normals;
  f.intr = r.depth.intrinsics;
  f.id = id;
  f.time_ms = id * 1000.0 / kFrameRateHz;
  const cv::Point c = nearest_valid_to_centre(r.true_depth_m);
  const glm::dvec3 p0 = back_project(f.intr, c.x, c.y, r.true_depth_m(c));
  const cv::Vec3f n = r.true_normals(c);
  f.script = make_script(p0, glm::normalize(glm::dvec3(n[0], n[1], n[2])));
  const auto ideal = std::make_shared<const Surface>(
      make_surface(r.true_depth_m.clone(), f.intr, 0, id, r.true_normals.clone()));
  f.ideal_force = run_script(ideal, f.script);
  return f;
}

Frame real_frame(const cv::Mat1w& depth_mm, const Intrinsics& intr, std::uint32_t id,
                 double time_ms) {
  Frame f;
  f.depth_mm = depth_mm;
  f.intr = intr;
  f.id = id;
  f.time_ms = time_ms;
  const cv::Point c = nearest_valid_to_centre(depth_mm);
  f.script = make_script(back_project(intr, c.x, c.y, depth_mm(c) * 1e-3), {0.0, 0.0, -1.0});
  return f;
}

// ---- the chain ---------------------------------------------------------------------------------

// Fraction of filled holes whose value lies within the range of the valid input depths in the
// 15x15 window around them (holes with no valid depth that near are not checked).
double range_ok(const cv::Mat1w& input, const cv::Mat1w& filled) {
  const cv::Mat kernel = cv::Mat::ones(15, 15, CV_8U);
  cv::Mat1w lo_src = input.clone(), lo, hi;
  lo_src.setTo(65535, input == 0);
  cv::erode(lo_src, lo, kernel);
  cv::dilate(input, hi, kernel);
  std::size_t checked = 0, ok = 0;
  for (int v = 0; v < input.rows; ++v)
    for (int u = 0; u < input.cols; ++u) {
      if (input(v, u) != 0 || filled(v, u) == 0 || lo(v, u) == 65535) continue;
      ++checked;
      ok += filled(v, u) >= lo(v, u) && filled(v, u) <= hi(v, u);
    }
  return checked ? static_cast<double>(ok) / static_cast<double>(checked) : 1.0;
}

struct NormalError {
  double mean_deg = kNaN, p95_deg = kNaN;
};

NormalError normal_error(const cv::Mat3f& got, const cv::Mat3f& truth) {
  std::vector<double> deg;
  deg.reserve(got.total());
  for (int v = 0; v < got.rows; ++v)
    for (int u = 0; u < got.cols; ++u) {
      const cv::Vec3f a = got(v, u), b = truth(v, u);
      if (a.dot(a) < 0.25f || b.dot(b) < 0.25f) continue;  // zero vector: no normal there
      const double c = std::clamp(static_cast<double>(a.dot(b)), -1.0, 1.0);
      deg.push_back(std::acos(c) * 180.0 / CV_PI);
    }
  if (deg.empty()) return {};
  NormalError e;
  e.mean_deg = std::accumulate(deg.begin(), deg.end(), 0.0) / static_cast<double>(deg.size());
  const auto k =
      deg.begin() + static_cast<std::ptrdiff_t>(0.95 * static_cast<double>(deg.size() - 1));
  std::nth_element(deg.begin(), k, deg.end());
  e.p95_deg = *k;
  return e;
}

struct ChainState {
  explicit ChainState(const Config& c) : temporal(c.temporal_options) {}
  TemporalFill temporal;
  cv::Mat1w temporal_out, filled, received;
};

// `pool` recycles the surface snapshots as the station's surface thread does (one per
// configuration, so only its first frame allocates): a frame pays for clearing its windows, not
// for allocating and zeroing two full-frame buffers.
Sample run_chain(const Config& c, const Frame& f, ChainState& st, local::SurfacePool& pool) {
  Sample s;
  s.fill(kNaN);
  // Remote side: temporal fill, spatial fill, tiles through the codec.
  double t0 = cpu_ms();
  const cv::Mat1w* cur = &f.depth_mm;
  if (c.temporal) {
    st.temporal.apply(f.depth_mm, f.time_ms, st.temporal_out);
    cur = &st.temporal_out;
  }
  s[kTemporalMs] = cpu_ms() - t0;
  t0 = cpu_ms();
  if (c.fill)
    fill_holes_mode_into(*cur, st.filled, c.fill_options);
  else
    cur->copyTo(st.filled);
  s[kFillMs] = cpu_ms() - t0;

  const proto::TileGrid grid{c.width, c.height, c.width / 8, c.height / 8};
  t0 = cpu_ms();
  const auto tiles = proto::encode_tiles(st.filled, grid, c.codec, c.zip_level);
  s[kEncodeMs] = cpu_ms() - t0;
  double bytes = 0.0;
  for (const auto& t : tiles) bytes += static_cast<double>(t.bytes.size());
  s[kBytes] = bytes;
  st.received.create(st.filled.size());
  st.received.setTo(0);
  t0 = cpu_ms();
  for (const auto& t : tiles)
    if (proto::decode_tile_into(t.bytes, grid, t.index, c.codec, st.received) !=
        proto::DecodeStatus::Ok)
      throw std::logic_error("tile " + std::to_string(t.index) + " failed to decode");
  s[kDecodeMs] = cpu_ms() - t0;
  if (cv::norm(st.received, st.filled, cv::NORM_INF) != 0.0)
    throw std::logic_error("codec " + std::string(proto::codec_name(c.codec)) + " is not lossless");

  // Local side: smoothing, normals, snapshot (over fingertip windows with ROI).
  local::AssembledFrame frame{st.received, f.intr, f.id, 0, 0, true, local::AssembledPart::Whole,
                              {}};
  local::SurfaceOptions so;
  so.bilateral = c.bilateral;
  so.bilateral_options = c.bilateral_options;
  so.normal_options = c.normal_options;
  so.roi = c.roi;
  std::shared_ptr<const Surface> surface;
  t0 = cpu_ms();
  if (c.normal_method == NormalMethod::Smoothed) {
    std::vector<cv::Rect> windows;
    if (c.roi) windows = local::fingertip_windows(f.script.hand, frame.depth_mm, f.intr, so);
    local::SurfaceBuildStats stats;
    surface = local::build_surface(frame, so, windows, &stats, &pool);
    s[kSurfaceMs] = cpu_ms() - t0;
    s[kPixels] = static_cast<double>(stats.pixels_processed);
    // build_surface's own stage times are wall clock, which the shared machine inflates: run the
    // same kernels again on the same pixels under the thread CPU clock for the split.
    cv::Mat1f depth_m;
    cv::Mat3f normals;
    if (!c.roi) {
      double t1 = cpu_ms();
      if (c.bilateral)
        bilateral_filter_depth(frame.depth_mm, depth_m, c.bilateral_options);
      else
        depth_m = depth_m_from_mm(frame.depth_mm);
      s[kFilterMs] = cpu_ms() - t1;
      t1 = cpu_ms();
      compute_normals(depth_m, f.intr, normals, c.normal_options);
      s[kNormalsMs] = cpu_ms() - t1;
    } else {
      s[kFilterMs] = s[kNormalsMs] = 0.0;
      for (const auto& r : windows) {
        double t1 = cpu_ms();
        if (c.bilateral)
          bilateral_filter_depth_roi(frame.depth_mm, r, depth_m, c.bilateral_options);
        s[kFilterMs] += cpu_ms() - t1;
        t1 = cpu_ms();
        compute_normals_roi(surface->depth_m, f.intr, r, normals, c.normal_options);
        s[kNormalsMs] += cpu_ms() - t1;
      }
    }
  } else {
    cv::Mat1f depth_m = c.bilateral ? bilateral_filter_depth(frame.depth_mm, c.bilateral_options)
                                    : depth_m_from_mm(frame.depth_mm);
    s[kFilterMs] = cpu_ms() - t0;
    const double t1 = cpu_ms();
    cv::Mat3f normals = normals_from_depth(depth_m, f.intr);
    s[kNormalsMs] = cpu_ms() - t1;
    surface = std::make_shared<const Surface>(
        make_surface(std::move(depth_m), f.intr, 0, f.id, std::move(normals)));
    s[kSurfaceMs] = cpu_ms() - t0;
    s[kPixels] = static_cast<double>(frame.depth_mm.total());
  }
  s[kTotalMs] = s[kTemporalMs] + s[kFillMs] + s[kEncodeMs] + s[kDecodeMs] + s[kSurfaceMs];

  // Errors (untimed).
  const std::size_t holes_in = count_holes(f.depth_mm);
  s[kFillRate] =
      holes_in ? 1.0 - static_cast<double>(count_holes(st.filled)) / static_cast<double>(holes_in)
               : 1.0;
  s[kRangeOk] = range_ok(f.depth_mm, st.filled);
  if (f.has_truth()) {
    double sum_all = 0.0, sum_fill = 0.0;
    std::size_t n_all = 0, n_fill = 0;
    for (int v = 0; v < f.depth_mm.rows; ++v)
      for (int u = 0; u < f.depth_mm.cols; ++u) {
        const double truth_mm = f.true_depth_m(v, u) * 1000.0;
        if (truth_mm <= 0.0 || st.filled(v, u) == 0) continue;
        const double e2 = (st.filled(v, u) - truth_mm) * (st.filled(v, u) - truth_mm);
        sum_all += e2;
        ++n_all;
        if (f.depth_mm(v, u) == 0) {
          sum_fill += e2;
          ++n_fill;
        }
      }
    s[kDepthRmse] = n_all ? std::sqrt(sum_all / static_cast<double>(n_all)) : kNaN;
    s[kFillRmse] = n_fill ? std::sqrt(sum_fill / static_cast<double>(n_fill)) : kNaN;
    const NormalError ne = normal_error(surface->normals, f.true_normals);
    s[kNormalMean] = ne.mean_deg;
    s[kNormalP95] = ne.p95_deg;
    s[kForceErr] = force_error(run_script(surface, f.script), f.ideal_force);
  }
  return s;
}

// ---- aggregation -------------------------------------------------------------------------------

struct Row {
  const Config* config = nullptr;
  std::string dataset;  // a scene name, "synthetic" (all scenes pooled) or "real_desk"
  std::size_t frames = 0;
  Sample value{};
};

Row aggregate(const Config& c, const std::string& dataset, const std::vector<Sample>& samples) {
  Row r{&c, dataset, samples.size(), {}};
  for (int m = 0; m < kMetricCount; ++m) {
    std::vector<double> v;
    for (const auto& s : samples) v.push_back(s[m]);
    r.value[m] = is_cost(m) ? median(v) : mean_finite(v);
  }
  return r;
}

const Row* find_row(const std::vector<Row>& rows, const std::string& config,
                    const std::string& dataset) {
  for (const auto& r : rows)
    if (r.config->name == config && r.dataset == dataset) return &r;
  return nullptr;
}

// ---- static against moving: bytes per second with changed-tile skipping and a stabiliser ------

// Keeps the previously sent depth where the new one differs by at most k axial noise sigmas
// (Nguyen model at the previous depth), so sensor noise alone does not mark a tile as changed.
// With persistence, a change of up to jump_sigma sigmas must also be seen in the next frame
// before it is sent: single-frame noise outliers (a 3-sigma tail hits every 80x60 tile each
// frame) then never reach the wire, at the price of one frame of delay for small real changes.
// Holes and new surfaces pass through. k <= 0 returns the new frame unchanged. Pure apart from
// the caller-owned `pending` mask (pixels that exceeded k sigmas in the previous frame).
struct Stabiliser {
  double k_sigma = 0.0;
  bool persistence = false;
  double jump_sigma = 8.0;
};

void stabilise(const cv::Mat1w& new_mm, const cv::Mat1w& held_mm, const Stabiliser& o,
               cv::Mat1b& pending, cv::Mat1w& out_mm) {
  new_mm.copyTo(out_mm);
  if (pending.size() != new_mm.size()) pending = cv::Mat1b::zeros(new_mm.size());
  if (o.k_sigma <= 0.0 || held_mm.size() != new_mm.size()) return;
  for (int v = 0; v < new_mm.rows; ++v)
    for (int u = 0; u < new_mm.cols; ++u) {
      const int a = new_mm(v, u), b = held_mm(v, u);
      std::uint8_t& p = pending(v, u);
      if (a == 0 || b == 0) {
        p = 0;
        continue;
      }
      const double d_sigma = std::abs(a - b) / (1000.0 * nguyen_axial_sigma_m(b * 1e-3));
      if (d_sigma <= o.k_sigma) {
        out_mm(v, u) = static_cast<std::uint16_t>(b);
        p = 0;
      } else if (o.persistence && d_sigma <= o.jump_sigma && p == 0) {
        out_mm(v, u) = static_cast<std::uint16_t>(b);
        p = 1;
      } else {
        p = 0;
      }
    }
}

std::string stab_name(const Stabiliser& s) {
  if (s.k_sigma <= 0.0) return "off";
  std::string n = "k=" + std::to_string(static_cast<int>(s.k_sigma));
  return s.persistence ? n + " +2-frame" : n;
}

struct StreamRow {
  std::string scene;
  Stabiliser stab;
  double bytes_per_s = 0.0;
  double tiles_changed = 0.0;  // fraction of tiles sent per frame after the first
  double rmse_mm = 0.0;        // of the frames the receiver ends up with, against truth
  double stabilise_ms = 0.0;   // median per frame
  int frames = 0;
};

std::vector<StreamRow> run_stream(int frames, const std::vector<Stabiliser>& variants) {
  std::vector<StreamRow> out;
  const Intrinsics k640 = kinect_v1_intrinsics(640, 480);
  const proto::TileGrid grid{640, 480, 80, 60};
  for (const std::string scene_name : {"plane", "desk", "moving"}) {
    const synth::Scene scene = synth::Scene::named(scene_name);
    synth::Renderer renderer(k640, synth::SensorModel{});
    TemporalFill temporal;
    std::vector<cv::Mat1w> filled;
    std::vector<cv::Mat1f> truth;
    for (int i = 0; i < frames; ++i) {
      const auto r =
          renderer.render(scene.at_time(i / kFrameRateHz), static_cast<std::uint64_t>(i));
      cv::Mat1w t;
      temporal.apply(r.depth.depth_mm, i * 1000.0 / kFrameRateHz, t);
      filled.push_back(fill_holes_mode(t).depth_mm);
      truth.push_back(r.true_depth_m);
    }
    for (const Stabiliser& stab : variants) {
      StreamRow row{scene_name, stab, 0.0, 0.0, 0.0, 0.0, frames};
      cv::Mat1w sent, next;
      cv::Mat1b pending;
      double bytes = 0.0, changed = 0.0, se = 0.0;
      std::size_t n = 0;
      std::vector<double> stab_ms;
      for (int i = 0; i < frames; ++i) {
        const double t0 = cpu_ms();
        stabilise(filled[i], sent, stab, pending, next);
        stab_ms.push_back(cpu_ms() - t0);
        if (i > 0)  // the first frame is a key frame in both scenes: not counted
          for (int t = 0; t < grid.count(); ++t) {
            const cv::Rect rc = grid.rect(t);
            if (cv::norm(next(rc), sent(rc), cv::NORM_INF) == 0.0) continue;
            changed += 1.0;
            bytes += static_cast<double>(proto::encode_depth(next(rc), proto::Codec::Zip).size());
          }
        next.copyTo(sent);
        for (int v = 0; v < sent.rows; ++v)
          for (int u = 0; u < sent.cols; ++u) {
            const double z = truth[i](v, u) * 1000.0;
            if (z <= 0.0 || sent(v, u) == 0) continue;
            se += (sent(v, u) - z) * (sent(v, u) - z);
            ++n;
          }
      }
      row.bytes_per_s = bytes / (frames - 1) * kFrameRateHz;
      row.tiles_changed = changed / (frames - 1) / grid.count();
      row.rmse_mm = n ? std::sqrt(se / static_cast<double>(n)) : kNaN;
      row.stabilise_ms = median(stab_ms);
      out.push_back(row);
    }
  }
  return out;
}

// ---- skipped stages ----------------------------------------------------------------------------

struct SkipRow {
  std::string what;
  double holes_frac = 0.0;
  double tiles_without_holes = 0.0;
  double count_holes_ms = 0.0;  // the check that decides whether a pass is needed
  double fill_ms = 0.0;
};

SkipRow measure_fill_skip(const std::string& what, const cv::Mat1w& depth, int repeats) {
  SkipRow r{what, static_cast<double>(count_holes(depth)) / static_cast<double>(depth.total())};
  const proto::TileGrid grid{depth.cols, depth.rows, depth.cols / 8, depth.rows / 8};
  int clean = 0;
  for (int t = 0; t < grid.count(); ++t) clean += count_holes(depth(grid.rect(t))) == 0;
  r.tiles_without_holes = static_cast<double>(clean) / grid.count();
  std::vector<double> check_ms, fill_ms;
  cv::Mat1w out;
  std::size_t sink = 0;
  for (int i = 0; i < repeats; ++i) {
    double t0 = cpu_ms();
    sink += count_holes(depth);
    check_ms.push_back(cpu_ms() - t0);
    t0 = cpu_ms();
    fill_holes_mode_into(depth, out, {});
    fill_ms.push_back(cpu_ms() - t0);
  }
  if (sink != count_holes(depth) * static_cast<std::size_t>(repeats))
    throw std::logic_error("count_holes is not deterministic");
  r.count_holes_ms = median(check_ms);
  r.fill_ms = median(fill_ms);
  return r;
}

// ---- output ------------------------------------------------------------------------------------

std::string fmt(double v, int prec = 3) {
  if (!std::isfinite(v)) return "";
  std::ostringstream os;
  os << std::setprecision(prec) << std::fixed << v;
  return os.str();
}
std::string fmt_g(double v) {
  if (!std::isfinite(v)) return "";
  std::ostringstream os;
  os << std::setprecision(5) << v;
  return os.str();
}

void write_csv(const fs::path& file, const std::vector<Row>& rows) {
  std::ofstream os(file);
  if (!os) throw std::runtime_error("cannot write " + file.string());
  os << "config,group,dataset,width,height,temporal,fill,fill_window_px,fill_bin_mm,bilateral,"
        "bilateral_radius_px,sigma_space_px,sigma_depth_mm,sigma_from_noise,normal_method,"
        "smooth_radius_px,codec,zip_level,roi,frames";
  for (const char* m : kMetricNames) os << ',' << m;
  os << '\n';
  for (const auto& r : rows) {
    const Config& c = *r.config;
    os << c.name << ',' << c.group << ',' << r.dataset << ',' << c.width << ',' << c.height << ','
       << c.temporal << ',' << c.fill << ',' << c.fill_options.window_px << ','
       << c.fill_options.bin_mm << ',' << c.bilateral << ',' << c.bilateral_options.radius_px << ','
       << c.bilateral_options.sigma_space_px << ',' << c.bilateral_options.sigma_depth_mm << ','
       << c.bilateral_options.sigma_from_noise_model << ','
       << (c.normal_method == NormalMethod::Plain ? "plain" : "smoothed") << ','
       << c.normal_options.smooth_radius_px << ',' << proto::codec_name(c.codec) << ','
       << c.zip_level << ',' << c.roi << ',' << r.frames;
    for (double v : r.value) os << ',' << fmt_g(v);
    os << '\n';
  }
}

std::string describe(const Config& c) {
  std::ostringstream os;
  os << c.width << 'x' << c.height << (c.temporal ? " T" : " -") << ' ';
  if (c.fill)
    os << "w" << c.fill_options.window_px << "/b" << c.fill_options.bin_mm;
  else
    os << "nofill";
  os << ' ';
  if (!c.bilateral)
    os << "nobil";
  else if (c.bilateral_options.sigma_from_noise_model)
    os << "r" << c.bilateral_options.radius_px << "/3sz";
  else
    os << "r" << c.bilateral_options.radius_px << "/" << c.bilateral_options.sigma_space_px << "/"
       << c.bilateral_options.sigma_depth_mm;
  os << ' '
     << (c.normal_method == NormalMethod::Plain
             ? std::string("plain")
             : "k" + std::to_string(c.normal_options.smooth_radius_px));
  os << ' ' << proto::codec_name(c.codec);
  if (c.codec == proto::Codec::Zip) os << c.zip_level;
  if (c.roi) os << " ROI";
  return os.str();
}

struct RoiTiming {
  double full_ms = kNaN, roi_ms = kNaN, none_ms = kNaN;
  double roi_snapshot_ms = kNaN;  // of roi_ms: taking the snapshot from the pool, clearing it
  int window_px = 0;
  std::size_t recycled = 0;
};

struct RoiRow {
  std::string full, roi;
  double full_ms, roi_ms, ratio, full_pixels, roi_pixels, full_force, roi_force;
  double full_kernel_ms, roi_kernel_ms;  // bilateral + normals only
  double kernel_ratio() const { return full_kernel_ms / roi_kernel_ms; }
};

std::vector<RoiRow> roi_rows(const std::vector<Row>& rows) {
  std::vector<RoiRow> out;
  for (auto [full, roi] : {std::pair{"default", "roi"},
                           {"res320", "roi320"},
                           {"res160", "roi160"},
                           {"bil_r6", "kinfu_r6_roi"}}) {
    const Row* a = find_row(rows, full, "synthetic");
    const Row* b = find_row(rows, roi, "synthetic");
    if (!a || !b) continue;
    out.push_back({full, roi, a->value[kSurfaceMs], b->value[kSurfaceMs],
                   a->value[kSurfaceMs] / b->value[kSurfaceMs], a->value[kPixels],
                   b->value[kPixels], a->value[kForceErr], b->value[kForceErr],
                   a->value[kFilterMs] + a->value[kNormalsMs],
                   b->value[kFilterMs] + b->value[kNormalsMs]});
  }
  return out;
}

void write_markdown(const fs::path& file, const std::vector<Row>& rows,
                    const std::vector<RoiRow>& roi, const std::vector<StreamRow>& stream,
                    const std::vector<SkipRow>& skip, const RoiTiming& rt, bool quick,
                    const std::string& real_note) {
  std::ofstream os(file);
  if (!os) throw std::runtime_error("cannot write " + file.string());
  os << "<!-- generated by `telex bench" << (quick ? " --quick" : "") << "` -->\n";
  os << "### Synthetic scenes (errors: mean over scenes, seeds, frames; costs: median ms per "
        "frame, one thread CPU time)\n\n";
  os << "| config | setting | depth RMSE mm | fill RMSE mm | normal err mean/p95 deg | force "
        "err % | bytes/frame | remote ms | encode/decode ms | surface ms | total ms |\n";
  os << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (r.dataset != "synthetic") continue;
    const auto& v = r.value;
    os << "| " << r.config->name << (r.config->name == "default" ? " **(default)**" : "") << " | `"
       << describe(*r.config) << "` | " << fmt(v[kDepthRmse], 2) << " | " << fmt(v[kFillRmse], 1)
       << " | " << fmt(v[kNormalMean], 2) << " / " << fmt(v[kNormalP95], 1) << " | "
       << fmt(100.0 * v[kForceErr], 2) << " | " << fmt(v[kBytes], 0) << " | "
       << fmt(v[kTemporalMs] + v[kFillMs], 2) << " | " << fmt(v[kEncodeMs], 2) << " / "
       << fmt(v[kDecodeMs], 2) << " | " << fmt(v[kSurfaceMs], 2) << " | " << fmt(v[kTotalMs], 2)
       << " |\n";
  }
  os << "\n### Real desk frames (" << real_note << ")\n\n";
  bool any_real = false;
  for (const auto& r : rows) any_real |= r.dataset == "real_desk";
  if (any_real) {
    os << "| config | fill rate % | in local range % | bytes/frame | total ms |\n"
          "|---|---|---|---|---|\n";
    for (const auto& r : rows) {
      if (r.dataset != "real_desk") continue;
      os << "| " << r.config->name << " | " << fmt(100.0 * r.value[kFillRate], 2) << " | "
         << fmt(100.0 * r.value[kRangeOk], 2) << " | " << fmt(r.value[kBytes], 0) << " | "
         << fmt(r.value[kTotalMs], 2) << " |\n";
    }
  }
  os << "\n### Region of interest against full frame (one fingertip near the surface)\n\n"
        "| full | ROI | surface ms full | surface ms ROI | ratio | bilateral+normals "
        "ms "
        "full | bilateral+normals ms ROI | kernel ratio | pixels full | pixels ROI | force err % "
        "full | force err % ROI |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : roi)
    os << "| " << r.full << " | " << r.roi << " | " << fmt(r.full_ms, 3) << " | "
       << fmt(r.roi_ms, 3) << " | " << fmt(r.ratio, 1) << "x | " << fmt(r.full_kernel_ms, 3)
       << " | " << fmt(r.roi_kernel_ms, 3) << " | " << fmt(r.kernel_ratio(), 1) << "x | "
       << fmt(r.full_pixels, 0) << " | " << fmt(r.roi_pixels, 0) << " | "
       << fmt(100.0 * r.full_force, 2) << " | " << fmt(100.0 * r.roi_force, 2) << " |\n";
  os << "\nSurface ms = everything the station's surface thread does per frame for the snapshot: "
        "fingertip windows, snapshot buffers from the pool (recycled; an ROI snapshot clears the "
        "windows its last use wrote), bilateral filter, normals.\n";
  os << "\nInterleaved on one 640x480 desk frame (median of repeats after the pools are filled; "
        "8 retired snapshots kept, as in the station): full frame "
     << fmt(rt.full_ms, 3) << " ms, ROI with one fingertip 1 cm above the surface (" << rt.window_px
     << " px window) " << fmt(rt.roi_ms, 3) << " ms, of which snapshot "
     << fmt(rt.roi_snapshot_ms, 4) << " ms (ratio " << fmt(rt.full_ms / rt.roi_ms, 1)
     << "x), ROI with the fingertip far away (no window) " << fmt(rt.none_ms, 4) << " ms.\n";
  os << "\n### Static against moving scene (640x480, 80x60 tiles, zip level 0, only changed tiles "
        "sent)\n\n| scene | stabiliser | kB/s | tiles sent % | RMSE vs truth mm | "
        "stabiliser ms |\n|---|---|---|---|---|---|\n";
  for (const auto& r : stream)
    os << "| " << r.scene << " | " << stab_name(r.stab) << " | " << fmt(r.bytes_per_s / 1000.0, 1)
       << " | " << fmt(100.0 * r.tiles_changed, 1) << " | " << fmt(r.rmse_mm, 2) << " | "
       << fmt(r.stabilise_ms, 2) << " |\n";
  os << "\n### Skipped stages: spatial fill with and without holes\n\n"
        "| frame | holes % | tiles without holes % | hole check ms | fill ms |\n"
        "|---|---|---|---|---|\n";
  for (const auto& r : skip)
    os << "| " << r.what << " | " << fmt(100.0 * r.holes_frac, 2) << " | "
       << fmt(100.0 * r.tiles_without_holes, 1) << " | " << fmt(r.count_holes_ms, 3) << " | "
       << fmt(r.fill_ms, 3) << " |\n";
}

void write_plots(const fs::path& dir, const std::vector<Row>& rows) {
  auto points = [&](auto x_of, auto y_of, auto keep) {
    std::vector<PlotPoint> pts;
    for (const auto& r : rows) {
      if (r.dataset != "synthetic" || !keep(*r.config)) continue;
      pts.push_back({x_of(r.value), y_of(r.value), r.config->name, group_index(r.config->group),
                     r.config->name == "default"});
    }
    return pts;
  };
  auto all = [](const Config&) { return true; };
  auto total = [](const Sample& v) { return v[kTotalMs]; };
  auto save = [&](const std::string& name, const PlotSpec& spec, const std::vector<PlotPoint>& p) {
    const fs::path file = dir / name;
    if (!cv::imwrite(file.string(), draw_scatter(spec, p)))
      throw std::runtime_error("cannot write " + file.string());
  };
  save("normal_error_vs_ms.png",
       {"Normal error against run time (synthetic scenes)", "total ms per frame (log)",
        "mean normal error (deg)", true, false, kGroups},
       points(
           total, [](const Sample& v) { return v[kNormalMean]; }, all));
  save("force_error_vs_ms.png",
       {"Force error against run time (press + stroke)", "total ms per frame (log)",
        "force RMS error (% of peak)", true, false, kGroups},
       points(
           total, [](const Sample& v) { return 100.0 * v[kForceErr]; }, all));
  save("depth_rmse_vs_ms.png",
       {"Depth RMSE after fill against fill time", "temporal + spatial fill ms per frame (log)",
        "depth RMSE (mm)", true, false, kGroups},
       points([](const Sample& v) { return v[kTemporalMs] + v[kFillMs]; },
              [](const Sample& v) { return v[kDepthRmse]; },
              [](const Config& c) {
                return c.group == "default" || c.group == "fill" || c.group == "temporal" ||
                       c.group == "resolution";
              }));
  save("bytes_vs_encode_ms.png",
       {"Bytes per frame against encode time (640x480, 80x60 tiles)", "encode ms per frame (log)",
        "bytes per frame (log)", true, true, kGroups},
       points([](const Sample& v) { return v[kEncodeMs]; },
              [](const Sample& v) { return v[kBytes]; },
              [](const Config& c) { return c.group == "default" || c.group == "codec"; }));
}

nlohmann::json row_json(const Row& r) {
  nlohmann::json j{{"config", r.config->name},
                   {"group", r.config->group},
                   {"dataset", r.dataset},
                   {"setting", describe(*r.config)},
                   {"frames", r.frames}};
  for (int m = 0; m < kMetricCount; ++m)
    j[kMetricNames[m]] = std::isfinite(r.value[m]) ? nlohmann::json(r.value[m]) : nlohmann::json();
  return j;
}

// ---- the command -------------------------------------------------------------------------------

struct Options {
  bool quick = false;
  bool json = false;
  std::string out = "bench_out";
  std::string real;
};

std::vector<cv::Mat1w> load_real(const std::string& dir, std::string& note) {
  std::vector<cv::Mat1w> frames;
  if (dir.empty()) {
    note = "skipped: no --real directory given";
    return frames;
  }
  for (int i = 0; i < 3; ++i) {
    const fs::path file = fs::path(dir) / ("desk_" + std::to_string(i) + "_depth_mm.png");
    if (!fs::exists(file)) {
      note = "skipped: " + file.string() + " not found";
      return {};
    }
    frames.push_back(load_depth(file, DepthUnits::Millimetres).depth_mm);
  }
  note = std::to_string(frames.size()) + " frames from " + dir +
         ", scaled with nearest neighbour to each resolution";
  return frames;
}

int run(const Options& o) {
  cv::setNumThreads(1);
  const fs::path out_dir(o.out);
  fs::create_directories(out_dir);
  const std::vector<Config> grid = make_grid(o.quick);
  const std::vector<std::string> scenes =
      o.quick ? std::vector<std::string>{"tilted", "box"}
              : std::vector<std::string>{"plane", "tilted", "sphere", "box", "desk"};
  const int seeds = o.quick ? 1 : 3;
  const int frames_per_seq = o.quick ? 2 : 4;
  std::string real_note;
  const std::vector<cv::Mat1w> real = load_real(o.real, real_note);
  if (!o.json) std::cerr << "telex bench: real desk frames " << real_note << "\n";

  // samples[config index][dataset]
  std::vector<std::map<std::string, std::vector<Sample>>> samples(grid.size());
  std::vector<std::pair<int, int>> resolutions;
  for (const auto& c : grid)
    if (std::find(resolutions.begin(), resolutions.end(), std::pair{c.width, c.height}) ==
        resolutions.end())
      resolutions.emplace_back(c.width, c.height);

  for (const auto& [w, h] : resolutions) {
    const Intrinsics k = kinect_v1_intrinsics(w, h);
    std::vector<std::pair<std::string, std::vector<Frame>>> sequences;
    for (const auto& name : scenes) {
      const synth::Scene scene = synth::Scene::named(name);
      for (int seed = 1; seed <= seeds; ++seed) {
        synth::SensorModel sensor;
        sensor.seed = static_cast<std::uint64_t>(seed);
        synth::Renderer renderer(k, sensor);
        std::vector<Frame> seq;
        for (int i = 0; i < frames_per_seq; ++i)
          seq.push_back(synthetic_frame(
              renderer.render(scene.at_time(i / kFrameRateHz), static_cast<std::uint64_t>(i)),
              static_cast<std::uint32_t>(i)));
        sequences.emplace_back(name, std::move(seq));
      }
    }
    if (!real.empty()) {
      const Intrinsics real_k = Intrinsics{525.0, 525.0, 320.0, 240.0, 640, 480}.scaled(w, h);
      std::vector<Frame> seq;
      for (std::size_t i = 0; i < real.size(); ++i) {
        cv::Mat1w d;
        cv::resize(real[i], d, cv::Size(w, h), 0, 0, cv::INTER_NEAREST);
        // The README gives about 0.25 s between the recorded frames.
        seq.push_back(real_frame(d, real_k, static_cast<std::uint32_t>(i), 250.0 * i));
      }
      sequences.emplace_back("real_desk", std::move(seq));
    }
    for (std::size_t ci = 0; ci < grid.size(); ++ci) {
      const Config& c = grid[ci];
      if (c.width != w || c.height != h) continue;
      if (!o.json) std::cerr << "  " << c.name << " (" << describe(c) << ")\n";
      local::SurfacePool pool;
      for (const auto& [name, seq] : sequences) {
        ChainState state(c);
        for (const auto& f : seq) samples[ci][name].push_back(run_chain(c, f, state, pool));
      }
    }
  }

  std::vector<Row> rows;
  for (std::size_t ci = 0; ci < grid.size(); ++ci) {
    std::vector<Sample> pooled;
    for (const auto& name : scenes)
      pooled.insert(pooled.end(), samples[ci][name].begin(), samples[ci][name].end());
    rows.push_back(aggregate(grid[ci], "synthetic", pooled));
    for (const auto& name : scenes) rows.push_back(aggregate(grid[ci], name, samples[ci][name]));
    if (samples[ci].count("real_desk"))
      rows.push_back(aggregate(grid[ci], "real_desk", samples[ci]["real_desk"]));
  }
  for (const auto& r : rows)
    if (r.dataset != "real_desk")
      for (int m : {kDepthRmse, kNormalMean, kForceErr, kTotalMs, kBytes})
        if (!std::isfinite(r.value[m]))
          throw std::logic_error("config " + r.config->name + " on " + r.dataset + ": " +
                                 kMetricNames[m] + " is not finite");

  // The station's per-frame surface work on one desk frame (fingertip windows, snapshot from the
  // pool, bilateral, normals), interleaved so that machine load hits all three alike: the full
  // frame, the windows of one fingertip 1 cm above the surface, and a fingertip far away (no
  // windows at all). Each keeps the station's ring of 8 retired snapshots, so the pool recycles
  // snapshots 8 frames old, as in the station.
  RoiTiming roi_timing;
  {
    const Intrinsics k = kinect_v1_intrinsics();
    const Frame f =
        synthetic_frame(synth::render(synth::Scene::named("desk"), k, synth::SensorModel{}), 0);
    local::HandState far_hand;
    far_hand.tips[1].valid = true;
    far_hand.tips[1].p_camera_m = {0.0, 0.0, 0.2};  // far in front of the desk
    local::SurfaceOptions full, roi;
    roi.roi = true;
    const local::AssembledFrame af{f.depth_mm, k, 0, 0, 0, true, local::AssembledPart::Whole, {}};
    std::vector<double> full_ms, roi_ms, none_ms, roi_snapshot_ms;
    local::SurfacePool full_pool, near_pool, none_pool;
    std::deque<std::shared_ptr<const Surface>> full_ring, near_ring, none_ring;
    auto retire = [](std::deque<std::shared_ptr<const Surface>>& ring,
                     std::shared_ptr<const Surface> s) {
      ring.push_back(std::move(s));
      if (ring.size() > 8) ring.pop_front();
    };
    for (int i = 0; i < (o.quick ? 15 : 61); ++i) {
      double t0 = cpu_ms();
      auto a = local::build_surface(af, full, {}, nullptr, &full_pool);
      full_ms.push_back(cpu_ms() - t0);
      local::SurfaceBuildStats near_stats;
      t0 = cpu_ms();
      const auto near = local::fingertip_windows(f.script.hand, f.depth_mm, k, roi);
      auto b = local::build_surface(af, roi, near, &near_stats, &near_pool);
      roi_ms.push_back(cpu_ms() - t0);
      roi_snapshot_ms.push_back(near_stats.snapshot_ms);
      t0 = cpu_ms();
      const auto none = local::fingertip_windows(far_hand, f.depth_mm, k, roi);
      auto c = local::build_surface(af, roi, none, nullptr, &none_pool);
      none_ms.push_back(cpu_ms() - t0);
      if (near.size() != 1 || !none.empty() || !a || !b || !c)
        throw std::logic_error("expected one window for the near fingertip, none for the far one");
      roi_timing.window_px = near[0].area();
      retire(full_ring, std::move(a));
      retire(near_ring, std::move(b));
      retire(none_ring, std::move(c));
    }
    // The first 8 frames fill the pools (fresh allocations); the rest recycle.
    for (auto* v : {&full_ms, &roi_ms, &none_ms, &roi_snapshot_ms})
      v->erase(v->begin(), v->begin() + 9);
    roi_timing.full_ms = median(full_ms);
    roi_timing.roi_ms = median(roi_ms);
    roi_timing.none_ms = median(none_ms);
    roi_timing.roi_snapshot_ms = median(roi_snapshot_ms);
    roi_timing.recycled = near_pool.recycled();
  }

  const std::vector<StreamRow> stream = run_stream(
      o.quick ? 6 : 30, {{0.0, false}, {3.0, false}, {5.0, false}, {3.0, true}, {5.0, true}});

  std::vector<SkipRow> skip;
  {
    const int reps = o.quick ? 5 : 21;
    const Intrinsics k = kinect_v1_intrinsics();
    skip.push_back(measure_fill_skip(
        "plane, ideal sensor (no holes)",
        synth::render(synth::Scene::named("plane"), k, synth::SensorModel::ideal()).depth.depth_mm,
        reps));
    skip.push_back(measure_fill_skip(
        "plane, sensor model",
        synth::render(synth::Scene::named("plane"), k, synth::SensorModel{}).depth.depth_mm, reps));
    skip.push_back(measure_fill_skip(
        "desk, sensor model",
        synth::render(synth::Scene::named("desk"), k, synth::SensorModel{}).depth.depth_mm, reps));
    if (!real.empty()) skip.push_back(measure_fill_skip("real desk_0", real[0], reps));
  }

  const std::vector<RoiRow> roi = roi_rows(rows);
  write_csv(out_dir / "bench.csv", rows);
  write_markdown(out_dir / "bench.md", rows, roi, stream, skip, roi_timing, o.quick, real_note);
  write_plots(out_dir, rows);

  if (o.json) {
    nlohmann::json j;
    j["configs"] = nlohmann::json::array();
    for (const auto& r : rows) j["configs"].push_back(row_json(r));
    for (const auto& r : roi)
      j["roi"].push_back({{"full", r.full},
                          {"roi", r.roi},
                          {"full_ms", r.full_ms},
                          {"roi_ms", r.roi_ms},
                          {"ratio", r.ratio},
                          {"full_kernel_ms", r.full_kernel_ms},
                          {"roi_kernel_ms", r.roi_kernel_ms},
                          {"kernel_ratio", r.kernel_ratio()},
                          {"full_force_err", r.full_force},
                          {"roi_force_err", r.roi_force}});
    j["roi_interleaved"] = {{"full_ms", roi_timing.full_ms},
                            {"roi_ms", roi_timing.roi_ms},
                            {"roi_snapshot_ms", roi_timing.roi_snapshot_ms},
                            {"no_window_ms", roi_timing.none_ms},
                            {"roi_recycled", roi_timing.recycled},
                            {"window_px", roi_timing.window_px}};
    for (const auto& r : stream)
      j["stream"].push_back({{"scene", r.scene},
                             {"stabiliser", stab_name(r.stab)},
                             {"bytes_per_s", r.bytes_per_s},
                             {"tiles_changed", r.tiles_changed},
                             {"rmse_mm", r.rmse_mm}});
    for (const auto& r : skip)
      j["skipped_stages"].push_back({{"frame", r.what},
                                     {"holes", r.holes_frac},
                                     {"tiles_without_holes", r.tiles_without_holes},
                                     {"hole_check_ms", r.count_holes_ms},
                                     {"fill_ms", r.fill_ms}});
    j["out"] = out_dir.string();
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "wrote " << (out_dir / "bench.csv").string() << ", bench.md and 4 PNG plots\n";
    for (const auto& r : roi)
      std::cout << "ROI " << r.roi << " vs " << r.full << ": " << fmt(r.ratio, 1)
                << "x less surface time (" << fmt(r.full_ms) << " -> " << fmt(r.roi_ms)
                << " ms; bilateral+normals " << fmt(r.kernel_ratio(), 1) << "x), force error "
                << fmt(100 * r.full_force, 2) << "% vs " << fmt(100 * r.roi_force, 2) << "%\n";
    std::cout << "ROI interleaved on one desk frame: full " << fmt(roi_timing.full_ms)
              << " ms, ROI " << fmt(roi_timing.roi_ms) << " ms ("
              << fmt(roi_timing.full_ms / roi_timing.roi_ms, 1) << "x; snapshot "
              << fmt(roi_timing.roi_snapshot_ms, 4) << " ms), no window "
              << fmt(roi_timing.none_ms, 4) << " ms\n";
    for (const auto& r : stream)
      std::cout << "stream " << r.scene << " " << stab_name(r.stab) << ": "
                << fmt(r.bytes_per_s / 1000, 1) << " kB/s, " << fmt(100 * r.tiles_changed, 1)
                << "% tiles sent\n";
    for (const auto& r : skip)
      std::cout << "fill on " << r.what << ": " << fmt(r.fill_ms) << " ms (hole check "
                << fmt(r.count_holes_ms) << " ms)\n";
  }
  return 0;
}

const RegisterCommand kRegister{
    "bench",
    "error against run time of the depth chain over a grid of configurations (CSV, Markdown, "
    "PNG plots)",
    [](CLI::App& app) {
      auto o = std::make_shared<Options>();
      if (const char* env = std::getenv("TELEX_REAL_DESK_DIR")) o->real = env;
      app.add_flag("--quick", o->quick, "small grid for CI smoke runs (under two minutes)");
      app.add_option("--out", o->out, "output directory for bench.csv, bench.md and the plots")
          ->capture_default_str();
      app.add_flag("--json", o->json, "print the results as one JSON object on stdout");
      app.add_option("--real", o->real,
                     "directory with desk_{0,1,2}_depth_mm.png (default: $TELEX_REAL_DESK_DIR); "
                     "skipped with a note when absent");
      return [o]() { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
