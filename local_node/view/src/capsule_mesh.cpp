// SPDX-License-Identifier: MIT
// The body as triangles: the canonical capsule mesh and its placement (capsule_mesh.h).
#include "telex/local/view/capsule_mesh.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace telex::local {

CapsuleMesh capsule_mesh(int around, int rings_per_cap) {
  if (around < 3 || rings_per_cap < 1)
    throw std::invalid_argument(
        "capsule_mesh: needs at least 3 vertices around and 1 ring a cap, "
        "got " +
        std::to_string(around) + " and " + std::to_string(rings_per_cap));
  CapsuleMesh m;
  const auto n = static_cast<std::uint32_t>(around);
  m.vertices.push_back({-1.0f, 0.0f, 0});  // pole A
  // Rings from pole A to the seam (cap A), then from the seam to pole B (cap B): the seam's two
  // rings sit at the same v, one on each sphere, and the band between them is the cone.
  std::vector<CapsuleVertex> rings;
  for (int i = 1; i <= rings_per_cap; ++i)
    rings.push_back({-1.0f + static_cast<float>(i) / static_cast<float>(rings_per_cap), 0.0f, 0});
  for (int i = 0; i < rings_per_cap; ++i)
    rings.push_back({static_cast<float>(i) / static_cast<float>(rings_per_cap), 0.0f, 1});
  for (const CapsuleVertex& r : rings)
    for (std::uint32_t k = 0; k < n; ++k)
      m.vertices.push_back({r.v, static_cast<float>(2.0 * std::numbers::pi * k / n), r.cap});
  const auto pole_b = static_cast<std::uint32_t>(m.vertices.size());
  m.vertices.push_back({1.0f, 0.0f, 1});
  const auto ring = [&](std::size_t r, std::uint32_t k) {
    return 1u + static_cast<std::uint32_t>(r) * n + k % n;
  };
  const auto tri = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
    m.indices.insert(m.indices.end(), {i, j, k});
  };
  for (std::uint32_t k = 0; k < n; ++k) tri(0, ring(0, k + 1), ring(0, k));
  for (std::size_t r = 0; r + 1 < rings.size(); ++r)
    for (std::uint32_t k = 0; k < n; ++k) {
      tri(ring(r, k), ring(r, k + 1), ring(r + 1, k + 1));
      tri(ring(r, k), ring(r + 1, k + 1), ring(r + 1, k));
    }
  const std::size_t last = rings.size() - 1;
  for (std::uint32_t k = 0; k < n; ++k) tri(pole_b, ring(last, k), ring(last, k + 1));
  return m;
}

PlacedVertex place_capsule_vertex(const CapsuleVertex& c, const glm::dvec3& a, double ra,
                                  const glm::dvec3& b, double rb) {
  constexpr double kHalfPi = std::numbers::pi / 2.0;
  const glm::dvec3 ab = b - a;
  const double d = glm::length(ab);
  const glm::dvec3 u = d > 1e-12 ? ab / d : glm::dvec3(0.0, 0.0, 1.0);
  // Any basis around the axis: the shader builds the same one from u.
  const glm::dvec3 helper =
      std::abs(u.x) < 0.9 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
  const glm::dvec3 e1 = glm::normalize(glm::cross(u, helper));
  const glm::dvec3 e2 = glm::cross(u, e1);
  const double theta = c.theta;
  const glm::dvec3 radial = std::cos(theta) * e1 + std::sin(theta) * e2;
  const double v = c.v;
  double alpha = 0.0, r = 0.0;
  glm::dvec3 centre{0.0};
  if (d <= std::abs(ra - rb) + 1e-12) {
    // One sphere holds the other: the capsule is the larger, and both caps cover it.
    alpha = v * kHalfPi;
    centre = ra >= rb ? a : b;
    r = std::max(ra, rb);
  } else {
    // The cone's normal leans towards the smaller sphere by phi: sin(phi) = (ra - rb) / d.
    const double phi = std::asin(std::clamp((ra - rb) / d, -1.0, 1.0));
    if (c.cap == 0) {
      alpha = -kHalfPi + (v + 1.0) * (phi + kHalfPi);
      centre = a;
      r = ra;
    } else {
      alpha = phi + v * (kHalfPi - phi);
      centre = b;
      r = rb;
    }
  }
  PlacedVertex out;
  out.normal = std::cos(alpha) * radial + std::sin(alpha) * u;
  out.p = centre + r * out.normal;
  return out;
}

double capsule_distance(const glm::dvec3& p, const glm::dvec3& a, double ra, const glm::dvec3& b,
                        double rb) {
  // Quilez's round cone, as the body pass's shader has it (body_pass_shaders.cpp: round_cone).
  const glm::dvec3 ba = b - a, pa = p - a;
  const double l2 = glm::dot(ba, ba);
  const double rr = ra - rb;
  const double a2 = l2 - rr * rr;
  if (l2 < 1e-12 || a2 <= 1e-12) return std::min(glm::length(pa) - ra, glm::length(p - b) - rb);
  const double il2 = 1.0 / l2;
  const double y = glm::dot(pa, ba);
  const double z = y - l2;
  const glm::dvec3 q = pa * l2 - ba * y;
  const double x2 = glm::dot(q, q);
  const double y2 = y * y * l2;
  const double z2 = z * z * l2;
  const double k = (rr > 0.0 ? 1.0 : rr < 0.0 ? -1.0 : 0.0) * rr * rr * x2;
  const double sz = z > 0.0 ? 1.0 : z < 0.0 ? -1.0 : 0.0;
  const double sy = y > 0.0 ? 1.0 : y < 0.0 ? -1.0 : 0.0;
  if (sz * a2 * z2 > k) return std::sqrt(x2 + z2) * il2 - rb;
  if (sy * a2 * y2 < k) return std::sqrt(x2 + y2) * il2 - ra;
  return (std::sqrt(x2 * a2 * il2) + y * rr) * il2 - ra;
}

}  // namespace telex::local
