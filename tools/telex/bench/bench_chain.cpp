// SPDX-License-Identifier: MIT
// `telex bench`: frames with ground truth, the scripted fingertip, and the chain each frame runs
// through: the shipping code of both daemons, stage by stage, never a copy of it.
#include <algorithm>
#include <cmath>
#include <deque>
#include <glm/geometric.hpp>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "bench.h"
#include "telex/common/stage_clock.h"
#include "telex/haptics/haptic_model.h"

namespace telex::tool::bench {
namespace {

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
  tip.p_CameraFingertip = p0 + 0.01 * n_free;
  tip.axis_Camera = t;
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
    in[0].p_ModelFingertip = script.path_camera[i];
    in[0].axis_Model = script.hand.tips[1].axis_Camera;
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

}  // namespace

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

Sample run_chain(const Config& c, const Frame& f, ChainState& st, local::SurfacePool& pool) {
  Sample s;
  s.fill(kNaN);
  // Remote side: the daemon's pipeline. Every tile is sent (a key frame), so the bytes are a whole
  // frame's; the temporal fill keeps its history across the sequence as in the daemon.
  remote::DepthFrame df;
  df.image.depth_mm = f.depth_mm;
  df.image.intrinsics = f.intr;
  df.frame_id = f.id;
  df.capture_ns = static_cast<std::int64_t>(std::llround(f.time_ms * 1e6));
  remote::FrameRequest request;
  request.force_key_frame = true;
  const remote::ProcessedFrame sent = st.pipeline.process(df, request);
  s[kTemporalMs] = sent.times.temporal_ms;
  s[kFillMs] = sent.times.fill_ms - sent.times.temporal_ms;
  s[kEncodeMs] = sent.times.encode_ms;
  double bytes = 0.0;
  for (const auto& t : sent.tiles) bytes += static_cast<double>(t.bytes.size());
  s[kBytes] = bytes;

  // Station side: proto's tile decoder into the frame the station assembles.
  st.received.create(sent.sent_view_mm.size());
  st.received.setTo(0);
  double t0 = thread_cpu_ms();
  for (const auto& t : sent.tiles)
    if (proto::decode_tile_into(t.bytes, sent.grid, t.index, sent.codec, st.received) !=
        proto::DecodeStatus::Ok)
      throw std::logic_error("tile " + std::to_string(t.index) + " failed to decode");
  s[kDecodeMs] = thread_cpu_ms() - t0;
  if (sent.tiles.size() != static_cast<std::size_t>(sent.grid.count()) ||
      cv::norm(st.received, sent.sent_view_mm, cv::NORM_INF) != 0.0)
    throw std::logic_error("codec " + std::string(proto::codec_name(sent.codec)) +
                           " is not lossless, or a key frame did not send every tile");
  const cv::Mat1w& filled = st.received;

  // Local side: the station's surface stage (smoothing and normals over fingertip windows with
  // ROI), its stage times by the thread's CPU clock.
  local::AssembledFrame frame{filled, f.intr, f.id, 0, 0, true, local::AssembledPart::Whole,
                              {},     {}};
  const local::SurfaceOptions so = surface_options(c);
  std::shared_ptr<const Surface> surface;
  t0 = thread_cpu_ms();
  if (c.normal_method == NormalMethod::Smoothed) {
    std::vector<cv::Rect> windows;
    if (c.roi) windows = local::fingertip_windows(f.script.hand, frame.depth_mm, f.intr, so);
    local::SurfaceBuildStats stats;
    surface = local::build_surface(frame, so, windows, &stats, &pool);
    s[kSurfaceMs] = thread_cpu_ms() - t0;
    s[kPixels] = static_cast<double>(stats.pixels_processed);
    s[kFilterMs] = stats.filter_ms;
    s[kNormalsMs] = stats.normals_ms;
  } else {
    // The comparison point: Surface's own fallback normals (make_surface without the normal
    // kernel), which no daemon uses.
    cv::Mat1f depth_m = c.bilateral ? bilateral_filter_depth(frame.depth_mm, c.bilateral_options)
                                    : depth_m_from_mm(frame.depth_mm);
    s[kFilterMs] = thread_cpu_ms() - t0;
    const double t1 = thread_cpu_ms();
    cv::Mat3f normals = normals_from_depth(depth_m, f.intr);
    s[kNormalsMs] = thread_cpu_ms() - t1;
    surface = std::make_shared<const Surface>(
        make_surface(std::move(depth_m), f.intr, 0, f.id, std::move(normals)));
    s[kSurfaceMs] = thread_cpu_ms() - t0;
    s[kPixels] = static_cast<double>(frame.depth_mm.total());
  }
  s[kTotalMs] = sent.times.total_ms + s[kDecodeMs] + s[kSurfaceMs];

  // Errors (untimed).
  const std::size_t holes_in = count_holes(f.depth_mm);
  s[kFillRate] =
      holes_in ? 1.0 - static_cast<double>(count_holes(filled)) / static_cast<double>(holes_in)
               : 1.0;
  s[kRangeOk] = range_ok(f.depth_mm, filled);
  if (f.has_truth()) {
    double sum_all = 0.0, sum_fill = 0.0;
    std::size_t n_all = 0, n_fill = 0;
    for (int v = 0; v < f.depth_mm.rows; ++v)
      for (int u = 0; u < f.depth_mm.cols; ++u) {
        const double truth_mm = f.true_depth_m(v, u) * 1000.0;
        if (truth_mm <= 0.0 || filled(v, u) == 0) continue;
        const double e2 = (filled(v, u) - truth_mm) * (filled(v, u) - truth_mm);
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

std::string stream_name(const StreamVariant& s) {
  if (s.k_sigma <= 0.0) return "off";
  std::string n = "k=" + std::to_string(static_cast<int>(s.k_sigma));
  return s.confirm_frames > 1 ? n + " +" + std::to_string(s.confirm_frames) + "-frame" : n;
}

// Bytes per second as telex-remote sends them with its defaults (zip, 80x60 tiles, key frame
// every 30 frames, only changed tiles) and the stabiliser variant, for a static and a moving
// scene. The first frame (a key frame) is not counted.
std::vector<StreamRow> run_stream(int frames, const std::vector<StreamVariant>& variants) {
  std::vector<StreamRow> out;
  const Intrinsics k640 = kinect_v1_intrinsics(640, 480);
  for (const std::string scene_name : {"plane", "desk", "moving"}) {
    const synth::Scene scene = synth::Scene::named(scene_name);
    synth::Renderer renderer(k640, synth::SensorModel{});
    std::vector<remote::DepthFrame> input;
    std::vector<cv::Mat1f> truth;
    for (int i = 0; i < frames; ++i) {
      const auto r =
          renderer.render(scene.at_time(i / kFrameRateHz), static_cast<std::uint64_t>(i));
      remote::DepthFrame df;
      df.image = r.depth;
      df.frame_id = static_cast<std::uint64_t>(i);
      df.capture_ns = static_cast<std::int64_t>(std::llround(i * 1e9 / kFrameRateHz));
      input.push_back(df);
      truth.push_back(r.true_depth_m);
    }
    for (const StreamVariant& stab : variants) {
      StreamRow row{scene_name, stab, 0.0, 0.0, 0.0, 0.0, frames};
      remote::PipelineConfig pc = remote_config(Config{});
      pc.stabilise_k_sigma = stab.k_sigma;
      pc.stabilise_confirm_frames = stab.confirm_frames;
      remote::FramePipeline pipeline(pc);
      double bytes = 0.0, changed = 0.0, se = 0.0;
      std::size_t n = 0;
      std::vector<double> stab_ms;
      int tiles = 1;
      for (int i = 0; i < frames; ++i) {
        const remote::ProcessedFrame sent = pipeline.process(input[i], remote::FrameRequest{});
        stab_ms.push_back(sent.times.stabilise_ms);
        tiles = sent.grid.count();
        if (i > 0) {
          changed += static_cast<double>(sent.tiles.size());
          for (const auto& t : sent.tiles) bytes += static_cast<double>(t.bytes.size());
        }
        const cv::Mat1w& held = sent.sent_view_mm;  // what the receiver now holds
        for (int v = 0; v < held.rows; ++v)
          for (int u = 0; u < held.cols; ++u) {
            const double z = truth[i](v, u) * 1000.0;
            if (z <= 0.0 || held(v, u) == 0) continue;
            se += (held(v, u) - z) * (held(v, u) - z);
            ++n;
          }
      }
      row.bytes_per_s = bytes / (frames - 1) * kFrameRateHz;
      row.tiles_changed = changed / (frames - 1) / tiles;
      row.rmse_mm = n ? std::sqrt(se / static_cast<double>(n)) : kNaN;
      row.stabilise_ms = median(stab_ms);
      out.push_back(row);
    }
  }
  return out;
}

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
    double t0 = thread_cpu_ms();
    sink += count_holes(depth);
    check_ms.push_back(thread_cpu_ms() - t0);
    t0 = thread_cpu_ms();
    fill_holes_mode_into(depth, out, {});
    fill_ms.push_back(thread_cpu_ms() - t0);
  }
  if (sink != count_holes(depth) * static_cast<std::size_t>(repeats))
    throw std::logic_error("count_holes is not deterministic");
  r.count_holes_ms = median(check_ms);
  r.fill_ms = median(fill_ms);
  return r;
}

namespace {

// One interleaved row: the station's surface thread's work for one frame, as SurfaceStage does it
// (the fingertip windows, then build_surface with a pool and 8 retired snapshots kept).
struct StationBuild {
  StationBuild(const local::SurfaceOptions& o, const local::HandState& h) : options(o), hand(h) {}
  local::SurfaceOptions options;
  local::HandState hand;
  local::SurfacePool pool;
  std::deque<std::shared_ptr<const Surface>> retired;
  std::vector<double> ms, snapshot_ms;
  std::vector<cv::Rect> windows;  // the last frame's
  std::size_t pixels = 0;         // the last frame's SurfaceBuildStats::pixels_processed

  void run(const local::AssembledFrame& af) {
    local::SurfaceBuildStats stats;
    const double t0 = thread_cpu_ms();
    windows = local::fingertip_windows(hand, af.depth_mm, af.intrinsics, options);
    auto s = local::build_surface(af, options, windows, &stats, &pool);
    ms.push_back(thread_cpu_ms() - t0);
    snapshot_ms.push_back(stats.snapshot_ms);
    pixels = stats.pixels_processed;
    retired.push_back(std::move(s));
    if (retired.size() > 8) retired.pop_front();
  }
};

}  // namespace

local::SurfaceOptions station_surface_options(bool full_frame) {
  local::SurfaceOptions o;  // telex-local's defaults
  o.roi = !full_frame;      // as `telex-local --full-frame` sets it
  o.clock_ms = thread_cpu_ms;
  return o;
}

// The station's per-frame surface work on one desk frame at telex-local's defaults, interleaved so
// that machine load hits all three alike: the whole frame (--full-frame), the windows of one
// fingertip 1 cm above the surface, and a fingertip far away (no windows at all). Each keeps the
// station's ring of 8 retired snapshots, so the pool recycles snapshots 8 frames old.
RoiTiming measure_roi_timing(bool quick) {
  const Intrinsics k = kinect_v1_intrinsics();
  const Frame f =
      synthetic_frame(synth::render(synth::Scene::named("desk"), k, synth::SensorModel{}), 0);
  local::HandState far_hand;
  far_hand.tips[1].valid = true;
  far_hand.tips[1].p_CameraFingertip = {0.0, 0.0, 0.2};  // far in front of the desk
  StationBuild full{station_surface_options(true), f.script.hand};
  StationBuild near{station_surface_options(false), f.script.hand};
  StationBuild none{station_surface_options(false), far_hand};
  const local::AssembledFrame af{f.depth_mm, k, 0, 0, 0, true, local::AssembledPart::Whole, {}, {}};
  for (int i = 0; i < (quick ? 15 : 61); ++i) {
    full.run(af);
    near.run(af);
    none.run(af);
    if (near.windows.size() != 1 || !none.windows.empty())
      throw std::logic_error("expected one window for the near fingertip, none for the far one");
  }
  // The first 8 frames fill the pools (fresh allocations); the rest recycle.
  for (auto* v : {&full.ms, &near.ms, &none.ms, &near.snapshot_ms})
    v->erase(v->begin(), v->begin() + 9);
  RoiTiming t;
  t.full_ms = median(full.ms);
  t.roi_ms = median(near.ms);
  t.none_ms = median(none.ms);
  t.roi_snapshot_ms = median(near.snapshot_ms);
  t.window_px = near.windows[0].area();
  t.recycled = near.pool.recycled();
  t.full_pixels = full.pixels;
  t.roi_pixels = near.pixels;
  t.bilateral_radius_px = near.options.bilateral_options.radius_px;
  t.fill_here = near.options.fill_here;
  return t;
}

}  // namespace telex::tool::bench
