// SPDX-License-Identifier: MIT
// The operator station's threads: network (SurfaceClient), surface building, the haptic loop, and
// the main thread for logging, status lines and the operator view.
#include "telex/local/station.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <mutex>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <thread>
#include <vector>

#include "telex/common/latest_slot.h"
#include "telex/local/frame_assembler.h"
#include "telex/local/operator_view.h"
#include "telex/local/periodic.h"
#include "telex/local/spsc_ring.h"
#include "telex/local/triple_buffer.h"

namespace telex::local {
namespace {

using std::chrono::milliseconds;

// What the haptic thread reports per tick; trivially copyable so the ring never allocates.
struct TickSample {
  std::int64_t t_ns = 0;
  std::int64_t period_ns = 0;
  std::uint64_t surface_frame = 0;
  std::int64_t surface_capture_ns = 0;  // remote clock; 0 = no surface yet
  std::array<FingertipForce, kFingerCount> forces{};
  std::array<bool, kFingerCount> tracked{};
  std::array<glm::dvec3, kFingerCount> p_camera{};
};

// Median depth (m) of the valid pixels in the central tenth of the raw frame: where scripts aim.
// The raw frame, not the snapshot: a region-of-interest snapshot holds nothing there yet.
double centre_depth_m(const cv::Mat1w& depth_mm) {
  const int w = std::max(1, depth_mm.cols / 10), h = std::max(1, depth_mm.rows / 10);
  const cv::Mat1w c = depth_mm(cv::Rect((depth_mm.cols - w) / 2, (depth_mm.rows - h) / 2, w, h));
  std::vector<std::uint16_t> v;
  for (auto z : c)
    if (z > 0) v.push_back(z);
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2] * 1e-3;
}

std::string view_dir_of(const std::string& spec) {
  if (spec == "none" || spec.empty()) return {};
  if (spec.rfind("png:", 0) == 0 && spec.size() > 4) return spec.substr(4);
  if (spec == "window") {
    // highgui exits the process when it cannot open a display: refuse up front instead.
    const char* x = std::getenv("DISPLAY");
    const char* w = std::getenv("WAYLAND_DISPLAY");
    if ((x == nullptr || *x == '\0') && (w == nullptr || *w == '\0'))
      throw std::invalid_argument(
          "--view window needs a display (neither DISPLAY nor WAYLAND_DISPLAY is set); use "
          "--view png:DIR to write the view to a file instead");
    return {};
  }
  throw std::invalid_argument("--view '" + spec + "': expected none, window or png:DIR");
}

const char* kFingerNames[kFingerCount] = {"thumb", "index", "middle", "ring", "little"};

cv::Rect grow_rect(const cv::Rect& r, int margin) {
  return {r.x - margin, r.y - margin, r.width + 2 * margin, r.height + 2 * margin};
}

}  // namespace

Station::Station(StationConfig config) : cfg_(std::move(config)) {
  cfg_.haptic.validate();
  if (!(cfg_.rate_hz >= 10 && cfg_.rate_hz <= 10000))
    throw std::invalid_argument("haptic rate must be within 10..10000 Hz");
  if (cfg_.log_every < 1) throw std::invalid_argument("--log-every must be >= 1");
  view_dir_of(cfg_.view_spec);
}

Station::~Station() = default;

StationSummary Station::run() {
  StationSummary summary;
  const std::int64_t t_start = monotonic_ns();
  const std::int64_t period_ns = static_cast<std::int64_t>(std::llround(1e9 / cfg_.rate_hz));

  // ---- outputs first, so a bad device or path fails before anything connects ----
  auto display = make_display(cfg_.haptics_spec, cfg_.display);
  std::ofstream forces_csv;
  if (!cfg_.log_forces_csv.empty()) {
    forces_csv.open(cfg_.log_forces_csv);
    if (!forces_csv)
      throw std::runtime_error("cannot write --log-forces file " + cfg_.log_forces_csv.string());
    forces_csv << "time_s,finger,pressure_N,shear_N,contact,fx_N,fy_N,fz_N,penetration_m,status,"
                  "x_m,y_m,z_m,surface_frame,surface_capture_ns\n";
  }
  std::ofstream tracking_csv;
  if (!cfg_.log_tracking_csv.empty()) {
    tracking_csv.open(cfg_.log_tracking_csv);
    if (!tracking_csv)
      throw std::runtime_error("cannot write --log-tracking file " +
                               cfg_.log_tracking_csv.string());
    tracking_csv << "time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid\n";
  }
  const std::string view_dir = view_dir_of(cfg_.view_spec);
  if (!view_dir.empty()) std::filesystem::create_directories(view_dir);
  const bool view_window = cfg_.view_spec == "window";

  // ---- network thread: tiles -> frames ----
  FrameAssembler assembler(static_cast<std::int64_t>(cfg_.max_tile_age_s * 1e9));
  LatestSlot<AssembledFrame> frames;
  std::mutex video_mu;
  std::vector<std::uint8_t> latest_jpeg;
  ClientEvents events;
  events.on_config = [&](const proto::StreamConfig& c) { assembler.configure(c); };
  events.on_tile = [&](const proto::Header& h, const proto::DepthTile& t) {
    assembler.apply_tile(h, t, monotonic_ns());
  };
  events.on_manifest = [&](const proto::Header& h, const proto::FrameManifest& m) {
    if (auto f = assembler.finish(h, m, monotonic_ns())) frames.put(std::move(*f));
  };
  events.on_video = [&](const proto::Header&, const proto::VideoFrame& v) {
    std::lock_guard lock(video_mu);
    latest_jpeg = v.jpeg;
  };
  events.on_state = [](ClientState s, const std::string& why) {
    std::fprintf(stderr, "telex-local: remote %s: %s\n", std::string(to_string(s)).c_str(),
                 why.c_str());
  };
  events.on_warning = [](const std::string& what) {
    std::fprintf(stderr, "telex-local: %s\n", what.c_str());
  };
  ClientConfig client_cfg = cfg_.client;
  client_cfg.want_video = client_cfg.want_video || view_window || !view_dir.empty();
  SurfaceClient client(client_cfg, std::move(events));
  client.start();

  // ---- surface thread: frames -> snapshots for the haptic loop ----
  TripleBuffer<std::shared_ptr<const Surface>> surfaces;
  TripleBuffer<HandState> hand_for_surface, hand_for_view;
  std::atomic<std::uint64_t> surfaces_built{0};
  std::atomic<double> first_centre_depth{0.0};
  std::atomic<double> build_ms{0.0};
  std::mutex view_mu;
  std::shared_ptr<const Surface> view_surface;
  cv::Mat1w view_depth;
  std::atomic<bool> surface_stop{false};
  std::thread surface_thread([&] {
    // Snapshots the haptic loop may still hold are released here, never on the 1 kHz thread.
    std::deque<std::shared_ptr<const Surface>> retired;
    // Snapshot buffers are recycled once nobody holds them (more than the retired ones + the
    // triple buffer's + the view's), so a frame neither allocates nor zeroes ~5 MB.
    SurfacePool pool(16);
    HandState hand{};
    std::vector<cv::Rect> last_windows;
    std::uint64_t surface_seq = 0;
    std::int64_t built_capture_ns = -1;
    // How far outside a window the filter and the normals read.
    const int reach_px =
        cfg_.surface.bilateral_options.radius_px + cfg_.surface.normal_options.smooth_radius_px + 1;
    while (!surface_stop.load()) {
      auto frame = frames.take(milliseconds(50));
      if (!frame) continue;
      // The rest of a frame whose ROI part is already built: rebuild only when it changed pixels
      // the surface's windows (or the filter reading around them) use.
      if (frame->part == AssembledPart::Rest && frame->capture_ns == built_capture_ns &&
          cfg_.surface.roi) {
        hand_for_surface.take(hand);
        const auto windows =
            fingertip_windows(hand, frame->depth_mm, frame->intrinsics, cfg_.surface);
        bool touches = windows != last_windows;
        for (const auto& w : windows)
          for (const auto& c : frame->changed_since_roi_part)
            touches = touches || (grow_rect(w, reach_px) & c).area() > 0;
        if (!touches) {
          std::lock_guard lock(view_mu);
          view_depth = frame->depth_mm;
          continue;
        }
      }
      built_capture_ns = frame->capture_ns;
      // Snapshot ids are the station's own sequence: a restarted remote numbers its frames from
      // the start again, and the haptic model ignores snapshots that go backwards.
      frame->frame_id = static_cast<std::uint32_t>(++surface_seq);
      hand_for_surface.take(hand);
      std::vector<cv::Rect> windows;
      if (cfg_.surface.roi)
        windows = fingertip_windows(hand, frame->depth_mm, frame->intrinsics, cfg_.surface);
      SurfaceBuildStats st;
      std::shared_ptr<const Surface> s = build_surface(*frame, cfg_.surface, windows, &st, &pool);
      build_ms.store(st.snapshot_ms + st.filter_ms + st.normals_ms);
      if (surfaces_built.load() == 0) first_centre_depth.store(centre_depth_m(frame->depth_mm));
      surfaces.publish(s);
      retired.push_back(s);
      if (retired.size() > 8) retired.pop_front();
      surfaces_built.fetch_add(1);
      {
        std::lock_guard lock(view_mu);
        view_surface = s;
        view_depth = frame->depth_mm;
      }
      if (cfg_.roi_requests && cfg_.surface.roi && windows != last_windows) {
        proto::RoiRequest roi;
        for (const auto& r : windows) {
          if (roi.rects.size() >= proto::kMaxRoiRects) break;
          roi.rects.push_back({static_cast<std::uint16_t>(r.x), static_cast<std::uint16_t>(r.y),
                               static_cast<std::uint16_t>(r.width),
                               static_cast<std::uint16_t>(r.height), 1});
        }
        client.request_roi(roi);
        last_windows = windows;
      }
    }
  });

  auto shutdown = [&] {
    surface_stop.store(true);
    frames.close();
    if (surface_thread.joinable()) surface_thread.join();
    client.stop();
  };

  // ---- wait for the first surface: scripted hands aim at it ----
  const std::int64_t wait_deadline =
      monotonic_ns() + static_cast<std::int64_t>(cfg_.first_surface_timeout_s * 1e9);
  while (surfaces_built.load() == 0 && !stop_.load()) {
    if (monotonic_ns() > wait_deadline) {
      shutdown();
      const auto& cs = client.stats();
      const std::uint64_t auth_drops = cs.auth_failed.load() + cs.unexpected_tag.load();
      if (auth_drops > 0)
        throw std::runtime_error(
            "no depth surface from the remote at " + cfg_.client.host + ":" +
            std::to_string(cfg_.client.port) + ": authentication failed (" +
            std::to_string(cs.auth_failed.load()) + " message(s) with a missing or wrong tag, " +
            std::to_string(cs.unexpected_tag.load()) +
            " tagged while this station has no key; see the lines above): start both daemons "
            "with the same --psk FILE, or neither");
      throw std::runtime_error(
          "no depth surface from the remote at " + cfg_.client.host + ":" +
          std::to_string(cfg_.client.port) + " within " +
          std::to_string(static_cast<int>(cfg_.first_surface_timeout_s)) +
          " s: is telex-remote running and listening there (telex-remote --listen HOST:PORT)?");
    }
    std::this_thread::sleep_for(milliseconds(10));
  }
  if (stop_.load()) {
    shutdown();
    return summary;
  }
  TrackerConfig tracker_cfg = cfg_.tracker;
  if (first_centre_depth.load() > 0) tracker_cfg.surface_depth_m = first_centre_depth.load();
  std::unique_ptr<HandTracker> tracker;
  try {
    tracker = make_tracker(cfg_.hand_spec, tracker_cfg);
  } catch (...) {
    shutdown();
    throw;
  }
  std::fprintf(stderr, "telex-local: surface at %.3f m ahead; hand %s; haptics %s\n",
               tracker_cfg.surface_depth_m, tracker->name().c_str(), display->name().c_str());

  // ---- haptic thread ----
  SpscRing<TickSample> samples(1 << 14);
  SpscRing<HandState> tracking(tracking_csv.is_open() ? 1024 : 1);
  std::atomic<bool> haptic_stop{false};
  std::string scheduling;
  std::atomic<bool> scheduling_ready{false};
  std::atomic<std::uint64_t> missed{0};
  HapticModel model(cfg_.haptic, kFingerCount);
  std::thread haptic_thread([&] {
    scheduling = cfg_.realtime ? try_realtime(80) : std::string("default scheduling");
    scheduling_ready.store(true);
    PeriodicTimer timer(period_ns);
    std::shared_ptr<const Surface> newest;
    HandState hand{};
    std::array<FingertipInput, kFingerCount> in{};
    std::array<FingertipForce, kFingerCount> out{};
    std::array<FingerForce, kFingerCount> shown{};
    TickSample sample{};
    std::int64_t prev = 0;
    const std::int64_t tracking_stale_ns =
        static_cast<std::int64_t>(cfg_.haptic.stale_limit_s * 1e9);
    while (!haptic_stop.load(std::memory_order_relaxed)) {
      const std::int64_t now = timer.wait_next();
      if (tracker->poll(now, hand)) {
        hand_for_surface.publish(hand);
        hand_for_view.publish(hand);
        if (hand.bodies_fresh && hand.body_count > 0) tracking.push(hand);
      }
      surfaces.take(newest);
      const bool fresh = now - hand.time_ns <= tracking_stale_ns;
      for (int i = 0; i < kFingerCount; ++i) {
        const auto& tip = hand.tips[static_cast<std::size_t>(i)];
        in[static_cast<std::size_t>(i)] = {tip.p_camera_m, tip.axis_camera, tip.valid && fresh};
      }
      model.tick(now, newest, in, out);
      for (int i = 0; i < kFingerCount; ++i) {
        const auto& f = out[static_cast<std::size_t>(i)];
        shown[static_cast<std::size_t>(i)] = {i, f.normal_force_N, f.shear_along_axis_N, f.contact};
      }
      display->write(now, shown);
      sample.t_ns = now;
      sample.period_ns = prev ? now - prev : period_ns;
      prev = now;
      sample.surface_frame = newest ? newest->frame_id : 0;
      sample.surface_capture_ns = newest ? newest->capture_ns : 0;
      sample.forces = out;
      for (int i = 0; i < kFingerCount; ++i) {
        sample.tracked[static_cast<std::size_t>(i)] = in[static_cast<std::size_t>(i)].tracked;
        sample.p_camera[static_cast<std::size_t>(i)] = in[static_cast<std::size_t>(i)].p_camera;
      }
      samples.push(sample);
      missed.store(timer.missed(), std::memory_order_relaxed);
    }
    // Release the device: zero force on every finger.
    for (auto& s : shown) s = {s.finger, 0.0, 0.0, false};
    display->write(monotonic_ns(), shown);
  });
  while (!scheduling_ready.load()) std::this_thread::sleep_for(milliseconds(1));
  summary.scheduling = scheduling;
  std::fprintf(stderr, "telex-local: haptic loop at %.0f Hz, %s\n", cfg_.rate_hz,
               scheduling.c_str());

  // ---- main thread: drain samples, log, print, view ----
  // Whole-run statistics in fixed memory, so a long run's resident size stays flat.
  Histogram period_us(1.0, 20'000), jitter_us(1.0, 20'000), latency_ms(0.1, 20'000),
      contact_latency_ms(0.1, 20'000);
  std::vector<std::int64_t> window_periods;
  std::vector<double> window_latency;
  TickSample s{};
  TickSample last{};
  HandState view_hand{};
  std::uint64_t tick_index = 0;
  std::uint64_t last_latency_frame = 0;
  std::int64_t last_latency_capture = 0;
  std::int64_t next_status = monotonic_ns() + 1'000'000'000;
  const std::int64_t print_period =
      cfg_.print_forces_hz > 0 ? static_cast<std::int64_t>(1e9 / cfg_.print_forces_hz) : 0;
  std::int64_t next_print = monotonic_ns();
  std::uint64_t surfaces_at_last_status = 0;
  const std::int64_t end_ns =
      cfg_.duration_s > 0 ? t_start + static_cast<std::int64_t>(cfg_.duration_s * 1e9) : 0;

  auto drain = [&] {
    while (samples.pop(s)) {
      ++tick_index;
      last = s;
      if (tick_index > 1) {
        period_us.add(static_cast<double>(s.period_ns) / 1e3);
        jitter_us.add(std::abs(static_cast<double>(s.period_ns - period_ns)) / 1e3);
        window_periods.push_back(s.period_ns);
      }
      // Capture-to-force latency: measured at the first tick that renders a newly arrived surface
      // of a new capture (a frame's rest rebuilding its surface is not a new capture).
      if (s.surface_capture_ns != 0 && s.surface_frame != last_latency_frame &&
          s.surface_capture_ns != last_latency_capture) {
        last_latency_frame = s.surface_frame;
        last_latency_capture = s.surface_capture_ns;
        const std::int64_t offset = client.stats().clock_offset_ns.load();
        const double lat = static_cast<double>(s.t_ns - (s.surface_capture_ns - offset)) / 1e6;
        latency_ms.add(lat);
        window_latency.push_back(lat);
        // The same, for surfaces first rendered while a finger touches them: the samples whose
        // force depends on the surface's age (a surface no fingertip is near renders 0 N at any
        // age; with --roi the remote then processes whole frames, not ROI parts).
        if (std::any_of(s.forces.begin(), s.forces.end(), [](const auto& f) { return f.contact; }))
          contact_latency_ms.add(lat);
      }
      for (const auto& f : s.forces) {
        summary.peak_pressure_N = std::max(summary.peak_pressure_N, f.normal_force_N);
        summary.peak_shear_N = std::max(summary.peak_shear_N, std::abs(f.shear_along_axis_N));
      }
      if (forces_csv.is_open() &&
          (tick_index - 1) % static_cast<std::uint64_t>(cfg_.log_every) == 0) {
        const double t = static_cast<double>(s.t_ns - t_start) / 1e9;
        for (int i = 0; i < kFingerCount; ++i) {
          if (!s.tracked[static_cast<std::size_t>(i)] &&
              !s.forces[static_cast<std::size_t>(i)].contact)
            continue;
          const auto& f = s.forces[static_cast<std::size_t>(i)];
          const auto& p = s.p_camera[static_cast<std::size_t>(i)];
          char row[400];
          std::snprintf(row, sizeof row,
                        "%.6f,%s,%.6f,%.6f,%d,%.6f,%.6f,%.6f,%.6f,%s,%.6f,%.6f,%.6f,%llu,%lld\n", t,
                        kFingerNames[i], f.normal_force_N, f.shear_along_axis_N, f.contact ? 1 : 0,
                        f.force_N.x, f.force_N.y, f.force_N.z, f.penetration_m,
                        std::string(to_string(f.status)).c_str(), p.x, p.y, p.z,
                        static_cast<unsigned long long>(s.surface_frame),
                        static_cast<long long>(s.surface_capture_ns));
          forces_csv << row;
        }
      }
      if (print_period && s.t_ns >= next_print) {
        next_print = s.t_ns + print_period;
        std::string line =
            "t=" + std::to_string(static_cast<double>(s.t_ns - t_start) / 1e9).substr(0, 6) + "s";
        for (int i = 0; i < kFingerCount; ++i) {
          const auto& f = s.forces[static_cast<std::size_t>(i)];
          if (!s.tracked[static_cast<std::size_t>(i)]) continue;
          char b[96];
          std::snprintf(b, sizeof b, "  %s P=%5.2fN S=%+5.2fN%s", kFingerNames[i], f.normal_force_N,
                        f.shear_along_axis_N, f.contact ? " contact" : "");
          line += b;
        }
        std::printf("%s\n", line.c_str());
        std::fflush(stdout);
      }
    }
  };

  HandState tracked_state{};
  auto drain_tracking = [&] {
    while (tracking.pop(tracked_state)) {
      if (!tracking_csv.is_open()) continue;
      const double t = static_cast<double>(tracked_state.time_ns - t_start) / 1e9;
      for (int b = 0; b < tracked_state.body_count; ++b) {
        const auto& body = tracked_state.bodies[static_cast<std::size_t>(b)];
        char row[256];
        std::snprintf(row, sizeof row, "%.6f,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n", t,
                      body.id, body.p_m.x, body.p_m.y, body.p_m.z, body.q.x, body.q.y, body.q.z,
                      body.q.w, body.valid ? 1 : 0);
        tracking_csv << row;
      }
    }
  };

  auto status_text = [&](double fps) {
    const auto ps = summarize_periods(window_periods, period_ns);
    char b[256];
    std::snprintf(b, sizeof b,
                  "surface %.1f fps | latency %.1f ms | haptic %.1f Hz jitter p99 %.0f us | "
                  "build %.1f ms | %s",
                  fps, percentile(window_latency, 0.5), ps.mean_rate_hz, ps.p99_jitter_us,
                  build_ms.load(), std::string(to_string(client.state())).c_str());
    return std::string(b);
  };

  std::string last_status = "starting";
  auto render_view = [&] {
    ViewInputs vi;
    std::shared_ptr<const Surface> vs;
    {
      std::lock_guard lock(view_mu);
      vs = view_surface;
      vi.depth_mm = view_depth;
    }
    vi.surface = vs.get();
    hand_for_view.take(view_hand);
    vi.hand = view_hand;
    vi.forces = last.forces;
    vi.status = last_status;
    {
      std::lock_guard lock(video_mu);
      if (!latest_jpeg.empty()) {
        cv::Mat raw(1, static_cast<int>(latest_jpeg.size()), CV_8U, latest_jpeg.data());
        vi.camera_bgr = cv::imdecode(raw, cv::IMREAD_COLOR);
      }
    }
    return render_operator_view(vi);
  };
  std::int64_t next_window = 0;

  while (!stop_.load()) {
    std::this_thread::sleep_for(milliseconds(5));
    if (view_window && monotonic_ns() >= next_window) {
      // A window at 20 Hz; highgui runs its event loop in waitKey on this thread.
      next_window = monotonic_ns() + 50'000'000;
      cv::imshow("telex-local", render_view());
      if (cv::waitKey(1) == 27) break;  // Esc closes the station
    }
    drain();
    drain_tracking();
    const std::int64_t now = monotonic_ns();
    if (end_ns && now >= end_ns) break;
    if (now >= next_status) {
      const std::uint64_t built = surfaces_built.load();
      const double fps = static_cast<double>(built - surfaces_at_last_status);
      surfaces_at_last_status = built;
      next_status += 1'000'000'000;
      const std::string text = status_text(fps);
      if (cfg_.status_line) {
        std::string forces;
        for (int i = 0; i < kFingerCount; ++i) {
          if (!last.tracked[static_cast<std::size_t>(i)]) continue;
          char b[48];
          std::snprintf(b, sizeof b, " %s %.2f/%+.2fN", kFingerNames[i],
                        last.forces[static_cast<std::size_t>(i)].normal_force_N,
                        last.forces[static_cast<std::size_t>(i)].shear_along_axis_N);
          forces += b;
        }
        std::fprintf(stderr, "telex-local: %s |%s\n", text.c_str(), forces.c_str());
      }
      last_status = text;
      if (!view_dir.empty()) {
        const cv::Mat3b img = render_view();
        const auto path = std::filesystem::path(view_dir) / "view.png";
        const auto tmp = std::filesystem::path(view_dir) / "view.tmp.png";
        if (cv::imwrite(tmp.string(), img)) std::filesystem::rename(tmp, path);
      }
      window_periods.clear();
      window_latency.clear();
    }
  }

  haptic_stop.store(true);
  haptic_thread.join();
  drain();
  drain_tracking();
  shutdown();
  if (forces_csv.is_open()) forces_csv.flush();

  summary.ticks = tick_index;
  summary.haptic_rate_hz =
      period_us.count() ? 1e6 * static_cast<double>(period_us.count()) / period_us.sum() : 0.0;
  summary.period_p99_jitter_us = jitter_us.quantile(0.99);
  summary.period_median_us = period_us.quantile(0.5);
  summary.missed_ticks = missed.load();
  summary.surfaces = surfaces_built.load();
  summary.frames = assembler.counters().frames;  // the network thread has stopped
  summary.roi_parts = assembler.counters().roi_parts;
  summary.latency_median_ms = latency_ms.quantile(0.5);
  summary.latency_p99_ms = latency_ms.quantile(0.99);
  summary.contact_latency_samples = contact_latency_ms.count();
  summary.contact_latency_median_ms = contact_latency_ms.quantile(0.5);
  summary.contact_latency_p99_ms = contact_latency_ms.quantile(0.99);
  summary.auth_failed = client.stats().auth_failed.load();
  summary.unexpected_tag = client.stats().unexpected_tag.load();
  summary.replayed = client.stats().replayed.load();
  summary.dropped_malformed = client.stats().dropped_malformed.load();
  return summary;
}

}  // namespace telex::local
