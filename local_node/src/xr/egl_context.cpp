// SPDX-License-Identifier: MIT
// The headless EGL context an OpenXR session with XR_MNDX_egl_enable is bound to.
#include <epoxy/egl.h>

#include <cstdio>
#include <stdexcept>
#include <string>

#include "gl_contexts.h"

namespace telex::local {
namespace {

std::string egl_error(const char* what) {
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04x", eglGetError());
  return std::string("openxr view: ") + what + " (EGL error " + hex +
         "); the headless view needs Mesa's EGL (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri)";
}

}  // namespace

EglContext::EglContext() {
  EGLDisplay display = EGL_NO_DISPLAY;
  if (epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless"))
    display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
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
    throw std::runtime_error(egl_error("no EGL config for OpenGL"));
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                    3,
                                    EGL_CONTEXT_MINOR_VERSION,
                                    3,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                    EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
  if (context == EGL_NO_CONTEXT) throw std::runtime_error(egl_error("no OpenGL 3.3 core context"));
  // Surfaceless: the view draws into its own framebuffers and the swapchain's textures.
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
    eglDestroyContext(display, context);
    throw std::runtime_error(egl_error("cannot make a surfaceless OpenGL context current"));
  }
  h_ = {display, config, context};
}

EglContext::~EglContext() {
  eglMakeCurrent(h_.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(h_.display, h_.context);
}

}  // namespace telex::local
