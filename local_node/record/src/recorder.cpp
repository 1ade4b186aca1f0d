// SPDX-License-Identifier: MIT
// Session recording to a ROS 1 bag on a writer thread, and replay through the shipped surface
// build and force model.
#include "telex/local/record/recorder.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <map>
#include <optional>
#include <stdexcept>

#include "telex/bag/bag.h"

namespace telex::local {

namespace {

constexpr const char* kFingerNames[kFingerCount] = {"thumb", "index", "middle", "ring", "little"};

bag::CameraIntrinsics camera_of(const Intrinsics& k) {
  return {k.fx, k.fy, k.cx, k.cy, k.width, k.height};
}

// The rotation taking +z onto `axis` (unit), as (x, y, z, w): a fingertip's pose shows its axis
// as the pose's z.
std::array<double, 4> quat_z_to(const glm::dvec3& axis) {
  const glm::dvec3 z{0, 0, 1};
  const double d = glm::dot(z, axis);
  if (d < -1.0 + 1e-12) return {1, 0, 0, 0};  // half a turn about x
  const glm::dvec3 c = glm::cross(z, axis);
  const double w = 1.0 + d;
  const double n = std::sqrt(w * w + glm::dot(c, c));
  return {c.x / n, c.y / n, c.z / n, w / n};
}

glm::dvec3 z_of(const std::array<double, 4>& q) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  return {2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)};
}

}  // namespace

const char* finger_name(int finger) {
  return finger >= 0 && finger < kFingerCount ? kFingerNames[finger] : "unknown";
}
std::string force_topic(int finger) { return std::string("/telex/force/") + finger_name(finger); }
std::string display_topic(int finger) {
  return std::string("/telex/display/") + finger_name(finger);
}

// ---- the parameters a replay needs ----

nlohmann::json session_config_json(const HapticParams& h, const SurfaceOptions& s, double rate_hz) {
  return {
      {"rate_hz", rate_hz},
      {"haptic",
       {{"stiffness_N_per_m", h.stiffness_N_per_m},
        {"proxy_epsilon_m", h.proxy_epsilon_m},
        {"mu_static", h.mu_static},
        {"mu_dynamic", h.mu_dynamic},
        {"slip_hysteresis", h.slip_hysteresis},
        {"max_force_N", h.max_force_N},
        {"max_force_step_N", h.max_force_step_N},
        {"startup_ramp_s", h.startup_ramp_s},
        {"fade_out_s", h.fade_out_s},
        {"stale_limit_s", h.stale_limit_s},
        {"crossfade_s", h.crossfade_s},
        {"pushout_speed_m_per_s", h.pushout_speed_m_per_s},
        {"virtual_damping_Ns_per_m", h.virtual_damping_Ns_per_m},
        {"passivity_observer", h.passivity_observer},
        {"max_observer_damping_Ns_per_m", h.max_observer_damping_Ns_per_m},
        {"nominal_period_s", h.nominal_period_s},
        {"max_tick_s", h.max_tick_s},
        {"step_abs_m", h.steps.abs_m},
        {"step_rel", h.steps.rel}}},
      {"surface",
       {{"bilateral", s.bilateral},
        {"radius_px", s.bilateral_options.radius_px},
        {"sigma_space_px", s.bilateral_options.sigma_space_px},
        {"sigma_depth_mm", s.bilateral_options.sigma_depth_mm},
        {"sigma_from_noise_model", s.bilateral_options.sigma_from_noise_model},
        {"noise_sigma_factor", s.bilateral_options.noise_sigma_factor},
        {"normal_smooth_radius_px", s.normal_options.smooth_radius_px},
        {"discontinuity_ratio", s.normal_options.discontinuity_ratio},
        {"roi", s.roi},
        {"fill_here", s.fill_here},
        {"roi_radius_m", s.roi_radius_m},
        {"roi_lookahead_s", s.roi_lookahead_s},
        {"roi_min_half_px", s.roi_min_half_px},
        {"roi_max_distance_m", s.roi_max_distance_m}}},
  };
}

void apply_session_config(const nlohmann::json& j, HapticParams& h, SurfaceOptions& s,
                          double& rate_hz) {
  auto take = [](const nlohmann::json& obj, const char* key, auto& field, const char* section) {
    if (!obj.is_object() || !obj.contains(key)) return;
    try {
      field = obj.at(key).get<std::remove_reference_t<decltype(field)>>();
    } catch (const nlohmann::json::exception&) {
      throw std::invalid_argument(fmt::format("session config: {}.{} has the wrong type ({})",
                                              section, key, obj.at(key).dump()));
    }
  };
  take(j, "rate_hz", rate_hz, "");
  if (j.contains("haptic")) {
    const auto& o = j["haptic"];
    const char* sec = "haptic";
    take(o, "stiffness_N_per_m", h.stiffness_N_per_m, sec);
    take(o, "proxy_epsilon_m", h.proxy_epsilon_m, sec);
    take(o, "mu_static", h.mu_static, sec);
    take(o, "mu_dynamic", h.mu_dynamic, sec);
    take(o, "slip_hysteresis", h.slip_hysteresis, sec);
    take(o, "max_force_N", h.max_force_N, sec);
    take(o, "max_force_step_N", h.max_force_step_N, sec);
    take(o, "startup_ramp_s", h.startup_ramp_s, sec);
    take(o, "fade_out_s", h.fade_out_s, sec);
    take(o, "stale_limit_s", h.stale_limit_s, sec);
    take(o, "crossfade_s", h.crossfade_s, sec);
    take(o, "pushout_speed_m_per_s", h.pushout_speed_m_per_s, sec);
    take(o, "virtual_damping_Ns_per_m", h.virtual_damping_Ns_per_m, sec);
    take(o, "passivity_observer", h.passivity_observer, sec);
    take(o, "max_observer_damping_Ns_per_m", h.max_observer_damping_Ns_per_m, sec);
    take(o, "nominal_period_s", h.nominal_period_s, sec);
    take(o, "max_tick_s", h.max_tick_s, sec);
    take(o, "step_abs_m", h.steps.abs_m, sec);
    take(o, "step_rel", h.steps.rel, sec);
  }
  if (j.contains("surface")) {
    const auto& o = j["surface"];
    const char* sec = "surface";
    take(o, "bilateral", s.bilateral, sec);
    take(o, "radius_px", s.bilateral_options.radius_px, sec);
    take(o, "sigma_space_px", s.bilateral_options.sigma_space_px, sec);
    take(o, "sigma_depth_mm", s.bilateral_options.sigma_depth_mm, sec);
    take(o, "sigma_from_noise_model", s.bilateral_options.sigma_from_noise_model, sec);
    take(o, "noise_sigma_factor", s.bilateral_options.noise_sigma_factor, sec);
    take(o, "normal_smooth_radius_px", s.normal_options.smooth_radius_px, sec);
    take(o, "discontinuity_ratio", s.normal_options.discontinuity_ratio, sec);
    take(o, "roi", s.roi, sec);
    take(o, "fill_here", s.fill_here, sec);
    take(o, "roi_radius_m", s.roi_radius_m, sec);
    take(o, "roi_lookahead_s", s.roi_lookahead_s, sec);
    take(o, "roi_min_half_px", s.roi_min_half_px, sec);
    take(o, "roi_max_distance_m", s.roi_max_distance_m, sec);
  }
}

// ---- recording ----

SessionRecorder::SessionRecorder(RecorderConfig config)
    : cfg_(std::move(config)),
      ticks_(cfg_.tick_queue),
      surfaces_(cfg_.surface_queue),
      bodies_(cfg_.body_queue),
      force_every_(cfg_.force_rate_hz > 0 && cfg_.tick_rate_hz > 0
                       ? static_cast<std::uint64_t>(
                             std::max(1.0, std::round(cfg_.tick_rate_hz / cfg_.force_rate_hz)))
                       : 0) {
  if (!(cfg_.force_rate_hz > 0 && cfg_.force_rate_hz <= 10000))
    throw std::invalid_argument(
        fmt::format("--record-rate {} Hz: expected 0 < rate <= 10000", cfg_.force_rate_hz));
  if (!(cfg_.tick_rate_hz > 0))
    throw std::invalid_argument("the recorder needs the haptic loop's rate");
  writer_ = std::make_unique<bag::Writer>(cfg_.path, bag::Compression::Lz4);
  const std::int64_t now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  writer_->text(kConfigTopic, now, cfg_.config_json);
  thread_ = std::jthread([this](std::stop_token st) { writer_loop(st); });
}

SessionRecorder::~SessionRecorder() {
  try {
    finish();
  } catch (...) {
    // finish() does not throw; the writer's errors are in stats().
  }
}

bool SessionRecorder::add_tick(const RecordedTick& tick) { return ticks_.push(tick); }
bool SessionRecorder::add_surface(const RecordedSurface& s) { return surfaces_.push(s); }
bool SessionRecorder::add_bodies(const HandState& state) { return bodies_.push(state); }

RecorderStats SessionRecorder::stats() const {
  if (finished_) return final_;
  RecorderStats s;
  s.ticks = ticks_written_.load();
  s.surfaces = surfaces_written_.load();
  s.body_frames = bodies_written_.load();
  s.dropped_ticks = ticks_.dropped();
  s.dropped_surfaces = surfaces_.dropped();
  s.dropped_bodies = bodies_.dropped();
  std::lock_guard lock(error_mu_);
  s.error = error_;
  return s;
}

RecorderStats SessionRecorder::finish() {
  if (finished_) return final_;
  if (thread_.joinable()) {
    thread_.request_stop();
    thread_.join();
  }
  {
    std::lock_guard lock(error_mu_);
    if (error_.empty()) {
      try {
        writer_->close();
      } catch (const std::exception& e) {
        error_ = e.what();
      }
    }
  }
  final_ = stats();
  finished_ = true;
  return final_;
}

void SessionRecorder::writer_loop(std::stop_token stop) {
  const bool ok = fault_.run([&] {
    try {
      while (!stop.stop_requested())
        if (!write_pending()) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      // The producers have stopped: write what they left.
      while (write_pending()) {
      }
    } catch (const std::exception& e) {
      // A write failed (a full disk): the recording stops here and the station goes on; what
      // comes after is counted as dropped, and telex-local exits 1 naming this at its end.
      spdlog::error(
          "recording stopped: {}; the haptics and the view go on, telex-local will "
          "exit 1 at its end (the bag keeps every whole chunk before this: `rosbag "
          "reindex` reads it back)",
          e.what());
      std::lock_guard lock(error_mu_);
      error_ = e.what();
    }
  });
  if (!ok) {
    const std::string what = fault_.report()->what();
    std::lock_guard lock(error_mu_);
    error_ = what;
  }
}

// Writes what is queued, surfaces first so a tick's surface precedes it in the file. False when
// there was nothing.
bool SessionRecorder::write_pending() {
  bool any = false;
  RecordedSurface s;
  while (surfaces_.pop(s)) {
    write_surface(s);
    s = {};  // release the pixels now, not at the next pop
    any = true;
  }
  HandState h;
  for (int n = 0; n < 64 && bodies_.pop(h); ++n) {
    write_bodies(h);
    any = true;
  }
  RecordedTick t;
  for (int n = 0; n < 256 && ticks_.pop(t); ++n) {
    write_tick(t);
    any = true;
  }
  return any;
}

std::string_view depth_pixels_of_registration(std::string_view registration) {
  if (registration == "hardware") return "sensor colour camera";
  if (registration == "rig") return "right eye";
  if (registration == "none") return "sensor depth (IR) camera";
  return "unknown";
}

void SessionRecorder::write_surface(const RecordedSurface& s) {
  if (!s.registration.empty() && s.registration != registration_written_) {
    const nlohmann::json j{
        {"registration", s.registration},
        {"depth_pixels", std::string(depth_pixels_of_registration(s.registration))}};
    writer_->text(kRemoteTopic, s.built_ns + cfg_.monotonic_to_bag_ns, j.dump());
    registration_written_ = s.registration;
  }
  // Header stamp: its capture time (the remote's clock, on loopback this host's); bag time: when
  // the station built it, which orders the file.
  writer_->depth_mm(kDepthTopic, kDepthInfoTopic, s.capture_ns + cfg_.monotonic_to_bag_ns,
                    static_cast<std::uint32_t>(s.seq), kCameraFrame, s.depth_mm,
                    camera_of(s.intrinsics), s.built_ns + cfg_.monotonic_to_bag_ns);
  surfaces_written_.fetch_add(1);
}

void SessionRecorder::write_bodies(const HandState& h) {
  std::vector<bag::Transform> tf;
  for (int b = 0; b < h.body_count; ++b) {
    const auto& body = h.bodies[static_cast<std::size_t>(b)];
    if (!body.valid) continue;
    bag::Transform t;
    t.parent = "optitrack";
    t.child = fmt::format("optitrack_body_{}", body.id);
    t.pose.p = {body.p_m.x, body.p_m.y, body.p_m.z};
    t.pose.q = {body.q.x, body.q.y, body.q.z, body.q.w};
    tf.push_back(std::move(t));
  }
  if (tf.empty()) return;
  writer_->tf(h.time_ns + cfg_.monotonic_to_bag_ns, tf);
  bodies_written_.fetch_add(1);
}

void SessionRecorder::write_tick(const RecordedTick& t) {
  const std::int64_t stamp = t.t_ns + cfg_.monotonic_to_bag_ns;
  // Every tick: what the model was given. A fingertip's pose is its position with its finger
  // axis as z; an untracked one has the zero quaternion (its position is kept as it was given).
  std::vector<bag::Pose> poses(kFingerCount);
  for (int i = 0; i < kFingerCount; ++i) {
    const auto& in = t.in[static_cast<std::size_t>(i)];
    auto& p = poses[static_cast<std::size_t>(i)];
    p.p = {in.p_ModelFingertip.x, in.p_ModelFingertip.y, in.p_ModelFingertip.z};
    p.q = in.tracked ? quat_z_to(in.axis_Model) : std::array<double, 4>{0, 0, 0, 0};
  }
  writer_->poses(kFingertipsTopic, stamp, static_cast<std::uint32_t>(t.surface_seq), kCameraFrame,
                 poses);
  ticks_written_.fetch_add(1);
  // Every N-th tick written (not by wake-up times, whose jitter would skip some).
  if (tick_count_++ % force_every_ != 0) return;
  std::vector<bag::Transform> tips;
  for (int i = 0; i < kFingerCount; ++i) {
    const auto& f = t.out[static_cast<std::size_t>(i)];
    writer_->wrench(force_topic(i), stamp, kCameraFrame, {f.force_N.x, f.force_N.y, f.force_N.z},
                    {0, 0, 0});
    // The display's command in the finger's own terms: pressure along z, shear along the finger
    // axis as x (docs/RECORDING.md).
    writer_->wrench(display_topic(i), stamp, std::string("telex_") + finger_name(i),
                    {f.shear_along_axis_N, 0, f.normal_force_N}, {0, 0, 0});
    const auto& in = t.in[static_cast<std::size_t>(i)];
    if (in.tracked)
      tips.push_back({kCameraFrame, std::string("telex_fingertip_") + finger_name(i),
                      poses[static_cast<std::size_t>(i)]});
  }
  if (!tips.empty()) writer_->tf(stamp, tips);
}

// ---- replay ----

void read_session_config(const std::string& bag_path, HapticParams& haptic, SurfaceOptions& surface,
                         double& rate_hz) {
  bag::Reader r(bag_path);
  r.select({kConfigTopic});
  bag::Message m;
  if (!r.next(m) || m.kind != bag::Message::Kind::Text)
    throw std::runtime_error(
        fmt::format("bag {} is not a telex session: no std_msgs/String on {} (it holds {})",
                    bag_path, kConfigTopic, r.describe_topics()));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(m.text);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(
        fmt::format("bag {}: {} is not JSON: {}", bag_path, kConfigTopic, e.what()));
  }
  apply_session_config(j, haptic, surface, rate_hz);
}

std::vector<RecordedSurface> read_session_depth(const std::string& bag_path,
                                                std::size_t max_frames) {
  bag::Reader r(bag_path);
  std::uint64_t total = 0;
  for (const auto& t : r.topics())
    if (t.topic == kDepthTopic) total = t.messages;
  if (total == 0)
    throw std::runtime_error(fmt::format("bag {} holds no {} (it holds {})", bag_path, kDepthTopic,
                                         r.describe_topics()));
  const std::uint64_t want = std::min<std::uint64_t>(std::max<std::size_t>(max_frames, 1), total);
  r.select({kDepthTopic, kDepthInfoTopic});
  std::map<std::uint32_t, bag::CameraIntrinsics> infos;
  std::vector<RecordedSurface> out;
  std::vector<bag::Message> images;
  bag::Message m;
  std::uint64_t index = 0, next_pick = 0, picked = 0;
  while (picked < want && r.next(m)) {
    if (m.kind == bag::Message::Kind::CameraInfo) {
      infos[m.seq] = m.camera;
    } else if (m.kind == bag::Message::Kind::Image && m.image.type() == CV_16UC1) {
      // Evenly spread: image i is taken when it reaches the next of want picks over total.
      if (index++ == next_pick) {
        images.push_back(m);
        ++picked;
        next_pick = picked * total / want;
      }
    }
  }
  for (auto& im : images) {
    // Its CameraInfo may follow it at the same bag time: read on until every one is known.
    while (!infos.count(im.seq) && r.next(m))
      if (m.kind == bag::Message::Kind::CameraInfo) infos[m.seq] = m.camera;
    const auto it = infos.find(im.seq);
    if (it == infos.end())
      throw std::runtime_error(fmt::format("bag {}: depth image {} has no CameraInfo on {}",
                                           bag_path, im.seq, kDepthInfoTopic));
    RecordedSurface s;
    s.seq = im.seq;
    s.built_ns = im.bag_time_ns;
    s.capture_ns = im.stamp_ns;
    s.depth_mm = im.image;
    s.intrinsics = {it->second.fx, it->second.fy,    it->second.cx,
                    it->second.cy, it->second.width, it->second.height};
    out.push_back(std::move(s));
    if (out.size() == want) break;
  }
  return out;
}

namespace {

// The recorded surfaces in sequence order, each with the intrinsics of the CameraInfo written
// beside it (same sequence number; the two may come in either order at the same bag time).
class RecordedSurfaces {
 public:
  RecordedSurfaces(const std::string& path, const SurfaceOptions& options)
      : reader_(path), options_(options) {
    reader_.select({kDepthTopic, kDepthInfoTopic});
  }
  // The surface built from recorded sequence `seq`, or the newest before it when `seq` itself
  // was not recorded; null before the first.
  std::shared_ptr<const Surface> at(std::uint64_t seq) {
    while (current_seq_ < seq) {
      if (!pending_ && !read_next()) break;
      if (pending_->seq > seq) break;  // `seq` was not recorded: keep the one before
      build();
    }
    return current_;
  }
  std::uint64_t built() const { return built_; }

 private:
  struct Pending {
    std::uint64_t seq = 0;
    std::int64_t stamp_ns = 0;
    cv::Mat depth_mm;
    std::optional<bag::CameraIntrinsics> camera;
  };

  bool read_next() {
    bag::Message m;
    while (reader_.next(m)) {
      if (m.kind == bag::Message::Kind::CameraInfo) {
        infos_[m.seq] = m.camera;
        continue;
      }
      if (m.kind != bag::Message::Kind::Image) continue;
      if (m.image.type() != CV_16UC1)
        throw std::runtime_error(fmt::format("bag {}: {} holds {}, a session records 16UC1",
                                             reader_.path(), kDepthTopic, m.encoding));
      pending_ = Pending{m.seq, m.stamp_ns, m.image, std::nullopt};
      return true;
    }
    return false;
  }

  void build() {
    // Its CameraInfo: already read, or the next message.
    auto found = infos_.find(pending_->seq);
    bag::Message m;
    while (found == infos_.end() && reader_.next(m)) {
      if (m.kind == bag::Message::Kind::CameraInfo) infos_[m.seq] = m.camera;
      found = infos_.find(pending_->seq);
    }
    if (found == infos_.end())
      throw std::runtime_error(fmt::format("bag {}: depth image {} has no CameraInfo on {}",
                                           reader_.path(), pending_->seq, kDepthInfoTopic));
    AssembledFrame frame;
    frame.depth_mm = pending_->depth_mm;
    frame.intrinsics = {found->second.fx, found->second.fy,    found->second.cx,
                        found->second.cy, found->second.width, found->second.height};
    frame.frame_id = static_cast<std::uint32_t>(pending_->seq);
    frame.capture_ns = pending_->stamp_ns;
    current_ = build_surface(frame, options_, {});
    current_seq_ = pending_->seq;
    infos_.erase(infos_.begin(), std::next(found));
    pending_.reset();
    ++built_;
  }

  bag::Reader reader_;
  SurfaceOptions options_;
  std::map<std::uint64_t, bag::CameraIntrinsics> infos_;
  std::optional<Pending> pending_;
  std::shared_ptr<const Surface> current_;
  std::uint64_t current_seq_ = 0, built_ = 0;
};

}  // namespace

ReplayResult replay_session(const std::string& bag_path, const HapticParams& haptic,
                            const SurfaceOptions& surface_in, const ReplayProgress& progress) {
  haptic.validate();
  bag::Reader ticks(bag_path), forces(bag_path);
  std::uint64_t tick_messages = 0, ticks_read = 0;
  for (const char* needed : {kFingertipsTopic, kDepthTopic}) {
    bool found = false;
    for (const auto& t : ticks.topics()) {
      found = found || t.topic == needed;
      if (t.topic == kFingertipsTopic) tick_messages = t.messages;
    }
    if (!found)
      throw std::runtime_error(fmt::format("bag {} has no {} to replay (it holds {})", bag_path,
                                           needed, ticks.describe_topics()));
  }
  ticks.select({kFingertipsTopic});
  std::vector<std::string> force_topics;
  for (int i = 0; i < kFingerCount; ++i) force_topics.push_back(force_topic(i));
  forces.select(force_topics);
  SurfaceOptions surface = surface_in;
  surface.roi = false;  // the recorded fingertips may be anywhere: build the whole frame
  RecordedSurfaces surfaces(bag_path, surface);

  HapticModel model(haptic, kFingerCount);
  ReplayResult r;
  std::array<FingertipInput, kFingerCount> in{};
  std::array<FingertipForce, kFingerCount> out{};
  bag::Message tick, force;
  bool have_force = forces.next(force);
  double sum_sq = 0;
  auto finger_of = [](const std::string& topic) {
    for (int i = 0; i < kFingerCount; ++i)
      if (topic == force_topic(i)) return i;
    return -1;
  };
  const std::uint64_t progress_every = std::max<std::uint64_t>(1, tick_messages / 100);
  while (ticks.next(tick)) {
    if (progress && ++ticks_read % progress_every == 0 && ticks_read < tick_messages)
      progress(static_cast<double>(ticks_read) / static_cast<double>(tick_messages));
    if (tick.kind != bag::Message::Kind::PoseArray || tick.poses.size() != kFingerCount) continue;
    for (int i = 0; i < kFingerCount; ++i) {
      const auto& p = tick.poses[static_cast<std::size_t>(i)];
      auto& f = in[static_cast<std::size_t>(i)];
      f.p_ModelFingertip = {p.p[0], p.p[1], p.p[2]};
      const double qn = p.q[0] * p.q[0] + p.q[1] * p.q[1] + p.q[2] * p.q[2] + p.q[3] * p.q[3];
      f.tracked = qn > 0.5;
      f.axis_Model = f.tracked ? z_of(p.q) : glm::dvec3{0, -1, 0};
    }
    model.tick(tick.stamp_ns, surfaces.at(tick.seq), in, out);
    ++r.ticks;
    // The recorded forces of this tick (and any left behind by a tick the recording dropped).
    while (have_force && force.stamp_ns <= tick.stamp_ns) {
      const int finger = finger_of(force.topic);
      const glm::dvec3 recorded{force.force_N[0], force.force_N[1], force.force_N[2]};
      r.recorded_peak_N = std::max(r.recorded_peak_N, glm::length(recorded));
      if (force.stamp_ns < tick.stamp_ns || finger < 0) {
        ++r.unmatched;
      } else {
        const glm::dvec3 replayed = out[static_cast<std::size_t>(finger)].force_N;
        const double d = glm::length(replayed - recorded);
        sum_sq += d * d;
        r.max_diff_N = std::max(r.max_diff_N, d);
        r.peak_N = std::max(r.peak_N, glm::length(replayed));
        ++r.rows;
      }
      have_force = forces.next(force);
    }
  }
  while (have_force) {
    ++r.unmatched;
    have_force = forces.next(force);
  }
  r.surfaces = surfaces.built();
  r.rms_diff_N = r.rows ? std::sqrt(sum_sq / static_cast<double>(r.rows)) : 0.0;
  if (progress) progress(1.0);
  return r;
}

}  // namespace telex::local
