// SPDX-License-Identifier: MIT
// The OpenGL contexts an OpenXR session can be bound to: a headless EGL one (XR_MNDX_egl_enable,
// as Monado and the project's runtime offer) or a GLX one on the X server (XR_KHR_opengl_enable's
// Xlib binding, which SteamVR needs). Either is made current on the calling thread, where the
// stereo view then draws (StereoView::use_current_context).
#pragma once

#include <memory>
#include <string>

namespace telex::local {

struct EglHandles {
  void* display = nullptr;  // EGLDisplay
  void* config = nullptr;   // EGLConfig
  void* context = nullptr;  // EGLContext
};

struct GlxHandles {
  void* x_display = nullptr;    // Display*
  unsigned long visual_id = 0;  // the config's X visual
  void* fb_config = nullptr;    // GLXFBConfig
  unsigned long drawable = 0;   // GLXDrawable (a 1x1 pbuffer)
  void* context = nullptr;      // GLXContext
};

// A headless EGL context, OpenGL 3.3 core or above, current on the creating thread. Throws
// std::runtime_error naming what is missing.
class EglContext {
 public:
  EglContext();
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;
  const EglHandles& handles() const { return h_; }

 private:
  EglHandles h_;
};

// A GLX context on $DISPLAY, OpenGL 3.3 core, current on the creating thread with a 1x1 pbuffer.
// Throws std::runtime_error naming what is missing (no X display, no GLX 1.3, no 3.3 context).
class GlxContext {
 public:
  GlxContext();
  ~GlxContext();
  GlxContext(const GlxContext&) = delete;
  GlxContext& operator=(const GlxContext&) = delete;
  const GlxHandles& handles() const { return h_; }

 private:
  GlxHandles h_;
};

}  // namespace telex::local
