// SPDX-License-Identifier: MIT
// The body pass: the body as triangles (BodyMesh), or as the reference, round cones joined by a
// smooth minimum and sphere-traced once per pixel over the capsules of its screen tile; lit to the
// video's brightness; and the fingertips' contact shadows on the remote scene.
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

bool finite(const glm::dvec3& v) { return std::isfinite(v.x + v.y + v.z); }

}  // namespace

struct BodyPass::Gl {
  GLuint body = 0, shadow = 0;
  GLuint vao = 0, tiles_vbo = 0, list_buffer = 0, list_tex = 0, caps_buffer = 0, caps_tex = 0;
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
  // Per slot (eye): its target, made on its first draw, and what composite_body needs of it.
  struct Slot {
    std::unique_ptr<BodyUpsample> target;
    std::vector<cv::Rect> areas_px;  // empty: nothing to composite
    int divisor = 1;
    // The mesh at the eye's size is drawn by composite_body straight into the eye's target,
    // depth-tested against the remote depth there: what it draws, kept until then.
    bool direct = false;
    std::vector<Capsule> capsules;
    Intrinsics k;
    glm::dvec3 p_RightEye{0.0};
    float exposure = 1.0f;
  };
  std::array<Slot, kSlots> slots;
  BodyTiles tiles;
  std::vector<float> caps;
  std::unique_ptr<BodyMesh> mesh;
  BodyShape shape = BodyShape::Mesh;
  // The samples that passed the depth test (for the mesh the fragments shaded: early depth,
  // opaque fragments) and, where the driver counts them, the fragment shader's runs (llvmpipe
  // counts every lane of the 4x4 blocks it runs the shader on).
  std::array<GLuint, 2> queries{};
  bool has_invocations = false;
  bool counting = false;
  BodyFragments fragments;
  // Around a body draw when counting: its fragment shader's runs into `fragments`.
  void begin_count();
  void end_count();
  // The ray-march into the bound target (k_body its intrinsics).
  void march(const Intrinsics& k_body, const glm::dvec3& p_RightEye,
             std::span<const Capsule> capsules, float exposure);
};

BodyPass::BodyPass() : gl_(std::make_unique<Gl>()) {
  Gl& g = *gl_;
  g.body = link_program(kBodyTilesVs, body_shader(kBodyTilesFs).c_str(), "stereo view: body");
  g.mesh = std::make_unique<BodyMesh>();
  glGenQueries(2, g.queries.data());
  g.has_invocations = epoxy_has_gl_extension("GL_ARB_pipeline_statistics_query");
  g.shadow = link_program(kRectVertexShader, kShadowFs, "stereo view: body");
  glGenVertexArrays(1, &g.vao);
  glGenVertexArrays(1, &g.empty_vao);
  glGenBuffers(1, &g.tiles_vbo);
  glGenBuffers(1, &g.list_buffer);
  glGenBuffers(1, &g.caps_buffer);
  glBindVertexArray(g.vao);
  glBindBuffer(GL_ARRAY_BUFFER, g.tiles_vbo);
  glVertexAttribIPointer(0, 4, GL_INT, 4 * sizeof(std::int32_t), nullptr);
  glEnableVertexAttribArray(0);
  glVertexAttribDivisor(0, 1);
  glBindVertexArray(0);
  glGenTextures(1, &g.list_tex);
  glGenTextures(1, &g.caps_tex);
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
  glUniform1f(glGetUniformLocation(g.shadow, "u_near"), static_cast<float>(kViewNear_m));
  glUniform1f(glGetUniformLocation(g.shadow, "u_far"), static_cast<float>(kViewFar_m));
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
    if (!finite(tip) || tip.z <= kViewNear_m + kShadowReach_m) continue;
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

void BodyPass::set_shape(BodyShape shape) { gl_->shape = shape; }
void BodyPass::set_counting(bool on) { gl_->counting = on; }
BodyFragments BodyPass::last_body_fragments() const { return gl_->fragments; }

void BodyPass::draw_body(int slot, const Intrinsics& k, const glm::dvec3& p_RightEye,
                         std::span<const Capsule> capsules, float exposure, int divisor) {
  Gl& g = *gl_;
  if (slot < 0 || slot >= kSlots)
    throw std::invalid_argument("stereo view: body slot out of range");
  Gl::Slot& s = g.slots[static_cast<std::size_t>(slot)];
  s.areas_px.clear();
  s.capsules.clear();
  s.divisor = std::max(1, divisor);
  g.fragments = {};
  if (capsules.size() > kMaxCapsules) capsules = capsules.first(kMaxCapsules);
  s.direct = g.shape == BodyShape::Mesh && s.divisor == 1;
  if (s.direct) {
    s.capsules.assign(capsules.begin(), capsules.end());
    s.k = k;
    s.p_RightEye = p_RightEye;
    s.exposure = exposure;
    return;
  }
  if (capsules.empty()) return;
  if (!s.target) s.target = std::make_unique<BodyUpsample>();
  const Intrinsics k_body = s.target->begin(k, s.divisor);
  g.begin_count();
  if (g.shape == BodyShape::Mesh)
    g.mesh->draw(k_body, p_RightEye, capsules, exposure);
  else
    g.march(k_body, p_RightEye, capsules, exposure);
  g.end_count();
  // Tiles of 32 eye pixels: most of the bounding rectangle of two arms reaching in holds no
  // body, and the composite costs llvmpipe some 20 ns per pixel it covers.
  s.areas_px = body_tiles_px(k, p_RightEye, capsules, s.divisor + 1, 32);
  s.target->end();
}

void BodyPass::Gl::begin_count() {
  fragments = {};
  if (!counting) return;
  glBeginQuery(GL_SAMPLES_PASSED, queries[0]);
  if (has_invocations) glBeginQuery(GL_FRAGMENT_SHADER_INVOCATIONS_ARB, queries[1]);
}

void BodyPass::Gl::end_count() {
  if (!counting) return;
  glEndQuery(GL_SAMPLES_PASSED);
  if (has_invocations) glEndQuery(GL_FRAGMENT_SHADER_INVOCATIONS_ARB);
  GLuint64 count = 0;
  glGetQueryObjectui64v(queries[0], GL_QUERY_RESULT, &count);
  fragments.passed = count;
  if (has_invocations) {
    glGetQueryObjectui64v(queries[1], GL_QUERY_RESULT, &count);
    fragments.invocations = count;
  }
}

bool BodyPass::draws_into_target(int slot) const {
  if (slot < 0 || slot >= kSlots) return false;
  const Gl::Slot& s = gl_->slots[static_cast<std::size_t>(slot)];
  return s.direct && !s.capsules.empty();
}

void BodyPass::Gl::march(const Intrinsics& k_body, const glm::dvec3& p_RightEye,
                         std::span<const Capsule> capsules, float exposure) {
  const auto neighbours = blend_neighbours(capsules);
  pack_capsules(capsules, p_RightEye, caps);
  // Tiles of 16 target pixels: smaller tiles have shorter lists but llvmpipe pays per quad; 8 and
  // 32 measured slower (4 much slower).
  constexpr int kTilePx = 16;
  bin_body_tiles(k_body, p_RightEye, capsules, neighbours, kTilePx, tiles);
  if (tiles.tiles.empty()) return;
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glUseProgram(body);
  glUniform2f(glGetUniformLocation(body, "u_size"), static_cast<float>(k_body.width),
              static_cast<float>(k_body.height));
  glUniform4f(glGetUniformLocation(body, "u_k"), static_cast<float>(k_body.fx),
              static_cast<float>(k_body.fy), static_cast<float>(k_body.cx),
              static_cast<float>(k_body.cy));
  glUniform1f(glGetUniformLocation(body, "u_near"), static_cast<float>(kViewNear_m));
  glUniform1f(glGetUniformLocation(body, "u_far"), static_cast<float>(kViewFar_m));
  glUniform1f(glGetUniformLocation(body, "u_exposure"), exposure);
  texture_buffer(caps_buffer, caps_tex, caps.data(), caps.size() * sizeof(float), GL_RGBA32F, 1,
                 glGetUniformLocation(body, "u_caps"));
  texture_buffer(list_buffer, list_tex, tiles.list.data(),
                 tiles.list.size() * sizeof(tiles.list[0]), GL_RG32I, 0,
                 glGetUniformLocation(body, "u_list"));
  glBindBuffer(GL_ARRAY_BUFFER, tiles_vbo);
  glBufferData(GL_ARRAY_BUFFER,
               static_cast<GLsizeiptr>(tiles.tiles.size() * sizeof(tiles.tiles[0])),
               tiles.tiles.data(), GL_STREAM_DRAW);
  glBindVertexArray(vao);
  glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(tiles.tiles.size()));
  glBindVertexArray(0);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_BUFFER, 0);
  glActiveTexture(GL_TEXTURE0);
}

void BodyPass::composite_body(int slot) {
  Gl& g = *gl_;
  if (slot < 0 || slot >= kSlots)
    throw std::invalid_argument("stereo view: body slot out of range");
  Gl::Slot& s = g.slots[static_cast<std::size_t>(slot)];
  if (s.direct) {
    if (s.capsules.empty()) return;
    g.begin_count();
    g.mesh->draw(s.k, s.p_RightEye, s.capsules, s.exposure);
    g.end_count();
    return;
  }
  if (s.areas_px.empty()) return;
  if (g.has_scene_depth) g.upload_scene_depth();
  s.target->composite(s.divisor, s.areas_px, g.has_scene_depth ? g.depth_tex : 0);
}

}  // namespace telex::local
