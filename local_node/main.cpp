// SPDX-License-Identifier: MIT
// telex-local: the operator-station daemon (thin main around telex::local::Station).
#include <openssl/ssl.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <thread>

#include "telex/local/display_supervisor.h"
#include "telex/local/station.h"
#include "telex/local/view_window.h"

namespace {

// Splits HOST:PORT; throws CLI::ValidationError naming the flag.
std::pair<std::string, std::uint16_t> host_port(const std::string& s, const char* flag) {
  const auto colon = s.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == s.size())
    throw CLI::ValidationError(flag, "expected HOST:PORT, got '" + s + "'");
  const std::string port_text = s.substr(colon + 1);
  char* end = nullptr;
  const long port = std::strtol(port_text.c_str(), &end, 10);
  if (*end != '\0' || port < 1 || port > 65535)
    throw CLI::ValidationError(flag, "port must be 1..65535, got '" + port_text + "'");
  return {s.substr(0, colon), static_cast<std::uint16_t>(port)};
}

}  // namespace

int main(int argc, char** argv) {
  using namespace telex::local;
  StationConfig cfg;
  // The rig sets the defaults before the flags are read, so any flag given overrides it.
  std::string rig_file;
  try {
    if (const auto rig_path = telex::rig_path_in_args(argc, argv)) {
      rig_file = rig_path->string();
      apply_rig(telex::load_rig(*rig_path), cfg);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "telex-local: error: %s\n", e.what());
    return 2;
  }
  CLI::App app{"telex-local: operator station (surface client, 1 kHz fingertip haptics, view)"};
  app.add_option("--rig", rig_file,
                 "rig FILE (docs/RIG.md): marker bodies, head-to-camera offset, body, hands, "
                 "gloves, eyes, display channels; the flags below override it");
  app.set_config("--config", "", "read flags from an INI/TOML file (same names as the flags)");
  std::string connect = "127.0.0.1:7300";
  std::string transport = "udp";
  std::string glove;
  std::string psk_file, cert_file, key_file, ca_file;
  bool insecure = false;
  std::string elbow_bodies;
  bool no_realtime = false, no_bilateral = false, json_summary = false, quiet = false;
  app.add_option("--connect", connect, "remote node HOST:PORT")->capture_default_str();
  app.add_option("--transport", transport, "depth transport: udp or tcp")
      ->check(CLI::IsMember({"udp", "tcp"}))
      ->capture_default_str();
  app.add_option("--udp-port", cfg.client.udp_bind_port, "local UDP port for depth (0 = any)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--udp-announce-port", cfg.client.udp_announce_port,
                 "UDP port announced to the remote instead of --udp-port, e.g. an impairment "
                 "proxy's (0 = the bound port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--hand", cfg.hand_spec,
                 "fingertips: script:press|stroke|tap|FILE, natnet:SERVER[,unicast][,local=IP], "
                 "5dt-usb[:PATH], 5dt-serial:DEV")
      ->capture_default_str();
  app.add_flag("--repeat", cfg.tracker.repeat, "repeat a scripted hand until --duration ends");
  app.add_option("--glove", glove,
                 "finger bends with a NatNet wrist: 5dt-usb[:PATH] | 5dt-serial:DEV");
  app.add_option("--glove-calibration", cfg.tracker.glove_calibration_path,
                 "glove calibration JSON");
  app.add_option("--head-body", cfg.tracker.head_body_id, "NatNet rigid body id of the head")
      ->capture_default_str();
  app.add_option("--hand-body", cfg.tracker.right_hand_body_id, "NatNet rigid body id of the hand")
      ->capture_default_str();
  app.add_option("--shoulder-body", cfg.tracker.right_shoulder_body_id,
                 "NatNet rigid body id of the shoulder (-1 none)")
      ->capture_default_str();
  app.add_option("--left-hand-body", cfg.tracker.left_hand_body_id,
                 "NatNet rigid body id of the left hand (-1 none; drawn, or felt with --left-hand)")
      ->capture_default_str();
  app.add_option("--left-shoulder-body", cfg.tracker.left_shoulder_body_id,
                 "NatNet rigid body id of the left shoulder (-1 none)")
      ->capture_default_str();
  app.add_option("--elbow-bodies", elbow_bodies,
                 "NatNet rigid body ids of the elbow markers LEFT,RIGHT (-1 none)");
  bool no_head = false;
  app.add_flag("--no-head", no_head,
               "no head teleoperation: the operator's head is not sent to the remote, and the "
               "fingertips are placed with the operator's head even when the remote reports its "
               "head's pose (the naive transform)");
  bool head_naive = false;
  app.add_flag("--head-naive", head_naive,
               "send the head, but place the fingertips with the operator's current head instead "
               "of the remote head's pose at each frame's capture (for comparison)");
  app.add_option("--head-rate", cfg.head_rate_hz, "head poses sent per second")
      ->check(CLI::Range(1.0, 1000.0))
      ->capture_default_str();
  app.add_option("--deadman", cfg.deadman_spec,
                 "dead-man key or pedal that must be held for the robot head to move: "
                 "evdev:/dev/input/eventN[,key=KEY_SPACE] (a keyboard or a pedal that acts as "
                 "one) | hid:VID:PID[,byte=N][,mask=M] (a HID report's bits); its state goes with "
                 "every head pose, released or a failed device holds the head");
  app.add_flag("--left-hand", cfg.tracker.use_left_hand,
               "the haptic fingertips are the left hand's (the right hand is drawn)");
  app.add_option("--other-glove", cfg.tracker.other_glove_spec,
                 "the other hand's glove (that hand is drawn): 5dt-usb[:PATH] | 5dt-serial:DEV");
  app.add_option("--natnet-cmd-port", cfg.tracker.natnet_command_port, "NatNet command port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--natnet-data-port", cfg.tracker.natnet_data_port, "NatNet data port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--natnet-multicast", cfg.tracker.natnet_multicast_group, "NatNet multicast group")
      ->capture_default_str();
  app.add_option("--haptics", cfg.haptics_spec,
                 "display: sim[:CSV] | gravity-grabber:HIDPATH|VID:PID[:SERIAL] | udp:HOST[:PORT]")
      ->capture_default_str();
  app.add_option("--gg-config", cfg.display.gravity_grabber_config_path,
                 "Gravity Grabber calibration JSON (docs/HARDWARE.md)");
  app.add_option("--max-force", cfg.haptic.max_force_N, "force clamp, N")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  app.add_option("--stiffness", cfg.haptic.stiffness_N_per_m, "surface stiffness, N/m")
      ->check(CLI::Range(1.0, 1e7))
      ->capture_default_str();
  app.add_option("--max-force-step", cfg.haptic.max_force_step_N, "force rate limit per tick, N")
      ->check(CLI::Range(1e-4, 100.0))
      ->capture_default_str();
  app.add_option("--mu-static", cfg.haptic.mu_static, "static friction coefficient")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  app.add_option("--mu-dynamic", cfg.haptic.mu_dynamic, "dynamic friction coefficient")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  app.add_option("--ramp", cfg.haptic.startup_ramp_s, "start-up force ramp, s")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
  app.add_option("--stale-limit", cfg.haptic.stale_limit_s,
                 "surface/tracking age that fades forces out, s")
      ->check(CLI::Range(0.01, 10.0))
      ->capture_default_str();
  app.add_option("--rate", cfg.rate_hz, "haptic loop rate, Hz")
      ->check(CLI::Range(10.0, 10000.0))
      ->capture_default_str();
  app.add_flag("--no-realtime", no_realtime,
               "do not try SCHED_FIFO for the threads from depth to force (haptic loop, surface, "
               "depth network, tracking) and the display supervisor");
  bool no_supervisor = false;
  app.add_flag("--no-supervisor", no_supervisor,
               "no display supervisor (default: a child process that commands zero force on the "
               "haptic display if the station dies by SIGKILL, abort or a segfault; "
               "docs/HARDWARE.md)");
  bool full_frame = false, roi_flag = false;
  app.add_flag("--full-frame", full_frame,
               "filter and build normals over the whole frame (default: only near the "
               "fingertips, the same force error at a fiftieth of the cost, docs/BENCHMARKS.md)");
  app.add_flag("--roi", roi_flag, "the default: filter and build normals only near the fingertips")
      ->excludes("--full-frame");
  bool no_fill_here = false;
  app.add_flag("--no-fill-here", no_fill_here,
               "do not fill holes on the station (default: fill them in the fingertip windows; "
               "the remote sends its depth unfilled unless run with --fill)");
  int bilateral_radius = cfg.surface.bilateral_options.radius_px;
  app.add_option("--bilateral-radius", bilateral_radius,
                 "bilateral window radius, px (default 6, KinectFusion's 13x13: 4.1 % force error "
                 "against 9.2 % at radius 2, docs/BENCHMARKS.md)")
      ->check(CLI::Range(1, 15))
      ->capture_default_str();
  bool no_frame_parts = false;
  app.add_flag("--no-frame-parts", no_frame_parts,
               "take each frame in one part (ROI tiles are otherwise sent and published first)");
  bool no_repair = false;
  app.add_flag("--no-repair", no_repair,
               "never ask the remote for lost tiles or key frames (default: a TileNack for the "
               "fingertip windows' lost tiles, a key frame when a frame cannot be completed; "
               "docs/PROTOCOL.md 2.5)");
  app.add_flag("--no-bilateral", no_bilateral, "skip the bilateral filter");
  app.add_option("--max-tile-age", cfg.max_tile_age_s,
                 "a missing tile keeps its value this long, s")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
  app.add_option("--log-forces", cfg.log_forces_csv, "CSV of forces, one row per finger per tick");
  app.add_option("--log-tracking", cfg.log_tracking_csv,
                 "CSV of every rigid body as the tracker reported it (tracker frame)");
  app.add_option("--record", cfg.record_bag,
                 "record the session to a ROS 1 bag FILE.bag: depth as received, tracked bodies, "
                 "fingertips, forces and display commands (docs/RECORDING.md)");
  app.add_option("--record-rate", cfg.record_rate_hz,
                 "rate of the recorded forces, display commands and fingertip frames, Hz "
                 "(the model's inputs are recorded every tick)")
      ->check(CLI::Range(0.1, 10000.0))
      ->capture_default_str();
  app.add_option("--log-every", cfg.log_every, "log one tick in N")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--view", cfg.view_spec,
                 "operator view: none | png:DIR (view.png, and the stereo pair left.png, "
                 "right.png, sbs.png, once a second) | window (the stereo pair side by side in a "
                 "resizable window; Esc or closing it stops the station) | hmd[:MONITOR] (the "
                 "same, full screen on a monitor: a name as xrandr lists it or a 0-based index; "
                 "default the last; an unknown one lists those present). window and hmd need an X "
                 "display (DISPLAY)")
      ->check([](const std::string& text) {
        try {
          ViewSpec::parse(text);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      })
      ->capture_default_str();
  app.add_option("--view-at", cfg.view_at_s,
                 "with --view png:DIR, write the view once, this many seconds after the hand "
                 "starts (a scripted hand's time), instead of once a second and at the end: the "
                 "pictures show that moment of the run")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--stereo-baseline", cfg.stereo_baseline_m,
                 "distance between the remote's eye cameras in metres (stereo view)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--print-forces", cfg.print_forces_hz,
                 "print forces on stdout at this rate, Hz (0 off)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--duration", cfg.duration_s, "stop after this many seconds (0 = until Ctrl-C)")
      ->check(CLI::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--first-surface-timeout", cfg.first_surface_timeout_s,
                 "give up when no surface arrives within this many seconds")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_flag("--json-summary", json_summary, "print a JSON summary on stdout at exit");
  app.add_flag("--quiet", quiet, "no status line");
  app.add_option("--psk", psk_file,
                 "pre-shared key FILE (16..1024 raw bytes, mode 0600): TLS 1.3 with this key and "
                 "(EC)DHE on TCP, sealed datagrams on UDP; the remote needs the same key");
  app.add_option("--cert", cert_file,
                 "this station's certificate chain FILE (PEM), instead of --psk; with --key, --ca");
  app.add_option("--key", key_file, "the private key FILE (PEM, mode 0600) of --cert");
  app.add_option("--ca", ca_file,
                 "CA FILE (PEM): the remote's certificate must chain to it (required, verified)");
  app.add_flag("--insecure", insecure,
               "accept a --connect address off loopback without --psk or certificates: anyone on "
               "the network can then move the robot head and watch its cameras and depth");
  try {
    app.parse(argc, argv);
    auto [host, port] = host_port(connect, "--connect");
    if (!elbow_bodies.empty()) {
      int left = -2, right = -2;
      char comma = 0, extra = 0;
      if (std::sscanf(elbow_bodies.c_str(), "%d%c%d%c", &left, &comma, &right, &extra) != 3 ||
          comma != ',' || left < -1 || right < -1)
        throw CLI::ValidationError(
            "--elbow-bodies", "expected LEFT,RIGHT body ids (-1 none), got '" + elbow_bodies + "'");
      cfg.tracker.left_elbow_body_id = left;
      cfg.tracker.right_elbow_body_id = right;
    }
    cfg.client.host = host;
    cfg.client.port = port;
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : 2;
  }
  try {
    telex::proto::validate_tls_flags(!psk_file.empty(), cert_file, key_file, ca_file);
    if (!psk_file.empty()) {
      try {
        telex::proto::check_key_file_permissions(psk_file);
        cfg.client.tls.psk = telex::proto::load_key_file(psk_file);
      } catch (const std::exception& e) {
        throw std::invalid_argument(std::string("--psk: ") + e.what());
      }
    }
    if (!cert_file.empty()) {
      telex::proto::check_key_file_permissions(key_file, "private key file");
      cfg.client.tls.cert = cert_file;
      cfg.client.tls.key = key_file;
      cfg.client.tls.ca = ca_file;
      // Loaded once here, so an unreadable or mismatched file exits 2 before anything starts.
      SSL_CTX_free(telex::proto::make_tls_context(cfg.client.tls, telex::proto::TlsRole::Client));
    }
    const bool loopback = telex::proto::is_loopback_host(cfg.client.host);
    if (!cfg.client.tls.enabled() && !loopback && !insecure)
      throw std::invalid_argument(telex::proto::insecure_refusal("--connect", connect));
    cfg.insecure = !cfg.client.tls.enabled() && !loopback;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "telex-local: error: %s\n", e.what());
    return 2;
  }
  if (cfg.insecure)
    std::fprintf(stderr, "telex-local: warning: %s\n", telex::proto::insecure_warning().c_str());
  // Forked before any thread starts: the supervisor is a copy of this one thread.
  DisplaySupervisor supervisor;
  if (!no_supervisor) {
    try {
      supervisor = start_display_supervisor(zero_channel_for(cfg.haptics_spec, cfg.display),
                                            {.realtime = !no_realtime});
    } catch (const std::exception& e) {
      std::fprintf(stderr, "telex-local: error: %s\n", e.what());
      return dynamic_cast<const std::invalid_argument*>(&e) != nullptr ? 2 : 1;
    }
  }
  cfg.client.use_udp = transport == "udp";
  cfg.client.frame_parts = !no_frame_parts;
  cfg.client.repair = !no_repair;
  cfg.tracker.glove_spec = glove;
  if (no_head) cfg.head_teleop = cfg.head_captured_pose = false;
  if (head_naive) cfg.head_captured_pose = false;
  cfg.realtime = !no_realtime;
  cfg.surface.bilateral = !no_bilateral;
  cfg.surface.roi = !full_frame;
  cfg.surface.fill_here = !no_fill_here;
  cfg.surface.bilateral_options.radius_px = bilateral_radius;
  cfg.status_line = !quiet;

  // Signals go to one waiting thread, never interrupting the haptic loop.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);  // our own wake-up for the signal thread when the run ends
  pthread_sigmask(SIG_BLOCK, &set, nullptr);

  try {
    Station station(cfg);
    std::thread signals([&] {
      int sig = 0;
      if (sigwait(&set, &sig) == 0 && sig != SIGUSR1) station.request_stop();
    });
    StationSummary s;
    try {
      s = station.run();
    } catch (...) {
      pthread_kill(signals.native_handle(), SIGUSR1);
      signals.join();
      throw;
    }
    // Wake the signal thread if the run ended by itself.
    pthread_kill(signals.native_handle(), SIGUSR1);
    signals.join();
    std::fprintf(stderr,
                 "telex-local: done: %llu ticks at %.2f Hz (p99 jitter %.0f us, %llu missed), %llu "
                 "surfaces, capture-to-force latency median %.2f ms p99 %.2f ms (in contact: "
                 "median %.2f ms p99 %.2f ms over %llu), peak pressure %.2f N, peak shear %.2f N\n",
                 static_cast<unsigned long long>(s.ticks), s.haptic_rate_hz, s.period_p99_jitter_us,
                 static_cast<unsigned long long>(s.missed_ticks),
                 static_cast<unsigned long long>(s.surfaces), s.latency_median_ms, s.latency_p99_ms,
                 s.contact_latency_median_ms, s.contact_latency_p99_ms,
                 static_cast<unsigned long long>(s.contact_latency_samples), s.peak_pressure_N,
                 s.peak_shear_N);
    if (!cfg.record_bag.empty())
      std::fprintf(stderr,
                   "telex-local: recorded %s: %llu ticks, %llu surfaces, %llu body frames; "
                   "dropped %llu ticks, %llu surfaces, %llu body frames%s%s\n",
                   cfg.record_bag.c_str(), static_cast<unsigned long long>(s.record_ticks),
                   static_cast<unsigned long long>(s.record_surfaces),
                   static_cast<unsigned long long>(s.record_body_frames),
                   static_cast<unsigned long long>(s.record_dropped_ticks),
                   static_cast<unsigned long long>(s.record_dropped_surfaces),
                   static_cast<unsigned long long>(s.record_dropped_bodies),
                   s.record_error.empty() ? "" : "; RECORDING FAILED: ", s.record_error.c_str());
    if (json_summary) {
      nlohmann::json thread_scheduling = nlohmann::json::object();
      for (const auto& [name, how] : s.thread_scheduling) thread_scheduling[name] = how;
      nlohmann::json j{
          {"ticks", s.ticks},
          {"haptic_rate_hz", s.haptic_rate_hz},
          {"period_median_us", s.period_median_us},
          {"period_p99_jitter_us", s.period_p99_jitter_us},
          {"missed_ticks", s.missed_ticks},
          {"nominal_rate_hz", s.nominal_rate_hz},
          {"haptic_span_s", s.haptic_span_s},
          {"log_origin_monotonic_ns", s.log_origin_monotonic_ns},
          {"surfaces", s.surfaces},
          {"frames", s.frames},
          {"roi_parts", s.roi_parts},
          {"latency_median_ms", s.latency_median_ms},
          {"latency_p99_ms", s.latency_p99_ms},
          {"contact_latency_samples", s.contact_latency_samples},
          {"contact_latency_median_ms", s.contact_latency_median_ms},
          {"contact_latency_p99_ms", s.contact_latency_p99_ms},
          {"arrive_median_ms", s.arrive_median_ms},
          {"arrive_p99_ms", s.arrive_p99_ms},
          {"build_wait_median_ms", s.build_wait_median_ms},
          {"build_wait_p99_ms", s.build_wait_p99_ms},
          {"peak_pressure_N", s.peak_pressure_N},
          {"peak_shear_N", s.peak_shear_N},
          {"scheduling", s.scheduling},
          {"thread_scheduling", thread_scheduling},
          {"auth_failed", s.auth_failed},
          {"unsealed", s.unsealed},
          {"replayed", s.replayed},
          {"dropped_malformed", s.dropped_malformed},
          {"upstream_dropped", s.upstream_dropped},
          {"udp_datagrams", s.udp_datagrams},
          {"udp_lost", s.udp_lost},
          {"bytes_in", s.bytes_in},
          // The stream's mean rate over the run (the remote's stats line gives each
          // second's): issue 16's 10 Mbit/s goal.
          {"stream_mbit_per_s",
           s.haptic_span_s > 0.0 ? static_cast<double>(s.bytes_in) * 8e-6 / s.haptic_span_s : 0.0},
          {"udp_messages_by_fragments", s.udp_messages_by_fragments},
          // Repair (docs/PROTOCOL.md 2.5) and tile ages in frame periods (issue 16).
          {"tiles_missing", s.tiles_missing},
          {"frames_incomplete", s.frames_incomplete},
          {"frames_unclosed", s.frames_unclosed},
          {"tiles_expired", s.tiles_expired},
          {"nacks", s.nacks},
          {"tiles_nacked", s.tiles_nacked},
          {"watched_tiles_nacked", s.watched_tiles_nacked},
          {"tiles_repaired", s.tiles_repaired},
          {"repairs_useless", s.repairs_useless},
          {"key_frame_requests", s.key_frame_requests},
          {"head_commands", s.head_commands},
          {"head_samples_stale", s.head_samples_stale},
          {"head_deadman_released", s.head_deadman_released},
          {"tile_age_watched_samples", s.tile_age_watched_samples},
          {"tile_age_watched_median_frames", s.tile_age_watched_median},
          {"tile_age_watched_p99_frames", s.tile_age_watched_p99},
          {"tile_age_watched_max_frames", s.tile_age_watched_max},
          {"tile_age_samples", s.tile_age_samples},
          {"tile_age_all_median_frames", s.tile_age_all_median},
          {"tile_age_all_p99_frames", s.tile_age_all_p99},
          {"tile_age_all_max_frames", s.tile_age_all_max}};
      j["head_commands_invalid"] = s.head_commands_invalid;
      // The tracker's frames and what its checks dropped (docs/HARDWARE.md, NatNet).
      j["tracker"] = {{"frames_in", s.tracker.frames_in},
                      {"frames_dropped", s.tracker.frames_dropped},
                      {"parse_errors", s.tracker.parse_errors},
                      {"io_errors", s.tracker.io_errors},
                      {"foreign_datagrams", s.tracker.foreign_datagrams},
                      {"rejected_nonfinite", s.tracker.rejected_nonfinite},
                      {"rejected_quaternion", s.tracker.rejected_quaternion},
                      {"rejected_too_fast", s.tracker.rejected_too_fast},
                      {"frames_rejected", s.tracker.frames_rejected},
                      {"thread_faults", s.tracker.thread_faults}};
      if (!cfg.record_bag.empty())
        j["record"] = {{"file", cfg.record_bag.string()},
                       {"ticks", s.record_ticks},
                       {"surfaces", s.record_surfaces},
                       {"body_frames", s.record_body_frames},
                       {"dropped_ticks", s.record_dropped_ticks},
                       {"dropped_surfaces", s.record_dropped_surfaces},
                       {"dropped_bodies", s.record_dropped_bodies},
                       {"error", s.record_error}};
      std::cout << j.dump() << std::endl;
    }
    return s.record_error.empty() ? 0 : 1;
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "telex-local: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "telex-local: error: %s\n", e.what());
    return 1;
  }
}
