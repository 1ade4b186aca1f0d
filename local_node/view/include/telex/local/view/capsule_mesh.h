// SPDX-License-Identifier: MIT
// The body as triangles (issue 43): one canonical mesh for every capsule, placed per capsule and
// per frame by the math a vertex shader runs. The surface is the ray-marched capsule's exactly:
// the convex hull of the sphere at a (radius ra) and the sphere at b (radius rb), a cone tangent
// to both between two spherical caps. A canonical vertex says which cap it is on and where; only
// the cone's half-angle depends on the capsule, so the mesh is built once and skinned by moving
// a and b (the bones) and the radii.
#pragma once

#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

namespace telex::local {

// A vertex of the canonical mesh. v in [-1, 1]: -1 the pole of cap A (behind a, away from b),
// 0 the seam where the cone meets both caps (cap A's rim at v = -0, cap B's at v = +0), 1 the
// pole of cap B; theta the angle around the axis, radians.
struct CapsuleVertex {
  float v = 0.0f;
  float theta = 0.0f;
  std::uint8_t cap = 0;  // 0: on sphere A, 1: on sphere B
};

struct CapsuleMesh {
  std::vector<CapsuleVertex> vertices;
  std::vector<std::uint32_t> indices;  // triangles, counter-clockwise seen from outside
};

// `around` vertices per ring (>= 3), `rings_per_cap` rings from each pole to the seam (>= 1).
// Closed: every edge is shared by exactly two triangles; the cone is the band between the caps'
// rims at the seam.
CapsuleMesh capsule_mesh(int around, int rings_per_cap);

// A canonical vertex placed on the capsule a-b with radii ra, rb (metres, > 0): its position and
// outward unit normal. When one sphere holds the other (|b - a| <= |ra - rb|) the capsule is the
// larger sphere and both caps cover it.
struct PlacedVertex {
  glm::dvec3 p{0.0};
  glm::dvec3 normal{0.0, 0.0, 1.0};
};
PlacedVertex place_capsule_vertex(const CapsuleVertex& c, const glm::dvec3& a, double ra,
                                  const glm::dvec3& b, double rb);

// The capsule's signed distance at p (negative inside): the shape the ray-march draws, for tests
// and for checking a placed mesh.
double capsule_distance(const glm::dvec3& p, const glm::dvec3& a, double ra, const glm::dvec3& b,
                        double rb);

}  // namespace telex::local
