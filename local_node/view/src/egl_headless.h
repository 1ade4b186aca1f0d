// SPDX-License-Identifier: MIT
// The one headless EGL setup of the station's views (the stereo renderer, the warp, the OpenXR
// output's EGL binding): Mesa's surfaceless platform where offered, else the default display; an
// OpenGL 3.3 core context with a pbuffer-capable config. Not made current: each caller binds it
// its own way (surfaceless, or a 1x1 pbuffer).
#pragma once

#include <epoxy/egl.h>

#include <string>

namespace telex::local {

struct HeadlessEgl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLConfig config = nullptr;
  EGLContext context = EGL_NO_CONTEXT;
};

// `who` starts every error ("stereo view", "warp", "openxr view"). Throws std::runtime_error
// naming what is missing and the Debian packages that provide it.
HeadlessEgl create_headless_egl(const char* who);

// "WHO: WHAT (EGL error 0x....); the headless view needs Mesa's EGL (...)", with eglGetError().
std::string egl_error(const char* who, const char* what);

}  // namespace telex::local
