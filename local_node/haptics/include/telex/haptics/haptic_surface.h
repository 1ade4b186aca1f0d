// SPDX-License-Identifier: MIT
// Immutable depth surface snapshot read by the 1 kHz haptic loop, and its point queries.
#pragma once

#include <array>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <opencv2/core.hpp>
#include <optional>

#include "telex/common/depth_image.h"

namespace telex {

// One received depth frame as the haptic loop sees it. Published once, then only read, so the
// 1 kHz thread can query it without locks. Depth is z along the optical axis (camera frame:
// x right, y down, z forward, metres); 0 marks a hole. Normals are unit vectors facing the camera
// (n . p_CameraQ < 0); a zero vector marks "no normal here" and the queries fall back to a plane
// fit.
struct Surface {
  cv::Mat1f depth_m;
  cv::Mat3f normals;
  Intrinsics intrinsics;
  std::int64_t capture_ns = 0;
  std::uint64_t frame_id = 0;
  // The robot head's joints at capture (yaw, pitch, roll; FrameManifest::head): the station places
  // the fingertips in this surface's camera with them. head_valid false: no head reading.
  bool head_valid = false;
  std::array<double, 3> head_joint_rad{0.0, 0.0, 0.0};
  // This surface's camera in the frame the haptic model works in (p_model = R_ModelCamera
  // p_camera): identity, or the head base's frame when the head turned between captures, so the
  // model's god-points and its crossfade between two surfaces stay put in the room.
  glm::dmat3 R_ModelCamera{1.0};
};

// Depths beyond this are treated as holes: no depth sensor this project targets reports them and
// they only arise from corrupt frames.
inline constexpr float kMaxSurfaceDepthM = 100.0f;

// How far apart two neighbouring depths may be and still count as one continuous surface:
// abs_m + rel * z. Beyond it they are a step edge and the nearer surface wins.
struct StepTolerance {
  double abs_m = 0.02;
  double rel = 0.03;
  double at(double z_m) const { return abs_m + rel * z_m; }
};

// Default neighbour distance of normals_from_depth in make_surface (see there).
inline constexpr int kSurfaceNormalRadiusPx = 2;

// Builds a snapshot. Non-finite, negative and absurdly far depths become holes. When `normals` is
// empty they are computed from the depth with normals_from_depth. Throws std::invalid_argument
// naming the problem when sizes disagree with the intrinsics or with each other.
Surface make_surface(cv::Mat1f depth_m, const Intrinsics& intrinsics, std::int64_t capture_ns,
                     std::uint64_t frame_id, cv::Mat3f normals = {},
                     const StepTolerance& steps = {},
                     int normal_radius_px = kSurfaceNormalRadiusPx);

// Normals from the depth itself: cross product of the back-projected derivatives along x and y,
// taken between neighbours `radius_px` pixels away (a wider baseline is less sensitive to
// millimetre quantisation). Each derivative uses the central difference, or the one-sided
// difference on the side that stays on the same surface at a step edge; pixels with no usable
// neighbour on an axis get a zero normal. Pure; the optimised normal kernel of the filtering
// pipeline replaces this in the daemon. Throws std::invalid_argument when radius_px < 1.
cv::Mat3f normals_from_depth(const cv::Mat1f& depth_m, const Intrinsics& intrinsics,
                             const StepTolerance& steps = {}, int radius_px = 1);

// Back-projects pixel (u, v) at depth z into the camera frame.
inline glm::dvec3 back_project(const Intrinsics& k, double u, double v, double z_m) {
  return {(u - k.cx) / k.fx * z_m, (v - k.cy) / k.fy * z_m, z_m};
}

// Local surface plane under a camera-frame point: Q on the surface (on the point's camera ray),
// and the unit normal facing the camera (the free side).
struct LocalPlane {
  glm::dvec3 p_CameraQ{0.0};
  glm::dvec3 normal_Camera{0.0, 0.0, -1.0};
  // True when the normal came from the neighbourhood plane fit or the view ray, not the normal map.
  bool normal_fallback = false;
};

enum class SurfaceQuery : std::uint8_t {
  Ok,
  BehindCamera,  // point at z <= 0 cannot be projected
  OutsideImage,  // projects outside the image
  Hole,          // the pixel under the point has no depth
};

// Depth (m) at image coordinates (u, v): bilinear over the four surrounding pixels, refusing
// holes: the nearest pixel must hold depth, and only neighbours on the nearest surface (within the
// step tolerance of the smallest depth) take part, so across a discontinuity the nearer surface
// wins and never blends with the background.
std::optional<double> depth_at(const Surface& s, double u, double v,
                               const StepTolerance& steps = {});

// Local plane under `p_CameraQ` (projected along its camera ray). The normal is the bilinear blend
// of valid normals on the nearer surface; if none is valid, a least-squares plane fit over the
// 5x5 neighbourhood on that surface; if that is degenerate (a lone pixel), the reversed view ray.
SurfaceQuery local_plane(const Surface& s, const glm::dvec3& p_CameraQ, LocalPlane& out,
                         const StepTolerance& steps = {});

// Least-squares plane z = a + b x + c y through the valid pixels of the (2r+1)^2 window centred on
// pixel (u, v) whose depth lies within the step tolerance of `z_ref`; returns the unit normal
// facing the camera, or nothing with fewer than three points or a degenerate layout.
std::optional<glm::dvec3> fit_plane_normal(const Surface& s, int u, int v, double z_ref, int r,
                                           const StepTolerance& steps = {});

}  // namespace telex
