// SPDX-License-Identifier: MIT
// The body at a fraction of the eye's resolution: its sphere tracing is most of an eye's cost on
// llvmpipe and scales with the pixels it covers, so a 1280x720 eye marches it at 640x360 into an
// offscreen target and composites that over the eye, each low-resolution sample tested against
// the remote depth at the full-resolution pixel (a finger stays hidden exactly where the real
// scene is nearer) and the kept ones blended bilinearly (the silhouette's edge comes out smooth).
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "body_pass.h"
#include "gl_program.h"

namespace telex::local {
namespace {

// The four low-resolution samples around this pixel, each kept only where it holds body nearer
// than the remote scene here, weighted bilinearly: premultiplied colour, blended over the eye.
// Most pixels of the bounds hold no body: one filtered read of the coverage discards them first
// (llvmpipe leaves a block of pixels once all are discarded).
constexpr const char* kCompositeFs = R"(#version 330 core
uniform sampler2D u_body_color;  // rgb, a = 1 where the body is; filtered linearly
uniform sampler2D u_body_depth;  // window depths, 1 where no body
uniform sampler2D u_scene_depth; // this eye's remote depth as window depths, full resolution
uniform bool u_has_scene;
uniform float u_divisor;
out vec4 o_color;
void main() {
  ivec2 size = textureSize(u_body_color, 0);
  if (u_divisor == 1.0) {  // one sample per pixel: the body's own, no blend
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 c = texelFetch(u_body_color, p, 0);
    if (c.a < 0.5) discard;
    float scene = u_has_scene ? texelFetch(u_scene_depth, p, 0).r : 1.0;
    if (texelFetch(u_body_depth, p, 0).r >= scene) discard;
    o_color = vec4(c.rgb, 1.0);
    return;
  }
  vec4 any = texture(u_body_color, gl_FragCoord.xy / (u_divisor * vec2(size)));
  if (any.a < 0.5 / 255.0) discard;
  float scene = u_has_scene ? texelFetch(u_scene_depth, ivec2(gl_FragCoord.xy), 0).r : 1.0;
  vec2 q = gl_FragCoord.xy / u_divisor - 0.5;
  ivec2 i0 = ivec2(floor(q));
  vec2 f = q - vec2(i0);
  vec4 sum = vec4(0.0);
  for (int k = 0; k < 4; ++k) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = clamp(i0 + o, ivec2(0), size - 1);
    vec2 w2 = mix(1.0 - f, f, vec2(o));
    vec4 c = texelFetch(u_body_color, t, 0);
    float d = texelFetch(u_body_depth, t, 0).r;
    if (c.a > 0.5 && d < scene) sum += w2.x * w2.y * vec4(c.rgb, 1.0);
  }
  if (sum.a < 0.5 / 255.0) discard;
  o_color = sum;
}
)";

}  // namespace

cv::Rect body_bounds_px(const Intrinsics& k, const glm::dvec3& p_RightEye,
                        std::span<const Capsule> capsules, int pad_px) {
  const cv::Rect all(0, 0, k.width, k.height);
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const Capsule& c : capsules) {
    const double rb = c.radius_b_m < 0.0 ? c.radius_m : c.radius_b_m;
    if (!(c.radius_m > 0.0) || !(rb > 0.0) || !std::isfinite(c.radius_m + rb)) continue;
    // A ball round each end holding the box's corners; the box lies in the hull of the two, and
    // the hull's image in the hull of theirs.
    const double reach = (std::max(c.radius_m, rb) * 1.2 + 5e-4) * std::sqrt(3.0);
    // The capsule's points in front of the near plane lie within `reach` of the segment's part
    // with z >= near - reach: clipped to it, and each end's box cut at the near plane.
    glm::dvec3 a = c.a - p_RightEye, b = c.b - p_RightEye;
    if (!std::isfinite(a.x + a.y + a.z + b.x + b.y + b.z)) continue;
    const double z_cut = kViewNear_m - reach;
    if (a.z < z_cut && b.z < z_cut) continue;
    if (a.z < z_cut) a += (b - a) * ((z_cut - a.z) / (b.z - a.z));
    if (b.z < z_cut) b += (a - b) * ((z_cut - b.z) / (a.z - b.z));
    for (const glm::dvec3& p : {a, b})
      for (const double z : {p.z - reach, p.z + reach})
        for (const double s : {-1.0, 1.0}) {
          const double z_in = std::max(z, kViewNear_m);
          const double u = k.fx * (p.x + s * reach) / z_in + k.cx;
          const double v = k.fy * (p.y + s * reach) / z_in + k.cy;
          x0 = std::min(x0, u);
          x1 = std::max(x1, u);
          y0 = std::min(y0, v);
          y1 = std::max(y1, v);
        }
  }
  if (x0 > x1) return {};
  const auto clamp = [](double v, int hi) {
    return static_cast<int>(std::clamp(v, -1.0, hi + 1.0));
  };
  const int left = clamp(std::floor(x0) - pad_px, k.width),
            top = clamp(std::floor(y0) - pad_px, k.height);
  const int right = clamp(std::ceil(x1) + pad_px + 1, k.width),
            bottom = clamp(std::ceil(y1) + pad_px + 1, k.height);
  return cv::Rect(left, top, right - left, bottom - top) & all;
}

std::vector<cv::Rect> body_tiles_px(const Intrinsics& k, const glm::dvec3& p_RightEye,
                                    std::span<const Capsule> capsules, int pad_px, int tile_px) {
  std::vector<cv::Rect> out;
  if (tile_px < 1 || k.width <= 0 || k.height <= 0) return out;
  const int cols = (k.width + tile_px - 1) / tile_px, rows = (k.height + tile_px - 1) / tile_px;
  cv::Mat1b covered(rows, cols, std::uint8_t{0});
  for (const Capsule& c : capsules) {
    const cv::Rect r = body_bounds_px(k, p_RightEye, std::span<const Capsule>(&c, 1), pad_px);
    if (r.empty()) continue;
    covered(cv::Range(r.y / tile_px, (r.br().y - 1) / tile_px + 1),
            cv::Range(r.x / tile_px, (r.br().x - 1) / tile_px + 1))
        .setTo(1);
  }
  const cv::Rect all(0, 0, k.width, k.height);
  // Rectangles still growing down: out's indices of those ending on the row above.
  std::vector<std::size_t> open, next;
  for (int ty = 0; ty < rows; ++ty) {
    next.clear();
    const std::uint8_t* row = covered.ptr<std::uint8_t>(ty);
    for (int tx = 0; tx < cols;) {
      if (!row[tx]) {
        ++tx;
        continue;
      }
      const int start = tx;
      while (tx < cols && row[tx]) ++tx;
      const cv::Rect run =
          cv::Rect(start * tile_px, ty * tile_px, (tx - start) * tile_px, tile_px) & all;
      const auto same = std::find_if(open.begin(), open.end(), [&](std::size_t i) {
        return out[i].x == run.x && out[i].width == run.width;
      });
      if (same != open.end()) {
        out[*same].height = run.br().y - out[*same].y;
        next.push_back(*same);
      } else {
        next.push_back(out.size());
        out.push_back(run);
      }
    }
    open.swap(next);
  }
  return out;
}

struct BodyUpsample::Gl {
  GLuint program = 0, vao = 0, fbo = 0, color = 0, depth = 0;
  int width = 0, height = 0;  // the low-resolution target's
  GLint outer_fbo = 0;
  EGLContext context = EGL_NO_CONTEXT;  // the objects' own
  std::array<GLint, 4> outer_viewport{};
};

BodyUpsample::BodyUpsample() : gl_(std::make_unique<Gl>()) {
  gl_->program = link_program(kRectVertexShader, kCompositeFs, "stereo view: body composite");
  glGenVertexArrays(1, &gl_->vao);
  gl_->context = eglGetCurrentContext();
}

BodyUpsample::~BodyUpsample() {
  Gl& g = *gl_;
  // Deleted only in their own context; otherwise they go with it.
  if (g.context == EGL_NO_CONTEXT || eglGetCurrentContext() != g.context) return;
  glDeleteProgram(g.program);
  glDeleteVertexArrays(1, &g.vao);
  glDeleteFramebuffers(1, &g.fbo);
  const GLuint textures[] = {g.color, g.depth};
  glDeleteTextures(2, textures);
}

Intrinsics BodyUpsample::begin(const Intrinsics& k, int divisor) {
  Gl& g = *gl_;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &g.outer_fbo);
  glGetIntegerv(GL_VIEWPORT, g.outer_viewport.data());
  const int w = (k.width + divisor - 1) / divisor, h = (k.height + divisor - 1) / divisor;
  if (w != g.width || h != g.height) {
    glDeleteFramebuffers(1, &g.fbo);
    const GLuint old[] = {g.color, g.depth};
    glDeleteTextures(2, old);
    g.color = make_texture(GL_RGBA8, w, h, GL_RGBA, GL_UNSIGNED_BYTE, GL_LINEAR);
    g.depth = make_texture(GL_DEPTH_COMPONENT32F, w, h, GL_DEPTH_COMPONENT, GL_FLOAT, GL_NEAREST);
    glGenFramebuffers(1, &g.fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, g.color, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, g.depth, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("stereo view: the body's offscreen framebuffer is incomplete");
    g.width = w;
    g.height = h;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  glViewport(0, 0, w, h);
  const GLfloat clear[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  glClearBufferfv(GL_COLOR, 0, clear);
  const GLfloat far_plane = 1.0f;
  glClearBufferfv(GL_DEPTH, 0, &far_plane);
  // Pixel i of the low-resolution target covers eye pixels [i d, (i + 1) d): its centre is eye
  // pixel (i + 0.5) d - 0.5.
  Intrinsics low = k;
  const double d = divisor;
  low.fx = k.fx / d;
  low.fy = k.fy / d;
  low.cx = (k.cx + 0.5) / d - 0.5;
  low.cy = (k.cy + 0.5) / d - 0.5;
  low.width = w;
  low.height = h;
  return low;
}

void BodyUpsample::end() {
  Gl& g = *gl_;
  glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(g.outer_fbo));
  const auto& vp = g.outer_viewport;
  glViewport(vp[0], vp[1], vp[2], vp[3]);
}

void BodyUpsample::composite(int divisor, std::span<const cv::Rect> areas_px,
                             unsigned scene_depth) {
  Gl& g = *gl_;
  if (areas_px.empty() || g.color == 0) return;
  std::array<GLint, 4> vp{};
  glGetIntegerv(GL_VIEWPORT, vp.data());
  glUseProgram(g.program);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, g.color);
  glActiveTexture(GL_TEXTURE1);
  glBindTexture(GL_TEXTURE_2D, g.depth);
  glActiveTexture(GL_TEXTURE2);
  glBindTexture(GL_TEXTURE_2D, scene_depth);
  glUniform1i(glGetUniformLocation(g.program, "u_body_color"), 0);
  glUniform1i(glGetUniformLocation(g.program, "u_body_depth"), 1);
  glUniform1i(glGetUniformLocation(g.program, "u_scene_depth"), 2);
  glUniform1i(glGetUniformLocation(g.program, "u_has_scene"), scene_depth != 0 ? 1 : 0);
  glUniform1f(glGetUniformLocation(g.program, "u_divisor"), static_cast<float>(divisor));
  glBindVertexArray(g.vao);
  glDisable(GL_DEPTH_TEST);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  const GLint rect = glGetUniformLocation(g.program, "u_rect");
  const auto ndc = [](int px, int size) { return static_cast<float>(2.0 * px / size - 1.0); };
  for (const cv::Rect& area : areas_px) {
    const cv::Rect r = area & cv::Rect(0, 0, vp[2], vp[3]);
    if (r.empty()) continue;
    glUniform4f(rect, ndc(r.x, vp[2]), ndc(r.y, vp[3]), ndc(r.x + r.width, vp[2]),
                ndc(r.y + r.height, vp[3]));
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  }
  glDisable(GL_BLEND);
  glEnable(GL_DEPTH_TEST);
  glBindVertexArray(0);
  glActiveTexture(GL_TEXTURE0);
}

}  // namespace telex::local
