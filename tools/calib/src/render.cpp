// SPDX-License-Identifier: MIT
// Calibration boards rendered by inverse mapping with known answers, and random fixed-seed poses.
#include "telex/calib/render.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>
#include <stdexcept>

#include "telex/calib/calibrate.h"

namespace telex::calib {
namespace {

constexpr double kPi = 3.14159265358979323846;

cv::Point2d distort(const std::array<double, 5>& d, double x, double y) {
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  return {x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
          y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y};
}

glm::dmat3 rot_x(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(1, 0, 0, 0, c, s, 0, -s, c);  // columns
}
glm::dmat3 rot_y(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(c, 0, -s, 0, 1, 0, s, 0, c);
}
glm::dmat3 rot_z(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(c, s, 0, -s, c, 0, 0, 0, 1);
}

}  // namespace

RenderStyle ir_style() {
  RenderStyle s;
  s.black = 12.0;
  s.white = 120.0;
  s.background = 45.0;
  s.noise_sigma = 3.0;
  s.blur_sigma_px = 1.0;
  return s;
}

cv::Point2d undistort_normalised(const std::array<double, 5>& d, cv::Point2d xd,
                                 std::optional<cv::Point2d> start) {
  double x = start ? start->x : xd.x, y = start ? start->y : xd.y;
  for (int it = 0; it < 200; ++it) {
    const cv::Point2d e = distort(d, x, y) - xd;
    if (std::abs(e.x) < 1e-12 && std::abs(e.y) < 1e-12) break;
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
    const double tx = 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
    const double ty = d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
    x = (xd.x - tx) / radial;
    y = (xd.y - ty) / radial;
  }
  return {x, y};
}

BoardRenderer::BoardRenderer(const CameraModel& camera, const BoardSpec& board,
                             const RenderStyle& style)
    : camera_(camera), board_(board), style_(style) {
  const Intrinsics& k = camera.k;
  if (k.width <= 0 || k.height <= 0 || k.width > 8192 || k.height > 8192)
    throw std::invalid_argument("BoardRenderer: bad image size");
  if (!(k.fx > 0.0 && k.fy > 0.0)) throw std::invalid_argument("BoardRenderer: bad focal length");
  if (style.supersample < 1 || style.supersample > 8)
    throw std::invalid_argument("BoardRenderer: supersample must be 1 to 8");
  const int n = style.supersample;
  // Undistorted exactly at the pixel corners, bilinear between them: the lens model's curvature
  // over one pixel leaves under 1e-4 px, and it is n*n times fewer solves.
  const int gw = k.width + 1, gh = k.height + 1;
  std::vector<cv::Point2d> grid(static_cast<std::size_t>(gw) * gh);
  for (int v = 0; v < gh; ++v) {
    std::optional<cv::Point2d> previous;  // each solve starts from its neighbour's answer
    for (int u = 0; u < gw; ++u) {
      previous = undistort_normalised(camera.distortion,
                                      {(u - 0.5 - k.cx) / k.fx, (v - 0.5 - k.cy) / k.fy}, previous);
      grid[static_cast<std::size_t>(v) * gw + u] = *previous;
    }
  }
  rays_.reserve(static_cast<std::size_t>(k.width) * k.height * n * n);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const cv::Point2d& p00 = grid[static_cast<std::size_t>(v) * gw + u];
      const cv::Point2d& p10 = grid[static_cast<std::size_t>(v) * gw + u + 1];
      const cv::Point2d& p01 = grid[static_cast<std::size_t>(v + 1) * gw + u];
      const cv::Point2d& p11 = grid[static_cast<std::size_t>(v + 1) * gw + u + 1];
      for (int sy = 0; sy < n; ++sy)
        for (int sx = 0; sx < n; ++sx) {
          // Sample (sx, sy) of the pixel whose centre is (u, v) (OpenCV's convention).
          const double fx = (sx + 0.5) / n, fy = (sy + 0.5) / n;
          const cv::Point2d p =
              (p00 * (1 - fx) + p10 * fx) * (1 - fy) + (p01 * (1 - fx) + p11 * fx) * fy;
          rays_.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y));
        }
    }
}

cv::Mat BoardRenderer::render(const RigidTransform& X_CameraBoard, std::uint64_t seed) const {
  const Intrinsics& k = camera_.k;
  const int n = style_.supersample;
  const glm::dmat3& R = X_CameraBoard.rotation;
  const glm::dvec3& t = X_CameraBoard.translation_m;
  const glm::dvec3 normal = R[2];
  const double nt = glm::dot(normal, t);
  const double s = board_.square_m, m = style_.margin_squares * s;
  const double x_lo = -s - m, x_hi = board_.cols * s + m;
  const double y_lo = -s - m, y_hi = board_.rows * s + m;
  cv::Mat1f img(k.height, k.width);
  std::size_t idx = 0;
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      double sum = 0.0;
      for (int q = 0; q < n * n; ++q, ++idx) {
        const glm::dvec3 ray(rays_[idx].x, rays_[idx].y, 1.0);
        const double denom = glm::dot(normal, ray);
        double value = style_.background;
        if (std::abs(denom) > 1e-12) {
          const double depth = nt / denom;
          if (depth > 0.0) {
            const glm::dvec3 d = ray * depth - t;
            const double bx = glm::dot(R[0], d), by = glm::dot(R[1], d);
            if (bx >= x_lo && bx <= x_hi && by >= y_lo && by <= y_hi) {
              value = style_.white;
              const int a = static_cast<int>(std::floor(bx / s)) + 1;
              const int b = static_cast<int>(std::floor(by / s)) + 1;
              if (a >= 0 && a <= board_.cols && b >= 0 && b <= board_.rows && (a + b) % 2 == 0)
                value = style_.black;
            }
          }
        }
        sum += value;
      }
      img(v, u) = static_cast<float>(sum / (n * n));
    }
  if (style_.blur_sigma_px > 0.0)
    cv::GaussianBlur(img, img, cv::Size(0, 0), style_.blur_sigma_px, style_.blur_sigma_px,
                     cv::BORDER_REPLICATE);
  if (style_.noise_sigma > 0.0) {
    cv::Mat1f noise(img.size());
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, style_.noise_sigma);
    img += noise;
  }
  cv::Mat out;
  img.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

cv::Mat1w BoardRenderer::render_depth(const RigidTransform& X_CameraBoard, double wall_m,
                                      double noise_mm, std::uint64_t seed) const {
  const Intrinsics& k = camera_.k;
  const glm::dmat3& R = X_CameraBoard.rotation;
  const glm::dvec3& t = X_CameraBoard.translation_m;
  const glm::dvec3 normal = R[2];
  const double nt = glm::dot(normal, t);
  const double s = board_.square_m, m = style_.margin_squares * s;
  cv::Mat1w out(k.height, k.width, static_cast<std::uint16_t>(kNoDepth));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, std::max(noise_mm, 0.0));
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const cv::Point2d r =
          undistort_normalised(camera_.distortion, {(u - k.cx) / k.fx, (v - k.cy) / k.fy});
      const glm::dvec3 ray(r.x, r.y, 1.0);
      double z_m = wall_m;
      const double denom = glm::dot(normal, ray);
      if (std::abs(denom) > 1e-12 && nt / denom > 0.0) {
        const glm::dvec3 d = ray * (nt / denom) - t;
        const double bx = glm::dot(R[0], d), by = glm::dot(R[1], d);
        if (bx >= -s - m && bx <= board_.cols * s + m && by >= -s - m && by <= board_.rows * s + m)
          z_m = nt / denom;
      }
      if (!(z_m > 0.0)) continue;
      const double mm = z_m * 1e3 + (noise_mm > 0.0 ? noise(rng) : 0.0);
      out(v, u) = static_cast<std::uint16_t>(std::clamp(std::lround(mm), 1L, 65535L));
    }
  return out;
}

cv::Point2d BoardRenderer::project(const glm::dvec3& p) const {
  const cv::Point2d d = distort(camera_.distortion, p.x / p.z, p.y / p.z);
  return {camera_.k.fx * d.x + camera_.k.cx, camera_.k.fy * d.y + camera_.k.cy};
}

std::vector<RigidTransform> random_board_poses(const BoardSpec& board,
                                               const std::vector<RenderCamera>& cameras, int count,
                                               std::uint64_t seed, double margin_px) {
  std::mt19937_64 rng(seed);
  auto uniform = [&](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  const double s = board.square_m, m = RenderStyle{}.margin_squares * s;
  // The outline of the printed board (squares and border), sampled along its edges so that a
  // bulging distorted edge is checked too, and the inner corners.
  std::vector<glm::dvec3> check;
  const double x0 = -s - m, x1 = board.cols * s + m, y0 = -s - m, y1 = board.rows * s + m;
  for (int i = 0; i <= 8; ++i) {
    const double f = i / 8.0;
    check.push_back({x0 + f * (x1 - x0), y0, 0.0});
    check.push_back({x0 + f * (x1 - x0), y1, 0.0});
    check.push_back({x0, y0 + f * (y1 - y0), 0.0});
    check.push_back({x1, y0 + f * (y1 - y0), 0.0});
  }
  const glm::dvec3 centre_Board((board.cols - 1) * s * 0.5, (board.rows - 1) * s * 0.5, 0.0);
  std::vector<RigidTransform> poses;
  for (int attempt = 0; attempt < 200000 && static_cast<int>(poses.size()) < count; ++attempt) {
    const double z = uniform(0.35, 0.75);
    const glm::dvec3 p_RigCentre(uniform(-0.25, 0.25) * z, uniform(-0.2, 0.2) * z, z);
    const double deg = kPi / 180.0;
    const glm::dmat3 R = rot_z(uniform(-25, 25) * deg) * rot_y(uniform(-40, 40) * deg) *
                         rot_x(uniform(-40, 40) * deg);
    const RigidTransform X_RigBoard{R, p_RigCentre - R * centre_Board};
    bool ok = true;
    for (const RenderCamera& cam : cameras) {
      const RigidTransform X_CameraBoard = compose(cam.X_CameraRig, X_RigBoard);
      // The printed face towards the camera, seen at most 50 degrees off its normal (steeper views
      // slow the detector and add little).
      const glm::dvec3 p_CameraCentre = apply(X_CameraBoard, centre_Board);
      const double facing =
          glm::dot(X_CameraBoard.rotation[2], p_CameraCentre) / glm::length(p_CameraCentre);
      if (facing < std::cos(50.0 * deg)) ok = false;
      const cv::Rect2d inside(margin_px, margin_px, cam.model.k.width - 1 - 2 * margin_px,
                              cam.model.k.height - 1 - 2 * margin_px);
      for (std::size_t i = 0; ok && i < check.size(); ++i) {
        const glm::dvec3 p = apply(X_CameraBoard, check[i]);
        if (p.z < 0.1) {
          ok = false;
          break;
        }
        const double x = p.x / p.z, y = p.y / p.z;
        // Far outside the image the distortion polynomial folds back: reject before projecting.
        if (std::abs(x) > 1.5 || std::abs(y) > 1.5) {
          ok = false;
          break;
        }
        const cv::Point2d d = distort(cam.model.distortion, x, y);
        const cv::Point2d px(cam.model.k.fx * d.x + cam.model.k.cx,
                             cam.model.k.fy * d.y + cam.model.k.cy);
        ok = inside.contains(px);
      }
      if (!ok) break;
    }
    if (ok) poses.push_back(X_RigBoard);
  }
  if (static_cast<int>(poses.size()) < count)
    throw std::runtime_error("random_board_poses: placed only " + std::to_string(poses.size()) +
                             " of " + std::to_string(count) +
                             " boards in view of every camera (cameras too far apart or board too "
                             "large)");
  return poses;
}

RenderRig example_render_rig() {
  const double deg = kPi / 180.0;
  RenderRig r;
  r.left.k = {532.4, 530.1, 324.2, 236.7, 640, 480};
  r.left.distortion = {-0.118, 0.052, 0.0009, -0.0006, 0.0};
  r.right.k = {527.8, 526.9, 316.1, 243.5, 640, 480};
  r.right.distortion = {-0.104, 0.041, -0.0007, 0.0005, 0.0};
  r.depth.k = {570.3, 570.3, 319.5, 239.5, 640, 480};
  r.X_RightEyeLeftEye = {rot_z(0.25 * deg) * rot_y(-0.9 * deg) * rot_x(0.4 * deg),
                         {-0.0652, 0.0006, -0.0011}};
  r.X_RightEyeDepth = {rot_z(0.3 * deg) * rot_y(-0.6 * deg) * rot_x(0.8 * deg),
                       {-0.0325, 0.045, 0.004}};
  return r;
}

std::vector<RenderedView> render_views(const RenderRig& rig, const BoardSpec& board, int count,
                                       std::uint64_t seed, const RenderStyle& eye_style,
                                       double depth_noise_mm) {
  const std::vector<RenderCamera> cameras{{rig.left, inverse(rig.X_RightEyeLeftEye)},
                                          {rig.right, RigidTransform{}},
                                          {rig.depth, inverse(rig.X_RightEyeDepth)}};
  const std::vector<RigidTransform> poses = random_board_poses(board, cameras, count, seed);
  const BoardRenderer left(rig.left, board, eye_style), right(rig.right, board, eye_style),
      ir(rig.depth, board, ir_style());
  std::vector<RenderedView> views;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    RenderedView v;
    v.X_RightEyeBoard = poses[i];
    const std::uint64_t s = seed * 1000 + i * 10;
    v.left = left.render(compose(cameras[0].X_CameraRig, poses[i]), s + 1);
    v.right = right.render(poses[i], s + 2);
    const RigidTransform X_DepthBoard = compose(cameras[2].X_CameraRig, poses[i]);
    v.ir = ir.render(X_DepthBoard, s + 3);
    v.depth_mm = ir.render_depth(X_DepthBoard, 1.6, depth_noise_mm, s + 4);
    views.push_back(std::move(v));
  }
  return views;
}

}  // namespace telex::calib
