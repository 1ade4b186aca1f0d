// SPDX-License-Identifier: MIT
// The body as triangles (issue 43): the canonical capsule mesh drawn once per capsule, instanced,
// each vertex put on its capsule's round cone by the vertex shader (place_capsule_vertex's math),
// nearest capsules first and depth-tested with no gl_FragDepth, so a hidden fragment is never
// shaded.
#include <epoxy/gl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <glm/gtc/type_ptr.hpp>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "body_pass.h"
#include "gl_program.h"
#include "telex/local/view/capsule_mesh.h"
#include "telex/local/view/stereo_renderer.h"

namespace telex::local {
namespace {

// Per vertex: v, theta, cap (capsule_mesh.h's CapsuleVertex). Per instance: its capsule and, a
// byte each, up to 8 capsules it blends with (blend_neighbours' order, as the march joins them)
// and their count; the capsules themselves in u_caps (pack_capsules). The vertex is put on its
// capsule's round cone (place_capsule_vertex line by line, the radius scaled so that a ring's
// polygon holds the circle's area) and then pushed out along its normal onto the smooth union
// with the neighbours (the march's field): starting inside, each step by the field's depth there
// never passes the surface. Its normal is then the field's gradient, and how deep it sits in a
// fillet darkens the crease as the march does.
constexpr const char* kMeshVs = R"(
layout(location = 0) in vec3 a_vertex;
layout(location = 1) in ivec4 a_capsule;  // self, neighbours 0-3, 4-7 (a byte each), count
uniform samplerBuffer u_caps;
uniform mat4 u_projection;
uniform float u_radius_scale;
out vec3 v_p;
out vec3 v_n;
out float v_crease;
flat out vec4 v_color;
const float kHalfPi = 1.57079632679;
vec4 g_a, g_b;
float field(vec3 p, out float blend) {
  float d = round_cone(p, g_a.xyz, g_b.xyz, g_a.w, g_b.w);
  float r = max(g_a.w, g_b.w);
  blend = 0.0;
  for (int k = 0; k < a_capsule.w; ++k) {
    int j = ((k < 4 ? a_capsule.y : a_capsule.z) >> (8 * (k & 3))) & 255;
    vec4 a = texelFetch(u_caps, 3 * j), b = texelFetch(u_caps, 3 * j + 1);
    if (a.w <= 0.0) continue;
    float kj = blend_reach(r, a, b);
    float dj = round_cone(p, a.xyz, b.xyz, a.w, b.w);
    blend = max(blend, max(kj - abs(d - dj), 0.0) / kj);
    d = smin(d, dj, kj);
  }
  return d;
}
void main() {
  g_a = texelFetch(u_caps, 3 * a_capsule.x);
  g_b = texelFetch(u_caps, 3 * a_capsule.x + 1);
  v_color = texelFetch(u_caps, 3 * a_capsule.x + 2);
  vec3 ab = g_b.xyz - g_a.xyz;
  float d = length(ab);
  vec3 u = d > 1e-9 ? ab / d : vec3(0.0, 0.0, 1.0);
  vec3 helper = abs(u.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 e1 = normalize(cross(u, helper));
  vec3 e2 = cross(u, e1);
  vec3 radial = cos(a_vertex.y) * e1 + sin(a_vertex.y) * e2;
  float v = a_vertex.x;
  float ra = g_a.w, rb = g_b.w;
  float alpha, r;
  vec3 centre;
  if (d <= abs(ra - rb) + 1e-9) {
    alpha = v * kHalfPi;
    centre = ra >= rb ? g_a.xyz : g_b.xyz;
    r = max(ra, rb);
  } else {
    float phi = asin(clamp((ra - rb) / d, -1.0, 1.0));
    if (a_vertex.z < 0.5) {
      alpha = -kHalfPi + (v + 1.0) * (phi + kHalfPi);
      centre = g_a.xyz;
      r = ra;
    } else {
      alpha = phi + v * (kHalfPi - phi);
      centre = g_b.xyz;
      r = rb;
    }
  }
  vec3 n = cos(alpha) * radial + sin(alpha) * u;
  vec3 p = centre + r * u_radius_scale * n;
  float blend = 0.0;
  v_crease = 0.0;
  // A vertex inside a neighbour is hidden by it and stays; one outside all of them is pushed
  // out onto the fillet, which is never deeper than a quarter of the blend's reach.
  bool outside = true;
  for (int k = 0; k < a_capsule.w; ++k) {
    int j = ((k < 4 ? a_capsule.y : a_capsule.z) >> (8 * (k & 3))) & 255;
    vec4 a = texelFetch(u_caps, 3 * j), b = texelFetch(u_caps, 3 * j + 1);
    if (a.w > 0.0 && round_cone(p, a.xyz, b.xyz, a.w, b.w) < 0.0) outside = false;
  }
  if (a_capsule.w > 0 && outside) {
    float t = 0.0;
    for (int i = 0; i < 2; ++i) t += max(-field(p + t * n, blend), 0.0);
    p += min(t, 0.35 * max(ra, rb)) * n;
    if (blend > 0.0) {
      const float e = 2e-4;
      float unused;
      float d0 = field(p, unused);
      n = normalize(vec3(field(p + vec3(e, 0.0, 0.0), unused), field(p + vec3(0.0, e, 0.0), unused),
                         field(p + vec3(0.0, 0.0, e), unused)) - d0);
      v_crease = blend;
    }
  }
  v_n = n;
  v_p = p;
  gl_Position = u_projection * vec4(v_p, 1.0);
}
)";

constexpr const char* kMeshFs = R"(
uniform float u_exposure;
in vec3 v_p;
in vec3 v_n;
in float v_crease;
flat in vec4 v_color;
out vec4 o_color;
void main() {
  o_color = vec4(shade_body(normalize(v_n), normalize(v_p), v_color, v_crease, u_exposure), 1.0);
}
)";

// Levels of detail, by the capsule's larger radius on screen in pixels: a ring of n sides sags
// r (1 - cos(pi / n)) ~ r pi^2 / (2 n^2) from its circle (its area is kept: the radius is scaled),
// at most a pixel with n >= pi sqrt(r / 2). llvmpipe sets up every triangle and shades whole 4x4
// blocks a triangle touches: more triangles than the outline needs cost more than vertices.
struct Lod {
  int around, rings_per_cap;
  double up_to_px;  // the largest radius on screen drawn at this level
};
constexpr std::array<Lod, 3> kLods{{{8, 2, 13.0}, {16, 4, 52.0}, {32, 6, 1e30}}};

}  // namespace

std::string body_shader(const char* body) {
  return std::string("#version 330 core\n") + kBodyShadeGlsl + kBodyFieldGlsl + body;
}

struct BodyMesh::Gl {
  GLuint program = 0, caps_buffer = 0, caps_tex = 0;
  struct Level {
    GLuint vao = 0, vertices = 0, indices = 0, instances = 0;
    GLsizei index_count = 0;
    std::vector<std::array<std::int32_t, 4>> drawn;  // this frame's instances, nearest first
    double nearest_z = 0.0;                          // the first one's
  };
  std::array<Level, kLods.size()> levels;
  std::vector<float> caps;
  std::vector<std::pair<double, std::size_t>> order;  // nearest z, capsule
};

BodyMesh::BodyMesh() : gl_(std::make_unique<Gl>()) {
  Gl& g = *gl_;
  g.program = link_program(body_shader(kMeshVs).c_str(), body_shader(kMeshFs).c_str(),
                           "stereo view: body mesh");
  glGenBuffers(1, &g.caps_buffer);
  glGenTextures(1, &g.caps_tex);
  for (std::size_t l = 0; l < kLods.size(); ++l) {
    Gl::Level& level = g.levels[l];
    const CapsuleMesh mesh = capsule_mesh(kLods[l].around, kLods[l].rings_per_cap);
    std::vector<float> vertices;
    for (const CapsuleVertex& v : mesh.vertices)
      vertices.insert(vertices.end(), {v.v, v.theta, static_cast<float>(v.cap)});
    level.index_count = static_cast<GLsizei>(mesh.indices.size());
    glGenVertexArrays(1, &level.vao);
    glGenBuffers(1, &level.vertices);
    glGenBuffers(1, &level.indices);
    glGenBuffers(1, &level.instances);
    glBindVertexArray(level.vao);
    glBindBuffer(GL_ARRAY_BUFFER, level.vertices);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(vertices.size() * sizeof(float)),
                 vertices.data(), GL_STATIC_DRAW);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
    glEnableVertexAttribArray(0);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, level.indices);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER,
                 static_cast<GLsizeiptr>(mesh.indices.size() * sizeof(std::uint32_t)),
                 mesh.indices.data(), GL_STATIC_DRAW);
    glBindBuffer(GL_ARRAY_BUFFER, level.instances);
    glVertexAttribIPointer(1, 4, GL_INT, 4 * sizeof(std::int32_t), nullptr);
    glEnableVertexAttribArray(1);
    glVertexAttribDivisor(1, 1);
    glBindVertexArray(0);
  }
  glBindBuffer(GL_ARRAY_BUFFER, 0);
}

BodyMesh::~BodyMesh() = default;  // the GL objects go with the context

void BodyMesh::draw(const Intrinsics& k, const glm::dvec3& p_RightEye,
                    std::span<const Capsule> capsules, float exposure) {
  Gl& g = *gl_;
  if (capsules.size() > 256) capsules = capsules.first(256);  // a neighbour is a byte
  pack_capsules(capsules, p_RightEye, g.caps);
  // Nearest first, so the depth test rejects what a nearer capsule hides before it is shaded;
  // capsules wholly behind the near plane are left out.
  g.order.clear();
  for (std::size_t i = 0; i < capsules.size(); ++i) {
    const float* c = g.caps.data() + i * kCapsuleFloats;
    if (!(c[3] > 0.0f)) continue;  // pack_capsules left it out
    const double near_z = std::min(c[2] - c[3], c[6] - c[7]);
    if (std::max(c[2] + c[3], c[6] + c[7]) < kViewNear_m) continue;
    g.order.emplace_back(near_z, i);
  }
  if (g.order.empty()) return;
  std::sort(g.order.begin(), g.order.end());
  const auto neighbours = blend_neighbours(capsules);
  for (Gl::Level& level : g.levels) level.drawn.clear();
  for (const auto& [near_z, i] : g.order) {
    const float* c = g.caps.data() + i * kCapsuleFloats;
    const double r_px = k.fx * std::max(c[3], c[7]) / std::max(near_z, kViewNear_m);
    std::size_t l = 0;
    while (l + 1 < kLods.size() && r_px > kLods[l].up_to_px) ++l;
    std::array<std::int32_t, 4> instance{static_cast<std::int32_t>(i), 0, 0, 0};
    for (const std::int32_t j : neighbours[i]) {
      if (j < 0) break;
      const int n = instance[3]++;
      instance[n < 4 ? 1 : 2] |= j << (8 * (n & 3));
    }
    if (g.levels[l].drawn.empty()) g.levels[l].nearest_z = near_z;
    g.levels[l].drawn.push_back(instance);
  }
  glUseProgram(g.program);
  texture_buffer(g.caps_buffer, g.caps_tex, g.caps.data(), g.caps.size() * sizeof(float),
                 GL_RGBA32F, 0, glGetUniformLocation(g.program, "u_caps"));
  const glm::mat4 projection = projection_from_intrinsics(k, kViewNear_m, kViewFar_m);
  glUniformMatrix4fv(glGetUniformLocation(g.program, "u_projection"), 1, GL_FALSE,
                     glm::value_ptr(projection));
  glUniform1f(glGetUniformLocation(g.program, "u_exposure"), exposure);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDepthMask(GL_TRUE);
  // The projection keeps the image's rows top-down: an outside face, counter-clockwise seen from
  // outside in the camera's right-handed frame, comes out clockwise in window coordinates.
  glEnable(GL_CULL_FACE);
  glFrontFace(GL_CW);
  glCullFace(GL_BACK);
  // One draw a level, the level whose nearest capsule is nearest first.
  std::array<std::size_t, kLods.size()> levels{};
  std::array<double, kLods.size()> nearest{};
  for (std::size_t l = 0; l < kLods.size(); ++l) {
    levels[l] = l;
    nearest[l] = g.levels[l].drawn.empty() ? 1e30 : g.levels[l].nearest_z;
  }
  std::sort(levels.begin(), levels.end(),
            [&](std::size_t a, std::size_t b) { return nearest[a] < nearest[b]; });
  for (const std::size_t l : levels) {
    Gl::Level& level = g.levels[l];
    if (level.drawn.empty()) continue;
    // A regular polygon of n sides whose area is the circle's.
    const double n = kLods[l].around;
    const double scale =
        std::sqrt(2.0 * std::numbers::pi / (n * std::sin(2.0 * std::numbers::pi / n)));
    glUniform1f(glGetUniformLocation(g.program, "u_radius_scale"), static_cast<float>(scale));
    glBindBuffer(GL_ARRAY_BUFFER, level.instances);
    glBufferData(GL_ARRAY_BUFFER,
                 static_cast<GLsizeiptr>(level.drawn.size() * sizeof(level.drawn[0])),
                 level.drawn.data(), GL_STREAM_DRAW);
    glBindVertexArray(level.vao);
    glDrawElementsInstanced(GL_TRIANGLES, level.index_count, GL_UNSIGNED_INT, nullptr,
                            static_cast<GLsizei>(level.drawn.size()));
  }
  glBindVertexArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, 0);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
  glDisable(GL_CULL_FACE);
  glFrontFace(GL_CCW);
}

}  // namespace telex::local
