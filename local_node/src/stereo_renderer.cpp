// SPDX-License-Identifier: MIT
// The stereo view's renderer: a headless EGL context (Mesa's surfaceless platform) and an
// offscreen framebuffer whose colour and depth textures are loaded with the eye's image and the
// remote depth (as window depths) before the body's capsules are ray-cast over them. Rows run
// top-down in every buffer (the projection flips y), so nothing is flipped on the way in or out.
#include "telex/local/stereo_renderer.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace telex::local {
namespace {

// Capsules are ray-cast in the fragment shader over a box around each (12 triangles a capsule:
// Mesa's llvmpipe pays per triangle, and a tessellated arm and hand cost it 40 ms an eye). The
// box vertex shader places a unit cube's corner c in [0, 1]^3 around the segment a-b, radius r.
constexpr const char* kCapsuleVs = R"(#version 330 core
layout(location = 0) in vec3 a_corner;
layout(location = 1) in vec3 a_a;       // per instance, eye frame
layout(location = 2) in vec3 a_b;
layout(location = 3) in float a_radius;
layout(location = 4) in vec3 a_color;
uniform mat4 u_projection;
out vec3 v_position;
flat out vec3 v_a;
flat out vec3 v_b;
flat out float v_radius;
flat out vec3 v_color;
void main() {
  vec3 d = a_b - a_a;
  float len = length(d);
  vec3 axis = len > 1e-9 ? d / len : vec3(0.0, 0.0, 1.0);
  vec3 helper = abs(axis.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  vec3 u = normalize(cross(axis, helper));
  vec3 w = cross(axis, u);
  // A little larger than the capsule, so its silhouette is never cut by the box.
  float r = a_radius * 1.01;
  vec3 p = a_a + u * (a_corner.x * 2.0 - 1.0) * r + w * (a_corner.y * 2.0 - 1.0) * r +
           axis * (-r + a_corner.z * (len + 2.0 * r));
  v_position = p;
  v_a = a_a;
  v_b = a_b;
  v_radius = a_radius;
  v_color = a_color;
  gl_Position = u_projection * vec4(p, 1.0);
}
)";

// The eye sits at the origin; the ray through this fragment meets the capsule (Quilez's capsule
// intersection) or the fragment is discarded. Depth is the hit's, shading Lambert from the eye.
constexpr const char* kCapsuleFs = R"(#version 330 core
uniform float u_near;
uniform float u_far;
in vec3 v_position;
flat in vec3 v_a;
flat in vec3 v_b;
flat in float v_radius;
flat in vec3 v_color;
out vec4 o_color;
float sphere_hit(vec3 rd, vec3 c, float r) {
  float b = dot(rd, -c);
  float h = b * b - (dot(c, c) - r * r);
  return h < 0.0 ? -1.0 : -b - sqrt(h);
}
void main() {
  vec3 rd = normalize(v_position);
  vec3 ba = v_b - v_a;
  vec3 oa = -v_a;
  float baba = dot(ba, ba);
  float t = -1.0;
  if (baba > 1e-12) {
    float bard = dot(ba, rd);
    float baoa = dot(ba, oa);
    float a = baba - bard * bard;
    if (a > 1e-9 * baba) {
      float b = baba * dot(rd, oa) - baoa * bard;
      float c = baba * dot(oa, oa) - baoa * baoa - v_radius * v_radius * baba;
      float h = b * b - a * c;
      if (h >= 0.0) {
        float tb = (-b - sqrt(h)) / a;
        float y = baoa + tb * bard;
        if (y > 0.0 && y < baba) t = tb;
      }
    }
  }
  if (t < 0.0) {
    // The round ends: the nearer hit of the two spheres.
    float t1 = sphere_hit(rd, v_a, v_radius);
    float t2 = sphere_hit(rd, v_b, v_radius);
    t = t1 < 0.0 ? t2 : (t2 < 0.0 ? t1 : min(t1, t2));
  }
  if (t <= 0.0) discard;
  vec3 hit = rd * t;
  float k = baba > 1e-12 ? clamp(dot(hit - v_a, ba) / baba, 0.0, 1.0) : 0.0;
  vec3 n = normalize(hit - (v_a + k * ba));
  float lit = abs(dot(n, -rd));
  o_color = vec4(v_color * (0.35 + 0.65 * lit), 1.0);
  float z = clamp(hit.z, u_near, u_far);
  float ndc = (u_far + u_near) / (u_far - u_near) - 2.0 * u_far * u_near / ((u_far - u_near) * z);
  gl_FragDepth = ndc * 0.5 + 0.5;
}
)";

GLuint compile(GLenum type, const char* source) {
  const GLuint s = glCreateShader(type);
  glShaderSource(s, 1, &source, nullptr);
  glCompileShader(s);
  GLint ok = 0;
  glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetShaderInfoLog(s, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("stereo view: shader does not compile: ") + log);
  }
  return s;
}

GLuint link(const char* vs, const char* fs) {
  const GLuint p = glCreateProgram();
  const GLuint v = compile(GL_VERTEX_SHADER, vs), f = compile(GL_FRAGMENT_SHADER, fs);
  glAttachShader(p, v);
  glAttachShader(p, f);
  glLinkProgram(p);
  glDeleteShader(v);
  glDeleteShader(f);
  GLint ok = 0;
  glGetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048] = {};
    glGetProgramInfoLog(p, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("stereo view: shaders do not link: ") + log);
  }
  return p;
}

// One capsule as the box shader takes it: both ends in the eye's frame, radius, colour.
struct Instance {
  std::array<float, 3> a, b;
  float radius;
  std::array<float, 3> rgb;
};

// The unit cube's 12 triangles, instanced once per capsule.
struct Boxes {
  GLuint vao = 0, vbo = 0, instances = 0;
  GLsizei vertices = 0;
};

Boxes make_boxes() {
  const float c[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  const int faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4},
                           {3, 2, 6, 7}, {0, 3, 7, 4}, {1, 2, 6, 5}};
  std::vector<float> corners;
  for (const auto& f : faces)
    for (int k : {0, 1, 2, 0, 2, 3}) corners.insert(corners.end(), c[f[k]], c[f[k]] + 3);
  Boxes m;
  glGenVertexArrays(1, &m.vao);
  glGenBuffers(1, &m.vbo);
  glGenBuffers(1, &m.instances);
  glBindVertexArray(m.vao);
  glBindBuffer(GL_ARRAY_BUFFER, m.vbo);
  glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(corners.size() * sizeof(float)),
               corners.data(), GL_STATIC_DRAW);
  glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float), nullptr);
  glEnableVertexAttribArray(0);
  glBindBuffer(GL_ARRAY_BUFFER, m.instances);
  const auto attrib = [](GLuint loc, GLint n, std::size_t offset) {
    glVertexAttribPointer(loc, n, GL_FLOAT, GL_FALSE, sizeof(Instance),
                          reinterpret_cast<const void*>(offset));
    glEnableVertexAttribArray(loc);
    glVertexAttribDivisor(loc, 1);
  };
  attrib(1, 3, offsetof(Instance, a));
  attrib(2, 3, offsetof(Instance, b));
  attrib(3, 1, offsetof(Instance, radius));
  attrib(4, 3, offsetof(Instance, rgb));
  m.vertices = static_cast<GLsizei>(corners.size() / 3);
  glBindVertexArray(0);
  return m;
}

std::string egl_error(const char* what) {
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04x", eglGetError());
  return std::string("stereo view: ") + what + " (EGL error " + hex +
         "); the headless view needs Mesa's EGL (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri)";
}

}  // namespace

std::vector<Capsule> body_capsules(const BodyState& body,
                                   const std::function<glm::dvec3(const glm::dvec3&)>& to_right_eye,
                                   cv::Vec3b skin) {
  std::vector<Capsule> out;
  for (const ArmState& arm : body.arms) {
    if (!arm.visible) continue;
    const auto cap = [&](const glm::dvec3& a, const glm::dvec3& b, double r) {
      out.push_back({to_right_eye(a), to_right_eye(b), r, skin});
    };
    cap(arm.shoulder, arm.elbow, 0.045);
    cap(arm.elbow, arm.wrist, 0.035);
    constexpr std::array<double, 3> kPhalanx{0.009, 0.008, 0.007};
    for (const auto& finger : arm.hand.joints) {
      cap(arm.wrist, finger[0], 0.014);
      for (std::size_t s = 0; s < 3; ++s) cap(finger[s], finger[s + 1], kPhalanx[s]);
    }
  }
  return out;
}

glm::mat4 projection_from_intrinsics(const Intrinsics& k, double n, double f) {
  const double w = k.width, h = k.height;
  glm::dmat4 p(0.0);  // column-major: p[col][row]
  p[0][0] = 2.0 * k.fx / w;
  p[2][0] = (2.0 * k.cx + 1.0) / w - 1.0;
  p[1][1] = 2.0 * k.fy / h;
  p[2][1] = (2.0 * k.cy + 1.0) / h - 1.0;
  p[2][2] = (f + n) / (f - n);
  p[3][2] = -2.0 * f * n / (f - n);
  p[2][3] = 1.0;
  return glm::mat4(p);
}

struct StereoRenderer::Impl {
  int width = 0, height = 0;
  bool own_context = true;
  GLuint blit_fbo = 0;  // blit_to's draw framebuffer
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;
  GLuint fbo = 0, color_tex = 0, depth_tex = 0;
  GLuint capsule = 0;
  std::vector<float> window_depth;  // by depth in mm
  cv::Mat1f depth_upload;
  Boxes boxes;
  std::vector<Instance> instances;  // this frame's, reused
  cv::Mat4b color_upload, readback;

  void init_egl() {
    if (epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless"))
      display =
          eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (display == EGL_NO_DISPLAY) display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
    EGLint major = 0, minor = 0;
    if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor))
      throw std::runtime_error(egl_error("no EGL display"));
    if (!eglBindAPI(EGL_OPENGL_API)) throw std::runtime_error(egl_error("EGL has no OpenGL API"));
    const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                     EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configs = 0;
    if (!eglChooseConfig(display, config_attribs, &config, 1, &configs) || configs < 1)
      throw std::runtime_error(egl_error("no EGL config for OpenGL with a pbuffer"));
    const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                      3,
                                      EGL_CONTEXT_MINOR_VERSION,
                                      3,
                                      EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                      EGL_NONE};
    context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
    if (context == EGL_NO_CONTEXT)
      throw std::runtime_error(egl_error("no OpenGL 3.3 core context"));
    // Rendering goes to our own framebuffer; a 1x1 pbuffer only gives the context a surface
    // where surfaceless contexts are not supported.
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
      const EGLint pbuffer_attribs[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
      surface = eglCreatePbufferSurface(display, config, pbuffer_attribs);
      if (surface == EGL_NO_SURFACE || !eglMakeCurrent(display, surface, surface, context))
        throw std::runtime_error(egl_error("cannot make the OpenGL context current"));
    }
  }

  void init_gl() {
    const auto texture = [](GLuint& t) {
      glGenTextures(1, &t);
      glBindTexture(GL_TEXTURE_2D, t);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    };
    texture(color_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_BGRA, GL_UNSIGNED_BYTE, nullptr);
    texture(depth_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, width, height, 0, GL_DEPTH_COMPONENT,
                 GL_FLOAT, nullptr);
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color_tex, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_tex, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("stereo view: the offscreen framebuffer is incomplete");
    // Window depth of each depth value in mm (0: no data, the far plane).
    window_depth.resize(65536);
    window_depth[0] = 1.0f;
    for (std::size_t mm = 1; mm < window_depth.size(); ++mm) {
      const double z = std::clamp(static_cast<double>(mm) * 1e-3, kNear_m, kFar_m);
      const double ndc = (kFar_m + kNear_m) / (kFar_m - kNear_m) -
                         2.0 * kFar_m * kNear_m / ((kFar_m - kNear_m) * z);
      window_depth[mm] = static_cast<float>(ndc * 0.5 + 0.5);
    }
    capsule = link(kCapsuleVs, kCapsuleFs);
    boxes = make_boxes();
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
  }
};

StereoRenderer::StereoRenderer(int width, int height) : impl_(std::make_unique<Impl>()) {
  if (width <= 0 || height <= 0 || width > 8192 || height > 8192)
    throw std::invalid_argument("stereo view: eye size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not in 1..8192");
  impl_->width = width;
  impl_->height = height;
  impl_->init_egl();
  if (epoxy_gl_version() < 33)
    throw std::runtime_error("stereo view: OpenGL " + std::to_string(epoxy_gl_version()) +
                             " is below 3.3 core");
  impl_->init_gl();
}

StereoRenderer::StereoRenderer(int width, int height, UseCurrentContext)
    : impl_(std::make_unique<Impl>()) {
  if (width <= 0 || height <= 0 || width > 8192 || height > 8192)
    throw std::invalid_argument("stereo view: eye size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not in 1..8192");
  impl_->width = width;
  impl_->height = height;
  impl_->own_context = false;
  if (epoxy_gl_version() < 33)
    throw std::runtime_error("stereo view: OpenGL " + std::to_string(epoxy_gl_version()) +
                             " is below 3.3 core");
  impl_->init_gl();
}

void StereoRenderer::blit_to(unsigned texture, int width, int height) {
  Impl& g = *impl_;
  if (!g.blit_fbo) glGenFramebuffers(1, &g.blit_fbo);
  glBindFramebuffer(GL_READ_FRAMEBUFFER, g.fbo);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, g.blit_fbo);
  glFramebufferTexture2D(GL_DRAW_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0);
  // The values are sRGB-encoded already: copied as they are, whatever the target's format.
  glDisable(GL_FRAMEBUFFER_SRGB);
  glBlitFramebuffer(0, 0, g.width, g.height, 0, height, width, 0, GL_COLOR_BUFFER_BIT, GL_LINEAR);
  glFramebufferTexture2D(GL_DRAW_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, 0, 0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

StereoRenderer::~StereoRenderer() {
  if (!impl_->own_context) {  // the context stays: only this renderer's objects go
    Impl& g = *impl_;
    const GLuint textures[] = {g.color_tex, g.depth_tex};
    glDeleteTextures(2, textures);
    const GLuint fbos[] = {g.fbo, g.blit_fbo};
    glDeleteFramebuffers(2, fbos);
    const GLuint buffers[] = {g.boxes.vbo, g.boxes.instances};
    glDeleteBuffers(2, buffers);
    glDeleteVertexArrays(1, &g.boxes.vao);
    glDeleteProgram(g.capsule);
    return;
  }
  if (impl_->display == EGL_NO_DISPLAY) return;
  eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (impl_->surface != EGL_NO_SURFACE) eglDestroySurface(impl_->display, impl_->surface);
  if (impl_->context != EGL_NO_CONTEXT) eglDestroyContext(impl_->display, impl_->context);
  // No eglTerminate: the display is shared with any other renderer in the process.
}

std::string StereoRenderer::gl_renderer() const {
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return s ? s : "";
}

cv::Mat3b StereoRenderer::render(const EyeView& eye, std::span<const Capsule> capsules) {
  Impl& g = *impl_;
  if (eye.k.width != g.width || eye.k.height != g.height)
    throw std::invalid_argument("stereo view: eye intrinsics are " + std::to_string(eye.k.width) +
                                "x" + std::to_string(eye.k.height) + ", the renderer " +
                                std::to_string(g.width) + "x" + std::to_string(g.height));
  const cv::Size size(g.width, g.height);
  const bool has_color = !eye.background.empty();
  const bool has_depth = !eye.depth_mm.empty();
  if ((has_color && eye.background.size() != size) || (has_depth && eye.depth_mm.size() != size))
    throw std::invalid_argument("stereo view: the eye's image or depth is not the eye's size");

  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  glViewport(0, 0, g.width, g.height);
  // The eye's image and the remote depth straight into the framebuffer's textures.
  if (has_color) {
    cv::cvtColor(eye.background, g.color_upload, cv::COLOR_BGR2BGRA);
    glBindTexture(GL_TEXTURE_2D, g.color_tex);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, g.width, g.height, GL_BGRA, GL_UNSIGNED_BYTE,
                    g.color_upload.data);
  } else {
    const GLfloat grey[4] = {0.25f, 0.25f, 0.25f, 1.0f};
    glClearBufferfv(GL_COLOR, 0, grey);
  }
  if (has_depth) {
    g.depth_upload.create(size);
    for (int y = 0; y < g.height; ++y) {
      const std::uint16_t* in = eye.depth_mm.ptr<std::uint16_t>(y);
      float* out = g.depth_upload.ptr<float>(y);
      for (int x = 0; x < g.width; ++x) out[x] = g.window_depth[in[x]];
    }
    glBindTexture(GL_TEXTURE_2D, g.depth_tex);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, g.width, g.height, GL_DEPTH_COMPONENT, GL_FLOAT,
                    g.depth_upload.data);
  } else {
    const GLfloat far_plane = 1.0f;
    glClearBufferfv(GL_DEPTH, 0, &far_plane);
  }
  glEnable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);

  // The body, hidden where the remote scene is nearer.
  glDepthFunc(GL_LESS);
  glUseProgram(g.capsule);
  const glm::mat4 projection = projection_from_intrinsics(eye.k, kNear_m, kFar_m);
  glUniformMatrix4fv(glGetUniformLocation(g.capsule, "u_projection"), 1, GL_FALSE,
                     glm::value_ptr(projection));
  glUniform1f(glGetUniformLocation(g.capsule, "u_near"), static_cast<float>(kNear_m));
  glUniform1f(glGetUniformLocation(g.capsule, "u_far"), static_cast<float>(kFar_m));
  g.instances.clear();
  for (const Capsule& c : capsules) {
    const glm::dvec3 a = c.a - eye.p_RightEye, b = c.b - eye.p_RightEye;
    if (!(c.radius_m > 0.0) || !std::isfinite(c.radius_m) || !std::isfinite(a.x + a.y + a.z) ||
        !std::isfinite(b.x + b.y + b.z))
      continue;
    g.instances.push_back(
        {{static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z)},
         {static_cast<float>(b.x), static_cast<float>(b.y), static_cast<float>(b.z)},
         static_cast<float>(c.radius_m),
         {c.bgr[2] / 255.0f, c.bgr[1] / 255.0f, c.bgr[0] / 255.0f}});
  }
  if (!g.instances.empty()) {
    glBindBuffer(GL_ARRAY_BUFFER, g.boxes.instances);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(g.instances.size() * sizeof(Instance)),
                 g.instances.data(), GL_STREAM_DRAW);
    glBindVertexArray(g.boxes.vao);
    glDrawArraysInstanced(GL_TRIANGLES, 0, g.boxes.vertices,
                          static_cast<GLsizei>(g.instances.size()));
  }

  if (!eye.read_back) return {};
  g.readback.create(size);
  glReadPixels(0, 0, g.width, g.height, GL_BGRA, GL_UNSIGNED_BYTE, g.readback.data);
  cv::Mat3b out;
  cv::cvtColor(g.readback, out, cv::COLOR_BGRA2BGR);
  return out;
}

}  // namespace telex::local
