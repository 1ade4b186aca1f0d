// SPDX-License-Identifier: MIT
// telex-remote's flags: their definitions, and what their text becomes (the registration flags:
// text -> RegistrationConfig).
#include "flags.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "telex/cli/cli.h"
#include "telex/cli/processing_flags.h"
#include "telex/common/endpoint.h"

namespace telex::remote {

RegisterMode parse_register_mode(std::string_view text) {
  if (text == "none") return RegisterMode::None;
  if (text == "shift") return RegisterMode::Shift;
  if (text == "full") return RegisterMode::Full;
  throw std::invalid_argument("registration mode '" + std::string(text) +
                              "' is not one of none, shift, full");
}

namespace {

std::vector<double> parse_numbers(std::string_view text, std::size_t count, const char* flag,
                                  const char* form) {
  std::vector<double> out;
  std::string item;
  const std::string all(text);
  std::size_t start = 0;
  while (start <= all.size()) {
    const std::size_t comma = std::min(all.find(',', start), all.size());
    item = all.substr(start, comma - start);
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || !std::isfinite(v))
      throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
    out.push_back(v);
    start = comma + 1;
  }
  if (out.size() != count)
    throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
  return out;
}

}  // namespace

RegistrationConfig parse_registration(std::string_view mode, std::string_view eye_centre_m,
                                      std::string_view rotation_deg, std::string_view eye,
                                      double nominal_depth_m) {
  RegistrationConfig c;
  c.mode = parse_register_mode(mode);
  const auto centre = parse_numbers(eye_centre_m, 3, "--register-baseline", "X,Y,Z in metres");
  const auto rot = parse_numbers(rotation_deg, 3, "--register-rotation", "RX,RY,RZ in degrees");
  const double k = std::numbers::pi / 180.0;
  const glm::dmat3 rx(1, 0, 0, 0, std::cos(rot[0] * k), std::sin(rot[0] * k), 0,
                      -std::sin(rot[0] * k), std::cos(rot[0] * k));
  const glm::dmat3 ry(std::cos(rot[1] * k), 0, -std::sin(rot[1] * k), 0, 1, 0, std::sin(rot[1] * k),
                      0, std::cos(rot[1] * k));
  const glm::dmat3 rz(std::cos(rot[2] * k), std::sin(rot[2] * k), 0, -std::sin(rot[2] * k),
                      std::cos(rot[2] * k), 0, 0, 0, 1);
  // The eye's axes, seen from the depth camera, are the depth camera's turned by R; a depth-frame
  // point p is at R^T (p - C) in the eye's frame.
  const glm::dmat3 r = rz * ry * rx;
  const glm::dvec3 c_m(centre[0], centre[1], centre[2]);
  c.X_EyeDepth.rotation = glm::transpose(r);
  c.X_EyeDepth.translation_m = -(glm::transpose(r) * c_m);
  if (!eye.empty()) {
    const auto e = parse_numbers(eye, 6, "--register-eye", "FX,FY,CX,CY,W,H in pixels");
    if (!(e[0] > 0 && e[1] > 0 && e[4] >= 1 && e[5] >= 1 && e[4] <= 8192 && e[5] <= 8192 &&
          e[4] == std::floor(e[4]) && e[5] == std::floor(e[5])))
      throw std::invalid_argument("--register-eye '" + std::string(eye) +
                                  "': FX, FY must be > 0 and W, H whole numbers 1..8192");
    c.eye = Intrinsics{e[0], e[1], e[2], e[3], static_cast<int>(e[4]), static_cast<int>(e[5])};
  }
  if (!(nominal_depth_m > 0) || !std::isfinite(nominal_depth_m))
    throw std::invalid_argument("--register-nominal must be > 0 m");
  c.nominal_depth_m = nominal_depth_m;
  return c;
}

void apply_rig(const Rig& rig, const RegistrationFlagsGiven& given, RegistrationConfig& reg) {
  if (rig.depth) reg.depth = rig.depth;
  if (rig.eye[index_of(Side::Right)] && !given.eye) reg.eye = rig.eye[index_of(Side::Right)]->k;
  if (rig.X_RightEyeDepth) {
    if (!given.centre) reg.X_EyeDepth.translation_m = rig.X_RightEyeDepth->translation_m;
    if (!given.rotation) reg.X_EyeDepth.rotation = rig.X_RightEyeDepth->rotation;
    if (!given.mode) reg.mode = RegisterMode::Full;
  }
}

namespace {

std::string rig_extrinsics_text(const Rig& rig) {
  return fmt::format("the rig's extrinsics.right_eye_from_depth (depth_pixels \"{}\"{})",
                     depth_pixels_name(rig.depth_pixels),
                     rig.path.empty() ? "" : ", " + rig.path.string());
}

void require_openni(std::string_view source_spec, const char* why) {
  std::string kind;
  try {
    kind = parse_source_spec(source_spec).kind;
  } catch (const std::invalid_argument&) {
    return;  // the source's own check names a bad spec
  }
  if (kind != "openni")
    throw std::invalid_argument(fmt::format(
        "{}: source '{}' has no sensor registration; only a live openni:URI device (PS1080: "
        "Kinect v1, Carmine, Xtion) registers depth to its colour camera",
        why, source_spec));
}

}  // namespace

DepthRegistration choose_registration(const RegistrationChoice& c, RegistrationConfig& reg,
                                      SourceOptions& source) {
  const bool extrinsics = reg.mode != RegisterMode::None;
  const bool from_rig = extrinsics && !c.register_given && c.rig && c.rig->X_RightEyeDepth;
  const std::string register_text = fmt::format("--register {}", register_mode_name(reg.mode));
  DepthRegistration r = extrinsics ? DepthRegistration::Rig : DepthRegistration::None;
  if (c.asked == "hardware") {
    r = DepthRegistration::Hardware;
  } else if (c.asked == "rig") {
    r = DepthRegistration::Rig;
  } else if (c.asked == "none") {
    r = DepthRegistration::None;
  } else if (!c.asked.empty()) {
    throw std::invalid_argument(
        fmt::format("--registration '{}' is not one of hardware, rig, none", c.asked));
  }
  source.hardware_registration = false;
  switch (r) {
    case DepthRegistration::Hardware:
      if (c.register_given)
        throw std::invalid_argument(fmt::format(
            "--registration hardware and {} would register twice: the sensor brings depth to its "
            "colour camera, then the extrinsics would move it again; choose one",
            register_text));
      if (from_rig && c.rig->depth_pixels == DepthPixels::Ir)
        throw std::invalid_argument(fmt::format(
            "--registration hardware and {} would register twice: those extrinsics start from the "
            "sensor's own pixels, which hardware registration has already left; use "
            "--registration rig, or calibrate on hardware-registered depth (depth_pixels "
            "\"color\")",
            rig_extrinsics_text(*c.rig)));
      require_openni(c.source_spec, "--registration hardware");
      reg.mode = RegisterMode::None;
      source.hardware_registration = true;
      break;
    case DepthRegistration::Rig:
      if (!extrinsics)
        throw std::invalid_argument(
            "--registration rig needs extrinsics: --rig FILE with "
            "extrinsics.right_eye_from_depth, or --register shift|full with --register-baseline");
      // Extrinsics calibrated on hardware-registered depth start from the colour camera: the
      // sensor registers first, then the extrinsics bring the depth to the right eye.
      if (from_rig && c.rig->depth_pixels == DepthPixels::Color) {
        require_openni(c.source_spec,
                       "--registration rig with extrinsics calibrated in colour pixels "
                       "(depth_pixels \"color\")");
        source.hardware_registration = true;
      }
      break;
    case DepthRegistration::None:
      if (c.register_given)
        throw std::invalid_argument(fmt::format(
            "--registration none and {} contradict each other: drop one", register_text));
      reg.mode = RegisterMode::None;
      break;
  }
  return r;
}

namespace {

// The eye centre X,Y,Z in the depth camera's frame (the inverse of parse_registration's).
std::string eye_centre_text(const RigidTransform& X_EyeDepth) {
  const glm::dvec3 c = -(glm::transpose(X_EyeDepth.rotation) * X_EyeDepth.translation_m);
  return fmt::format("{:.4f},{:.4f},{:.4f}", c.x, c.y, c.z);
}

std::string intrinsics_text(const Intrinsics& k) {
  return fmt::format("{:.2f},{:.2f},{:.2f},{:.2f},{},{}", k.fx, k.fy, k.cx, k.cy, k.width,
                     k.height);
}

}  // namespace

void show_rig_defaults(CLI::App& app, const Rig& rig) {
  const auto set = [&](const char* flag, const std::string& text) {
    if (CLI::Option* opt = app.get_option_no_throw(flag)) opt->default_str(text + " (rig)");
  };
  if (rig.eye[index_of(Side::Right)]) set("--register-eye", intrinsics_text(rig.eye[1]->k));
  if (rig.X_RightEyeDepth) {
    set("--register", "full");
    set("--register-baseline", eye_centre_text(*rig.X_RightEyeDepth));
    set("--register-rotation", "the rig's extrinsics.right_eye_from_depth");
  }
}

std::string describe_rig(const Rig& rig) {
  std::string text = "rig " + rig.path.string() + ":";
  if (rig.depth) text += " depth " + intrinsics_text(*rig.depth) + ";";
  if (rig.eye[index_of(Side::Right)])
    text += " right eye " + intrinsics_text(rig.eye[index_of(Side::Right)]->k) + ";";
  if (rig.X_RightEyeDepth)
    text += " eye centre in depth frame " + eye_centre_text(*rig.X_RightEyeDepth) + " m;";
  text += " robot head joints and limits";
  return text;
}

void load_remote_rig(int argc, char** argv, RemoteFlags& f) {
  if (const auto rig = cli::rig_before_flags(argc, argv)) {
    f.rig_file = rig->value;
    try {
      f.rig = telex::load_rig(f.rig_file);
    } catch (const std::exception& e) {
      if (rig->file.empty()) throw;
      throw std::runtime_error(e.what() + rig->note("rig"));
    }
  }
}

namespace {

// The rig and the sources.
void add_source_options(CLI::App& app, RemoteFlags& f) {
  app.add_option("--rig", f.rig_file,
                 "Rig FILE (docs/RIG.md): the depth and eye cameras' calibration and the "
                 "depth-to-right-eye extrinsics (registration becomes full), the robot head's "
                 "joints; the flags below override it");
  app.add_option("--source", f.cfg.depth_source, "Depth source: " + depth_source_help());
  app.add_option("--stereo", f.cfg.stereo_source,
                 "Stereo video source (empty = none): " + stereo_source_help());
}

// Where the operator connects, and how depth and video reach it.
void add_link_options(CLI::App& app, RemoteFlags& f) {
  app.add_option("--listen", f.listen, "TCP control endpoint HOST:PORT");
  app.add_option("--transport", f.transport,
                 "Depth/video transport when the client offers UDP: udp | tcp")
      ->check(CLI::IsMember({"udp", "tcp"}));
}

// The depth pipeline's encoding: codec, tiles, key frames, stabilisation.
void add_pipeline_options(CLI::App& app, RemoteFlags& f) {
  PipelineConfig& p = f.cfg.pipeline;
  app.add_option("--codec", f.codec, "Preferred depth codec: raw | zip | fast")
      ->check(CLI::IsMember({"raw", "zip", "fast"}));
  app.add_option("--zip-level", p.zip_level, "Deflate level of the zip codec (0 = Huffman only)")
      ->check(CLI::Range(0, 9));
  app.add_option("--tile", f.tile, "Tile size WxH in pixels");
  app.add_option("--key-every", p.key_frame_every, "Frames between key frames")
      ->check(CLI::Range(1, 100000));
  app.add_option("--stream-tiles", p.stream_tiles,
                 "Send a frame's tiles in batches of N as they are encoded, ahead of its manifest "
                 "(0 = each part at once)")
      ->check(CLI::Range(0, 4096));
  app.add_option("--background-every", p.background_every,
                 "While an ROI is requested, tiles outside it are considered every Nth frame")
      ->check(CLI::Range(1, 1000));
  app.add_option(
         "--stabilise", p.stabilise_k_sigma,
         "Hold a pixel's last sent depth while within K sensor-noise sigmas (0 = off, bit-exact)")
      ->check(CLI::Range(0.0, 100.0));
}

// Depth registered into the right-eye camera (the rig may set these; show_rig_defaults).
void add_registration_options(CLI::App& app, RemoteFlags& f) {
  app.add_option(
         "--registration", f.registration,
         "The run's one registration: hardware (the sensor registers depth to its colour "
         "camera; openni:URI only), rig (the calibrated extrinsics bring depth to the right "
         "eye) or none (depth in the sensor's own pixels). Default: rig when the rig or "
         "--register gives extrinsics, else none")
      ->check(CLI::IsMember({"hardware", "rig", "none"}));
  app.add_option("--register", f.register_mode,
                 "How --registration rig registers depth into the right-eye camera before fill: "
                 "none | shift | full (a rig with extrinsics: full)")
      ->check(CLI::IsMember({"none", "shift", "full"}));
  app.add_option("--register-baseline", f.register_baseline,
                 "Eye camera centre X,Y,Z in the depth camera's frame, metres (x right, y down, "
                 "z forward)");
  app.add_option("--register-rotation", f.register_rotation,
                 "Eye camera rotation RX,RY,RZ in degrees (about x, then y, then z) relative to "
                 "the depth camera; shift mode ignores it");
  app.add_option("--register-eye", f.register_eye,
                 "Eye camera intrinsics FX,FY,CX,CY,W,H in pixels (empty = the depth source's)");
  app.add_option("--register-nominal", f.cfg.pipeline.registration.nominal_depth_m,
                 "Depth in metres at which shift registration is exact")
      ->check(CLI::Range(0.05, 100.0));
}

// Hole filling here (off by default: the station fills).
void add_fill_options(CLI::App& app, RemoteFlags& f) {
  app.add_flag("--fill", f.fill,
               "Fill holes here (spatial, then temporal) before sending. Off by default: the "
               "station fills what it needs, the same force error for 18 % fewer bytes and "
               "3.5 ms less work here (docs/BENCHMARKS.md, where to fill)");
  app.add_flag("--no-fill", f.no_fill, "Send holes as they are (the default)")->excludes("--fill");
  app.add_flag("--no-temporal", f.no_temporal, "With --fill: spatial fill only");
  f.cfg.pipeline.hole_fill = telex::cli::shipping_fill();
  telex::cli::add_fill_flags(app, f.cfg.pipeline.hole_fill);
  app.add_option("--temporal-age", f.cfg.pipeline.temporal.max_age_frames,
                 "Frames a remembered depth stays usable")
      ->check(CLI::Range(1, 1000));
}

// Synthetic sources' frames and the video sent.
void add_frame_options(CLI::App& app, RemoteFlags& f) {
  app.add_option("--fps", f.cfg.source_options.synthetic_fps, "Frame rate of synthetic sources");
  app.add_option("--size", f.size, "Render size WxH of synthetic sources");
  app.add_option("--seed", f.cfg.source_options.seed, "Noise seed of synthetic sources");
  app.add_option("--jpeg-quality", f.cfg.jpeg_quality,
                 "JPEG quality of the video with --video-codec mjpeg (1..100)");
  app.add_option("--video-size", f.video_size,
                 "Video size WxH of each eye sent to the operator (0x0 = source size)");
  app.add_option("--video-codec", f.cfg.video_codec,
                 "The eyes' codec, both eyes side by side in one picture: h264 (libx264, "
                 "software) | h264-vaapi | h264-nvenc (hardware: a start that cannot open it "
                 "fails naming libavcodec's reason, exit 2) | mjpeg (camera MJPEG passes through "
                 "unchanged) | auto (the first hardware encoder that opens, else h264)");
  app.add_option("--video-bitrate", f.video_bitrate,
                 "The eyes' H.264 target in bit/s (4M, 2500k, 800000; 50k..1G)");
}

// The operator's session and the daemon's run.
void add_run_options(CLI::App& app, RemoteFlags& f) {
  app.add_option("--client-timeout-ms", f.client_timeout_ms,
                 "Drop an operator silent for this long")
      ->check(CLI::Range(100, 600000));
  app.add_option("--max-queued-frames", f.cfg.server.max_queued_frames,
                 "Frames queued per client before the oldest is dropped")
      ->check(CLI::Range(1, 100));
  app.add_option("--duration", f.cfg.duration_s, "Stop after S seconds (0 = until SIGINT/SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--no-stats", f.no_stats, "No stats line every second");
  app.add_option("--stats", f.stats_form,
                 "The stats line every second: short (rates, the station, the eyes, the head and "
                 "the problem counters that are not zero) | full (every counter and stage time)")
      ->capture_default_str()
      ->check(CLI::IsMember({"short", "full"}));
  app.add_flag("--no-realtime", f.no_realtime,
               "Do not try SCHED_FIFO for the threads from capture to the network and the head "
               "loop (the default keeps other programs on this machine from delaying depth)");
}

// The robot head.
void add_head_options(CLI::App& app, RemoteFlags& f) {
  app.add_option("--head", f.cfg.head,
                 "Robot head driver: none | sim[,tau_ms=80] (first-order servos) | "
                 "dynamixel:DEV[,ids=1,2,3][,baud=57600] (Protocol 2.0 servos yaw, pitch, roll) | "
                 "udp:HOST:PORT (a lab's own head controller; docs/PROTOCOL.md)");
  app.add_flag("--require-deadman", f.cfg.require_deadman,
               "Move the head only while the station reports its dead-man input pressed "
               "(telex-local --deadman); a station without one holds the head still");
  app.add_option("--log-head", f.cfg.head_log_csv,
                 "CSV of the head loop, one row per loop: measured pose, command, the operator "
                 "sample's id and age, the dead-man state and why the head holds (docs/PROTOCOL.md "
                 "2.6)");
}

// TLS: a pre-shared key or certificates, or --insecure off loopback.
void add_security_options(CLI::App& app, RemoteFlags& f) {
  telex::cli::add_link_security(app, f.security, {"remote", "station", "--listen", true});
}

// The keys whose value is a path (a source's files too): in a --config file they are relative to
// its folder. Device nodes (/dev/...) are given whole.
void add_config_paths(CLI::App& app) {
  telex::cli::config_paths(app, {"rig", "log-head", "psk", "cert", "key", "ca"});
  telex::cli::config_paths(app, {"source"},
                           telex::cli::spec_paths_in({{"oni", 1}, {"files", 1}, {"bag", 1}}));
  telex::cli::config_paths(app, {"stereo"}, telex::cli::spec_paths_in({{"files", 2}, {"bag", 1}}));
}

}  // namespace

void add_remote_options(CLI::App& app, RemoteFlags& f) {
  telex::cli::add_strict_config(app, "Read options from FILE");
  add_source_options(app, f);
  add_link_options(app, f);
  add_pipeline_options(app, f);
  add_registration_options(app, f);
  add_fill_options(app, f);
  add_frame_options(app, f);
  add_run_options(app, f);
  add_head_options(app, f);
  add_security_options(app, f);
  add_config_paths(app);
  if (f.rig) show_rig_defaults(app, *f.rig);
}

namespace {

bool parse_size(const std::string& text, int& w, int& h) {
  char x = 0;
  std::istringstream in(text);
  return static_cast<bool>(in >> w >> x >> h) && x == 'x' && in.peek() == EOF;
}

// --listen, --transport, --client-timeout-ms, --codec.
void resolve_link(RemoteFlags& f) {
  DaemonConfig& cfg = f.cfg;
  const Endpoint listen_at = parse_endpoint(f.listen, "--listen", true);
  cfg.server.host = listen_at.host;
  cfg.server.port = listen_at.port;
  cfg.server.force_tcp = f.transport == "tcp";
  cfg.server.client_timeout = std::chrono::milliseconds(f.client_timeout_ms);
  cfg.pipeline.codec = *proto::parse_codec(f.codec);
}

// --tile, --size, --video-size: WxH.
void resolve_sizes(RemoteFlags& f) {
  DaemonConfig& cfg = f.cfg;
  if (!parse_size(f.tile, cfg.pipeline.tile_width, cfg.pipeline.tile_height))
    throw std::invalid_argument(fmt::format("--tile '{}' is not WxH", f.tile));
  if (!parse_size(f.size, cfg.source_options.width, cfg.source_options.height) ||
      cfg.source_options.width < 16 || cfg.source_options.height < 16 ||
      cfg.source_options.width > 4096 || cfg.source_options.height > 4096)
    throw std::invalid_argument(fmt::format("--size '{}' is not WxH within 16..4096", f.size));
  if (!parse_size(f.video_size, cfg.video_width, cfg.video_height))
    throw std::invalid_argument(fmt::format("--video-size '{}' is not WxH", f.video_size));
  cfg.video_bitrate_bps = parse_bitrate_bps(f.video_bitrate);
  video_encoder_names(cfg.video_codec);  // throws naming --video-codec
}

// The registration flags, then the rig (the flags given win) and the rig's robot head.
void resolve_registration(const CLI::App& app, RemoteFlags& f) {
  DaemonConfig& cfg = f.cfg;
  cfg.pipeline.registration =
      parse_registration(f.register_mode, f.register_baseline, f.register_rotation, f.register_eye,
                         cfg.pipeline.registration.nominal_depth_m);
  if (f.rig) {
    apply_rig(*f.rig,
              {app.count("--register") > 0, app.count("--register-baseline") > 0,
               app.count("--register-rotation") > 0, app.count("--register-eye") > 0},
              cfg.pipeline.registration);
    cfg.robot_head = f.rig->robot_head;
    cfg.head_limits = head_limits_from(f.rig->robot_head);
  }
  cfg.registration =
      choose_registration({f.registration, app.count("--register") > 0 && f.register_mode != "none",
                           f.rig ? &*f.rig : nullptr, cfg.depth_source},
                          cfg.pipeline.registration, cfg.source_options);
}

// --psk, --cert/--key/--ca and --insecure: the keys loaded and checked, and a plain link off
// loopback refused without --insecure.
void resolve_security(RemoteFlags& f) {
  ServerConfig& server = f.cfg.server;
  server.tls = telex::cli::load_link_security(f.security, proto::TlsRole::Server);
  // A name (localhost) listens on its first address; the address checked is the one bound.
  try {
    server.host = proto::resolve_host(server.host).front();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("--listen " + f.listen + ": " + e.what());
  }
  const bool loopback = proto::is_loopback_address(server.host);
  if (!server.tls.enabled() && !loopback && !f.security.insecure)
    throw std::invalid_argument(proto::insecure_refusal("--listen", f.listen));
  f.cfg.insecure = !server.tls.enabled() && !loopback;
}

}  // namespace

void resolve_remote_flags(const CLI::App& app, RemoteFlags& f) {
  resolve_link(f);
  resolve_sizes(f);
  resolve_registration(app, f);
  f.cfg.pipeline.fill = f.fill && !f.no_fill;
  f.cfg.pipeline.temporal_fill = !f.no_temporal;
  f.cfg.stats_line = !f.no_stats;
  f.cfg.stats_full = f.stats_form == "full";
  f.cfg.realtime = !f.no_realtime;
  resolve_security(f);
  validate(f.cfg);
}

std::optional<int> parse_remote_command_line(int argc, char** argv, RemoteFlags& flags) {
  // The rig is read before the flags; the flags given override what it sets.
  if (const auto rc =
          cli::load_before_flags("telex-remote", [&] { load_remote_rig(argc, argv, flags); }))
    return rc;
  CLI::App app{
      "telex-remote: streams filled, tiled, compressed depth (and optional stereo video) to one "
      "operator"};
  cli::prepare(app, "telex-remote");
  add_remote_options(app, flags);
  if (const auto rc = cli::parse(app, argc, argv)) return rc;
  flags.config = cli::config_origin(app, argc, argv);
  if (flags.rig) spdlog::info("{}", describe_rig(*flags.rig));
  try {
    resolve_remote_flags(app, flags);
  } catch (const std::exception& e) {
    spdlog::error("{}{}", e.what(), flags.config.note(e.what()));
    return cli::kUsageExit;
  }
  return std::nullopt;
}

}  // namespace telex::remote
