// SPDX-License-Identifier: MIT
// The remote's stats line, once a second on stderr: rates, stage times, the link's and the head's
// counters between two snapshots of DaemonStats (--stats full), or the short line (the default):
// rates, the station, the eyes, the head, and only the problem counters that are not zero.
#include <fmt/format.h>

#include <string>

#include "telex/remote/daemon.h"

namespace telex::remote {

std::string format_stats_line(const DaemonStats& now, const DaemonStats& before, double seconds) {
  const double dt = seconds > 0 ? seconds : 1.0;
  std::string ended;  // sessions ended so far, by reason
  for (std::size_t i = 0; i < kSessionEndCount; ++i)
    if (now.sessions_ended[i] != 0)
      ended += fmt::format(" {}={}", session_end_name(static_cast<SessionEnd>(i)),
                           now.sessions_ended[i]);
  const std::uint64_t n = now.frames_processed - before.frames_processed;
  const auto mean = [&](double a, double b) { return n ? (a - b) / static_cast<double>(n) : 0.0; };
  return fmt::format(
      "in {:.1f} out {:.1f} fps | slot-drop {} queue-drop {} | ms reg {:.2f} fill {:.2f} stab "
      "{:.2f} tile {:.2f} enc {:.2f} total {:.2f} first-part {:.2f} rest-cut {} | "
      "{:.1f} kB/s {:.2f} Mbit/s | tiles sent {} skipped {} | video {} pairs {:.2f} Mbit/s "
      "(target {:.2f}) depth {:.2f} Mbit/s failed {} plis {} pair-nacks {} resent {} "
      "pair-over-queue {} intra {} | "
      "station "
      "lost {} delay "
      "{:.1f} ms | client {} (accepted {} "
      "rejected {} timeouts {}) | ended{} | "
      "errors {} malformed {} | auth-failed {} unsealed {} replayed {} udp-ignored {} | "
      "pre-auth-evicted {} pre-auth-timeouts {} accept-errors {} | "
      "key-requests {} nacks {} repaired {} unavailable {} repair-dup {} over-budget {} "
      "over-queue {} control-dropped {} | frames-sent {} | head-in {} "
      "clamped {} rate-limited {} accel-limited {} link-lost {} stale-held {} repeat-held {} "
      "deadman-held {}{} head-errors {} | registration {} | realtime {}/{} | eyes {}",
      static_cast<double>(now.frames_in - before.frames_in) / dt,
      static_cast<double>(now.frames_sent - before.frames_sent) / dt,
      now.frames_slot_dropped - before.frames_slot_dropped,
      now.frames_queue_dropped - before.frames_queue_dropped,
      mean(now.stage_ms_sum.register_ms, before.stage_ms_sum.register_ms),
      mean(now.stage_ms_sum.fill_ms, before.stage_ms_sum.fill_ms),
      mean(now.stage_ms_sum.stabilise_ms, before.stage_ms_sum.stabilise_ms),
      mean(now.stage_ms_sum.tile_ms, before.stage_ms_sum.tile_ms),
      mean(now.stage_ms_sum.encode_ms, before.stage_ms_sum.encode_ms),
      mean(now.stage_ms_sum.total_ms, before.stage_ms_sum.total_ms),
      mean(now.first_part_ms_sum, before.first_part_ms_sum), now.rests_cut - before.rests_cut,
      static_cast<double>(now.bytes_sent - before.bytes_sent) / dt / 1000.0,
      static_cast<double>(now.bytes_sent - before.bytes_sent) * 8.0 / dt / 1e6,
      now.tiles_sent - before.tiles_sent, now.tiles_skipped - before.tiles_skipped,
      now.video_frames - before.video_frames,
      static_cast<double>(now.video_bytes_sent - before.video_bytes_sent) * 8.0 / dt / 1e6,
      static_cast<double>(now.video_bitrate_bps) / 1e6,
      static_cast<double>((now.bytes_sent - now.video_bytes_sent) -
                          (before.bytes_sent - before.video_bytes_sent)) *
          8.0 / dt / 1e6,
      now.video_failed, now.plis_in, now.video_nacks_in, now.video_pairs_resent,
      now.video_repair_over_queue, now.video_intra_requests, now.last_report.fragments_lost,
      static_cast<double>(now.last_report.delay_mean_us) / 1e3, client_state_name(now.client),
      now.clients_accepted, now.clients_rejected, now.client_timeouts,
      ended.empty() ? std::string(" none") : ended, now.source_errors, now.malformed_in,
      now.auth_failed, now.unsealed, now.replayed, now.udp_ignored, now.preauth_evicted,
      now.preauth_timeouts, now.accept_errors, now.key_frame_requests, now.nacks_in,
      now.repair_tiles_sent, now.repair_unavailable, now.repair_duplicates, now.repair_over_budget,
      now.repair_over_queue, now.control_dropped, now.frames_sent, now.head_commands_in,
      now.head_control.clamped, now.head_control.rate_limited, now.head_control.accel_limited,
      now.head_control.link_losses, now.head_control.stale_holds, now.head_control.repeat_holds,
      now.head_control.deadman_holds,
      now.head_holding ? std::string(" holding (") + head_hold_name(now.head_hold) + ")" : "",
      now.head.timeouts + now.head.crc_errors + now.head.bad_packets + now.head.status_errors +
          now.head.hardware_errors + now.head.io_errors,
      depth_registration_name(now.registration), now.realtime_threads, now.path_threads,
      eye_state_name(now.eyes));
}

std::string format_stats_short(const DaemonStats& now, const DaemonStats& before, double seconds) {
  const double dt = seconds > 0 ? seconds : 1.0;
  const auto mbit = [&](std::uint64_t a, std::uint64_t b) {
    return static_cast<double>(a - b) * 8.0 / dt / 1e6;
  };
  // What went wrong, since the start: only the counters that are not zero.
  std::string problems;
  const auto add = [&](const char* name, std::uint64_t n) {
    if (n != 0) problems += fmt::format("{}{} {}", problems.empty() ? "" : ", ", name, n);
  };
  add("source-errors", now.source_errors);
  add("slot-drop", now.frames_slot_dropped);
  add("queue-drop", now.frames_queue_dropped);
  add("malformed", now.malformed_in);
  add("auth-failed", now.auth_failed);
  add("unsealed", now.unsealed);
  add("replayed", now.replayed);
  add("udp-ignored", now.udp_ignored);
  add("pre-auth-evicted", now.preauth_evicted);
  add("pre-auth-timeouts", now.preauth_timeouts);
  add("accept-errors", now.accept_errors);
  add("control-dropped", now.control_dropped);
  add("video-failed", now.video_failed);
  add("client-timeouts", now.client_timeouts);
  add("head-errors", now.head.timeouts + now.head.crc_errors + now.head.bad_packets +
                         now.head.status_errors + now.head.hardware_errors + now.head.io_errors);
  std::string line = fmt::format(
      "in {:.1f} out {:.1f} fps | depth {:.2f} Mbit/s | {} | station {}",
      static_cast<double>(now.frames_in - before.frames_in) / dt,
      static_cast<double>(now.frames_sent - before.frames_sent) / dt,
      mbit(now.bytes_sent - now.video_bytes_sent, before.bytes_sent - before.video_bytes_sent),
      now.video_frames == before.video_frames
          ? std::string("no video sent")
          : fmt::format("video {} pairs {:.2f} Mbit/s", now.video_frames - before.video_frames,
                        mbit(now.video_bytes_sent, before.video_bytes_sent)),
      client_state_name(now.client));
  if (now.head_commands_in != 0)  // a station commands the head (none without a head driver)
    line += fmt::format(
        " | head {} commands{}", now.head_commands_in - before.head_commands_in,
        now.head_holding ? std::string(", holding (") + head_hold_name(now.head_hold) + ")" : "");
  if (now.source_ended) line += " | depth source ended";
  if (!problems.empty()) line += " | " + problems;
  // The same ending as the full line.
  line += fmt::format(" | registration {} | realtime {}/{} | eyes {}",
                      depth_registration_name(now.registration), now.realtime_threads,
                      now.path_threads, eye_state_name(now.eyes));
  return line;
}

}  // namespace telex::remote
