// SPDX-License-Identifier: MIT
// telex-remote: the robot-head daemon (depth source -> pipeline -> operator over TCP/UDP).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <iostream>

#include "flags.h"
#include "telex/cli/cli.h"
#include "telex/cli/processing_flags.h"
#include "telex/common/endpoint.h"
#include "telex/common/logging.h"
#include "telex/remote/daemon.h"

namespace {

bool parse_size(const std::string& text, int& w, int& h) {
  char x = 0;
  std::istringstream in(text);
  return static_cast<bool>(in >> w >> x >> h) && x == 'x' && in.peek() == EOF;
}

}  // namespace

int main(int argc, char** argv) {
  telex::init_logging("telex-remote");
  using telex::remote::DaemonConfig;
  DaemonConfig cfg;
  // The rig is read before the flags; the flags given override what it sets.
  std::optional<telex::Rig> rig;
  std::string rig_file;
  try {
    if (const auto rig_path = telex::rig_path_in_args(argc, argv)) {
      rig = telex::load_rig(*rig_path);
      rig_file = rig_path->string();
    }
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  CLI::App app{
      "telex-remote: streams filled, tiled, compressed depth (and optional stereo video) to one "
      "operator"};
  telex::cli::prepare(app, "telex-remote");
  telex::cli::add_strict_config(app, "Read options from FILE");

  std::string listen = "127.0.0.1:7300", transport = "udp", codec = "zip", tile = "80x60",
              size = "640x480", video_size = "0x0";
  int client_timeout_ms = 3000;
  std::string psk_file, cert_file, key_file, ca_file;
  bool insecure = false;
  bool no_fill = false, no_temporal = false, no_stats = false, no_realtime = false;
  app.add_option("--rig", rig_file,
                 "Rig FILE (docs/RIG.md): the depth and eye cameras' calibration and the "
                 "depth-to-right-eye extrinsics (registration becomes full), the robot head's "
                 "joints; the flags below override it");
  app.add_option("--source", cfg.depth_source,
                 "Depth source: " + telex::remote::depth_source_help());
  app.add_option("--stereo", cfg.stereo_source,
                 "Stereo video source (empty = none): " + telex::remote::stereo_source_help());
  app.add_option("--listen", listen, "TCP control endpoint HOST:PORT");
  app.add_option("--transport", transport,
                 "Depth/video transport when the client offers UDP: udp | tcp")
      ->check(CLI::IsMember({"udp", "tcp"}));
  app.add_option("--codec", codec, "Preferred depth codec: raw | zip | fast")
      ->check(CLI::IsMember({"raw", "zip", "fast"}));
  app.add_option("--zip-level", cfg.pipeline.zip_level,
                 "Deflate level of the zip codec (0 = Huffman only)")
      ->check(CLI::Range(0, 9));
  app.add_option("--tile", tile, "Tile size WxH in pixels");
  app.add_option("--key-every", cfg.pipeline.key_frame_every, "Frames between key frames")
      ->check(CLI::Range(1, 100000));
  app.add_option("--stream-tiles", cfg.pipeline.stream_tiles,
                 "Send a frame's tiles in batches of N as they are encoded, ahead of its manifest "
                 "(0 = each part at once)")
      ->check(CLI::Range(0, 4096));
  app.add_option("--background-every", cfg.pipeline.background_every,
                 "While an ROI is requested, tiles outside it are considered every Nth frame")
      ->check(CLI::Range(1, 1000));
  app.add_option(
         "--stabilise", cfg.pipeline.stabilise_k_sigma,
         "Hold a pixel's last sent depth while within K sensor-noise sigmas (0 = off, bit-exact)")
      ->check(CLI::Range(0.0, 100.0));
  std::string register_mode = "none", register_baseline = "0.025,0,0", register_rotation = "0,0,0",
              register_eye;
  app.add_option("--register", register_mode,
                 "Register depth into the right-eye camera before fill: none | shift | full. "
                 "none (default): OpenNI sources deliver hardware-registered depth already")
      ->check(CLI::IsMember({"none", "shift", "full"}));
  app.add_option("--register-baseline", register_baseline,
                 "Eye camera centre X,Y,Z in the depth camera's frame, metres (x right, y down, "
                 "z forward)");
  app.add_option("--register-rotation", register_rotation,
                 "Eye camera rotation RX,RY,RZ in degrees (about x, then y, then z) relative to "
                 "the depth camera; shift mode ignores it");
  app.add_option("--register-eye", register_eye,
                 "Eye camera intrinsics FX,FY,CX,CY,W,H in pixels (empty = the depth source's)");
  app.add_option("--register-nominal", cfg.pipeline.registration.nominal_depth_m,
                 "Depth in metres at which shift registration is exact")
      ->check(CLI::Range(0.05, 100.0));
  bool fill = false;
  app.add_flag("--fill", fill,
               "Fill holes here (spatial, then temporal) before sending. Off by default: the "
               "station fills what it needs, the same force error for 18 % fewer bytes and "
               "3.5 ms less work here (docs/BENCHMARKS.md, where to fill)");
  app.add_flag("--no-fill", no_fill, "Send holes as they are (the default)")->excludes("--fill");
  app.add_flag("--no-temporal", no_temporal, "With --fill: spatial fill only");
  cfg.pipeline.hole_fill = telex::cli::shipping_fill();
  telex::cli::add_fill_flags(app, cfg.pipeline.hole_fill);
  app.add_option("--temporal-age", cfg.pipeline.temporal.max_age_frames,
                 "Frames a remembered depth stays usable")
      ->check(CLI::Range(1, 1000));
  app.add_option("--fps", cfg.source_options.synthetic_fps, "Frame rate of synthetic sources");
  app.add_option("--size", size, "Render size WxH of synthetic sources");
  app.add_option("--seed", cfg.source_options.seed, "Noise seed of synthetic sources");
  app.add_option("--jpeg-quality", cfg.jpeg_quality, "JPEG quality of the video (1..100)");
  app.add_option("--video-size", video_size,
                 "Video size WxH sent to the operator (0x0 = source size)");
  app.add_option("--client-timeout-ms", client_timeout_ms, "Drop an operator silent for this long")
      ->check(CLI::Range(100, 600000));
  app.add_option("--max-queued-frames", cfg.server.max_queued_frames,
                 "Frames queued per client before the oldest is dropped")
      ->check(CLI::Range(1, 100));
  app.add_option("--duration", cfg.duration_s, "Stop after S seconds (0 = until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--no-stats", no_stats, "No stats line every second");
  app.add_flag("--no-realtime", no_realtime,
               "Do not try SCHED_FIFO for the threads from capture to the network and the head "
               "loop (the default keeps other programs on this machine from delaying depth)");
  app.add_option("--head", cfg.head,
                 "Robot head driver: none | sim[,tau_ms=80] (first-order servos) | "
                 "dynamixel:DEV[,ids=1,2,3][,baud=57600] (Protocol 2.0 servos yaw, pitch, roll) | "
                 "udp:HOST:PORT (a lab's own head controller; docs/PROTOCOL.md)");
  app.add_flag("--require-deadman", cfg.require_deadman,
               "Move the head only while the station reports its dead-man input pressed "
               "(telex-local --deadman); a station without one holds the head still");
  app.add_option("--log-head", cfg.head_log_csv,
                 "CSV of the head loop, one row per loop: measured pose, command, the operator "
                 "sample's id and age, the dead-man state and why the head holds (docs/PROTOCOL.md "
                 "2.6)");
  app.add_option("--psk", psk_file,
                 "Pre-shared key FILE (16..1024 raw bytes, mode 0600): TLS 1.3 with this key and "
                 "(EC)DHE on TCP, sealed datagrams on UDP; the station needs the same key");
  app.add_option(
      "--cert", cert_file,
      "This remote's certificate chain FILE (PEM), instead of --psk; with --key and --ca");
  app.add_option("--key", key_file, "The private key FILE (PEM, mode 0600) of --cert");
  app.add_option("--ca", ca_file,
                 "CA FILE (PEM): the station's certificate must chain to it (required, verified)");
  app.add_flag("--insecure", insecure,
               "Accept a --listen address off loopback without --psk or certificates: anyone on "
               "the network can then move the robot head and watch its cameras and depth");

  if (rig) telex::remote::show_rig_defaults(app, *rig);
  if (const auto rc = telex::cli::parse(app, argc, argv)) return *rc;
  telex::cli::log_config_values(app);
  if (rig) spdlog::info("telex-remote: {}", telex::remote::describe_rig(*rig));

  try {
    const telex::Endpoint listen_at = telex::parse_endpoint(listen, "--listen", true);
    cfg.server.host = listen_at.host;
    cfg.server.port = listen_at.port;
    cfg.server.force_tcp = transport == "tcp";
    cfg.server.client_timeout = std::chrono::milliseconds(client_timeout_ms);
    cfg.pipeline.codec = *telex::proto::parse_codec(codec);
    if (!parse_size(tile, cfg.pipeline.tile_width, cfg.pipeline.tile_height))
      throw std::invalid_argument(fmt::format("--tile '{}' is not WxH", tile));
    if (!parse_size(size, cfg.source_options.width, cfg.source_options.height) ||
        cfg.source_options.width < 16 || cfg.source_options.height < 16 ||
        cfg.source_options.width > 4096 || cfg.source_options.height > 4096)
      throw std::invalid_argument(fmt::format("--size '{}' is not WxH within 16..4096", size));
    if (!parse_size(video_size, cfg.video_width, cfg.video_height))
      throw std::invalid_argument(fmt::format("--video-size '{}' is not WxH", video_size));
    cfg.pipeline.registration =
        telex::remote::parse_registration(register_mode, register_baseline, register_rotation,
                                          register_eye, cfg.pipeline.registration.nominal_depth_m);
    if (rig)
      telex::remote::apply_rig(
          *rig,
          {app.count("--register") > 0, app.count("--register-baseline") > 0,
           app.count("--register-rotation") > 0, app.count("--register-eye") > 0},
          cfg.pipeline.registration);
    if (rig) {
      cfg.robot_head = rig->robot_head;
      cfg.head_limits = telex::remote::head_limits_from(rig->robot_head);
    }
    cfg.pipeline.fill = fill && !no_fill;
    cfg.pipeline.temporal_fill = !no_temporal;
    cfg.stats_line = !no_stats;
    cfg.realtime = !no_realtime;
    telex::proto::validate_tls_flags(!psk_file.empty(), cert_file, key_file, ca_file);
    if (!psk_file.empty()) {
      telex::proto::check_key_file_permissions(psk_file);
      cfg.server.tls.psk = telex::proto::load_key_file(psk_file);
    }
    if (!cert_file.empty()) {
      telex::proto::check_key_file_permissions(key_file, "private key file");
      cfg.server.tls.cert = cert_file;
      cfg.server.tls.key = key_file;
      cfg.server.tls.ca = ca_file;
    }
    if (!cfg.server.tls.enabled() && !telex::proto::is_loopback_host(cfg.server.host) && !insecure)
      throw std::invalid_argument(telex::proto::insecure_refusal("--listen", listen));
    cfg.insecure = !cfg.server.tls.enabled() && !telex::proto::is_loopback_host(cfg.server.host);
    telex::remote::validate(cfg);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }

  std::unique_ptr<telex::remote::RemoteDaemon> daemon;
  try {
    daemon = std::make_unique<telex::remote::RemoteDaemon>(cfg);  // bad source specs are bad flags
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  try {
    daemon->start();
  } catch (const std::invalid_argument& e) {
    spdlog::error("{}", e.what());
    return 2;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  spdlog::info("head {}", daemon->head()->name());
  std::string path;
  for (const auto& [name, how] : daemon->scheduling())
    path += (path.empty() ? "" : ", ") + name + " " + how;
  spdlog::info("depth path: {}", path);
  spdlog::info("{} -> listening on {}:{} ({}, {})", daemon->depth_source().describe(),
               cfg.server.host, daemon->port(),
               cfg.server.force_tcp ? "tcp" : "udp if the client offers it",
               cfg.server.tls.enabled() ? cfg.server.tls.describe() + ", datagrams sealed"
                                        : "plain: unauthenticated, unencrypted");
  if (cfg.insecure) spdlog::warn("{}", telex::proto::insecure_warning());
  return daemon->run();
}
