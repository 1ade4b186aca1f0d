// SPDX-License-Identifier: MIT
// The surfaces as the force model sees them in one tick: each queried in its own camera, answered
// in the Model frame, the previous one cross-faded into the current.
#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <optional>
#include <tuple>

#include "telex/haptics/detail/force_steps.h"

namespace telex::detail {

namespace {

// Samples per pixel of projected motion when marching a segment: two keeps a one-pixel-wide
// object from slipping between samples. The cap bounds the worst case (a teleport across the
// whole image) to a few tens of microseconds.
constexpr double kSamplesPerPixel = 2.0;
constexpr int kMaxMarchSamples = 2048;
constexpr int kBisections = 12;

// p_ModelQ's depth behind surface s along s's camera ray, and s's depth there.
std::optional<std::pair<double, double>> behind_of(const Surface& s, const glm::dvec3& p_ModelQ,
                                                   const StepTolerance& steps) {
  const glm::dvec3 p = glm::transpose(s.R_ModelCamera) * p_ModelQ;
  if (!(p.z > 1e-6)) return std::nullopt;
  const Intrinsics& k = s.intrinsics;
  const auto z = depth_at(s, k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy, steps);
  if (!z) return std::nullopt;
  return std::pair{p.z - *z, *z};
}

}  // namespace

SurfaceQuery SurfaceView::plane_of(const Surface& s, const glm::dvec3& p_ModelQ, ModelPlane& out,
                                   const StepTolerance& steps) {
  LocalPlane c;
  const SurfaceQuery q = local_plane(s, glm::transpose(s.R_ModelCamera) * p_ModelQ, c, steps);
  if (q != SurfaceQuery::Ok) return q;
  out.p_ModelQ = s.R_ModelCamera * c.p_CameraQ;
  out.normal_Model = s.R_ModelCamera * c.normal_Camera;
  return q;
}

SurfaceQuery SurfaceView::plane(const glm::dvec3& p_ModelQ, ModelPlane& out) const {
  const SurfaceQuery qc = plane_of(*cur, p_ModelQ, out, steps);
  if (prev == nullptr) return qc;
  ModelPlane old;
  const SurfaceQuery qp = plane_of(*prev, p_ModelQ, old, steps);
  if (qp != SurfaceQuery::Ok) return qc;
  if (qc != SurfaceQuery::Ok) {
    out = old;
    return qp;
  }
  // Both points lie on the same camera ray (when both surfaces share a camera), so the blend
  // stays on it.
  out.p_ModelQ = old.p_ModelQ + alpha * (out.p_ModelQ - old.p_ModelQ);
  const glm::dvec3 n = old.normal_Model + alpha * (out.normal_Model - old.normal_Model);
  const double len = glm::length(n);
  if (len > 1e-9) out.normal_Model = n / len;
  return SurfaceQuery::Ok;
}

bool SurfaceView::behind(const glm::dvec3& p_ModelQ, double& d, double& z) const {
  const auto c = behind_of(*cur, p_ModelQ, steps);
  if (prev == nullptr) {
    if (!c) return false;
    d = c->first;
    z = c->second;
    return true;
  }
  // Each frame projects with its own intrinsics (the stream may change resolution) and its own
  // camera (the head may have turned).
  const auto o = behind_of(*prev, p_ModelQ, steps);
  if (c && o) {
    d = o->first + alpha * (c->first - o->first);
    z = o->second + alpha * (c->second - o->second);
  } else if (c) {
    std::tie(d, z) = *c;
  } else if (o) {
    std::tie(d, z) = *o;
  } else {
    return false;
  }
  return true;
}

bool SurfaceView::inside(const glm::dvec3& p_ModelQ) const {
  double d, z;
  return behind(p_ModelQ, d, z) && d > 0.0;
}

SurfaceView::Hit SurfaceView::march(const glm::dvec3& p_ModelA, const glm::dvec3& p_ModelB,
                                    glm::dvec3& p_ModelStop) const {
  const Intrinsics& k = cur->intrinsics;
  int samples = kMaxMarchSamples;
  // How many pixels the segment crosses in the current surface's camera.
  const glm::dvec3 a = glm::transpose(cur->R_ModelCamera) * p_ModelA;
  const glm::dvec3 b = glm::transpose(cur->R_ModelCamera) * p_ModelB;
  if (a.z > 1e-6 && b.z > 1e-6) {
    const double du = k.fx * (b.x / b.z - a.x / a.z);
    const double dv = k.fy * (b.y / b.z - a.y / a.z);
    const double px = std::max(std::abs(du), std::abs(dv));
    samples =
        static_cast<int>(std::min<double>(kMaxMarchSamples, std::ceil(px * kSamplesPerPixel)));
    samples = std::max(samples, 1);
  }
  glm::dvec3 prev_s = p_ModelA;
  for (int i = 1; i <= samples; ++i) {
    const glm::dvec3 s = p_ModelA + (p_ModelB - p_ModelA) * (static_cast<double>(i) / samples);
    if (!inside(s)) {
      prev_s = s;
      continue;
    }
    glm::dvec3 lo = prev_s, hi = s;
    for (int j = 0; j < kBisections; ++j) {
      const glm::dvec3 mid = 0.5 * (lo + hi);
      (inside(mid) ? hi : lo) = mid;
    }
    double d_hi = 0.0, z_hi = 0.0;
    behind(hi, d_hi, z_hi);
    if (d_hi > steps.at(z_hi)) {
      p_ModelStop = lo;
      return Hit::Side;
    }
    p_ModelStop = hi;
    return Hit::Front;
  }
  p_ModelStop = p_ModelB;
  return Hit::None;
}

}  // namespace telex::detail
