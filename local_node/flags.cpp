// SPDX-License-Identifier: MIT
// telex-local's flags: their definitions and what their text becomes.
#include "flags.h"

#include <openssl/ssl.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <utility>

#include "telex/base/realtime.h"
#include "telex/cli/cli.h"
#include "telex/cli/processing_flags.h"
#include "telex/common/endpoint.h"
#include "telex/local/inputs/glove.h"
#include "telex/local/inputs/hand_script.h"
#include "telex/local/inputs/natnet_client.h"
#include "telex/local/inputs/tracker_registry.h"
#include "telex/local/view/view_window.h"

namespace telex::local {

void load_station_rig(int argc, char** argv, StationFlags& f) {
  if (const auto rig = cli::rig_before_flags(argc, argv)) {
    f.rig_file = rig->value;
    try {
      apply_rig(telex::load_rig(f.rig_file), f.cfg);
    } catch (const std::exception& e) {
      if (rig->file.empty()) throw;
      throw std::runtime_error(e.what() + rig->note("rig"));
    }
    // The options below are added after this, so --help shows the rig's values as defaults.
    spdlog::info(
        "rig {}: marker bodies, head-to-camera offset, body, hands, gloves, eyes and "
        "display channels from the file (flags given override them)",
        f.rig_file);
  }
}

namespace {

// --view png:DIR: the directory exists or is made now, or the error names --view.
void check_view_dir(const std::string& view_spec) {
  ViewSpec v;
  try {
    v = ViewSpec::parse(view_spec);
  } catch (const std::invalid_argument& e) {
    throw CLI::ValidationError("--view", e.what());
  }
  if (v.kind != ViewSpec::Kind::Png) return;
  std::error_code ec;
  std::filesystem::create_directories(v.dir, ec);
  if (ec || !std::filesystem::is_directory(v.dir))
    throw CLI::ValidationError("--view", "png:" + v.dir.string() +
                                             ": cannot create the directory (" +
                                             (ec ? ec.message() : "not a directory") + ")");
}

// --hand, --glove, --other-glove and --natnet-multicast: their grammar and addresses, and gloves
// only where they are used (a NatNet hand's wrist takes their finger bends).
void check_tracking_specs(const StationFlags& f) {
  const auto checked = [](const char* flag, const auto& check) {
    try {
      check();
    } catch (const std::invalid_argument& e) {
      throw CLI::ValidationError(flag, e.what());
    }
  };
  const std::string& hand = f.cfg.hand_spec;
  checked("--hand", [&] { check_hand_spec(hand); });
  const bool natnet = hand.rfind("natnet:", 0) == 0;
  for (const auto& [flag, spec] : {std::pair<const char*, const std::string&>{"--glove", f.glove},
                                   {"--other-glove", f.cfg.tracker.other_glove_spec}}) {
    if (spec.empty()) continue;
    // Clang before 16 cannot capture a structured binding (P1091); the fuzz build uses clang 14.
    const std::string& glove = spec;
    checked(flag, [&] { check_glove_spec(glove); });
    if (!natnet)
      throw CLI::ValidationError(
          flag,
          spec + " gives finger bends to a NatNet hand (--hand natnet:SERVER), and --hand " + hand +
              " has none" +
              (flag == std::string("--glove") ? " (a glove alone: --hand " + spec + ")" : ""));
  }
  if (natnet)
    checked("--natnet-multicast",
            [&] { check_multicast_group(f.cfg.tracker.natnet_multicast_group); });
}

// The remote, the rig and the depth link.
void add_link_options(CLI::App& app, StationFlags& f) {
  app.add_option("--rig", f.rig_file,
                 "rig FILE (docs/RIG.md): marker bodies, head-to-camera offset, body, hands, "
                 "gloves, eyes, display channels; the flags below override it");
  telex::cli::add_strict_config(
      app,
      "read flags from a TOML or JSON file (keys = the long flag names; an unknown key or a "
      "wrong type is an error naming the key and the file)");
  app.add_option("--connect", f.connect, "remote node HOST:PORT")->capture_default_str();
  app.add_option("--transport", f.transport, "depth transport: udp or tcp")
      ->check(CLI::IsMember({"udp", "tcp"}))
      ->capture_default_str();
  app.add_option("--udp-port", f.cfg.client.udp_bind_port, "local UDP port for depth (0 = any)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  app.add_option("--udp-announce-port", f.cfg.client.udp_announce_port,
                 "UDP port announced to the remote instead of --udp-port, e.g. an impairment "
                 "proxy's (0 = the bound port)")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
}

// The operator: hand, gloves, tracked bodies, head teleoperation.
void add_tracking_options(CLI::App& app, StationFlags& f) {
  app.add_option("--hand", f.cfg.hand_spec,
                 "fingertips: script:press|stroke|tap|FILE, natnet:SERVER[,unicast][,local=IP], "
                 "5dt-usb[:PATH], 5dt-serial:DEV")
      ->capture_default_str();
  app.add_flag("--repeat", f.cfg.tracker.repeat, "repeat a scripted hand until --duration ends");
  app.add_option("--glove", f.glove,
                 "finger bends with a NatNet wrist: 5dt-usb[:PATH] | 5dt-serial:DEV");
  app.add_option("--glove-calibration", f.cfg.tracker.glove_calibration_path,
                 "glove calibration JSON");
  app.add_option("--head-body", f.cfg.tracker.head_body_id, "NatNet rigid body id of the head")
      ->capture_default_str();
  app.add_option("--hand-body", f.cfg.tracker.right_hand_body_id,
                 "NatNet rigid body id of the hand")
      ->capture_default_str();
  app.add_option("--shoulder-body", f.cfg.tracker.right_shoulder_body_id,
                 "NatNet rigid body id of the shoulder (-1 none)")
      ->capture_default_str();
  app.add_option("--left-hand-body", f.cfg.tracker.left_hand_body_id,
                 "NatNet rigid body id of the left hand (-1 none; drawn, or felt with --left-hand)")
      ->capture_default_str();
  app.add_option("--left-shoulder-body", f.cfg.tracker.left_shoulder_body_id,
                 "NatNet rigid body id of the left shoulder (-1 none)")
      ->capture_default_str();
  app.add_option("--elbow-bodies", f.elbow_bodies,
                 "NatNet rigid body ids of the elbow markers LEFT,RIGHT (-1 none)");
  app.add_flag("--no-head", f.no_head,
               "no head teleoperation: the operator's head is not sent to the remote, and the "
               "fingertips are placed with the operator's head even when the remote reports its "
               "head's pose (the naive transform)");
  app.add_flag("--head-naive", f.head_naive,
               "send the head, but place the fingertips with the operator's current head instead "
               "of the remote head's pose at each frame's capture (for comparison)");
  app.add_option("--head-rate", f.cfg.head_rate_hz, "head poses sent per second")
      ->check(CLI::Range(1.0, 1000.0))
      ->capture_default_str();
  app.add_option("--deadman", f.cfg.deadman_spec,
                 "dead-man key or pedal that must be held for the robot head to move: "
                 "evdev:/dev/input/eventN[,key=KEY_SPACE] (a keyboard or a pedal that acts as "
                 "one) | hid:VID:PID[,byte=N][,mask=M] (a HID report's bits); its state goes with "
                 "every head pose, released or a failed device holds the head");
  app.add_flag("--left-hand", f.cfg.tracker.use_left_hand,
               "the haptic fingertips are the left hand's (the right hand is drawn)");
  app.add_option("--other-glove", f.cfg.tracker.other_glove_spec,
                 "the other hand's glove (that hand is drawn): 5dt-usb[:PATH] | 5dt-serial:DEV");
  app.add_option("--natnet-cmd-port", f.cfg.tracker.natnet_command_port, "NatNet command port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--natnet-data-port", f.cfg.tracker.natnet_data_port, "NatNet data port")
      ->check(CLI::Range(1, 65535))
      ->capture_default_str();
  app.add_option("--natnet-multicast", f.cfg.tracker.natnet_multicast_group,
                 "NatNet multicast group")
      ->capture_default_str();
}

// The haptic display, the force model and the haptic loop.
void add_haptic_options(CLI::App& app, StationFlags& f) {
  app.add_option("--haptics", f.cfg.haptics_spec,
                 "display: sim[:CSV] | gravity-grabber:HIDPATH|VID:PID[:SERIAL] | udp:HOST[:PORT]")
      ->capture_default_str();
  app.add_option("--gg-config", f.cfg.display.gravity_grabber_config_path,
                 "Gravity Grabber calibration JSON (docs/HARDWARE.md)");
  app.add_option("--max-force", f.cfg.haptic.max_force_N, "force clamp, N")
      ->check(CLI::Range(0.01, 100.0))
      ->capture_default_str();
  app.add_option("--stiffness", f.cfg.haptic.stiffness_N_per_m, "surface stiffness, N/m")
      ->check(CLI::Range(1.0, 1e7))
      ->capture_default_str();
  app.add_option("--max-force-step", f.cfg.haptic.max_force_step_N, "force rate limit per tick, N")
      ->check(CLI::Range(1e-4, 100.0))
      ->capture_default_str();
  app.add_option("--mu-static", f.cfg.haptic.mu_static, "static friction coefficient")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  app.add_option("--mu-dynamic", f.cfg.haptic.mu_dynamic, "dynamic friction coefficient")
      ->check(CLI::Range(0.0, 5.0))
      ->capture_default_str();
  app.add_option("--ramp", f.cfg.haptic.startup_ramp_s, "start-up force ramp, s")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
  app.add_option("--stale-limit", f.cfg.haptic.stale_limit_s,
                 "surface/tracking age that fades forces out, s")
      ->check(CLI::Range(0.01, 10.0))
      ->capture_default_str();
  app.add_option("--link-silence-ms", f.link_silence_ms,
                 "zero force at once when nothing authenticated has come from the remote for "
                 "this long (the station probes every 10 ms); 0: off, only --stale-limit's fade. "
                 "Raise it for a link whose round trip jitters more (a WAN)")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  app.add_option("--tracking-silence-ms", f.tracking_silence_ms,
                 "zero force at once when the hand tracker's frames stop for this long; 0: off. "
                 "Raise it for a tracker slower than 60 Hz")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  app.add_option("--rate", f.cfg.rate_hz, "haptic loop rate, Hz")
      ->check(CLI::Range(10.0, 10000.0))
      ->capture_default_str();
  app.add_flag("--no-realtime", f.no_realtime,
               "do not try SCHED_FIFO for the threads from depth to force (haptic loop, surface, "
               "depth network, tracking) and the display supervisor");
  app.add_option("--haptic-cpu", f.cfg.haptic_cpu,
                 "pin the haptic thread to this CPU (0-based; one the process may run on; "
                 "default: any). With --no-realtime it is pinned all the same");
  app.add_flag("--no-supervisor", f.no_supervisor,
               "no display supervisor (default: a child process that commands zero force on the "
               "haptic display if the station dies by SIGKILL, abort or a segfault, or is stopped "
               "or hung; docs/HARDWARE.md)");
}

// The surface: where it is built, how it is filtered, repair.
void add_surface_options(CLI::App& app, StationFlags& f) {
  app.add_flag("--full-frame", f.full_frame,
               "filter and build normals over the whole frame (default: only near the "
               "fingertips, the same force error at a fiftieth of the cost, docs/BENCHMARKS.md)");
  app.add_flag("--roi", f.roi_flag,
               "the default: filter and build normals only near the fingertips")
      ->excludes("--full-frame");
  app.add_flag("--no-fill-here", f.no_fill_here,
               "do not fill holes on the station (default: fill them in the fingertip windows; "
               "the remote sends its depth unfilled unless run with --fill)");
  f.bilateral_radius = f.cfg.surface.bilateral_options.radius_px;
  telex::cli::add_bilateral_radius(app, f.bilateral_radius);
  app.add_flag("--no-frame-parts", f.no_frame_parts,
               "take each frame in one part (ROI tiles are otherwise sent and published first)");
  app.add_flag("--no-repair", f.no_repair,
               "never ask the remote for lost tiles or key frames (default: a TileNack for the "
               "fingertip windows' lost tiles, a key frame when a frame cannot be completed; "
               "docs/PROTOCOL.md 2.5)");
  app.add_flag("--no-bilateral", f.no_bilateral, "skip the bilateral filter");
  app.add_option("--max-tile-age", f.cfg.max_tile_age_s,
                 "a missing tile keeps its value this long, s")
      ->check(CLI::Range(0.0, 60.0))
      ->capture_default_str();
}

// Logs, recording, the view, the run's length, the summary.
void add_output_options(CLI::App& app, StationFlags& f) {
  app.add_option("--log-forces", f.cfg.log_forces_csv,
                 "CSV of forces, one row per finger per tick");
  app.add_option("--log-tracking", f.cfg.log_tracking_csv,
                 "CSV of every rigid body as the tracker reported it (tracker frame)");
  app.add_option("--record-hmd-poses", f.cfg.record_hmd_poses_csv,
                 "with --view openxr and --hand natnet:...: write the headset's view in its STAGE "
                 "space and the NatNet head body at the same moments, 10 a second, to FILE.csv "
                 "for `telex calibrate hmd --poses` (docs/RIG.md section 3)");
  app.add_option("--record", f.cfg.record_bag,
                 "record the session to a ROS 1 bag FILE.bag: depth as received, tracked bodies, "
                 "fingertips, forces and display commands (docs/RECORDING.md)");
  app.add_option("--record-rate", f.cfg.record_rate_hz,
                 "rate of the recorded forces, display commands and fingertip frames, Hz "
                 "(the model's inputs are recorded every tick)")
      ->check(CLI::Range(0.1, 10000.0))
      ->capture_default_str();
  app.add_option("--log-every", f.cfg.log_every, "log one tick in N")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  app.add_option("--view", f.cfg.view_spec,
                 "operator view: none | png:DIR (view.png, and the stereo pair left.png, "
                 "right.png, sbs.png, once a second) | window (the stereo pair side by side in a "
                 "resizable window; Esc or closing it stops the station) | hmd[:MONITOR] (the "
                 "same, full screen on a monitor: a name as xrandr lists it or a 0-based index; "
                 "default the last; an unknown one lists those present). window and hmd need an X "
                 "display (DISPLAY) | openxr (a headset through its OpenXR runtime: the active "
                 "one, or the manifest XR_RUNTIME_JSON names; force only while the session is "
                 "focused; docs/HARDWARE.md)")
      ->check([](const std::string& text) {
        try {
          ViewSpec::parse(text);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      })
      ->capture_default_str();
  app.add_option("--head-source", f.cfg.head_source,
                 "the operator's head, which turns the robot head and places the hands: natnet "
                 "(the head marker body) | hmd (the headset's pose with --view openxr, put in the "
                 "NatNet frame by the rig's operator.hmd_stage_in_natnet)")
      ->check(CLI::IsMember({"natnet", "hmd"}))
      ->capture_default_str();
  app.add_option("--view-at", f.cfg.view_at_s,
                 "with --view png:DIR, write the view once, this many seconds after the hand "
                 "starts (a scripted hand's time), instead of once a second and at the end: the "
                 "pictures show that moment of the run")
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--eye-size", f.eye_size,
                 "each eye of the stereo view rendered at WxH pixels (e.g. 1280x720); default the "
                 "eye video's size, or the depth's before video comes");
  app.add_option("--view-layout", f.cfg.view_layout,
                 "sbs: the stereo pair side by side | fig7: the paper's Fig. 7, the right eye "
                 "beside the full-frame normal map with each fingertip's touch vector (god-point, "
                 "normal, force, shear); --view png:DIR writes it as DIR/fig7.png, a window shows "
                 "it")
      ->check(CLI::IsMember({"sbs", "fig7"}))
      ->capture_default_str();
  app.add_option("--view-overlays", f.cfg.view_overlays,
                 "the status text and the normal-map inset drawn into each eye of the stereo "
                 "view: on | off | auto (on, except with --view hmd, where they would sit in the "
                 "operator's sight)")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  app.add_option("--stereo-baseline", f.cfg.stereo_baseline_m,
                 "distance between the remote's eye cameras in metres (stereo view)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option_function<std::string>(
         "--warp", [&f](const std::string& v) { f.cfg.view_warp = v == "on"; },
         "stereo view: on = each eye's video reprojected from the robot head's pose at capture "
         "to the operator's head now, through the remote depth, when both poses are known "
         "(the remote reports its head, a head body is tracked); off = shown as captured")
      ->check(CLI::IsMember({"on", "off"}))
      ->default_str("on");
  app.add_option("--print-forces", f.cfg.print_forces_hz,
                 "print forces on stdout at this rate, Hz (0 off)")
      ->check(CLI::Range(0.0, 1000.0))
      ->capture_default_str();
  app.add_option("--duration", f.cfg.duration_s, "stop after this many seconds (0 = until Ctrl-C)")
      ->check(CLI::Range(0.0, 1e7))
      ->capture_default_str();
  app.add_option("--first-surface-timeout", f.cfg.first_surface_timeout_s,
                 "give up when no surface arrives within this many seconds")
      ->check(CLI::Range(0.1, 3600.0))
      ->capture_default_str();
  app.add_flag("--json-summary", f.json_summary, "print a JSON summary on stdout at exit");
  app.add_flag("--quiet", f.quiet, "no status line");
}

// Keys and certificates (docs/PROTOCOL.md).
void add_security_options(CLI::App& app, StationFlags& f) {
  cli::add_link_security(app, f.security, {"station", "remote", "--connect", false});
}

// The keys whose value is a path (a spec's file or folder too): in a --config file they are
// relative to its folder. Device nodes (/dev/...) are given whole.
void add_config_paths(CLI::App& app) {
  cli::config_paths(app, {"rig", "glove-calibration", "gg-config", "log-forces", "log-tracking",
                          "record-hmd-poses", "record", "psk", "cert", "key", "ca"});
  cli::config_paths(app, {"haptics"}, cli::spec_paths_in({{"sim", 1}}));
  cli::config_paths(app, {"view"}, cli::spec_paths_in({{"png", 1}}));
  // script:press|stroke|tap are built in; script:FILE is a file.
  cli::config_paths(app, {"hand"}, [](const std::string& value, const std::filesystem::path& dir) {
    const auto names = HandScript::builtin_names();
    if (value.rfind("script:", 0) == 0 &&
        std::find(names.begin(), names.end(), value.substr(7)) != names.end())
      return value;
    return cli::spec_paths_in({{"script", 1}})(value, dir);
  });
}

}  // namespace

void add_station_options(CLI::App& app, StationFlags& f) {
  add_link_options(app, f);
  add_tracking_options(app, f);
  add_haptic_options(app, f);
  add_surface_options(app, f);
  add_output_options(app, f);
  add_security_options(app, f);
  add_config_paths(app);
}

void resolve_station_flags(StationFlags& f) {
  try {
    const Endpoint remote = parse_endpoint(f.connect, "--connect");
    f.cfg.client.host = remote.host;
    f.cfg.client.port = remote.port;
  } catch (const std::invalid_argument& e) {
    throw CLI::ValidationError(e.what());
  }
  // Every spec is checked before anything starts (a remote connects, a device opens).
  check_tracking_specs(f);
  check_view_dir(f.cfg.view_spec);
  if (f.cfg.haptic_cpu != -1 && !cpu_usable(f.cfg.haptic_cpu))
    throw CLI::ValidationError("--haptic-cpu",
                               std::to_string(f.cfg.haptic_cpu) +
                                   " is not a CPU this process may run on (it has " +
                                   std::to_string(usable_cpu_count()) + ")");
  f.cfg.link_silence_s = f.link_silence_ms * 1e-3;
  f.cfg.tracking_silence_s = f.tracking_silence_ms * 1e-3;
  if (!f.eye_size.empty()) {
    try {
      f.cfg.eye_size = parse_eye_size(f.eye_size);
    } catch (const std::invalid_argument& e) {
      throw CLI::ValidationError("--eye-size", e.what());
    }
  }
  if (f.cfg.head_source == "hmd" && f.cfg.view_spec != "openxr")
    throw CLI::ValidationError("--head-source",
                               "hmd takes the head from the headset: it needs --view openxr");
  if (!f.cfg.record_hmd_poses_csv.empty() && f.cfg.view_spec != "openxr")
    throw CLI::ValidationError("--record-hmd-poses",
                               "it records the headset's pose: it needs --view openxr");
  if (!f.cfg.record_hmd_poses_csv.empty() && f.cfg.hand_spec.rfind("natnet:", 0) != 0)
    throw CLI::ValidationError("--record-hmd-poses",
                               "it records the NatNet head body beside the headset: it needs "
                               "--hand natnet:SERVER, not '" +
                                   f.cfg.hand_spec + "'");
  if (f.elbow_bodies.empty()) return;
  int left = -2, right = -2;
  char comma = 0, extra = 0;
  if (std::sscanf(f.elbow_bodies.c_str(), "%d%c%d%c", &left, &comma, &right, &extra) != 3 ||
      comma != ',' || left < -1 || right < -1)
    throw CLI::ValidationError(
        "--elbow-bodies", "expected LEFT,RIGHT body ids (-1 none), got '" + f.elbow_bodies + "'");
  f.cfg.tracker.left_elbow_body_id = left;
  f.cfg.tracker.right_elbow_body_id = right;
}

cv::Size parse_eye_size(const std::string& text) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X'))
    throw std::invalid_argument("expected WIDTHxHEIGHT in pixels (e.g. 1280x720), got '" + text +
                                "'");
  if (w < 16 || h < 16 || w > 8192 || h > 8192)
    throw std::invalid_argument("each side must be 16..8192 pixels, got '" + text + "'");
  return {w, h};
}

void apply_security_flags(StationFlags& f) {
  ClientConfig& client = f.cfg.client;
  client.tls = cli::load_link_security(f.security, proto::TlsRole::Client);
  try {
    client.addresses = proto::resolve_host(client.host);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--connect ") + f.connect + ": " + e.what());
  }
  const bool loopback =
      std::all_of(client.addresses.begin(), client.addresses.end(), proto::is_loopback_address);
  if (!client.tls.enabled() && !loopback && !f.security.insecure)
    throw std::invalid_argument(proto::insecure_refusal("--connect", f.connect));
  f.cfg.insecure = !client.tls.enabled() && !loopback;
}

void apply_station_switches(StationFlags& f) {
  StationConfig& cfg = f.cfg;
  cfg.client.use_udp = f.transport == "udp";
  cfg.client.frame_parts = !f.no_frame_parts;
  cfg.client.repair = !f.no_repair;
  cfg.tracker.glove_spec = f.glove;
  if (f.no_head) cfg.head_teleop = cfg.head_captured_pose = false;
  if (f.head_naive) cfg.head_captured_pose = false;
  cfg.realtime = !f.no_realtime;
  cfg.surface.bilateral = !f.no_bilateral;
  cfg.surface.roi = !f.full_frame;
  cfg.surface.fill_here = !f.no_fill_here;
  cfg.surface.bilateral_options.radius_px = f.bilateral_radius;
  cfg.status_line = !f.quiet;
}

std::optional<int> parse_station_command_line(int argc, char** argv, StationFlags& flags) {
  // The rig sets the defaults before the flags are read, so any flag given overrides it.
  if (const auto rc =
          cli::load_before_flags("telex-local", [&] { load_station_rig(argc, argv, flags); }))
    return rc;
  CLI::App app{"telex-local: operator station (surface client, 1 kHz fingertip haptics, view)"};
  cli::prepare(app, "telex-local");
  add_station_options(app, flags);
  if (const auto rc = cli::parse(app, argc, argv)) return rc;
  flags.config = cli::config_origin(app, argc, argv);
  try {
    resolve_station_flags(flags);
  } catch (const CLI::ParseError& e) {
    spdlog::error("{}{}", e.what(), flags.config.note(e.what()));
    return cli::kUsageExit;
  }
  return std::nullopt;
}

}  // namespace telex::local
