// SPDX-License-Identifier: MIT
// `telex process`: one depth frame through hole fill, bilateral and normals; images and JSON out.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.h"
#include "telex/cli/processing_flags.h"
#include "telex/common/bilateral.h"
#include "telex/common/colorize.h"
#include "telex/common/depth_io.h"
#include "telex/common/hole_fill.h"
#include "telex/common/normals.h"
#include "telex/common/registration.h"

namespace telex::tool {
namespace {

struct ProcessArgs {
  std::string in;
  std::string units = "mm";
  std::string out_dir;
  bool json = false;
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;  // Kinect v1 at 640x480
  HoleFillOptions fill = cli::shipping_fill();
  BilateralOptions bilateral = cli::shipping_bilateral();
  NormalOptions normals;
  // Registration to the right-eye image (same size and intrinsics as the depth): shift+scale.
  double register_shift_px = 0.0;
  double register_scale = 1.0;
  bool register_depth = false;
  int runs = 5;  // the stages run this often; timings are medians of the warm runs
};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// A stage's per-frame cost: the first run pays for first use (allocations, page faults, lookup
// tables), the later ones are what a daemon pays per frame.
struct StageRuns {
  std::vector<double> ms;
  double first() const { return ms.front(); }
  double warm() const {
    return ms.size() > 1 ? median_of(std::vector<double>(ms.begin() + 1, ms.end())) : ms.front();
  }
};

void write_png(const std::filesystem::path& file, const cv::Mat& image) {
  if (!cv::imwrite(file.string(), image)) throw std::runtime_error("cannot write " + file.string());
}

int run_process(const ProcessArgs& a) {
  using clock = std::chrono::steady_clock;
  nlohmann::json j;
  j["input"] = a.in;
  j["units"] = a.units;

  auto t0 = clock::now();
  const Intrinsics intr{a.fx, a.fy, a.cx, a.cy, 640, 480};
  DepthImage depth = load_depth(a.in, parse_depth_units(a.units), intr);
  j["load_ms"] = ms_since(t0);
  if (a.register_depth) {
    if (!(a.register_scale > 0.0))
      throw std::invalid_argument("--register-scale must be > 0, got " +
                                  std::to_string(a.register_scale));
    ShiftScale params;
    params.shift_x_px = a.register_shift_px;
    params.scale_x = params.scale_y = a.register_scale;
    t0 = clock::now();
    depth = register_shift_scale(depth, params, depth.intrinsics);
    j["register_ms"] = ms_since(t0);
    j["register_shift_px"] = a.register_shift_px;
    j["register_scale"] = a.register_scale;
  }
  j["width"] = depth.width();
  j["height"] = depth.height();

  if (a.runs < 1) throw std::invalid_argument("--runs must be >= 1");
  StageRuns fill_runs, bilateral_runs, normals_runs;
  HoleFillResult filled;
  cv::Mat1f smooth_m;
  cv::Mat3f normals;
  for (int run = 0; run < a.runs; ++run) {
    t0 = clock::now();
    filled = fill_holes_mode(depth.depth_mm, a.fill);
    fill_runs.ms.push_back(ms_since(t0));
    t0 = clock::now();
    bilateral_filter_depth(filled.depth_mm, smooth_m, a.bilateral);
    bilateral_runs.ms.push_back(ms_since(t0));
    t0 = clock::now();
    compute_normals(smooth_m, depth.intrinsics, normals, a.normals);
    normals_runs.ms.push_back(ms_since(t0));
  }
  j["runs"] = a.runs;
  j["fill_ms"] = fill_runs.warm();
  j["bilateral_ms"] = bilateral_runs.warm();
  j["normals_ms"] = normals_runs.warm();
  j["first_run"] = {{"fill_ms", fill_runs.first()},
                    {"bilateral_ms", bilateral_runs.first()},
                    {"normals_ms", normals_runs.first()}};
  j["holes_in"] = filled.holes_in;
  j["holes_out"] = filled.holes_out;
  j["fill_passes"] = filled.passes_run;

  std::size_t valid = 0;
  for (int y = 0; y < normals.rows; ++y)
    for (int x = 0; x < normals.cols; ++x) valid += normals(y, x) != cv::Vec3f(0, 0, 0);
  j["valid_normals"] = valid;

  if (!a.out_dir.empty()) {
    const std::filesystem::path dir(a.out_dir);
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec)
      throw std::runtime_error("cannot create output directory " + dir.string() + ": " +
                               ec.message());
    const std::string stem = std::filesystem::path(a.in).stem().string();
    const auto filled_png = dir / (stem + "_filled_mm.png");
    const auto normals_png = dir / (stem + "_normals.png");
    const auto colour_png = dir / (stem + "_depth_colour.png");
    save_depth_png(filled_png, filled.depth_mm);
    write_png(normals_png, colorize_normals(normals));
    write_png(colour_png, colorize_depth(filled.depth_mm));
    j["outputs"] = {{"filled_depth_mm", filled_png.string()},
                    {"normals_rgb", normals_png.string()},
                    {"depth_colour", colour_png.string()}};
  }

  if (a.json) {
    std::cout << j.dump() << "\n";
  } else {
    std::cout << a.in << ": " << depth.width() << "x" << depth.height() << ", holes "
              << filled.holes_in << " -> " << filled.holes_out << " in " << filled.passes_run
              << " passes; fill " << j["fill_ms"].get<double>() << " ms, bilateral "
              << j["bilateral_ms"].get<double>() << " ms, normals " << j["normals_ms"].get<double>()
              << " ms (median of " << std::max(1, a.runs - 1) << " warm run(s); first run "
              << fill_runs.first() << " / " << bilateral_runs.first() << " / "
              << normals_runs.first() << " ms)\n";
  }
  return 0;
}

const RegisterCommand kRegister{
    "process", "Fill holes, smooth and compute normals of one depth frame",
    [](cli::CommandLine& app) {
      auto a = std::make_shared<ProcessArgs>();
      app.add_option("--in", a->in, "Depth file (16-bit PNG, or 16-bit PGM for kinect-disparity)")
          ->required();  // a missing file is bad input (exit 1 from load_depth), not a bad flag
      app.add_option("--units", a->units, "Stored units: mm | tum | kinect-disparity")
          ->check(cli::IsMember({"mm", "tum", "kinect-disparity"}))
          ->capture_default_str();
      app.add_option("--out", a->out_dir,
                     "Directory for the filled depth, normals and colour PNGs");
      app.add_flag("--json", a->json, "Print one JSON object with sizes, hole counts and timings");
      app.add_option("--runs", a->runs,
                     "Run the stages this often on the frame; times are medians of the runs after "
                     "the first (first_run in the JSON has the cold figures)")
          ->check(cli::Range(1, 1000))
          ->capture_default_str();
      app.add_option("--fx", a->fx, "Focal length x (px) at 640x480")->capture_default_str();
      app.add_option("--fy", a->fy, "Focal length y (px) at 640x480")->capture_default_str();
      app.add_option("--cx", a->cx, "Principal point x (px) at 640x480")->capture_default_str();
      app.add_option("--cy", a->cy, "Principal point y (px) at 640x480")->capture_default_str();
      app.add_option("--register-shift", a->register_shift_px,
                     "Register to the right eye: horizontal shift (px) after scaling")
          ->each([a](const std::string&) { a->register_depth = true; });
      app.add_option("--register-scale", a->register_scale,
                     "Register to the right eye: field-of-view scale about the principal point")
          ->each([a](const std::string&) { a->register_depth = true; });
      cli::add_fill_flags(app, a->fill);
      cli::add_bilateral_radius(app, a->bilateral.radius_px);
      cli::add_bilateral_sigmas(app, a->bilateral);
      app.add_option("--normal-smooth", a->normals.smooth_radius_px,
                     "Half-width of the derivative box (0 = central differences)")
          ->capture_default_str();
      return [a] { return run_process(*a); };
    }};

}  // namespace
}  // namespace telex::tool
