// SPDX-License-Identifier: MIT
// The GLX context an OpenXR session with XR_KHR_opengl_enable's Xlib binding is bound to (SteamVR
// on Linux offers no other OpenGL binding).
#include <epoxy/glx.h>

#include <cstdlib>
#include <stdexcept>
#include <string>

#include "telex/local/view/gl_contexts.h"

namespace telex::local {

GlxContext::GlxContext() {
  const char* name = std::getenv("DISPLAY");
  Display* x = XOpenDisplay(nullptr);
  if (x == nullptr)
    throw std::runtime_error(std::string("openxr view: the runtime needs an OpenGL context on X "
                                         "(Xlib binding) and no X display opens at DISPLAY='") +
                             (name ? name : "") + "'");
  const auto fail = [x](const std::string& what) {
    XCloseDisplay(x);
    return std::runtime_error("openxr view (Xlib binding): " + what);
  };
  int major = 0, minor = 0;
  if (!glXQueryVersion(x, &major, &minor) || major < 1 || (major == 1 && minor < 3))
    throw fail("the X server has no GLX 1.3");
  const int fb_attribs[] = {GLX_DRAWABLE_TYPE,
                            GLX_PBUFFER_BIT,
                            GLX_RENDER_TYPE,
                            GLX_RGBA_BIT,
                            GLX_RED_SIZE,
                            8,
                            GLX_GREEN_SIZE,
                            8,
                            GLX_BLUE_SIZE,
                            8,
                            None};
  int count = 0;
  GLXFBConfig* configs = glXChooseFBConfig(x, DefaultScreen(x), fb_attribs, &count);
  if (configs == nullptr || count < 1) throw fail("no GLX config with 8-bit RGB and pbuffers");
  GLXFBConfig config = configs[0];
  XFree(configs);
  if (!epoxy_has_glx_extension(x, DefaultScreen(x), "GLX_ARB_create_context_profile"))
    throw fail("GLX_ARB_create_context_profile is missing (no core profile contexts)");
  const int ctx_attribs[] = {GLX_CONTEXT_MAJOR_VERSION_ARB,
                             3,
                             GLX_CONTEXT_MINOR_VERSION_ARB,
                             3,
                             GLX_CONTEXT_PROFILE_MASK_ARB,
                             GLX_CONTEXT_CORE_PROFILE_BIT_ARB,
                             None};
  GLXContext context = glXCreateContextAttribsARB(x, config, nullptr, True, ctx_attribs);
  if (context == nullptr) throw fail("no OpenGL 3.3 core context");
  const int pb_attribs[] = {GLX_PBUFFER_WIDTH, 1, GLX_PBUFFER_HEIGHT, 1, None};
  const GLXPbuffer pbuffer = glXCreatePbuffer(x, config, pb_attribs);
  if (!glXMakeContextCurrent(x, pbuffer, pbuffer, context)) {
    glXDestroyContext(x, context);
    throw fail("cannot make the OpenGL context current");
  }
  XVisualInfo* vi = glXGetVisualFromFBConfig(x, config);
  h_.visual_id = vi ? vi->visualid : 0;
  if (vi) XFree(vi);
  h_.x_display = x;
  h_.fb_config = config;
  h_.drawable = pbuffer;
  h_.context = context;
}

GlxContext::~GlxContext() {
  auto* x = static_cast<Display*>(h_.x_display);
  glXMakeContextCurrent(x, None, None, nullptr);
  glXDestroyPbuffer(x, h_.drawable);
  glXDestroyContext(x, static_cast<GLXContext>(h_.context));
  XCloseDisplay(x);
}

}  // namespace telex::local
