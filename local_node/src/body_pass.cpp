// SPDX-License-Identifier: MIT
// The body pass: round cones joined by a smooth minimum and sphere-traced per box, lit to the
// video's brightness, and the fingertips' contact shadows on the remote scene.
#include "body_pass.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <glm/gtc/type_ptr.hpp>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

#include "gl_program.h"

namespace telex::local {
namespace {

// Each capsule's box (a unit cube's corner c in [0, 1]^3 placed around the segment a-b with room
// for the blend), rasterised once per capsule: Mesa's llvmpipe pays per triangle, so a box of 12
// triangles with the surface found per fragment beats a tessellated hand. The fragments get the
// capsule's index alone and read the rest from uniform blocks: llvmpipe loads every input of a
// fragment shader up front, and some forty flat inputs cost more than the read.
constexpr const char* kBodyVs = R"(#version 330 core
layout(location = 0) in vec3 a_corner;
layout(location = 1) in vec3 a_a;        // per instance, this eye's frame
layout(location = 2) in vec3 a_b;
layout(location = 3) in vec2 a_radii;    // at a, at b
layout(location = 4) in int a_id;
uniform mat4 u_projection;
out vec3 v_position;
flat out int v_id;  // this capsule in Capsules
void main() {
  vec3 d = a_b - a_a;
  float len = length(d);
  vec3 axis = len > 1e-9 ? d / len : vec3(0.0, 0.0, 1.0);
  vec3 helper = abs(axis.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 u = normalize(cross(axis, helper));
  vec3 w = cross(axis, u);
  // Room for the smooth union's fillet (it lies within a quarter of the smaller radius).
  float r = max(a_radii.x, a_radii.y) * 1.2 + 5e-4;
  vec3 p = a_a + u * (a_corner.x * 2.0 - 1.0) * r + w * (a_corner.y * 2.0 - 1.0) * r +
           axis * (-r + a_corner.z * (len + 2.0 * r));
  v_position = p;
  v_id = a_id;
  gl_Position = u_projection * vec4(p, 1.0);
}
)";

// The eye sits at the origin. The ray through this fragment is marched from where it enters the
// box (or the near plane, with the eye inside it) on the field of this capsule smoothly joined to
// its neighbours; each pixel is worked once per box (face culling keeps one face a pixel).
constexpr const char* kBodyFs = R"(#version 330 core
// Per capsule: a and its radius, b and its radius, rgb and lit (1) or a flat marker (0).
layout(std140) uniform Capsules { vec4 u_caps[3 * 256]; };
// Per capsule its blend neighbours, -1 ending the list.
layout(std140) uniform Neighbours { ivec4 u_neighbours[2 * 256]; };
uniform float u_near;
uniform float u_far;
uniform float u_exposure;
in vec3 v_position;
flat in int v_id;
out vec4 o_color;

float dot2(vec3 v) { return dot(v, v); }
// Quilez's round cone: spheres of radii r1 at a and r2 at b and the cone tangent to both.
float round_cone(vec3 p, vec3 a, vec3 b, float r1, float r2) {
  vec3 ba = b - a;
  float l2 = dot(ba, ba);
  float rr = r1 - r2;
  float a2 = l2 - rr * rr;
  vec3 pa = p - a;
  if (l2 < 1e-12 || a2 <= 1e-12) return min(length(pa) - r1, length(p - b) - r2);
  float il2 = 1.0 / l2;
  float y = dot(pa, ba);
  float z = y - l2;
  float x2 = dot2(pa * l2 - ba * y);
  float y2 = y * y * l2;
  float z2 = z * z * l2;
  float k = sign(rr) * rr * rr * x2;
  if (sign(z) * a2 * z2 > k) return sqrt(x2 + z2) * il2 - r2;
  if (sign(y) * a2 * y2 < k) return sqrt(x2 + y2) * il2 - r1;
  return (sqrt(x2 * a2 * il2) + y * rr) * il2 - r1;
}
float smin(float a, float b, float k) {
  if (k <= 0.0) return min(a, b);
  float h = max(k - abs(a - b), 0.0) / k;
  return min(a, b) - h * h * k * 0.25;
}
float capsule(int i, vec3 p) {
  vec4 a = u_caps[3 * i], b = u_caps[3 * i + 1];
  return round_cone(p, a.xyz, b.xyz, a.w, b.w);
}
float radius(int i) { return max(u_caps[3 * i].w, u_caps[3 * i + 1].w); }
vec4 g_self_a, g_self_b;  // this capsule
int g_near_lo, g_near_hi;  // the neighbours near this pixel's ray, a byte each
int g_count;
// llvmpipe runs both sides of a branch but leaves a loop once every pixel of a block is done: the
// neighbours are looped over by their count (the same for the whole box), never skipped by a test.
// g_blend: how deep in a fillet the last point was (0 on a lone capsule, 1 in a crease).
float g_blend = 0.0;
float field(vec3 p) {
  float d = round_cone(p, g_self_a.xyz, g_self_b.xyz, g_self_a.w, g_self_b.w);
  float r = max(g_self_a.w, g_self_b.w);
  g_blend = 0.0;
  for (int k = 0; k < g_count; ++k) {
    int j = ((k < 4 ? g_near_lo : g_near_hi) >> (8 * (k & 3))) & 255;
    float kj = 0.7 * min(r, radius(j));
    float dj = capsule(j, p);
    g_blend = max(g_blend, max(kj - abs(d - dj), 0.0) / kj);
    d = smin(d, dj, kj);
  }
  return d;
}
// Where the ray from the eye along rd is inside the capsule a-b of radius r: (enter, leave), or
// enter > leave on a miss. The capsule is convex: its interval is the union of its cylinder's and
// its two balls'.
vec2 capsule_span(vec3 rd, vec3 a, vec3 b, float r) {
  vec2 span = vec2(1e30, -1e30);
  vec3 ba = b - a, oa = -a;
  float baba = dot(ba, ba), bard = dot(ba, rd), baoa = dot(ba, oa);
  float rdoa = dot(rd, oa), oaoa = dot(oa, oa);
  float qa = baba - bard * bard;
  if (qa > 1e-9 * max(baba, 1e-12)) {
    float qb = baba * rdoa - baoa * bard;
    float qc = baba * oaoa - baoa * baoa - r * r * baba;
    float h = qb * qb - qa * qc;
    if (h >= 0.0) {
      float s = sqrt(h);
      vec2 cyl = vec2(-qb - s, -qb + s) / qa;
      // Between the end planes: y(t) = baoa + t bard in [0, baba].
      if (abs(bard) > 1e-20) {
        vec2 ends = vec2(-baoa, baba - baoa) / bard;
        cyl = vec2(max(cyl.x, min(ends.x, ends.y)), min(cyl.y, max(ends.x, ends.y)));
      } else if (baoa < 0.0 || baoa > baba) {
        cyl = vec2(1e30, -1e30);
      }
      if (cyl.x <= cyl.y) span = cyl;
    }
  }
  for (int e = 0; e < 2; ++e) {
    vec3 c = e == 0 ? a : b;
    float pb = dot(rd, c);
    float h = pb * pb - (dot(c, c) - r * r);
    if (h < 0.0) continue;
    float s = sqrt(h);
    span = vec2(min(span.x, pb - s), max(span.y, pb + s));
  }
  return span;
}
// Where the ray from the eye along rd enters the round cone (Quilez's intersector), with the
// outward normal there; x < 0: a miss.
vec4 round_cone_hit(vec3 rd, vec3 pa, vec3 pb, float ra, float rb) {
  vec3 ba = pb - pa, oa = -pa, ob = -pb;
  float rr = ra - rb;
  float m0 = dot(ba, ba), m1 = dot(ba, oa), m2 = dot(ba, rd), m3 = dot(rd, oa), m5 = dot(oa, oa);
  float m6 = dot(ob, rd), m7 = dot(ob, ob);
  float d2 = m0 - rr * rr;
  if (d2 > 1e-6 * max(m0, 1e-12)) {
    // The cone's side, where it touches neither ball.
    float k2 = d2 - m2 * m2;
    float k1 = d2 * m3 - m1 * m2 + m2 * rr * ra;
    float k0 = d2 * m5 - m1 * m1 + m1 * rr * ra * 2.0 - m0 * ra * ra;
    float h = k1 * k1 - k0 * k2;
    if (abs(k2) > 1e-12 && h >= 0.0) {
      float t = (-sqrt(h) - k1) / k2;
      float y = m1 - ra * rr + t * m2;
      if (t > 0.0 && y > 0.0 && y < d2) return vec4(t, normalize(d2 * (oa + t * rd) - ba * y));
    }
  }
  // The balls (the larger alone where it holds the other).
  vec4 best = vec4(-1.0);
  float h1 = m3 * m3 - m5 + ra * ra, h2 = m6 * m6 - m7 + rb * rb;
  if (h1 >= 0.0) {
    float t = -m3 - sqrt(h1);
    if (t > 0.0) best = vec4(t, (oa + t * rd) / ra);
  }
  if (h2 >= 0.0) {
    float t = -m6 - sqrt(h2);
    if (t > 0.0 && (best.x < 0.0 || t < best.x)) best = vec4(t, (ob + t * rd) / rb);
  }
  return best;
}
void main() {
  vec3 rd = normalize(v_position);
  g_self_a = u_caps[3 * v_id];
  g_self_b = u_caps[3 * v_id + 1];
  vec4 color = u_caps[3 * v_id + 2];
  // This capsule grown by the blend's reach bounds what the pixel can meet (the box holds it; the
  // eye may be inside it): a miss is discarded here.
  vec4 ca = g_self_a, cb = g_self_b;
  float r = max(ca.w, cb.w);
  vec2 span = capsule_span(rd, ca.xyz, cb.xyz, r * 1.2 + 5e-4);
  if (span.x > span.y || span.y < u_near) discard;
  float t = max(span.x, u_near), t_exit = span.y;
  // A neighbour j changes the smooth union only where this capsule's distance and j's differ by
  // less than k_j and the union is below zero: within 1.25 k_j of j. Only the neighbours whose
  // so grown capsule the ray meets are kept (their indices packed a byte each: llvmpipe runs a
  // loop as long as its longest lane, and indexes local arrays slowly), and the ray is marched
  // only from where it meets the first of them; elsewhere the surface is this round cone's,
  // found and shaded exactly.
  ivec4 n0 = u_neighbours[2 * v_id], n1 = u_neighbours[2 * v_id + 1];
  g_near_lo = 0;
  g_near_hi = 0;
  g_count = 0;
  float blend_lo = 1e30, blend_hi = -1e30;
  for (int k = 0; k < 8; ++k) {
    int j = k < 4 ? n0[k] : n1[k - 4];
    if (j < 0) break;
    float rj = radius(j);
    vec2 s = capsule_span(rd, u_caps[3 * j].xyz, u_caps[3 * j + 1].xyz,
                          rj + 0.875 * min(r, rj) + 2e-4);
    if (s.x <= s.y && s.y > t && s.x < t_exit) {
      if (g_count < 4) g_near_lo |= j << (8 * g_count);
      else g_near_hi |= j << (8 * (g_count - 4));
      ++g_count;
      blend_lo = min(blend_lo, s.x);
      blend_hi = max(blend_hi, s.y);
    }
  }
  vec4 self_hit = round_cone_hit(rd, ca.xyz, cb.xyz, ca.w, cb.w);
  bool exact = self_hit.x > 0.0 && (g_count == 0 || self_hit.x <= blend_lo);
  if (!exact && g_count == 0) discard;
  // Past the blends the field is this cone's alone again.
  float t_end = min(t_exit, blend_hi);
  bool hit = exact;
  t = exact ? self_hit.x : max(t, blend_lo);
  for (int i = 0; i < 32 && !hit && t < t_end; ++i) {
    float d = field(rd * t);
    if (d < 1.5e-4 + 2e-4 * t) hit = true;
    else t += d;
  }
  if (!hit && self_hit.x >= t_end && t >= t_end) {
    t = self_hit.x;
    hit = exact = true;
  }
  if (!hit) discard;
  vec3 p = rd * t;
  vec3 n = self_hit.yzw;
  float crease = 0.0;
  if (!exact) {
    // The crease depth at the hit, then the normal from three forward differences (the field is
    // about zero at the hit).
    float d0 = field(p);
    crease = g_blend;
    const float e = 2e-4;
    n = normalize(vec3(field(p + vec3(e, 0.0, 0.0)), field(p + vec3(0.0, e, 0.0)),
                       field(p + vec3(0.0, 0.0, e))) - d0);
  }
  float facing = max(dot(n, -rd), 0.0);
  vec3 albedo = color.rgb;
  vec3 c;
  if (color.a > 0.5) {
    // Skin: a key light from above and to the left (the camera's y is down), wrapped so the
    // shadow side stays soft, a sky-and-ground ambient, the creases (deep in a fillet between two
    // capsules) darkened, a warm rim where light scatters under the skin, and a faint sheen.
    vec3 l = normalize(vec3(-0.35, -0.85, -0.4));
    float diffuse = max((dot(n, l) + 0.35) / 1.35, 0.0);
    float ambient = 0.22 + 0.14 * (0.5 - 0.5 * n.y);
    float ao = 1.0 - 0.12 * crease * crease;
    vec3 rim = vec3(0.85, 0.35, 0.25) * pow(1.0 - facing, 3.0) * 0.12;
    float sheen = pow(max(dot(reflect(-l, n), -rd), 0.0), 20.0) * 0.06;
    c = (albedo * (0.78 * diffuse + ambient) * ao + rim + sheen) * u_exposure;
  } else {
    c = albedo * (0.55 + 0.45 * facing);
  }
  o_color = vec4(c, 1.0);
  float z = clamp(p.z, u_near, u_far);
  float ndc = (u_far + u_near) / (u_far - u_near) - 2.0 * u_far * u_near / ((u_far - u_near) * z);
  gl_FragDepth = ndc * 0.5 + 0.5;
}
)";

// A screen rectangle (NDC, from u_rect) around one fingertip; the remote surface point of each
// pixel is rebuilt from the eye's depth and darkened by its nearness to the fingertip: an
// occluding ball's falloff, (r / d)^2, faded out by kShadowReach_m.
constexpr const char* kShadowFs = R"(#version 330 core
uniform sampler2D u_depth;  // window depths, rows top-down
uniform vec4 u_k;           // fx, fy, cx, cy
uniform vec3 u_tip;         // this eye's frame
uniform float u_near;
uniform float u_far;
uniform float u_radius;
uniform float u_reach;
out vec4 o_color;
void main() {
  float wd = texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r;
  if (wd >= 1.0) discard;
  float ndc = wd * 2.0 - 1.0;
  float z = 2.0 * u_far * u_near / ((u_far + u_near) - ndc * (u_far - u_near));
  vec2 px = gl_FragCoord.xy - 0.5;
  vec3 p = vec3((px.x - u_k.z) / u_k.x * z, (px.y - u_k.w) / u_k.y * z, z);
  float d = max(distance(p, u_tip), 1e-4);
  float occ = min(u_radius * u_radius / (d * d), 1.0) * (1.0 - smoothstep(0.4 * u_reach, u_reach, d));
  o_color = vec4(vec3(1.0 - 0.65 * occ), 1.0);
}
)";

constexpr double kShadowReach_m = 0.05;
constexpr double kShadowRadius_m = 0.012;

// One capsule as the box shader takes it.
struct Instance {
  std::array<float, 3> a, b;
  std::array<float, 2> radii;
  std::int32_t id;  // in the Capsules and Neighbours blocks
};
constexpr std::size_t kCapsuleFloats = 12;  // a, radius at a, b, radius at b, rgba

std::array<float, 3> f3(const glm::dvec3& v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

bool finite(const glm::dvec3& v) { return std::isfinite(v.x + v.y + v.z); }

// Whether a capsule's box (the vertex shader's: 1.2 times the larger radius around the segment)
// may hold the eye or meet the near plane: such boxes are drawn by their far faces. Conservative
// (the box's corner reach and twice the near distance).
bool box_near_eye(const glm::dvec3& a, const glm::dvec3& b, double r) {
  const glm::dvec3 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  const double u = len2 > 1e-18 ? std::clamp(glm::dot(-a, ab) / len2, 0.0, 1.0) : 0.0;
  const double d = glm::length(a + u * ab);
  return d < (r * 1.2 + 5e-4) * std::sqrt(3.0) + 2.0 * StereoRenderer::kNear_m;
}

double radius_b(const Capsule& c) { return c.radius_b_m < 0.0 ? c.radius_m : c.radius_b_m; }

}  // namespace

struct BodyPass::Gl {
  GLuint body = 0, shadow = 0;
  GLuint vao = 0, corners = 0, instances = 0, ubo = 0, neighbours_ubo = 0;
  GLuint empty_vao = 0, depth_tex = 0;
  cv::Size depth_size;
  bool has_scene_depth = false;
  cv::Mat1f scene_depth;  // the last set_scene_depth's (shares its data)
  // Per 16x16 tile of the scene depth its nearest and farthest window depth, made on the first
  // contact shadow drawn after set_scene_depth.
  cv::Mat2f depth_tiles;
  bool tiles_valid = false;
  bool depth_uploaded = false;  // scene_depth in depth_tex
  void upload_scene_depth();
  std::unique_ptr<BodyUpsample> upsample;  // made on the first draw at a reduced resolution
  GLsizei vertices = 0;
  std::vector<Instance> instance_data, around_eye;
  std::vector<float> caps;
  std::vector<std::int32_t> neighbours;
};

BodyPass::BodyPass() : gl_(std::make_unique<Gl>()) {
  Gl& g = *gl_;
  g.body = link_program(kBodyVs, kBodyFs, "stereo view: body");
  g.shadow = link_program(kRectVertexShader, kShadowFs, "stereo view: body");
  glUniformBlockBinding(g.body, glGetUniformBlockIndex(g.body, "Capsules"), 0);
  glUniformBlockBinding(g.body, glGetUniformBlockIndex(g.body, "Neighbours"), 1);
  const float c[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  // Counter-clockwise seen from outside the cube (the box frame is right-handed).
  const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                           {3, 7, 6, 2}, {0, 4, 7, 3}, {1, 2, 6, 5}};
  std::vector<float> corners;
  for (const auto& f : faces)
    for (int k : {0, 1, 2, 0, 2, 3}) corners.insert(corners.end(), c[f[k]], c[f[k]] + 3);
  g.vertices = static_cast<GLsizei>(corners.size() / 3);
  glGenVertexArrays(1, &g.vao);
  glGenVertexArrays(1, &g.empty_vao);
  glGenBuffers(1, &g.corners);
  glGenBuffers(1, &g.instances);
  glGenBuffers(1, &g.ubo);
  glGenBuffers(1, &g.neighbours_ubo);
  glBindVertexArray(g.vao);
  glBindBuffer(GL_ARRAY_BUFFER, g.corners);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(corners.size() * sizeof(float)),
               corners.data(), GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  glEnableVertexAttribArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, g.instances);
  const auto attrib = [](GLuint loc, GLint n, std::size_t offset, bool integer) {
    const auto* at = reinterpret_cast<const void*>(offset);
    if (integer)
      glVertexAttribIPointer(loc, n, GL_INT, sizeof(Instance), at);
    else
      glVertexAttribPointer(loc, n, GL_FLOAT, GL_FALSE, sizeof(Instance), at);
    glEnableVertexAttribArray(loc);
    glVertexAttribDivisor(loc, 1);
  };
  attrib(1, 3, offsetof(Instance, a), false);
  attrib(2, 3, offsetof(Instance, b), false);
  attrib(3, 2, offsetof(Instance, radii), false);
  attrib(4, 1, offsetof(Instance, id), true);
  glBindVertexArray(0);
  glBindBuffer(GL_UNIFORM_BUFFER, g.ubo);
  glBufferData(GL_UNIFORM_BUFFER,
               static_cast<GLsizeiptr>(kMaxCapsules * kCapsuleFloats * sizeof(float)), nullptr,
               GL_STREAM_DRAW);
  glBindBuffer(GL_UNIFORM_BUFFER, g.neighbours_ubo);
  glBufferData(GL_UNIFORM_BUFFER,
               static_cast<GLsizeiptr>(kMaxCapsules * kMaxBlendNeighbours * sizeof(std::int32_t)),
               nullptr, GL_STREAM_DRAW);
  glGenTextures(1, &g.depth_tex);
  glBindTexture(GL_TEXTURE_2D, g.depth_tex);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
}

BodyPass::~BodyPass() = default;  // the GL objects go with the context

void BodyPass::set_scene_depth(const cv::Mat1f& window_depth) {
  Gl& g = *gl_;
  g.has_scene_depth = !window_depth.empty();
  g.scene_depth = window_depth;
  g.tiles_valid = false;
  g.depth_uploaded = false;
}

// The scene depth into its texture (bound to the active unit) on its first use after
// set_scene_depth: with the hands in the air and the body at full resolution nothing reads it.
void BodyPass::Gl::upload_scene_depth() {
  glBindTexture(GL_TEXTURE_2D, depth_tex);
  if (depth_uploaded) return;
  if (scene_depth.size() != depth_size) {
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R32F, scene_depth.cols, scene_depth.rows, 0, GL_RED, GL_FLOAT,
                 nullptr);
    depth_size = scene_depth.size();
  }
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, scene_depth.cols, scene_depth.rows, GL_RED, GL_FLOAT,
                  scene_depth.data);
  depth_uploaded = true;
}

void BodyPass::draw_contact_shadows(const Intrinsics& k, const glm::dvec3& p_RightEye,
                                    std::span<const glm::dvec3> fingertips) {
  Gl& g = *gl_;
  if (fingertips.empty() || !g.has_scene_depth) return;
  glUseProgram(g.shadow);
  glUniform1i(glGetUniformLocation(g.shadow, "u_depth"), 0);
  glUniform4f(glGetUniformLocation(g.shadow, "u_k"), static_cast<float>(k.fx),
              static_cast<float>(k.fy), static_cast<float>(k.cx), static_cast<float>(k.cy));
  glUniform1f(glGetUniformLocation(g.shadow, "u_near"),
              static_cast<float>(StereoRenderer::kNear_m));
  glUniform1f(glGetUniformLocation(g.shadow, "u_far"), static_cast<float>(StereoRenderer::kFar_m));
  glUniform1f(glGetUniformLocation(g.shadow, "u_radius"), static_cast<float>(kShadowRadius_m));
  glUniform1f(glGetUniformLocation(g.shadow, "u_reach"), static_cast<float>(kShadowReach_m));
  glActiveTexture(GL_TEXTURE0);
  glBindVertexArray(g.empty_vao);
  glDisable(GL_DEPTH_TEST);
  glDepthMask(GL_FALSE);
  glEnable(GL_BLEND);
  glBlendFunc(GL_DST_COLOR, GL_ZERO);  // multiplies what is there
  if (!g.tiles_valid) {
    depth_tiles(g.scene_depth, g.depth_tiles);
    g.tiles_valid = true;
  }
  for (const glm::dvec3& tip_right : fingertips) {
    const glm::dvec3 tip = tip_right - p_RightEye;
    if (!finite(tip) || tip.z <= StereoRenderer::kNear_m + kShadowReach_m) continue;
    // The reach's ball on screen, a little generously (the ball's centre is nearer the eye than
    // the nearest point of the surface it shades), cut to the tiles whose depths reach into the
    // ball's: a hand in the air shades nothing and costs nothing.
    const double u = k.fx * tip.x / tip.z + k.cx, v = k.fy * tip.y / tip.z + k.cy;
    const double half = k.fx * kShadowReach_m / (tip.z - kShadowReach_m) + 2.0;
    const cv::Rect r = tiles_within(
        g.depth_tiles, cv::Rect2d(u - half, v - half, 2.0 * half + 1.0, 2.0 * half + 1.0),
        window_depth_of(tip.z - kShadowReach_m), window_depth_of(tip.z + kShadowReach_m));
    if (r.empty()) continue;
    const auto ndc = [](double px, int size) {
      return static_cast<float>(std::clamp(2.0 * px / size - 1.0, -1.0, 1.0));
    };
    glUniform4f(glGetUniformLocation(g.shadow, "u_rect"), ndc(r.x, k.width), ndc(r.y, k.height),
                ndc(r.br().x, k.width), ndc(r.br().y, k.height));
    g.upload_scene_depth();
    glUniform3f(glGetUniformLocation(g.shadow, "u_tip"), static_cast<float>(tip.x),
                static_cast<float>(tip.y), static_cast<float>(tip.z));
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  }
  glDisable(GL_BLEND);
  glDepthMask(GL_TRUE);
  glEnable(GL_DEPTH_TEST);
  glBindVertexArray(0);
}

void BodyPass::draw_body(const Intrinsics& k, const glm::dvec3& p_RightEye,
                         std::span<const Capsule> capsules, float exposure, int divisor) {
  Gl& g = *gl_;
  if (capsules.size() > kMaxCapsules) capsules = capsules.first(kMaxCapsules);
  const auto neighbours = blend_neighbours(capsules);
  g.instance_data.clear();
  g.around_eye.clear();
  g.caps.assign(capsules.size() * kCapsuleFloats, 0.0f);
  g.neighbours.assign(capsules.size() * kMaxBlendNeighbours, -1);
  for (std::size_t i = 0; i < capsules.size(); ++i) {
    const Capsule& c = capsules[i];
    const glm::dvec3 a = c.a - p_RightEye, b = c.b - p_RightEye;
    const double ra = c.radius_m, rb = radius_b(c);
    if (!(ra > 0.0) || !(rb > 0.0) || !std::isfinite(ra + rb) || !finite(a) || !finite(b)) continue;
    const auto fa = f3(a), fb = f3(b);
    float* cap = g.caps.data() + i * kCapsuleFloats;
    std::copy(fa.begin(), fa.end(), cap);
    cap[3] = static_cast<float>(ra);
    std::copy(fb.begin(), fb.end(), cap + 4);
    cap[7] = static_cast<float>(rb);
    cap[8] = c.bgr[2] / 255.0f;
    cap[9] = c.bgr[1] / 255.0f;
    cap[10] = c.bgr[0] / 255.0f;
    cap[11] = c.lit ? 1.0f : 0.0f;
    std::copy(neighbours[i].begin(), neighbours[i].end(),
              g.neighbours.begin() + static_cast<std::ptrdiff_t>(i * kMaxBlendNeighbours));
    Instance in{
        fa, fb, {static_cast<float>(ra), static_cast<float>(rb)}, static_cast<std::int32_t>(i)};
    (box_near_eye(a, b, std::max(ra, rb)) ? g.around_eye : g.instance_data).push_back(in);
  }
  const std::size_t outside = g.instance_data.size();
  g.instance_data.insert(g.instance_data.end(), g.around_eye.begin(), g.around_eye.end());
  if (g.instance_data.empty()) return;
  if (divisor > 1 && !g.upsample) g.upsample = std::make_unique<BodyUpsample>();
  const Intrinsics k_body = divisor > 1 ? g.upsample->begin(k, divisor) : k;
  const glm::mat4 projection =
      projection_from_intrinsics(k_body, StereoRenderer::kNear_m, StereoRenderer::kFar_m);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glUseProgram(g.body);
  glUniformMatrix4fv(glGetUniformLocation(g.body, "u_projection"), 1, GL_FALSE,
                     glm::value_ptr(projection));
  glUniform1f(glGetUniformLocation(g.body, "u_near"), static_cast<float>(StereoRenderer::kNear_m));
  glUniform1f(glGetUniformLocation(g.body, "u_far"), static_cast<float>(StereoRenderer::kFar_m));
  glUniform1f(glGetUniformLocation(g.body, "u_exposure"), exposure);
  glBindBuffer(GL_UNIFORM_BUFFER, g.ubo);
  glBufferSubData(GL_UNIFORM_BUFFER, 0, static_cast<GLsizeiptr>(g.caps.size() * sizeof(float)),
                  g.caps.data());
  glBindBufferBase(GL_UNIFORM_BUFFER, 0, g.ubo);
  glBindBuffer(GL_UNIFORM_BUFFER, g.neighbours_ubo);
  glBufferSubData(GL_UNIFORM_BUFFER, 0,
                  static_cast<GLsizeiptr>(g.neighbours.size() * sizeof(std::int32_t)),
                  g.neighbours.data());
  glBindBufferBase(GL_UNIFORM_BUFFER, 1, g.neighbours_ubo);
  glBindBuffer(GL_ARRAY_BUFFER, g.instances);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.instance_data.size() * sizeof(Instance)),
               g.instance_data.data(), GL_STREAM_DRAW);
  glBindVertexArray(g.vao);
  // The projection turns y down, which mirrors the winding: faces toward the eye arrive
  // clockwise, as GL's back faces.
  glEnable(GL_CULL_FACE);
  if (outside > 0) {
    glCullFace(GL_FRONT);
    glDrawArraysInstanced(GL_TRIANGLES, 0, g.vertices, static_cast<GLsizei>(outside));
  }
  if (g.instance_data.size() > outside) {
    // Rebound from the first of them: a 3.3 context has no base instance.
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.around_eye.size() * sizeof(Instance)),
                 g.around_eye.data(), GL_STREAM_DRAW);
    glCullFace(GL_BACK);
    glDrawArraysInstanced(GL_TRIANGLES, 0, g.vertices, static_cast<GLsizei>(g.around_eye.size()));
  }
  glDisable(GL_CULL_FACE);
  glBindVertexArray(0);
  if (divisor > 1) {
    if (g.has_scene_depth) g.upload_scene_depth();
    // Tiles of 32 eye pixels: most of the bounding rectangle of two arms reaching in holds no
    // body, and the composite costs llvmpipe some 20 ns per pixel it covers.
    g.upsample->composite(divisor, body_tiles_px(k, p_RightEye, capsules, divisor + 1, 32),
                          g.has_scene_depth ? g.depth_tex : 0);
  }
}

}  // namespace telex::local
