// SPDX-License-Identifier: MIT
// The station's summary as JSON and as the lines telex-local logs at exit.
#include "telex/local/station/station_summary.h"

#include <fmt/format.h>

namespace telex::local {

double StationSummary::stream_mbit_per_s() const {
  return haptic_span_s > 0.0 ? static_cast<double>(bytes_in) * 8e-6 / haptic_span_s : 0.0;
}

double StationSummary::video_mbit_per_s() const {
  return haptic_span_s > 0.0 ? static_cast<double>(video_bytes) * 8e-6 / haptic_span_s : 0.0;
}

double StationSummary::depth_mbit_per_s() const {
  return haptic_span_s > 0.0 ? static_cast<double>(depth_bytes) * 8e-6 / haptic_span_s : 0.0;
}

namespace {

nlohmann::json tracker_json(const TrackerStats& t, const std::string& silent) {
  return {{"frames_in", t.frames_in},
          {"silent", silent},
          {"frames_dropped", t.frames_dropped},
          {"parse_errors", t.parse_errors},
          {"io_errors", t.io_errors},
          {"foreign_datagrams", t.foreign_datagrams},
          {"frame_jumps", t.frame_jumps},
          {"rejected_nonfinite", t.rejected_nonfinite},
          {"rejected_quaternion", t.rejected_quaternion},
          {"rejected_too_fast", t.rejected_too_fast},
          {"frames_rejected", t.frames_rejected},
          {"thread_faults", t.thread_faults}};
}

// The eyes (issue 28) and what a person sees of them and of the body (issue 29).
nlohmann::json video_json(const StationSummary& s) {
  return {// The eyes beside depth (issue 28): message bytes, so the two add up to a
          // little less than the stream (fragment headers and seals).
          {"video_mbit_s", s.video_mbit_per_s()},
          {"depth_mbit_s", s.depth_mbit_per_s()},
          {"video_pairs_received", s.video_pairs_received},
          {"video_pairs_decoded", s.video_pairs_decoded},
          {"video_pairs_with_head_pose", s.video_pairs_with_head_pose},
          {"video_pairs_damaged", s.video_pairs_damaged},
          {"video_decode_errors", s.video_decode_errors},
          {"video_pairs_shown", s.video_pairs_shown},
          {"video_plis_sent", s.video_plis_sent},
          {"video_nacks_sent", s.video_nacks_sent},
          {"video_pairs_repaired", s.video_pairs_repaired},
          {"video_pairs_given_up", s.video_pairs_given_up},
          {"video_pairs_expected", s.video_pairs_expected},
          {"video_pairs_asked_overdue", s.video_pairs_asked_overdue},
          {"video_pairs_queue_dropped", s.video_pairs_queue_dropped},
          {"shown_frame_age_ms_median", s.shown_frame_age_ms_median},
          {"shown_frame_age_ms_p99", s.shown_frame_age_ms_p99},
          {"video_frames_drawn", s.video_frames_drawn},
          {"video_drawn_fresh_share", s.video_frames_drawn > 0
                                          ? static_cast<double>(s.video_pairs_shown) /
                                                static_cast<double>(s.video_frames_drawn)
                                          : 0.0},
          {"video_late_waits", s.video_late_waits},
          {"video_late_waits_met", s.video_late_waits_met},
          {"video_delivered_age_samples", s.video_delivered_age_samples},
          {"video_delivered_age_ms_median", s.video_delivered_age_ms_median},
          {"video_delivered_age_ms_p99", s.video_delivered_age_ms_p99},
          {"video_delivered_age_ms_max", s.video_delivered_age_ms_max},
          {"video_replaced_age_ms_p99", s.video_replaced_age_ms_p99},
          {"video_replaced_age_ms_max", s.video_replaced_age_ms_max},
          {"video_replaced_over_100ms", s.video_replaced_over_100ms},
          {"glass_to_glass_samples", s.glass_to_glass_samples},
          {"glass_to_glass_mismatched", s.glass_to_glass_mismatched},
          {"glass_to_glass_ms_median", s.glass_to_glass_ms_median},
          {"glass_to_glass_ms_p99", s.glass_to_glass_ms_p99},
          {"motion_to_photon_samples", s.motion_to_photon_samples},
          {"motion_to_photon_ms_median", s.motion_to_photon_ms_median},
          {"motion_to_photon_ms_p99", s.motion_to_photon_ms_p99},
          {"capture_to_photon_samples", s.capture_to_photon_samples},
          {"capture_to_photon_ms_median", s.capture_to_photon_ms_median},
          {"capture_to_photon_ms_p99", s.capture_to_photon_ms_p99},
          {"video_eye_width_px", s.video_eye_width_px},
          {"video_eye_height_px", s.video_eye_height_px}};
}

}  // namespace

nlohmann::json StationSummary::to_json() const {
  nlohmann::json threads = nlohmann::json::object();
  for (const auto& [name, how] : thread_scheduling) threads[name] = how;
  nlohmann::json j{{"ticks", ticks},
                   {"haptic_rate_hz", haptic_rate_hz},
                   {"period_median_us", period_median_us},
                   {"period_p99_jitter_us", period_p99_jitter_us},
                   {"wake_latency_median_us", wake_latency_median_us},
                   {"wake_latency_p99_us", wake_latency_p99_us},
                   {"wake_latency_max_us", wake_latency_max_us},
                   {"missed_ticks", missed_ticks},
                   {"ticks_link_silent", ticks_link_silent},
                   {"ticks_tracking_silent", ticks_tracking_silent},
                   {"nominal_rate_hz", nominal_rate_hz},
                   {"haptic_span_s", haptic_span_s},
                   {"log_origin_monotonic_ns", log_origin_monotonic_ns},
                   {"surfaces", surfaces},
                   {"frames", frames},
                   {"roi_parts", roi_parts},
                   {"latency_median_ms", latency_median_ms},
                   {"latency_p99_ms", latency_p99_ms},
                   {"contact_latency_samples", contact_latency_samples},
                   {"contact_latency_median_ms", contact_latency_median_ms},
                   {"contact_latency_p99_ms", contact_latency_p99_ms},
                   {"arrive_median_ms", arrive_median_ms},
                   {"arrive_p99_ms", arrive_p99_ms},
                   {"build_wait_median_ms", build_wait_median_ms},
                   {"build_wait_p99_ms", build_wait_p99_ms},
                   {"peak_pressure_N", peak_pressure_N},
                   {"peak_shear_N", peak_shear_N},
                   {"scheduling", scheduling},
                   {"thread_scheduling", threads},
                   {"memory_locked", memory_locked},
                   {"memory_lock", memory_lock},
                   {"auth_failed", auth_failed},
                   {"unsealed", unsealed},
                   {"replayed", replayed},
                   {"dropped_malformed", dropped_malformed},
                   {"upstream_dropped", upstream_dropped},
                   {"udp_datagrams", udp_datagrams},
                   {"udp_lost", udp_lost},
                   {"bytes_in", bytes_in},
                   // The stream's mean rate over the run (the remote's stats line gives each
                   // second's): issue 16's 10 Mbit/s goal.
                   {"stream_mbit_per_s", stream_mbit_per_s()},
                   {"udp_messages_by_fragments", udp_messages_by_fragments},
                   // Repair (docs/PROTOCOL.md 2.5) and tile ages in frame periods (issue 16).
                   {"tiles_missing", tiles_missing},
                   {"frames_incomplete", frames_incomplete},
                   {"frames_unclosed", frames_unclosed},
                   {"tiles_expired", tiles_expired},
                   {"nacks", nacks},
                   {"tiles_nacked", tiles_nacked},
                   {"watched_tiles_nacked", watched_tiles_nacked},
                   {"tiles_repaired", tiles_repaired},
                   {"repairs_useless", repairs_useless},
                   {"key_frame_requests", key_frame_requests},
                   {"head_commands", head_commands},
                   {"head_samples_stale", head_samples_stale},
                   {"head_deadman_released", head_deadman_released},
                   {"tile_age_watched_samples", tile_age_watched_samples},
                   {"tile_age_watched_median_frames", tile_age_watched_median},
                   {"tile_age_watched_p99_frames", tile_age_watched_p99},
                   {"tile_age_watched_max_frames", tile_age_watched_max},
                   {"tile_age_samples", tile_age_samples},
                   {"tile_age_all_median_frames", tile_age_all_median},
                   {"tile_age_all_p99_frames", tile_age_all_p99},
                   {"tile_age_all_max_frames", tile_age_all_max},
                   {"head_commands_invalid", head_commands_invalid},
                   // The tracker's frames and what its checks dropped (docs/HARDWARE.md, NatNet).
                   {"tracker", tracker_json(tracker, tracker_silent)}};
  j.update(video_json(*this));
  if (!record_file.empty())
    j["record"] = {{"file", record_file},
                   {"ticks", record_ticks},
                   {"surfaces", record_surfaces},
                   {"body_frames", record_body_frames},
                   {"dropped_ticks", record_dropped_ticks},
                   {"dropped_surfaces", record_dropped_surfaces},
                   {"dropped_bodies", record_dropped_bodies},
                   {"error", record_error}};
  if (openxr)
    j["openxr"] = {{"runtime", openxr_runtime},
                   {"eye_width", openxr_eye_width},
                   {"eye_height", openxr_eye_height},
                   {"frames_submitted", openxr_frames_submitted},
                   {"end_reason", openxr_end_reason},
                   {"haptic_ticks_gated", openxr_ticks_gated},
                   {"gate_closed_ns", openxr_gate_closed_ns}};
  if (!hmd_poses_file.empty())
    j["hmd_poses"] = {{"file", hmd_poses_file},
                      {"rows", hmd_poses_rows},
                      {"hmd_taken", hmd_poses_taken},
                      {"unpaired", hmd_poses_unpaired},
                      {"natnet_frames", hmd_poses_natnet_frames},
                      {"hmd_dropped", hmd_poses_dropped}};
  return j;
}

std::string StationSummary::done_text() const {
  const std::string silent = tracker_silent.empty() ? "" : "; " + tracker_silent;
  // Stopped before the first surface (Ctrl-C while connecting): no rates to report.
  if (ticks == 0)
    return fmt::format("done: stopped before the haptic loop started ({} surfaces received){}",
                       surfaces, silent);
  return fmt::format(
      "done: {} ticks at {:.2f} Hz (p99 jitter {:.0f} us, {} missed), {} surfaces, "
      "capture-to-force latency median {:.2f} ms p99 {:.2f} ms (in contact: median {:.2f} ms "
      "p99 {:.2f} ms over {}), peak pressure {:.2f} N, peak shear {:.2f} N{}",
      ticks, haptic_rate_hz, period_p99_jitter_us, missed_ticks, surfaces, latency_median_ms,
      latency_p99_ms, contact_latency_median_ms, contact_latency_p99_ms, contact_latency_samples,
      peak_pressure_N, peak_shear_N, silent);
}

std::string StationSummary::record_text() const {
  if (record_file.empty()) return {};
  return fmt::format(
      "recorded {}: {} ticks, {} surfaces, {} body frames; dropped {} ticks, {} surfaces, {} body "
      "frames{}{}",
      record_file, record_ticks, record_surfaces, record_body_frames, record_dropped_ticks,
      record_dropped_surfaces, record_dropped_bodies,
      record_error.empty() ? "" : "; RECORDING FAILED: ", record_error);
}

}  // namespace telex::local
