// SPDX-License-Identifier: MIT
// What one station run measured: the summary Station::run returns, its JSON (telex-local
// --json-summary, read by the tests and tools) and its one-line reports.
#pragma once

#include <array>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "telex/local/inputs/tracker.h"

namespace telex::local {

// Summary a run returns (and the status line prints), for tests and the benchmark report.
struct StationSummary {
  std::uint64_t ticks = 0;
  double haptic_rate_hz = 0;
  double period_p99_jitter_us = 0;
  double period_median_us = 0;
  // Each tick's wake-up less its deadline (cyclictest's measure, comparable to its figures).
  double wake_latency_median_us = 0, wake_latency_p99_us = 0, wake_latency_max_us = 0;
  std::uint64_t missed_ticks = 0;
  // Ticks whose force was zeroed for the link's silence (--link-silence-ms) or the tracker's
  // (--tracking-silence-ms).
  std::uint64_t ticks_link_silent = 0, ticks_tracking_silent = 0;
  // The haptic loop's nominal rate and the time from its first deadline to its last: every
  // deadline is ticked or missed, so ticks + missed_ticks = span * rate + 1 (PeriodicTimer).
  double nominal_rate_hz = 0;
  double haptic_span_s = 0;
  // CLOCK_MONOTONIC (ns) at the logs' time 0: the time_s of --log-forces and --log-tracking rows
  // is (monotonic - this) / 1e9, so other processes' events can be put on the same time base.
  std::int64_t log_origin_monotonic_ns = 0;
  std::uint64_t surfaces = 0;
  std::uint64_t frames = 0;      // depth frames assembled (closing manifests)
  std::uint64_t roi_parts = 0;   // frames whose ROI part was published before the rest
  double latency_median_ms = 0;  // capture (remote clock, offset-corrected) to force output
  double latency_p99_ms = 0;
  // Over the surfaces first rendered while a finger was in contact (the force-carrying samples).
  std::uint64_t contact_latency_samples = 0;
  double contact_latency_median_ms = 0;
  double contact_latency_p99_ms = 0;
  // Of every surface built from a new frame or part: capture to its manifest's arrival, and from
  // that arrival to the surface's publication.
  double arrive_median_ms = 0, arrive_p99_ms = 0, build_wait_median_ms = 0, build_wait_p99_ms = 0;
  double peak_pressure_N = 0;
  double peak_shear_N = 0;
  std::string scheduling;  // the haptic thread's
  // The process's memory lock (telex::lock_memory): locked, or why not.
  bool memory_locked = false;
  std::string memory_lock;
  // Per thread on the depth-to-force path (surface, network, haptic, tracking): what it got.
  std::vector<std::pair<std::string, std::string>> thread_scheduling;
  // Messages the surface client dropped (ClientStats): authentication, replays, malformed.
  std::uint64_t auth_failed = 0, unsealed = 0, replayed = 0, dropped_malformed = 0;
  std::uint64_t upstream_dropped = 0;  // messages to the remote dropped behind a stalled write
  // The depth stream over UDP: datagrams received, and those the reassembler knows were lost.
  std::uint64_t udp_datagrams = 0, udp_lost = 0;
  std::uint64_t bytes_in = 0;  // everything the remote sent (TCP and UDP, headers and tags)
  std::array<std::uint64_t, 8> udp_messages_by_fragments{};  // [n - 1]: messages of n fragments
  // Whole messages' bytes by stream (ClientStats): the eyes' EncodedVideo and depth.
  std::uint64_t video_bytes = 0, depth_bytes = 0;
  // The eyes (VideoReceiver): pairs received, decoded whole, decoded on a missing reference (not
  // shown), refused; distinct pairs the view showed; PLIs sent; and the age of each pair shown
  // (display time minus capture time, the remote's clock).
  std::uint64_t video_pairs_received = 0, video_pairs_decoded = 0, video_pairs_damaged = 0;
  std::uint64_t video_decode_errors = 0, video_pairs_shown = 0, video_plis_sent = 0;
  // Repair (VideoReorder): NACKs sent, missing pairs that came in time, missing pairs given up at
  // their deadline, and the pairs the encoder's sequence accounts for (arrived or given up): the
  // share of those decoded whole is the share of the remote's pairs a person could see.
  std::uint64_t video_nacks_sent = 0, video_pairs_repaired = 0, video_pairs_given_up = 0;
  std::uint64_t video_pairs_expected = 0;
  std::uint64_t video_pairs_asked_overdue = 0;  // asked for before a later pair showed the gap
  // Dropped before decoding: the decode thread (nice 5) fell kMaxQueued pairs behind.
  std::uint64_t video_pairs_queue_dropped = 0;
  // Pairs decoded whole that carried the robot head's joints at their capture (the warp turns
  // the video from them; without, from the depth frame's).
  std::uint64_t video_pairs_with_head_pose = 0;
  double shown_frame_age_ms_median = 0, shown_frame_age_ms_p99 = 0;
  // Frames the view drew with a pair: video_pairs_shown of them took one not drawn before.
  std::uint64_t video_frames_drawn = 0;
  // On screen the pair is taken once the body is drawn; when the next pair was due within
  // kMaxLatePairWaitNs the view waited for it: that many times, and how often it came in time.
  std::uint64_t video_late_waits = 0, video_late_waits_met = 0;
  // Every pair decoded whole, not only the drawn ones (VideoReceiver::DeliveryAges): capture to
  // delivery to the view, and the age the previous pair had reached when it was replaced (what a
  // display at any rate showed at worst), with how many of those exceeded 3 periods at 30 Hz.
  std::uint64_t video_delivered_age_samples = 0, video_replaced_over_100ms = 0;
  double video_delivered_age_ms_median = 0, video_delivered_age_ms_p99 = 0;
  double video_delivered_age_ms_max = 0, video_replaced_age_ms_p99 = 0;
  double video_replaced_age_ms_max = 0;
  // Glass to glass: capture to the rendered eye handed to the display (PNG, window), for pairs
  // whose frame counter read back from that image is their id (synthetic eyes stamp it).
  std::uint64_t glass_to_glass_samples = 0, glass_to_glass_mismatched = 0;
  double glass_to_glass_ms_median = 0, glass_to_glass_ms_p99 = 0;
  int video_eye_width_px = 0, video_eye_height_px = 0;  // of the newest pair decoded
  // Latency a person notices, per stereo frame handed to the display (PNGs written, the window
  // swapped, xrEndFrame returned): from the body or head sample it drew (HandState::motion_ns),
  // and from the capture of the eyes' pair it drew (the remote's clock, offset-corrected).
  std::uint64_t motion_to_photon_samples = 0, capture_to_photon_samples = 0;
  double motion_to_photon_ms_median = 0, motion_to_photon_ms_p99 = 0;
  double capture_to_photon_ms_median = 0, capture_to_photon_ms_p99 = 0;
  // Repair (FrameAssembler's counters) and tile ages in frame periods at each closed frame: the
  // tiles under the fingertip windows, and all tiles.
  std::uint64_t tiles_missing = 0, frames_incomplete = 0, frames_unclosed = 0, tiles_expired = 0;
  std::uint64_t nacks = 0, tiles_nacked = 0, watched_tiles_nacked = 0, tiles_repaired = 0,
                repairs_useless = 0;
  std::uint64_t key_frame_requests = 0;
  std::uint64_t head_commands = 0;  // head poses sent to the remote (head teleoperation)
  // ... of them, sent with a tracking sample older than 100 ms (tracking lost: the remote holds),
  // and with the dead-man released.
  std::uint64_t head_samples_stale = 0, head_deadman_released = 0;
  std::uint64_t tile_age_samples = 0, tile_age_watched_samples = 0;
  double tile_age_watched_median = 0, tile_age_watched_p99 = 0, tile_age_watched_max = 0;
  double tile_age_all_median = 0, tile_age_all_p99 = 0, tile_age_all_max = 0;
  // --record: the bag written (empty: not recording), what was written and what the queues
  // dropped; record_error when writing failed.
  std::string record_file;
  std::uint64_t record_ticks = 0, record_surfaces = 0, record_body_frames = 0;
  std::uint64_t record_dropped_ticks = 0, record_dropped_surfaces = 0, record_dropped_bodies = 0;
  std::string record_error;
  // Head poses not sent because a joint target was not finite (never reached with checked poses).
  std::uint64_t head_commands_invalid = 0;
  // The tracker's counters: frames, and what its checks dropped (foreign senders, bad poses).
  TrackerStats tracker;
  // Its inputs silent at the end (InputWatch: a NatNet server that sent nothing, and what to
  // check); empty when all delivered. In the JSON object `tracker` as "silent" and in done_text.
  std::string tracker_silent;
  // --view openxr (JSON "openxr", absent otherwise): the runtime, the eyes' swapchain size, the
  // frames submitted, why the session ended, the haptic ticks whose force the headset's focus
  // gate zeroed, and the gate's closed windows (CLOCK_MONOTONIC ns; 0 = closed at the end).
  bool openxr = false;
  std::string openxr_runtime, openxr_end_reason;
  int openxr_eye_width = 0, openxr_eye_height = 0;
  std::uint64_t openxr_frames_submitted = 0, openxr_ticks_gated = 0;
  std::vector<std::pair<std::int64_t, std::int64_t>> openxr_gate_closed_ns;
  // --record-hmd-poses (JSON "hmd_poses", absent otherwise): rows written, the headset poses taken
  // for a row and those without a NatNet frame near enough, the NatNet head frames seen.
  std::string hmd_poses_file;
  std::uint64_t hmd_poses_rows = 0, hmd_poses_taken = 0, hmd_poses_unpaired = 0,
                hmd_poses_natnet_frames = 0, hmd_poses_dropped = 0;

  // The stream's mean rate over the haptic loop's span (0 before the loop ran).
  double stream_mbit_per_s() const;
  double video_mbit_per_s() const;  // whole EncodedVideo messages, over the same span
  double depth_mbit_per_s() const;
  // telex-local --json-summary: every key once, here (docs/BENCHMARKS.md and the tests read them).
  nlohmann::json to_json() const;
  // The run in one line: ticks, rate, jitter, latencies, peak forces, a silent tracker input.
  std::string done_text() const;
  // --record: what the bag got and what was dropped (and a failure); empty when not recording.
  std::string record_text() const;
};

}  // namespace telex::local
