// SPDX-License-Identifier: MIT
// `telex capture`: N depth frames from any depth source as 16-bit millimetre PNGs, with the eye
// images when the run has an eye view, the sensor's IR images with --ir (what `telex calibrate
// depth-eye --ir` reads), and a capture.json of what was written (as librealsense's
// rs-save-to-disk does for its cameras). The sources are the daemon's own (make_depth_source,
// make_eye_source), so a capture holds exactly what telex-remote would have read.
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <system_error>

#include "command.h"
#include "telex/common/depth_io.h"
#include "telex/remote/sources.h"

namespace telex::tool {
namespace {

namespace fs = std::filesystem;

struct CaptureArgs {
  std::string source;
  std::string stereo;
  std::string out;
  int frames = 1;
  int every = 1;
  double timeout_s = 5.0;
  bool json = false;
  bool ir = false;
  int ir_bits = 10;
};

// The output directory exists and takes a file, or an error names it and why.
void prepare_out(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(fmt::format("cannot create {}: {}", dir.string(), ec.message()));
  const fs::path probe = dir / ".telex_capture_probe";
  if (!std::ofstream(probe))
    throw std::runtime_error(fmt::format("cannot write in {}", dir.string()));
  fs::remove(probe, ec);
}

void write_png(const fs::path& file, const cv::Mat& image) {
  bool ok = false;
  try {
    ok = cv::imwrite(file.string(), image);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(fmt::format("cannot write {}: {}", file.string(), e.what()));
  }
  if (!ok) throw std::runtime_error(fmt::format("cannot write {}", file.string()));
}

// Ctrl-C and SIGTERM end a capture between frames: the frames written so far are listed in
// capture.json, as after a full run.
std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop = true; }

// What one run wrote: the rows of capture.json and the counts its summary gives.
struct CaptureLog {
  nlohmann::json frames = nlohmann::json::array();
  int read = 0, kept = 0, eye_frames = 0, ir_frames = 0;
};

// The IR image read after depth frame `log.kept`: 8-bit PNG, or 16-bit holding its 10 bits.
void save_ir(const fs::path& out, remote::DepthSource& depth, std::chrono::milliseconds timeout,
             CaptureLog& log, nlohmann::json& row) {
  auto ir = depth.read_ir(timeout);
  if (ir.status == remote::ReadStatus::Timeout)
    throw std::runtime_error(
        fmt::format("source {} gave no IR image in {} ms", depth.describe(), timeout.count()));
  if (ir.status != remote::ReadStatus::Frame)
    throw std::runtime_error(fmt::format("source {}: IR: {}", depth.describe(),
                                         ir.error.empty() ? "the recording ended" : ir.error));
  const std::string file = fmt::format("ir_{:06d}.png", log.kept);
  write_png(out / file, ir.frame.image);
  row["ir"] = file;
  row["ir_bits"] = ir.frame.bits;
  row["ir_capture_ns"] = ir.frame.capture_ns;
  ++log.ir_frames;
}

// Saves one depth frame (and its eye pair when there is one) and adds its row.
void save_frame(const fs::path& out, const remote::DepthFrame& f, remote::DepthSource& depth,
                bool ir, remote::StereoSource* eyes, std::chrono::milliseconds timeout,
                CaptureLog& log) {
  const std::string file = fmt::format("depth_{:06d}_mm.png", log.kept);
  save_depth_png(out / file, f.image.depth_mm);
  nlohmann::json row{{"file", file},
                     {"frame_id", f.frame_id},
                     {"capture_ns", f.capture_ns},
                     {"scene_time_s", f.scene_time_s}};
  if (ir) save_ir(out, depth, timeout, log, row);
  if (eyes) {
    auto e = eyes->read(timeout);
    if (e.status == remote::ReadStatus::Error)
      throw std::runtime_error(fmt::format("eye source {}: {}", eyes->describe(), e.error));
    if (e.status == remote::ReadStatus::Frame) {
      const std::string left = fmt::format("left_{:06d}.png", log.kept);
      const std::string right = fmt::format("right_{:06d}.png", log.kept);
      write_png(out / left, e.frame.left_bgr);
      write_png(out / right, e.frame.right_bgr);
      row["left"] = left;
      row["right"] = right;
      row["eye_capture_ns"] = e.frame.capture_ns;
      ++log.eye_frames;
    }
  }
  log.frames.push_back(std::move(row));
  ++log.kept;
}

// Reads until `a.frames` are kept, the source fails, or a stop signal. Throws on a source error
// (after which the caller still writes what was kept); returns false when stopped by a signal.
bool capture_frames(const CaptureArgs& a, const fs::path& out, remote::DepthSource& depth,
                    remote::StereoSource* eyes, const std::string& name, CaptureLog& log) {
  const auto timeout = std::chrono::milliseconds(static_cast<long>(a.timeout_s * 1000.0));
  const auto per_read = std::min(timeout, std::chrono::milliseconds(100));
  auto waiting_since = std::chrono::steady_clock::now();
  auto last_progress = waiting_since;
  while (log.kept < a.frames) {
    if (g_stop) return false;
    auto r = depth.read(per_read);
    if (r.status == remote::ReadStatus::Error)
      throw std::runtime_error(fmt::format("source {}: {}", name, r.error));
    if (r.status == remote::ReadStatus::EndOfStream)
      throw std::runtime_error(fmt::format("source {} ended after {} frames ({} kept of {} asked)",
                                           name, log.read, log.kept, a.frames));
    const auto now = std::chrono::steady_clock::now();
    if (r.status == remote::ReadStatus::Timeout) {
      if (now - waiting_since > timeout)
        throw std::runtime_error(
            fmt::format("source {} gave no frame in {} s ({} kept of {} asked)", name, a.timeout_s,
                        log.kept, a.frames));
      continue;
    }
    waiting_since = now;
    if (log.read++ % a.every != 0) continue;
    save_frame(out, r.frame, depth, a.ir, eyes, timeout, log);
    if (now - last_progress > std::chrono::seconds(2)) {
      std::cerr << fmt::format("telex capture: {} of {} frames written\n", log.kept, a.frames);
      last_progress = now;
    }
  }
  return true;
}

void write_capture_json(const fs::path& out, const nlohmann::json& summary) {
  std::ofstream os(out / "capture.json");
  os << summary.dump(2) << "\n";
  if (!os.flush())
    throw std::runtime_error(fmt::format("cannot write {}", (out / "capture.json").string()));
}

int run_capture(const CaptureArgs& a) {
  const fs::path out = a.out;
  // A spec that does not parse is a usage error (exit 2); a source that cannot open is exit 1.
  std::unique_ptr<remote::DepthSource> depth;
  std::unique_ptr<remote::StereoSource> eyes;
  try {
    depth = remote::make_depth_source(a.source);
    eyes = remote::make_eye_source(a.source, a.stereo);
    if (a.ir) depth->enable_ir({a.ir_bits});
  } catch (const std::invalid_argument& e) {
    std::cerr << "telex capture: " << e.what() << "\n";
    return 2;
  }
  prepare_out(out);
  depth->start();
  if (eyes) eyes->start();
  const std::string name = depth->describe();
  g_stop = false;
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);

  CaptureLog log;
  std::string error;
  bool complete = false;
  try {
    complete = capture_frames(a, out, *depth, eyes.get(), name, log);
  } catch (const std::exception& e) {
    error = e.what();
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  const Intrinsics k = depth->intrinsics();
  const nlohmann::json summary{{"source", name},
                               {"eye_source", eyes ? eyes->describe() : ""},
                               {"frames", log.kept},
                               {"frames_asked", a.frames},
                               {"complete", complete},
                               {"ended_by", complete        ? "done"
                                            : error.empty() ? "signal"
                                                            : error},
                               {"frames_read", log.read},
                               {"eye_frames", log.eye_frames},
                               {"ir_frames", log.ir_frames},
                               {"ir_projector", a.ir ? depth->ir_projector() : ""},
                               {"every", a.every},
                               {"out", out.string()},
                               {"intrinsics",
                                {{"fx", k.fx},
                                 {"fy", k.fy},
                                 {"cx", k.cx},
                                 {"cy", k.cy},
                                 {"width", k.width},
                                 {"height", k.height}}},
                               {"nominal_fps", depth->nominal_fps()},
                               {"files", log.frames}};
  depth->stop();
  if (eyes) eyes->stop();
  write_capture_json(out, summary);
  if (!error.empty()) throw std::runtime_error(error + "; capture.json lists the frames written");
  if (a.json) {
    nlohmann::json brief = summary;
    brief.erase("files");
    std::cout << brief.dump() << "\n";
  } else {
    std::cout << fmt::format(
        "{} depth frames ({} with eye images{}) from {} in {}{}\n", log.kept, log.eye_frames,
        a.ir
            ? fmt::format(", {} with IR images, projector {}", log.ir_frames, depth->ir_projector())
            : "",
        name, out.string(), complete ? "" : " (interrupted; capture.json lists them)");
  }
  // Interrupted: the shell's convention for a run ended by SIGINT.
  return complete ? 0 : 130;
}

const RegisterCommand kRegister{
    "capture", "save N depth frames (16-bit mm PNG) and eye images from any source",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto a = std::make_shared<CaptureArgs>();
      app.add_option("--source", a->source, "depth source spec: " + remote::depth_source_help())
          ->required();
      app.add_option(
          "--stereo", a->stereo,
          "eye view spec (default: a bag source's colour=): " + remote::stereo_source_help());
      app.add_option("--frames", a->frames, "frames to save")->check(cli::Range(1, 1'000'000));
      app.add_option("--out", a->out, "output directory (created)")->required();
      app.add_option("--every", a->every, "keep every K-th frame read")
          ->check(cli::Range(1, 1'000'000));
      app.add_option("--timeout", a->timeout_s, "seconds to wait for a frame before giving up")
          ->check(cli::Range(0.1, 3600.0));
      app.add_flag("--json", a->json, "print a JSON summary instead of the text line");
      app.add_flag("--ir", a->ir,
                   "also save the depth sensor's IR image with each frame (ir_NNNNNN.png, for "
                   "`telex calibrate depth-eye --ir`), the projector off where the device allows; "
                   "openni:URI and freenect:N only");
      app.add_option("--ir-bits", a->ir_bits,
                     "IR depth: 8 (8-bit PNG) or 10 (16-bit PNG holding 0..1023)")
          ->check(cli::IsMember({8, 10}));
      return [a] { return run_capture(*a); };
    }};

}  // namespace
}  // namespace telex::tool
