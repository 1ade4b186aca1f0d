// SPDX-License-Identifier: MIT
// `telex calibrate stereo|depth-eye|render`: chessboard calibration of the eyes and of the depth
// sensor against the right eye, written into a rig file; `render` makes boards with known answers.
// `body` and `glove` (the operator) live in cmd_calibrate_body.cpp, `hmd` in cmd_calibrate_hmd.cpp.
#include <fmt/format.h>
#include <glob.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "calibrate_cli.h"
#include "calibrate_report.h"
#include "command.h"
#include "telex/calib/board.h"
#include "telex/calib/calibrate.h"
#include "telex/calib/render.h"
#include "telex/common/rig.h"

namespace telex::tool {

// cmd_calibrate_body.cpp: `body` and `glove`; the runner returns -1 when neither was parsed.
std::function<int()> add_calibrate_operator(cli::CommandLine& app);
// cmd_calibrate_hmd.cpp: `hmd`; the runner returns -1 when it was not parsed.
std::function<int()> add_calibrate_hmd(cli::CommandLine& app);

namespace {

namespace fs = std::filesystem;
using calib::BoardSpec;
using calib::CalibrationError;
using calib::ViewCorners;

constexpr double kDeg = 180.0 / 3.14159265358979323846;

BoardSpec board_from_flags(const std::string& cxr, double square_mm) {
  try {
    return calib::parse_board(cxr, square_mm);
  } catch (const std::invalid_argument& e) {
    throw FlagError(e.what());
  }
}

// The files a glob pattern matches, in sorted order (glob(3) sorts); directories left out.
std::vector<std::string> expand(const std::string& pattern, const char* flag) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), GLOB_TILDE, nullptr, &g);
  std::vector<std::string> files;
  if (rc == 0)
    for (std::size_t i = 0; i < g.gl_pathc; ++i) {
      std::error_code ec;
      if (!fs::is_directory(g.gl_pathv[i], ec)) files.emplace_back(g.gl_pathv[i]);
    }
  globfree(&g);
  if (rc != 0 && rc != GLOB_NOMATCH)
    throw FlagError(fmt::format("{} '{}': cannot read the directories it names", flag, pattern));
  if (files.empty()) throw FlagError(fmt::format("{} '{}' matches no file", flag, pattern));
  return files;
}

void same_count(const std::vector<std::string>& a, const char* flag_a,
                const std::vector<std::string>& b, const char* flag_b) {
  if (a.size() != b.size())
    throw FlagError(fmt::format(
        "{} matches {} files but {} matches {}: views are paired in sorted name order, so the "
        "counts must agree",
        flag_a, a.size(), flag_b, b.size()));
}

// Fewer views than the calibration needs is known before any image is read: say so at once.
void check_view_count(const std::vector<std::string>& files, const char* flag, int min_views) {
  if (static_cast<int>(files.size()) >= min_views) return;
  throw FlagError(fmt::format(
      "{} matches {} file(s) but at least {} views are needed (--min-views {}); take more views",
      flag, files.size(), min_views, min_views));
}

cv::Mat read_gray(const std::string& path) {
  cv::Mat img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error("cannot read image " + path);
  return img;
}

cv::Mat1w read_depth(const std::string& path, const Intrinsics& depth) {
  const cv::Mat img = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (img.empty()) throw std::runtime_error("cannot read depth image " + path);
  if (img.type() != CV_16UC1)
    throw CalibrationError("depth image " + path + " is not a 16-bit single-channel PNG (mm)");
  if (img.cols != depth.width || img.rows != depth.height)
    throw CalibrationError(fmt::format("depth image {} is {}x{} but the depth intrinsics are {}x{}",
                                       path, img.cols, img.rows, depth.width, depth.height));
  return img;
}

// Every image of one camera must have one size: the one its intrinsics give, or else the first
// image's.
class SizeCheck {
 public:
  SizeCheck(const char* camera, std::optional<cv::Size> expected, std::string expected_from)
      : camera_(camera), size_(expected), from_(std::move(expected_from)), given_(expected) {}
  void check(const cv::Mat& img, const std::string& path) {
    if (!size_) {
      size_ = img.size();
      from_ = path;
      return;
    }
    if (img.size() == *size_) return;
    throw CalibrationError(fmt::format("{}{} image {} is {}x{} but {} is {}x{}",
                                       given_ ? "" : "mixed image sizes: ", camera_, path, img.cols,
                                       img.rows, from_, size_->width, size_->height));
  }
  cv::Size size() const { return *size_; }

 private:
  const char* camera_;
  std::optional<cv::Size> size_;
  std::string from_;
  bool given_;
};

// The corners of the views where every camera found the board; the others named on stderr.
struct PairedCorners {
  std::vector<ViewCorners> corners;  // per camera
  std::vector<std::size_t> used;     // view indices
  std::vector<std::string> not_found;
};

PairedCorners detect_views(const char* command, const std::vector<std::vector<std::string>>& files,
                           const std::vector<const char*>& cameras, std::vector<SizeCheck>& sizes,
                           const BoardSpec& board) {
  PairedCorners out;
  out.corners.resize(files.size());
  const std::size_t views = files[0].size();
  // Detection takes seconds per view at full resolution: a progress line every two seconds.
  auto last_progress = std::chrono::steady_clock::now();
  for (std::size_t v = 0; v < views; ++v) {
    if (const auto now = std::chrono::steady_clock::now();
        now - last_progress > std::chrono::seconds(2)) {
      std::fprintf(stderr, "telex calibrate %s: finding the board: view %zu of %zu\n", command,
                   v + 1, views);
      last_progress = now;
    }
    std::vector<std::vector<cv::Point2f>> found(files.size());
    bool all = true;
    for (std::size_t c = 0; c < files.size(); ++c) {
      const std::string& path = files[c][v];
      const cv::Mat img = read_gray(path);
      sizes[c].check(img, path);
      calib::CornerDetection d = calib::detect_corners(img, board);
      if (!d.found) {
        std::fprintf(stderr,
                     "telex calibrate %s: no %dx%d board found in %s (%s); view %zu skipped\n",
                     command, board.cols, board.rows, path.c_str(), cameras[c], v);
        out.not_found.push_back(path);
        all = false;
      }
      found[c] = std::move(d.corners_px);
    }
    if (!all) continue;
    for (std::size_t c = 0; c < files.size(); ++c) out.corners[c].push_back(std::move(found[c]));
    out.used.push_back(v);
  }
  return out;
}

void check_enough(const PairedCorners& p, std::size_t views, int min_views) {
  if (static_cast<int>(p.used.size()) >= min_views) return;
  throw CalibrationError(fmt::format(
      "the board was found in every camera in only {} of {} views; at least {} are needed (take "
      "more views, or check --board: it counts inner corners)",
      p.used.size(), views, min_views));
}

nlohmann::json intrinsics_summary(const calib::CameraCalibration& c) {
  return {{"fx_px", c.model.k.fx},
          {"fy_px", c.model.k.fy},
          {"cx_px", c.model.k.cx},
          {"cy_px", c.model.k.cy},
          {"width", c.model.k.width},
          {"height", c.model.k.height},
          {"distortion", c.model.distortion},
          {"rms_px", c.rms_px}};
}

// ---- stereo ------------------------------------------------------------------------------------

struct StereoOptions {
  std::string left, right, board, out;
  double square_mm = 0.0;
  int min_views = 5;
  bool k3 = false;
  bool json = false;
};

int run_stereo(const StereoOptions& o) {
  const BoardSpec board = board_from_flags(o.board, o.square_mm);
  const auto left = expand(o.left, "--left");
  const auto right = expand(o.right, "--right");
  same_count(left, "--left", right, "--right");
  check_out(o.out);
  check_view_count(left, "--left", o.min_views);
  std::vector<SizeCheck> sizes{{"left", std::nullopt, ""}, {"right", std::nullopt, ""}};
  const PairedCorners p = detect_views("stereo", {left, right}, {"left", "right"}, sizes, board);
  check_enough(p, left.size(), o.min_views);
  calib::CalibrateOptions opt;
  opt.min_views = o.min_views;
  opt.fix_k3 = !o.k3;
  const calib::StereoCalibration s = calib::calibrate_stereo(p.corners[0], p.corners[1], board,
                                                             sizes[0].size(), sizes[1].size(), opt);

  nlohmann::json patch;
  patch["eyes"]["left"] = camera_model_json(s.left.model);
  patch["eyes"]["right"] = camera_model_json(s.right.model);
  patch["extrinsics"]["right_eye_from_left_eye"] = transform_json(s.X_RightEyeLeftEye);
  update_rig_file(o.out, patch);

  if (s.rms_px > 1.0)
    std::fprintf(stderr,
                 "telex calibrate stereo: warning: RMS %.2f px is high (a board that is not flat, "
                 "a wrong --board, or left and right images not taken together?)\n",
                 s.rms_px);
  if (o.json) {
    nlohmann::json j{{"rms_px", s.rms_px},
                     {"baseline_m", s.baseline_m()},
                     {"left", intrinsics_summary(s.left)},
                     {"right", intrinsics_summary(s.right)},
                     {"translation_m", vec(s.X_RightEyeLeftEye.translation_m)},
                     {"rotation_deg", rotation_vector_deg(s.X_RightEyeLeftEye.rotation)},
                     {"views", left.size()},
                     {"views_used", p.used.size()},
                     {"skipped", p.not_found},
                     {"view_rms_px", s.view_rms_px},
                     {"rig", o.out}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("views: %zu of %zu pairs used\n", p.used.size(), left.size());
    for (const auto* c : {&s.left, &s.right})
      std::printf(
          "%-5s fx %.2f fy %.2f cx %.2f cy %.2f px, distortion [%.4f %.4f %.5f %.5f %.4f], RMS "
          "%.3f px\n",
          c == &s.left ? "left" : "right", c->model.k.fx, c->model.k.fy, c->model.k.cx,
          c->model.k.cy, c->model.distortion[0], c->model.distortion[1], c->model.distortion[2],
          c->model.distortion[3], c->model.distortion[4], c->rms_px);
    const glm::dvec3 t = s.X_RightEyeLeftEye.translation_m;
    const double angle = cv::norm(calib::rotation_vector_rad(s.X_RightEyeLeftEye.rotation)) * kDeg;
    std::printf(
        "baseline %.2f mm (right from left: t = [%.2f %.2f %.2f] mm, turned %.3f deg), "
        "stereo RMS %.3f px\n",
        s.baseline_m() * 1e3, t.x * 1e3, t.y * 1e3, t.z * 1e3, angle, s.rms_px);
    std::printf("wrote eyes.left, eyes.right, extrinsics.right_eye_from_left_eye into %s\n",
                o.out.c_str());
  }
  return 0;
}

// ---- depth-eye ---------------------------------------------------------------------------------

struct DepthEyeOptions {
  std::string ir, right, depth, board, rig, out;
  std::vector<double> depth_intrinsics;
  double square_mm = 0.0;
  int min_views = 5;
  bool json = false;
};

Intrinsics intrinsics_from_flag(const std::vector<double>& v) {
  if (v.size() != 6)
    throw FlagError("--depth-intrinsics: needs FX,FY,CX,CY,W,H (6 numbers), got " +
                    std::to_string(v.size()));
  Intrinsics k;
  k.fx = v[0];
  k.fy = v[1];
  k.cx = v[2];
  k.cy = v[3];
  if (v[4] != std::floor(v[4]) || v[5] != std::floor(v[5]) || v[4] < 1 || v[5] < 1 || v[4] > 8192 ||
      v[5] > 8192)
    throw FlagError("--depth-intrinsics: W and H must be whole numbers of pixels in [1, 8192]");
  k.width = static_cast<int>(v[4]);
  k.height = static_cast<int>(v[5]);
  if (!(k.fx > 0 && k.fy > 0)) throw FlagError("--depth-intrinsics: FX and FY must be positive");
  return k;
}

// The rig calibrated against: it must hold the right eye already.
Rig load_rig_with_right_eye(const std::string& path) {
  Rig rig;
  try {
    rig = load_rig(path);
  } catch (const RigError& e) {
    throw FlagError(e.what());
  }
  if (!rig.eye[1])
    throw FlagError("rig " + path +
                    " has no eyes.right: calibrate the eyes first (telex calibrate stereo --out " +
                    path + ")");
  return rig;
}

// --depth-intrinsics, else the rig's `depth` key.
Intrinsics depth_intrinsics_of(const DepthEyeOptions& o, const Rig& rig) {
  if (!o.depth_intrinsics.empty()) return intrinsics_from_flag(o.depth_intrinsics);
  if (rig.depth) return *rig.depth;
  throw FlagError(
      "no depth intrinsics: give --depth-intrinsics FX,FY,CX,CY,W,H or a `depth` "
      "key in " +
      o.rig);
}

// The depth sensor's pose in the right eye, and its intrinsics when they came from the flag.
void write_depth_eye_rig(const std::string& out, const calib::DepthEyeCalibration& c,
                         const Intrinsics& depth, bool depth_from_flag) {
  nlohmann::json patch;
  patch["extrinsics"]["right_eye_from_depth"] = transform_json(c.X_RightEyeDepth);
  // The board was found in the sensor's IR images: the extrinsics start from its own pixels.
  patch["extrinsics"]["depth_pixels"] = "ir";
  if (depth_from_flag)
    patch["depth"] = {{"width", depth.width}, {"height", depth.height}, {"fx_px", depth.fx},
                      {"fy_px", depth.fy},    {"cx_px", depth.cx},      {"cy_px", depth.cy}};
  update_rig_file(out, patch);
}

int run_depth_eye(const DepthEyeOptions& o) {
  const BoardSpec board = board_from_flags(o.board, o.square_mm);
  const auto ir = expand(o.ir, "--ir");
  const auto right = expand(o.right, "--right");
  same_count(ir, "--ir", right, "--right");
  std::vector<std::string> depth_files;
  if (!o.depth.empty()) {
    depth_files = expand(o.depth, "--depth");
    same_count(ir, "--ir", depth_files, "--depth");
  }
  const Rig rig = load_rig_with_right_eye(o.rig);
  const CameraModel right_eye = *rig.eye[1];
  if (!o.out.empty() && o.out != o.rig) check_out(o.out);
  const Intrinsics depth = depth_intrinsics_of(o, rig);
  const bool depth_from_flag = !o.depth_intrinsics.empty();
  std::vector<SizeCheck> sizes{
      {"IR", cv::Size(depth.width, depth.height),
       depth_from_flag ? "--depth-intrinsics" : "the rig's depth intrinsics"},
      {"right", cv::Size(right_eye.k.width, right_eye.k.height), "the rig's eyes.right"}};
  check_view_count(ir, "--ir", o.min_views);
  const PairedCorners p = detect_views("depth-eye", {ir, right}, {"IR", "right"}, sizes, board);
  check_enough(p, ir.size(), o.min_views);
  std::vector<cv::Mat1w> maps;
  for (std::size_t v : p.used)
    if (!depth_files.empty()) maps.push_back(read_depth(depth_files[v], depth));
  calib::CalibrateOptions opt;
  opt.min_views = o.min_views;
  const calib::DepthEyeCalibration c =
      calib::calibrate_depth_eye(p.corners[0], p.corners[1], board, depth, right_eye, maps, opt);

  const std::string out = o.out.empty() ? o.rig : o.out;
  write_depth_eye_rig(out, c, depth, depth_from_flag);
  DepthEyeResult result{c, ir.size(), p.used.size(), p.not_found, {}, out, depth_from_flag};
  if (!maps.empty()) result.planes = depth_plane_summary(c);
  if (o.json)
    print_depth_eye_json(result);
  else
    print_depth_eye_text(result);
  return 0;
}

// ---- render ------------------------------------------------------------------------------------

struct RenderOptions {
  std::string out, board = "9x6";
  double square_mm = 30.0;
  int views = 14;
  std::uint64_t seed = 1;
  double noise = calib::RenderStyle{}.noise_sigma;
  double blur_px = calib::RenderStyle{}.blur_sigma_px;
  double depth_noise_mm = 1.0;
};

int run_render(const RenderOptions& o) {
  const BoardSpec board = board_from_flags(o.board, o.square_mm);
  if (o.views < 1 || o.views > 200) throw FlagError("--views: must be within [1, 200]");
  if (!(o.noise >= 0.0 && o.blur_px >= 0.0 && o.depth_noise_mm >= 0.0))
    throw FlagError("--noise, --blur-px and --depth-noise-mm must not be negative");
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) throw FlagError("--out " + o.out + ": cannot create it: " + ec.message());
  calib::RenderStyle style;
  style.noise_sigma = o.noise;
  style.blur_sigma_px = o.blur_px;
  const calib::RenderRig rig = calib::example_render_rig();
  const auto views = calib::render_views(rig, board, o.views, o.seed, style, o.depth_noise_mm);
  nlohmann::json poses = nlohmann::json::array();
  for (std::size_t i = 0; i < views.size(); ++i) {
    const std::string n = fmt::format("{:02d}", i);
    const fs::path dir(o.out);
    for (const auto& [name, img] :
         {std::pair{"left_", &views[i].left}, std::pair{"right_", &views[i].right},
          std::pair{"ir_", &views[i].ir}})
      if (!cv::imwrite((dir / (name + n + ".png")).string(), *img))
        throw std::runtime_error("cannot write " + (dir / (name + n + ".png")).string());
    if (!cv::imwrite((dir / ("depth_" + n + ".png")).string(), views[i].depth_mm))
      throw std::runtime_error("cannot write " + (dir / ("depth_" + n + ".png")).string());
    poses.push_back(transform_json(views[i].X_RightEyeBoard));
  }
  // The answers, as rig keys, and the board poses in the right eye's frame.
  nlohmann::json truth;
  truth["depth"] = camera_model_json(rig.depth);
  truth["depth"].erase("distortion");
  truth["eyes"]["left"] = camera_model_json(rig.left);
  truth["eyes"]["right"] = camera_model_json(rig.right);
  truth["extrinsics"]["right_eye_from_left_eye"] = transform_json(rig.X_RightEyeLeftEye);
  truth["extrinsics"]["right_eye_from_depth"] = transform_json(rig.X_RightEyeDepth);
  nlohmann::json j{{"board", fmt::format("{}x{}", board.cols, board.rows)},
                   {"square_mm", o.square_mm},
                   {"seed", o.seed},
                   {"truth", truth},
                   {"X_RightEyeBoard", poses}};
  const fs::path truth_path = fs::path(o.out) / "truth.json";
  std::ofstream f(truth_path);
  f << j.dump(2) << "\n";
  if (!f) throw std::runtime_error("cannot write " + truth_path.string());
  std::printf("wrote %zu views (left_NN, right_NN, ir_NN, depth_NN .png) and truth.json into %s\n",
              views.size(), o.out.c_str());
  return 0;
}

void board_flags(const cli::CommandLine& app, std::string& board, double& square_mm,
                 bool required) {
  const auto b =
      app.add_option("--board", board,
                     "chessboard as CxR INNER corners (OpenCV's pattern size: a 10x7-square "
                     "board is 9x6); best one side even, one odd");
  const auto s = app.add_option("--square-mm", square_mm, "side of one square, millimetres")
                     ->check(cli::PositiveNumber());
  if (required) {
    b->required();
    s->required();
  }
}

const RegisterCommand kRegister{
    "calibrate",
    "Calibrate the eyes (stereo) and the depth sensor against the right eye (depth-eye) from "
    "chessboard images, the operator's arms (body) and gloves (glove), into a rig file; render "
    "boards with known answers; the headset's tracking space in the NatNet frame (hmd)",
    [](cli::CommandLine& app) -> std::function<int()> {
      app.require_subcommand(1);
      auto so = std::make_shared<StereoOptions>();
      cli::CommandLine stereo = app.add_subcommand(
          "stereo",
          "each eye's intrinsics and distortion, then the right eye's pose of the left; writes "
          "eyes.left, eyes.right, extrinsics.right_eye_from_left_eye into --out");
      stereo->add_option("--left", so->left, "glob of the left eye's images (quote it)")
          ->required();
      stereo
          ->add_option("--right", so->right,
                       "glob of the right eye's images, paired in sorted "
                       "name order with --left")
          ->required();
      board_flags(stereo, so->board, so->square_mm, true);
      stereo->add_option("--out", so->out, "rig file to write (created or updated)")->required();
      stereo
          ->add_option("--min-views", so->min_views,
                       "fewest pairs with the board found in both images")
          ->check(cli::Range(3, 1000));
      stereo->add_flag("--k3", so->k3, "also estimate k3 (wide-angle lenses)");
      stereo->add_flag("--json", so->json, "print one JSON object");

      auto de = std::make_shared<DepthEyeOptions>();
      cli::CommandLine depth_eye = app.add_subcommand(
          "depth-eye",
          "the depth sensor's pose in the right eye from the board seen in the sensor's IR image "
          "and the right eye at once; writes extrinsics.right_eye_from_depth into --out");
      depth_eye
          ->add_option("--ir", de->ir, "glob of the depth sensor's IR images (projector covered)")
          ->required();
      depth_eye
          ->add_option("--right", de->right,
                       "glob of the right eye's images, paired in sorted name order")
          ->required();
      depth_eye->add_option("--depth", de->depth,
                            "glob of the depth maps taken with the IR images (16-bit PNG, mm): "
                            "adds the board-plane check and the plane-only estimate");
      board_flags(depth_eye, de->board, de->square_mm, true);
      depth_eye
          ->add_option("--rig", de->rig,
                       "rig file with eyes.right (and depth, unless --depth-intrinsics)")
          ->required();
      depth_eye->add_option("--out", de->out, "rig file to write (default: --rig)");
      depth_eye
          ->add_option("--depth-intrinsics", de->depth_intrinsics,
                       "FX,FY,CX,CY,W,H of the depth (IR) camera, overriding the rig's depth; "
                       "also written into --out")
          ->delimiter(',');
      depth_eye->add_option("--min-views", de->min_views, "fewest views with the board in both")
          ->check(cli::Range(3, 1000));
      depth_eye->add_flag("--json", de->json, "print one JSON object");

      auto ro = std::make_shared<RenderOptions>();
      cli::CommandLine render = app.add_subcommand(
          "render",
          "render boards with known answers (both eyes, the IR image and the depth map of a "
          "paper-like head) and truth.json, for trying the other subcommands");
      render->add_option("--out", ro->out, "directory to write into")->required();
      board_flags(render, ro->board, ro->square_mm, false);
      render->add_option("--views", ro->views, "number of board poses")
          ->check(cli::Range(1, 10000));
      render->add_option("--seed", ro->seed, "seed of the poses and the noise");
      render->add_option("--noise", ro->noise, "image noise sigma, grey levels")
          ->check(cli::Range(0.0, 128.0));
      render->add_option("--blur-px", ro->blur_px, "Gaussian blur sigma, pixels");
      render->add_option("--depth-noise-mm", ro->depth_noise_mm, "depth map noise sigma, mm");

      const std::function<int()> run_operator = add_calibrate_operator(app);
      const std::function<int()> run_hmd = add_calibrate_hmd(app);

      return [=]() -> int {
        if (stereo->parsed()) return guarded("stereo", [&] { return run_stereo(*so); });
        if (depth_eye->parsed()) return guarded("depth-eye", [&] { return run_depth_eye(*de); });
        if (render->parsed()) return guarded("render", [&] { return run_render(*ro); });
        if (const int rc = run_operator(); rc >= 0) return rc;
        if (const int rc = run_hmd(); rc >= 0) return rc;
        return 2;
      };
    }};

}  // namespace
}  // namespace telex::tool
