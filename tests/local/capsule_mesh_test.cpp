// SPDX-License-Identifier: MIT
// The canonical capsule mesh (issue 43's body as triangles): closed, outward, and placed exactly on
// the surface the body pass ray-marches (Quilez's round cone).
#include "telex/local/view/capsule_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <utility>

namespace telex::local {
namespace {

struct Shape {
  glm::dvec3 a, b;
  double ra, rb;
  const char* what;
};

// Equal radii, a forearm-like taper both ways, a short fat phalanx, and a sphere held in another.
const Shape kShapes[] = {
    {{0.0, 0.0, 0.5}, {0.0, 0.0, 0.8}, 0.03, 0.03, "equal radii along z"},
    {{0.1, -0.2, 0.6}, {0.3, 0.05, 0.7}, 0.035, 0.025, "tapering forearm"},
    {{0.0, 0.0, 0.5}, {0.02, 0.01, 0.49}, 0.008, 0.011, "short phalanx, b larger"},
    {{0.0, 0.0, 0.5}, {0.001, 0.0, 0.5}, 0.02, 0.005, "b inside a"},
    {{0.2, 0.0, 0.5}, {0.9, 0.0, 0.5}, 0.01, 0.01, "along x (the other basis)"},
};

glm::dvec3 sdf_gradient(const glm::dvec3& p, const Shape& s) {
  const double h = 1e-7;
  glm::dvec3 g;
  for (int i = 0; i < 3; ++i) {
    glm::dvec3 d(0.0);
    d[i] = h;
    g[i] = (capsule_distance(p + d, s.a, s.ra, s.b, s.rb) -
            capsule_distance(p - d, s.a, s.ra, s.b, s.rb)) /
           (2 * h);
  }
  return g;
}

TEST(CapsuleMesh, IsClosedWithEveryEdgeOnceEachWay) {
  const CapsuleMesh m = capsule_mesh(16, 5);
  ASSERT_EQ(m.indices.size() % 3, 0u);
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (std::size_t t = 0; t < m.indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) ++directed[{m.indices[t + e], m.indices[t + (e + 1) % 3]}];
  for (const auto& [edge, count] : directed) {
    EXPECT_EQ(count, 1) << edge.first << "->" << edge.second;
    EXPECT_EQ(directed.count({edge.second, edge.first}), 1u) << edge.first << "->" << edge.second;
  }
  // Two poles, 2 x 5 rings of 16; 2 x 16 pole triangles and 2 per quad of 9 bands.
  EXPECT_EQ(m.vertices.size(), 2u + 10u * 16u);
  EXPECT_EQ(m.indices.size() / 3, 2u * 16u + 2u * 9u * 16u);
  EXPECT_THROW(capsule_mesh(2, 4), std::invalid_argument);
  EXPECT_THROW(capsule_mesh(8, 0), std::invalid_argument);
}

TEST(CapsuleMesh, PlacedVerticesLieOnTheRayMarchedSurfaceWithItsNormal) {
  const CapsuleMesh m = capsule_mesh(24, 6);
  for (const Shape& s : kShapes) {
    for (const CapsuleVertex& c : m.vertices) {
      const PlacedVertex v = place_capsule_vertex(c, s.a, s.ra, s.b, s.rb);
      EXPECT_NEAR(capsule_distance(v.p, s.a, s.ra, s.b, s.rb), 0.0, 1e-9) << s.what;
      EXPECT_NEAR(glm::length(v.normal), 1.0, 1e-12) << s.what;
      const glm::dvec3 g = sdf_gradient(v.p, s);
      EXPECT_GT(glm::dot(glm::normalize(g), v.normal), 1.0 - 1e-6)
          << s.what << " at v " << c.v << " cap " << int(c.cap);
    }
  }
}

TEST(CapsuleMesh, TrianglesFaceOutwards) {
  const CapsuleMesh m = capsule_mesh(20, 6);
  for (const Shape& s : kShapes) {
    int faced = 0;
    for (std::size_t t = 0; t < m.indices.size(); t += 3) {
      const PlacedVertex p0 = place_capsule_vertex(m.vertices[m.indices[t]], s.a, s.ra, s.b, s.rb);
      const PlacedVertex p1 =
          place_capsule_vertex(m.vertices[m.indices[t + 1]], s.a, s.ra, s.b, s.rb);
      const PlacedVertex p2 =
          place_capsule_vertex(m.vertices[m.indices[t + 2]], s.a, s.ra, s.b, s.rb);
      const glm::dvec3 area = glm::cross(p1.p - p0.p, p2.p - p0.p);
      if (glm::length(area) < 1e-14) continue;  // the seam's band on a held sphere is flat
      EXPECT_GT(glm::dot(area, p0.normal + p1.normal + p2.normal), 0.0) << s.what << " tri " << t;
      ++faced;
    }
    EXPECT_GT(faced, 0) << s.what;
  }
}

// The enclosed volume (divergence theorem over the triangles) converges to the capsule's.
double volume(const CapsuleMesh& m, const Shape& s) {
  double v6 = 0.0;
  for (std::size_t t = 0; t < m.indices.size(); t += 3) {
    const glm::dvec3 p0 = place_capsule_vertex(m.vertices[m.indices[t]], s.a, s.ra, s.b, s.rb).p;
    const glm::dvec3 p1 =
        place_capsule_vertex(m.vertices[m.indices[t + 1]], s.a, s.ra, s.b, s.rb).p;
    const glm::dvec3 p2 =
        place_capsule_vertex(m.vertices[m.indices[t + 2]], s.a, s.ra, s.b, s.rb).p;
    v6 += glm::dot(p0 - s.a, glm::cross(p1 - s.a, p2 - s.a));
  }
  return v6 / 6.0;
}

TEST(CapsuleMesh, EnclosesTheCapsulesVolume) {
  const Shape& s = kShapes[0];  // equal radii: a cylinder and a sphere
  const double r = s.ra, d = glm::length(s.b - s.a);
  const double exact = std::numbers::pi * r * r * d + 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double fine = volume(capsule_mesh(256, 64), s);
  const double coarse = volume(capsule_mesh(16, 4), s);
  EXPECT_NEAR(fine / exact, 1.0, 1e-3);
  EXPECT_LT(coarse, fine);  // an inscribed polyhedron
  EXPECT_GT(coarse / exact, 0.9);
  // A held sphere: the larger sphere's volume.
  const Shape& held = kShapes[3];
  const double sphere = 4.0 / 3.0 * std::numbers::pi * std::pow(held.ra, 3);
  EXPECT_NEAR(volume(capsule_mesh(256, 64), held) / sphere, 1.0, 1e-3);
}

}  // namespace
}  // namespace telex::local
