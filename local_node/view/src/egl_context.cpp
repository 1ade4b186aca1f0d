// SPDX-License-Identifier: MIT
// The headless EGL context an OpenXR session with XR_MNDX_egl_enable is bound to.
#include <epoxy/egl.h>

#include <stdexcept>

#include "egl_headless.h"
#include "telex/local/view/gl_contexts.h"

namespace telex::local {

EglContext::EglContext() {
  const HeadlessEgl egl = create_headless_egl("openxr view");
  const EGLDisplay display = egl.display;
  const EGLContext context = egl.context;
  // Surfaceless: the view draws into its own framebuffers and the swapchain's textures.
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    eglDestroyContext(display, context);
    throw std::runtime_error(
        egl_error("openxr view", "cannot make a surfaceless OpenGL context current"));
  }
  h_ = {display, egl.config, context};
}

EglContext::~EglContext() {
  eglMakeCurrent(h_.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(h_.display, h_.context);
}

}  // namespace telex::local
