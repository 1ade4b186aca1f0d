// SPDX-License-Identifier: MIT
// The warp's ground-truth check: a room ray-cast exactly (colour and depth per pixel), a head that
// yaws about its neck with the eyes in front of the axis (so a turn also moves them), discs of
// distinct hues found again in what is shown.
#include "telex/local/view/warp_check.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

namespace telex::local {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDiscRadius_m = 0.05;
constexpr int kDiscs = 12, kHueStep = 15;  // OpenCV hues (0..180): 12 distinct
constexpr int kMargin_px = 30;

// The head base's frame (the right eye's camera frame at zero yaw): x right, y down, z forward.
// The neck's yaw axis is the base's y axis through its origin; the eyes sit 9 cm in front of it.
const std::array<glm::dvec3, 2> kEyeOnHead{glm::dvec3{-0.0325, 0.0, 0.09},
                                           glm::dvec3{0.0325, 0.0, 0.09}};

struct Plane {
  int axis;     // the normal's axis
  double at;    // the plane: p[axis] == at
  double tone;  // grey level
};
struct Box {
  glm::dvec3 lo, hi;
  double tone;
};
struct Disc {
  glm::dvec3 p;  // centre, on a surface whose normal is `axis`
  int axis;
};

struct Room {
  std::vector<Plane> planes{{1, 1.3, 120},  {1, -1.4, 170}, {2, 4.0, 150},
                            {0, -3.0, 135}, {0, 3.0, 140},  {2, -3.0, 130}};
  std::vector<Box> boxes{{{-1.0, 0.3, 1.8}, {-0.4, 1.3, 2.4}, 185},
                         {{0.5, 0.5, 2.6}, {1.3, 1.3, 3.2}, 95},
                         {{-0.15, -0.45, 1.3}, {0.25, -0.05, 1.45}, 200}};
  std::vector<Disc> discs{{{-2.5, -0.8, 4.0}, 2}, {{-1.4, -1.1, 4.0}, 2}, {{-0.3, -0.9, 4.0}, 2},
                          {{0.8, -0.7, 4.0}, 2},  {{2.0, -1.0, 4.0}, 2},  {{2.4, 0.3, 4.0}, 2},
                          {{-0.7, 0.6, 1.8}, 2},  {{0.9, 0.8, 2.6}, 2},   {{0.05, -0.25, 1.3}, 2},
                          {{0.1, 1.3, 3.0}, 1},   {{-3.0, -0.5, 3.5}, 0}, {{3.0, -0.3, 3.6}, 0}};
  std::array<cv::Vec3b, kDiscs> disc_bgr{};

  Room() {
    for (int i = 0; i < kDiscs; ++i) {
      cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<unsigned char>(i * kHueStep), 255, 230)), bgr;
      cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
      disc_bgr[static_cast<std::size_t>(i)] = bgr(0, 0);
    }
  }
};

struct Hit {
  double t = std::numeric_limits<double>::infinity();
  int axis = 0;
  double tone = 0.0;
};

Hit cast(const Room& room, const glm::dvec3& o, const glm::dvec3& d) {
  Hit h;
  for (const Plane& p : room.planes) {
    if (std::abs(d[p.axis]) < 1e-12) continue;
    const double t = (p.at - o[p.axis]) / d[p.axis];
    if (t > 1e-6 && t < h.t) h = {t, p.axis, p.tone};
  }
  for (const Box& b : room.boxes) {
    double enter = -std::numeric_limits<double>::infinity(), leave = -enter;
    int axis = 0;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) {
        if (o[a] < b.lo[a] || o[a] > b.hi[a]) enter = leave + 1.0;
        continue;
      }
      double t0 = (b.lo[a] - o[a]) / d[a], t1 = (b.hi[a] - o[a]) / d[a];
      if (t0 > t1) std::swap(t0, t1);
      if (t0 > enter) {
        enter = t0;
        axis = a;
      }
      leave = std::min(leave, t1);
    }
    if (enter <= leave && enter > 1e-6 && enter < h.t) h = {enter, axis, b.tone};
  }
  return h;
}

// A 30 cm grey checker, the discs in their colours.
cv::Vec3b shade(const Room& room, const glm::dvec3& p, const Hit& h) {
  for (std::size_t i = 0; i < room.discs.size(); ++i) {
    const Disc& disc = room.discs[i];
    if (disc.axis == h.axis && std::abs(p[h.axis] - disc.p[h.axis]) < 1e-3 &&
        glm::length(p - disc.p) < kDiscRadius_m)
      return room.disc_bgr[i];
  }
  const int u = static_cast<int>(std::floor(p[(h.axis + 1) % 3] / 0.3));
  const int v = static_cast<int>(std::floor(p[(h.axis + 2) % 3] / 0.3));
  const double g = ((u + v) & 1) ? h.tone : h.tone * 0.75;
  const auto c = static_cast<unsigned char>(g);
  return {c, c, c};
}

struct EyePose {
  glm::dmat3 R_BaseEye{1.0};
  glm::dvec3 p_BaseEye{0.0};
};

EyePose eye_pose(double yaw_rad, std::size_t eye) {
  const glm::dmat3 R(glm::rotate(glm::dmat4(1.0), yaw_rad, glm::dvec3(0.0, 1.0, 0.0)));
  return {R, R * kEyeOnHead[eye]};
}

struct Capture {
  cv::Mat3b bgr;
  cv::Mat1w depth_mm;
};

Capture render(const Room& room, const EyePose& eye, const Intrinsics& k) {
  Capture c{cv::Mat3b(k.height, k.width), cv::Mat1w(k.height, k.width)};
  for (int y = 0; y < k.height; ++y)
    for (int x = 0; x < k.width; ++x) {
      const glm::dvec3 d_Eye = glm::normalize(glm::dvec3((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1));
      const glm::dvec3 d_Base = eye.R_BaseEye * d_Eye;
      const Hit h = cast(room, eye.p_BaseEye, d_Base);
      c.bgr(y, x) = shade(room, eye.p_BaseEye + h.t * d_Base, h);
      c.depth_mm(y, x) = static_cast<std::uint16_t>(std::clamp(h.t * d_Eye.z * 1e3, 0.0, 65535.0));
    }
  return c;
}

// Where a disc's centre is seen from `eye` (pixels), when the disc is whole in view there: inside
// the margin, in front, and its centre and rim not hidden by anything nearer.
std::optional<glm::dvec2> visible_at(const Room& room, const Disc& disc, const EyePose& eye,
                                     const Intrinsics& k) {
  const glm::dvec3 p = glm::transpose(eye.R_BaseEye) * (disc.p - eye.p_BaseEye);
  if (p.z <= 0.1) return std::nullopt;
  const glm::dvec2 px{k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy};
  if (px.x < kMargin_px || px.y < kMargin_px || px.x > k.width - 1 - kMargin_px ||
      px.y > k.height - 1 - kMargin_px)
    return std::nullopt;
  glm::dvec3 u(0.0), v(0.0);
  u[(disc.axis + 1) % 3] = kDiscRadius_m;
  v[(disc.axis + 2) % 3] = kDiscRadius_m;
  for (const glm::dvec3& q : {disc.p, disc.p + u, disc.p - u, disc.p + v, disc.p - v}) {
    const glm::dvec3 to = q - eye.p_BaseEye;
    if (cast(room, eye.p_BaseEye, glm::normalize(to)).t < glm::length(to) - 2e-3)
      return std::nullopt;
  }
  return px;
}

// Each disc's largest blob of its hue in `bgr` (centroid, pixels), or none.
std::array<std::optional<glm::dvec2>, kDiscs> find_discs(const cv::Mat3b& bgr) {
  cv::Mat3b hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
  std::array<cv::Mat1b, kDiscs> masks;
  for (auto& m : masks) m = cv::Mat1b::zeros(bgr.size());
  for (int y = 0; y < hsv.rows; ++y)
    for (int x = 0; x < hsv.cols; ++x) {
      const cv::Vec3b c = hsv(y, x);
      if (c[1] < 120 || c[2] < 60) continue;
      const int i = ((c[0] + kHueStep / 2) / kHueStep) % kDiscs;
      const int gap = std::abs(c[0] - i * kHueStep);
      if (std::min(gap, 180 - gap) <= 4) masks[static_cast<std::size_t>(i)](y, x) = 255;
    }
  std::array<std::optional<glm::dvec2>, kDiscs> out;
  for (std::size_t i = 0; i < masks.size(); ++i) {
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(masks[i], labels, stats, centroids, 8);
    int best = 0;
    for (int l = 1; l < n; ++l)
      if (best == 0 || stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA))
        best = l;
    if (best > 0 && stats.at<int>(best, cv::CC_STAT_AREA) >= 20)
      out[i] = glm::dvec2(centroids.at<double>(best, 0), centroids.at<double>(best, 1));
  }
  return out;
}

double angle_deg(const Intrinsics& k, const glm::dvec2& a, const glm::dvec2& b) {
  const glm::dvec3 ra = glm::normalize(glm::dvec3((a.x - k.cx) / k.fx, (a.y - k.cy) / k.fy, 1));
  const glm::dvec3 rb = glm::normalize(glm::dvec3((b.x - k.cx) / k.fx, (b.y - k.cy) / k.fy, 1));
  return std::acos(std::clamp(glm::dot(ra, rb), -1.0, 1.0)) * 180.0 / kPi;
}

// X_AB: points in B's eye frame into A's.
RigidTransform relative(const EyePose& A, const EyePose& B) {
  const glm::dmat3 R_ABase = glm::transpose(A.R_BaseEye);
  return {R_ABase * B.R_BaseEye, R_ABase * (B.p_BaseEye - A.p_BaseEye)};
}

// The sums behind WarpCheckResult's means.
struct ErrorSums {
  double with = 0.0, without = 0.0, depth_pose = 0.0;
};

// Each disc in view at the video's and the display's poses, found in what is shown (`with`, and
// `depth_pose` when given) and in the video as captured (`without`), against the world's place.
void measure(const Room& room, const Intrinsics& k, const EyePose& video, const EyePose& display,
             const cv::Mat3b& with_bgr, const cv::Mat3b& without_bgr,
             const cv::Mat3b* depth_pose_bgr, ErrorSums& sums, WarpCheckResult& r) {
  const auto with = find_discs(with_bgr), without = find_discs(without_bgr);
  std::array<std::optional<glm::dvec2>, kDiscs> depth_pose;
  if (depth_pose_bgr) depth_pose = find_discs(*depth_pose_bgr);
  for (std::size_t i = 0; i < room.discs.size(); ++i) {
    const auto truth = visible_at(room, room.discs[i], display, k);
    if (!truth || !visible_at(room, room.discs[i], video, k)) continue;
    if (!with[i] || !without[i] || (depth_pose_bgr && !depth_pose[i])) {
      ++r.points_missed;
      continue;
    }
    const double e_with = angle_deg(k, *with[i], *truth);
    sums.with += e_with;
    sums.without += angle_deg(k, *without[i], *truth);
    sums.depth_pose += depth_pose_bgr ? angle_deg(k, *depth_pose[i], *truth) : e_with;
    r.max_error_deg_with = std::max(r.max_error_deg_with, e_with);
    ++r.points_measured;
  }
}

}  // namespace

WarpCheckResult run_warp_check(const WarpCheckOptions& o) {
  if (o.width < 64 || o.height < 64 || o.width > 8192 || o.height > 8192)
    throw std::invalid_argument("warp check: the eye size must be 64..8192 each way");
  if (o.frames < 2 || o.frames > 1000 || !(o.frame_rate_hz > 0.0) || !(o.lag_ms >= 0.0) ||
      !std::isfinite(o.yaw_deg_s) || std::abs(o.yaw_deg_s) > 720.0 || !(o.pair_gap_ms >= 0.0) ||
      o.pair_gap_ms > 1000.0)
    throw std::invalid_argument(
        "warp check: frames 2..1000, a positive frame rate, a lag >= 0, |yaw rate| <= 720 "
        "deg/s and a pair gap in 0..1000 ms");
  const Room room;
  Intrinsics k;
  k.width = o.width;
  k.height = o.height;
  k.fx = k.fy = o.width / 2.0;  // 90 degrees across
  k.cx = (o.width - 1) / 2.0;
  k.cy = (o.height - 1) / 2.0;
  const bool gap = o.pair_gap_ms > 0.0;
  // The warps keep their previous output for the hole fill: one per eye and per way of warping.
  std::array<std::unique_ptr<DepthWarp>, 2> warps, depth_pose_warps;
  for (auto& w : warps) w = std::make_unique<DepthWarp>(o.width, o.height, o.warp);
  if (gap)
    for (auto& w : depth_pose_warps) w = std::make_unique<DepthWarp>(o.width, o.height, o.warp);

  const double rate = o.yaw_deg_s * kPi / 180.0;
  // The sweep is centred on straight ahead.
  const double yaw0 = -rate * (o.frames - 1) / o.frame_rate_hz / 2.0;
  std::array<glm::dmat3, 2> R_BasePreviousDisplay{glm::dmat3(1.0), glm::dmat3(1.0)};
  ErrorSums sums;
  WarpCheckResult r;
  std::vector<double> ms;
  for (int f = 0; f < o.frames; ++f) {
    const double yaw_display = yaw0 + rate * f / o.frame_rate_hz;
    const double yaw_video = yaw_display - rate * o.lag_ms * 1e-3;
    const double yaw_depth = yaw_video - rate * o.pair_gap_ms * 1e-3;
    for (std::size_t eye = 0; eye < 2; ++eye) {
      const EyePose V = eye_pose(yaw_video, eye), S = eye_pose(yaw_display, eye),
                    D = eye_pose(yaw_depth, eye);
      const Capture video = render(room, V, k);
      const cv::Mat1w depth_mm = gap ? render(room, D, k).depth_mm : video.depth_mm;
      const glm::dmat3 R_DisplayPrevious = glm::transpose(S.R_BaseEye) * R_BasePreviousDisplay[eye];
      const auto t0 = std::chrono::steady_clock::now();
      const WarpedEye shown = warps[eye]->warp(video.bgr, depth_mm, k, relative(S, D),
                                               relative(V, D), R_DisplayPrevious);
      const auto t1 = std::chrono::steady_clock::now();
      if (f > 0) ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      // A pair without its own pose: the video taken as captured at the depth's pose.
      std::optional<WarpedEye> depth_pose;
      if (gap)
        depth_pose =
            depth_pose_warps[eye]->warp(video.bgr, depth_mm, k, relative(S, D), R_DisplayPrevious);
      R_BasePreviousDisplay[eye] = S.R_BaseEye;
      measure(room, k, V, S, shown.bgr, video.bgr, depth_pose ? &depth_pose->bgr : nullptr, sums,
              r);
    }
  }
  if (r.points_measured > 0) {
    r.error_deg_with = sums.with / r.points_measured;
    r.error_deg_without = sums.without / r.points_measured;
    r.error_deg_depth_pose = sums.depth_pose / r.points_measured;
  }
  std::nth_element(ms.begin(), ms.begin() + static_cast<std::ptrdiff_t>(ms.size() / 2), ms.end());
  r.warp_ms_per_eye = ms[ms.size() / 2];
  return r;
}

}  // namespace telex::local
