// SPDX-License-Identifier: MIT
#include "egl_headless.h"

#include <cstdio>
#include <stdexcept>

namespace telex::local {

std::string egl_error(const char* who, const char* what) {
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%04x", eglGetError());
  return std::string(who) + ": " + what + " (EGL error " + hex +
         "); the headless view needs Mesa's EGL (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri)";
}

HeadlessEgl create_headless_egl(const char* who) {
  HeadlessEgl h;
  if (epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless"))
    h.display =
        eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (h.display == EGL_NO_DISPLAY) h.display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  EGLint major = 0, minor = 0;
  if (h.display == EGL_NO_DISPLAY || !eglInitialize(h.display, &major, &minor))
    throw std::runtime_error(egl_error(who, "no EGL display"));
  if (!eglBindAPI(EGL_OPENGL_API))
    throw std::runtime_error(egl_error(who, "EGL has no OpenGL API"));
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                   EGL_OPENGL_BIT, EGL_NONE};
  EGLint configs = 0;
  if (!eglChooseConfig(h.display, config_attribs, &h.config, 1, &configs) || configs < 1)
    throw std::runtime_error(egl_error(who, "no EGL config for OpenGL with a pbuffer"));
  const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION,
                                    3,
                                    EGL_CONTEXT_MINOR_VERSION,
                                    3,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                    EGL_NONE};
  h.context = eglCreateContext(h.display, h.config, EGL_NO_CONTEXT, context_attribs);
  if (h.context == EGL_NO_CONTEXT)
    throw std::runtime_error(egl_error(who, "no OpenGL 3.3 core context"));
  return h;
}

}  // namespace telex::local
