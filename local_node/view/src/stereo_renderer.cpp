// SPDX-License-Identifier: MIT
// The stereo view's renderer: a headless EGL context (Mesa's surfaceless platform) and an
// offscreen framebuffer whose colour and depth textures are loaded with the eye's image and the
// remote depth (as window depths) before the body's capsules are drawn over them. Rows run
// top-down in every buffer (the projection flips y), so nothing is flipped on the way in or out.
#include "telex/local/view/stereo_renderer.h"

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

#include "body_pass.h"
#include "egl_headless.h"

namespace telex::local {
namespace {

std::string egl_error(const char* what) { return local::egl_error("stereo view", what); }

}  // namespace

std::vector<Capsule> body_capsules(const BodyState& body,
                                   const std::function<glm::dvec3(const glm::dvec3&)>& to_right_eye,
                                   cv::Vec3b skin) {
  std::vector<Capsule> out;
  for (const ArmState& arm : body.arms) {
    if (!arm.visible) continue;
    const auto cap = [&](const glm::dvec3& a, const glm::dvec3& b, double ra, double rb) {
      out.push_back({to_right_eye(a), to_right_eye(b), ra, skin, true, rb});
    };
    // Each arm segment in two, so that the long part, large on screen, blends with one neighbour
    // only and the short one by the wrist with the palm's fan.
    const glm::dvec3 p_wrist_joint = arm.wrist + 0.2 * (arm.elbow - arm.wrist);
    cap(arm.shoulder, arm.elbow, 0.045, 0.038);
    cap(arm.elbow, p_wrist_joint, 0.036, 0.028);
    cap(p_wrist_joint, arm.wrist, 0.028, 0.026);
    // Radii at the knuckle, the two finger joints and the tip (the thumb 15 % fuller); each
    // joint's ball is a little fuller than the bones it joins.
    constexpr std::array<double, 4> kFinger{0.0095, 0.0085, 0.0078, 0.0068};
    constexpr double kKnuckle = 1.06, kThumb = 1.15;
    for (std::size_t f = 0; f < arm.hand.joints.size(); ++f) {
      const auto& finger = arm.hand.joints[f];
      const double scale = f == 0 ? kThumb : 1.0;
      cap(arm.wrist, finger[0], 0.02, 0.013 * scale);
      for (std::size_t s = 0; s < 3; ++s) {
        const double r = kFinger[s] * scale;
        cap(finger[s], finger[s], r * kKnuckle, r * kKnuckle);
        cap(finger[s], finger[s + 1], r, kFinger[s + 1] * scale);
      }
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
  GLuint blit_fbo = 0;    // blit_to's draw framebuffer
  GLuint source_fbo = 0;  // EyeView::background_texture's, to copy it in
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;
  GLuint fbo = 0, color_tex = 0;  // the eye's picture
  // The eye's depth buffer: the remote depth, loaded when the body mesh is drawn into the eye.
  GLuint depth_tex = 0;
  std::vector<float> window_depth;  // by depth in mm
  cv::Mat1f depth_upload;
  std::unique_ptr<BodyPass> body;
  int body_divisor = 0;  // 0: by the eye's width
  BodyShape body_shape = BodyShape::Mesh;
  cv::Mat4b readback;
  // A turned eye's capsules and fingertips in its own frame (EyeView::R_EyeRight), kept for reuse.
  std::vector<Capsule> turned_capsules;
  std::vector<glm::dvec3> turned_tips;

  void init_egl() {
    const HeadlessEgl egl = create_headless_egl("stereo view");
    display = egl.display;
    context = egl.context;
    const EGLConfig config = egl.config;
    // Rendering goes to our own framebuffer; a 1x1 pbuffer only gives the context a surface
    // where surfaceless contexts are not supported.
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
      const EGLint pbuffer_attribs[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
      surface = eglCreatePbufferSurface(display, config, pbuffer_attribs);
      if (surface == EGL_NO_SURFACE || !eglMakeCurrent(display, surface, surface, context))
        throw std::runtime_error(egl_error("cannot make the OpenGL context current"));
    }
  }

  // The context current and the eye's framebuffer bound; throws on an eye of another size.
  void begin(const Intrinsics& k);
  void make_current();

  void init_gl() {
    const auto texture = [](GLuint& t) {
      glGenTextures(1, &t);
      glBindTexture(GL_TEXTURE_2D, t);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    };
    texture(color_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, width, height, 0, GL_BGRA, GL_UNSIGNED_BYTE, nullptr);
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color_tex, 0);
    texture(depth_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, width, height, 0, GL_DEPTH_COMPONENT,
                 GL_FLOAT, nullptr);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_tex, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw std::runtime_error("stereo view: the offscreen framebuffer is incomplete");
    // Window depth of each depth value in mm (0: no data, the far plane).
    window_depth.resize(65536);
    window_depth[0] = 1.0f;
    for (std::size_t mm = 1; mm < window_depth.size(); ++mm) {
      const double z = std::clamp(static_cast<double>(mm) * 1e-3, kViewNear_m, kViewFar_m);
      const double ndc = (kViewFar_m + kViewNear_m) / (kViewFar_m - kViewNear_m) -
                         2.0 * kViewFar_m * kViewNear_m / ((kViewFar_m - kViewNear_m) * z);
      window_depth[mm] = static_cast<float>(ndc * 0.5 + 0.5);
    }
    body = std::make_unique<BodyPass>();
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
    const GLuint fbos[] = {g.fbo, g.blit_fbo, g.source_fbo};
    glDeleteFramebuffers(3, fbos);
    g.body.reset();  // the body pass's programs and buffers
    return;
  }
  if (impl_->display == EGL_NO_DISPLAY) return;
  // Only this renderer's own context is released: another one made since stays current.
  if (eglGetCurrentContext() == impl_->context)
    eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  if (impl_->surface != EGL_NO_SURFACE) eglDestroySurface(impl_->display, impl_->surface);
  if (impl_->context != EGL_NO_CONTEXT) eglDestroyContext(impl_->display, impl_->context);
  // No eglTerminate: the display is shared with any other renderer in the process.
}

void StereoRenderer::set_body_divisor(int divisor) {
  if (divisor < 0 || divisor > 8)
    throw std::invalid_argument("stereo view: body divisor " + std::to_string(divisor) +
                                " is not in 0..8");
  impl_->body_divisor = divisor;
}

void StereoRenderer::set_body_shape(BodyShape shape) {
  impl_->body_shape = shape;
  impl_->body->set_shape(shape);
}

void StereoRenderer::set_count_body_fragments(bool on) { impl_->body->set_counting(on); }
BodyFragments StereoRenderer::body_fragments() const { return impl_->body->last_body_fragments(); }

std::string StereoRenderer::gl_renderer() const {
  const auto* s = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return s ? s : "";
}

void StereoRenderer::Impl::make_current() {
  // With two renderers on a thread, the one drawing needs its own context current.
  if (own_context && eglGetCurrentContext() != context &&
      !eglMakeCurrent(display, surface, surface, context))
    throw std::runtime_error(egl_error("cannot make the OpenGL context current"));
}

void StereoRenderer::Impl::begin(const Intrinsics& k) {
  if (k.width != width || k.height != height)
    throw std::invalid_argument("stereo view: eye intrinsics are " + std::to_string(k.width) + "x" +
                                std::to_string(k.height) + ", the renderer " +
                                std::to_string(width) + "x" + std::to_string(height));
  make_current();
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, width, height);
}

cv::Mat3b StereoRenderer::render(const EyeView& eye, std::span<const Capsule> capsules) {
  draw_body_layer(0, eye, capsules, exposure_from_image(eye.background));  // 1 with none
  return compose(0, eye);
}

void StereoRenderer::draw_body_layer(int slot, const EyeView& eye,
                                     std::span<const Capsule> capsules, float exposure) {
  Impl& g = *impl_;
  g.begin(eye.k);
  // A turned eye: the capsules re-expressed in its frame (its centre the origin).
  glm::dvec3 p_RightEye = eye.p_RightEye;
  if (eye.R_EyeRight != glm::dmat3(1.0)) {
    g.turned_capsules.assign(capsules.begin(), capsules.end());
    for (Capsule& c : g.turned_capsules) {
      c.a = eye.R_EyeRight * (c.a - eye.p_RightEye);
      c.b = eye.R_EyeRight * (c.b - eye.p_RightEye);
    }
    capsules = g.turned_capsules;
    p_RightEye = glm::dvec3(0.0);
  }
  // The mesh costs little per pixel: drawn at the eye's size unless asked otherwise.
  const int divisor = g.body_divisor > 0                ? g.body_divisor
                      : g.body_shape == BodyShape::Mesh ? 1
                                                        : std::max(1, g.width / 640);
  g.body->draw_body(slot, eye.k, p_RightEye, capsules, exposure, divisor);
}

void StereoRenderer::finish() {
  impl_->make_current();
  glFinish();
}

cv::Mat3b StereoRenderer::compose(int slot, const EyeView& eye) {
  Impl& g = *impl_;
  g.begin(eye.k);
  const cv::Size size(g.width, g.height);
  const bool has_color = !eye.background.empty();
  const bool has_depth = !eye.depth_mm.empty();
  if ((has_color && eye.background.size() != size) || (has_depth && eye.depth_mm.size() != size))
    throw std::invalid_argument("stereo view: the eye's image or depth is not the eye's size");

  // The eye's image straight into the framebuffer's texture.
  if (eye.background_texture != 0) {
    // Already in this context (the warp's output): copied on the GPU, no read-back and upload.
    if (!g.source_fbo) glGenFramebuffers(1, &g.source_fbo);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, g.source_fbo);
    glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D,
                           eye.background_texture, 0);
    glBlitFramebuffer(0, 0, g.width, g.height, 0, 0, g.width, g.height, GL_COLOR_BUFFER_BIT,
                      GL_NEAREST);
    glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, 0, 0);
    glBindFramebuffer(GL_FRAMEBUFFER, g.fbo);
  } else if (has_color) {
    // BGR as it is: Mesa packs it into the RGBA8 texture faster than OpenCV adds the alpha
    // first (0.4 ms an eye less at 1280x720 on llvmpipe).
    const cv::Mat3b bgr = eye.background.isContinuous() ? eye.background : eye.background.clone();
    glBindTexture(GL_TEXTURE_2D, g.color_tex);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, g.width, g.height, GL_BGR, GL_UNSIGNED_BYTE, bgr.data);
  } else {
    const GLfloat grey[4] = {0.25f, 0.25f, 0.25f, 1.0f};
    glClearBufferfv(GL_COLOR, 0, grey);
  }
  // The remote depth as window depths: the contact shadows and the body's composite test it
  // (uploaded by the body pass only where they read it).
  if (has_depth) {
    g.depth_upload.create(size);
    for (int y = 0; y < g.height; ++y) {
      const std::uint16_t* in = eye.depth_mm.ptr<std::uint16_t>(y);
      float* out = g.depth_upload.ptr<float>(y);
      for (int x = 0; x < g.width; ++x) out[x] = g.window_depth[in[x]];
    }
  }
  glDisable(GL_CULL_FACE);

  g.body->set_scene_depth(has_depth ? g.depth_upload : cv::Mat1f());
  // A turned eye: its fingertips re-expressed in its frame (its centre the origin).
  glm::dvec3 p_RightEye = eye.p_RightEye;
  std::span<const glm::dvec3> fingertips = eye.fingertips;
  if (eye.R_EyeRight != glm::dmat3(1.0)) {
    g.turned_tips.clear();
    for (const glm::dvec3& p : eye.fingertips)
      g.turned_tips.push_back(eye.R_EyeRight * (p - eye.p_RightEye));
    fingertips = g.turned_tips;
    p_RightEye = glm::dvec3(0.0);
  }
  g.body->draw_contact_shadows(eye.k, p_RightEye, fingertips);
  // The body, hidden where the remote scene is nearer: drawn into the eye with the remote depth
  // in its depth buffer, or composited from its own target.
  if (g.body->draws_into_target(slot)) {
    if (has_depth) {
      glBindTexture(GL_TEXTURE_2D, g.depth_tex);
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, g.width, g.height, GL_DEPTH_COMPONENT, GL_FLOAT,
                      g.depth_upload.data);
    } else {
      const GLfloat far = 1.0f;
      glClearBufferfv(GL_DEPTH, 0, &far);
    }
  }
  g.body->composite_body(slot);

  if (!eye.read_back) return {};
  // Read as BGRA and dropped to BGR by OpenCV: reading GL_BGR straight is slower on llvmpipe.
  g.readback.create(size);
  glReadPixels(0, 0, g.width, g.height, GL_BGRA, GL_UNSIGNED_BYTE, g.readback.data);
  cv::Mat3b out;
  cv::cvtColor(g.readback, out, cv::COLOR_BGRA2BGR);
  return out;
}

}  // namespace telex::local
