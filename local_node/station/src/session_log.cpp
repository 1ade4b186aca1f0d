// SPDX-License-Identifier: MIT
// The run's CSV logs and ROS bag.
#include "session_log.h"

#include <chrono>
#include <cstdio>
#include <stdexcept>

#include "telex/base/periodic.h"

namespace telex::local {
namespace {

std::ofstream open_csv(const std::filesystem::path& path, const char* flag, const char* header) {
  std::ofstream out;
  if (path.empty()) return out;
  out.open(path);
  if (!out)
    throw std::runtime_error(std::string("cannot write ") + flag + " file " + path.string());
  out << header;
  return out;
}

std::unique_ptr<SessionRecorder> open_recorder(const StationConfig& cfg) {
  if (cfg.record_bag.empty()) return nullptr;
  RecorderConfig rc;
  rc.path = cfg.record_bag.string();
  rc.force_rate_hz = cfg.record_rate_hz;
  rc.tick_rate_hz = cfg.rate_hz;
  rc.monotonic_to_bag_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count() -
                           monotonic_ns();
  auto j = session_config_json(cfg.haptic, cfg.surface, cfg.rate_hz);
  j["station"] = {{"hand", cfg.hand_spec},
                  {"haptics", cfg.haptics_spec},
                  {"remote", cfg.client.host + ":" + std::to_string(cfg.client.port)},
                  {"max_tile_age_s", cfg.max_tile_age_s}};
  rc.config_json = j.dump();
  return std::make_unique<SessionRecorder>(std::move(rc));
}

}  // namespace

SessionLog::SessionLog(const StationConfig& cfg, std::int64_t t_start_ns)
    : cfg_(cfg),
      t_start_ns_(t_start_ns),
      forces_csv_(open_csv(cfg.log_forces_csv, "--log-forces",
                           "time_s,finger,pressure_N,shear_N,contact,fx_N,fy_N,fz_N,penetration_m,"
                           "status,x_m,y_m,z_m,surface_frame,surface_capture_ns\n")),
      tracking_csv_(open_csv(cfg.log_tracking_csv, "--log-tracking",
                             "time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid\n")),
      hmd_csv_(open_csv(cfg.record_hmd_poses_csv, "--record-hmd-poses",
                        "# telex-local --record-hmd-poses: for telex calibrate hmd --poses "
                        "(docs/RIG.md section 3)\n"
                        "time_s,stage_view_x_m,stage_view_y_m,stage_view_z_m,stage_view_qx,"
                        "stage_view_qy,stage_view_qz,stage_view_qw,natnet_head_x_m,natnet_head_y_m,"
                        "natnet_head_z_m,natnet_head_qx,natnet_head_qy,natnet_head_qz,"
                        "natnet_head_qw\n")),
      recorder_(open_recorder(cfg)) {}

void SessionLog::add_tick(const TickSample& s, std::uint64_t tick_index) {
  if (recorder_) {
    RecordedTick t;
    t.t_ns = s.t_ns;
    t.surface_seq = s.surface_frame;
    for (std::size_t i = 0; i < kFingerCount; ++i)
      t.in[i] = {s.p_CameraFingertip[i], s.axis_Camera[i], s.tracked[i]};
    t.out = s.forces;
    recorder_->add_tick(t);
  }
  if (forces_csv_.is_open() && (tick_index - 1) % static_cast<std::uint64_t>(cfg_.log_every) == 0)
    write_forces(s);
}

void SessionLog::write_forces(const TickSample& s) {
  const double t = static_cast<double>(s.t_ns - t_start_ns_) / 1e9;
  for (std::size_t i = 0; i < kFingerCount; ++i) {
    if (!s.tracked[i] && !s.forces[i].contact) continue;
    const auto& f = s.forces[i];
    const auto& p = s.p_CameraFingertip[i];
    char row[400];
    std::snprintf(
        row, sizeof row, "%.6f,%s,%.6f,%.6f,%d,%.6f,%.6f,%.6f,%.6f,%s,%.6f,%.6f,%.6f,%llu,%lld\n",
        t, kFingerNames[i], f.normal_force_N, f.shear_along_axis_N, f.contact ? 1 : 0, f.force_N.x,
        f.force_N.y, f.force_N.z, f.penetration_m, std::string(to_string(f.status)).c_str(), p.x,
        p.y, p.z, static_cast<unsigned long long>(s.surface_frame),
        static_cast<long long>(s.surface_capture_ns));
    forces_csv_ << row;
  }
}

void SessionLog::add_bodies(const HandState& state) {
  if (recorder_) recorder_->add_bodies(state);
  if (hmd_csv_.is_open() && state.bodies_sampled_ns != 0) {
    for (int b = 0; b < state.body_count; ++b) {
      const auto& body = state.bodies[static_cast<std::size_t>(b)];
      if (body.id == cfg_.tracker.head_body_id && body.valid)
        hmd_pairer_.add_natnet(state.bodies_sampled_ns, Pose{body.p_m, body.q});
    }
    write_hmd_rows();
  }
  if (!tracking_csv_.is_open()) return;
  const double t = static_cast<double>(state.time_ns - t_start_ns_) / 1e9;
  for (int b = 0; b < state.body_count; ++b) {
    const auto& body = state.bodies[static_cast<std::size_t>(b)];
    char row[256];
    std::snprintf(row, sizeof row, "%.6f,%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d\n", t, body.id,
                  body.p_m.x, body.p_m.y, body.p_m.z, body.q.x, body.q.y, body.q.z, body.q.w,
                  body.valid ? 1 : 0);
    tracking_csv_ << row;
  }
}

void SessionLog::add_hmd_pose(std::int64_t t_ns, const Pose& X_StageView) {
  if (!hmd_csv_.is_open()) return;
  hmd_pairer_.add_hmd(t_ns, X_StageView);
  write_hmd_rows();
}

void SessionLog::write_hmd_rows() {
  HmdPoseRow r;
  while (hmd_pairer_.pop(r)) {
    const Pose& v = r.X_StageView;
    const Pose& h = r.X_NatNetHead;
    char row[400];
    std::snprintf(row, sizeof row,
                  "%.6f,%.6f,%.6f,%.6f,%.7f,%.7f,%.7f,%.7f,%.6f,%.6f,%.6f,%.7f,%.7f,%.7f,%.7f\n",
                  static_cast<double>(r.t_ns - t_start_ns_) / 1e9, v.p_m.x, v.p_m.y, v.p_m.z, v.q.x,
                  v.q.y, v.q.z, v.q.w, h.p_m.x, h.p_m.y, h.p_m.z, h.q.x, h.q.y, h.q.z, h.q.w);
    hmd_csv_ << row;
  }
}

void SessionLog::finish() {
  if (forces_csv_.is_open()) forces_csv_.flush();
  if (hmd_csv_.is_open()) hmd_csv_.flush();
  if (recorder_) recorder_->finish();  // everything queued is written and the bag closed
}

void SessionLog::summarize(StationSummary& s) const {
  if (hmd_csv_.is_open()) {
    const HmdPosePairerStats h = hmd_pairer_.stats();
    s.hmd_poses_file = cfg_.record_hmd_poses_csv.string();
    s.hmd_poses_rows = h.rows;
    s.hmd_poses_taken = h.hmd_taken;
    s.hmd_poses_unpaired = h.unpaired;
    s.hmd_poses_natnet_frames = h.natnet_frames;
  }
  if (!recorder_) return;
  const RecorderStats r = recorder_->finish();
  s.record_file = cfg_.record_bag.string();
  s.record_ticks = r.ticks;
  s.record_surfaces = r.surfaces;
  s.record_body_frames = r.body_frames;
  s.record_dropped_ticks = r.dropped_ticks;
  s.record_dropped_surfaces = r.dropped_surfaces;
  s.record_dropped_bodies = r.dropped_bodies;
  s.record_error = r.error;
}

}  // namespace telex::local
