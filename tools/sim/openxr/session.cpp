// SPDX-License-Identifier: MIT
// telex-sim-openxr: the session and its state script, reference spaces, GL swapchains in the
// application's EGL context, and the frame loop paced at the script's period.
#include <dlfcn.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "sim_openxr.h"

namespace telex::sim::xr {
namespace {

constexpr std::size_t kRecordedFrames = 4000;
constexpr std::array<std::int64_t, 2> kFormats = {GL_SRGB8_ALPHA8, GL_RGBA8};

const XrBaseInStructure* find_in_chain(const void* next, XrStructureType type) {
  for (auto* s = static_cast<const XrBaseInStructure*>(next); s != nullptr; s = s->next)
    if (s->type == type) return s;
  return nullptr;
}

// Down from wherever the session is to STOPPING (the headset's user quit, or the application
// asked to exit).
void descend_to_stopping(Instance& inst, Session& s) {
  if (s.state == XR_SESSION_STATE_FOCUSED) inst.push_state(s, XR_SESSION_STATE_VISIBLE);
  if (s.state == XR_SESSION_STATE_VISIBLE) inst.push_state(s, XR_SESSION_STATE_SYNCHRONIZED);
  if (s.state == XR_SESSION_STATE_SYNCHRONIZED) inst.push_state(s, XR_SESSION_STATE_STOPPING);
}

// The script's state changes, by frames ended so far.
void run_script(Instance& inst, Session& s) {
  const Script& sc = inst.script;
  const std::uint64_t n = s.frames_ended;
  if (s.state == XR_SESSION_STATE_SYNCHRONIZED && !s.exit_requested && n == 1) {
    inst.push_state(s, XR_SESSION_STATE_VISIBLE);
    inst.push_state(s, XR_SESSION_STATE_FOCUSED);
  }
  if (n == sc.unfocus_at_frame && s.state == XR_SESSION_STATE_FOCUSED)
    inst.push_state(s, XR_SESSION_STATE_VISIBLE);
  if (n == sc.refocus_at_frame && s.state == XR_SESSION_STATE_VISIBLE)
    inst.push_state(s, XR_SESSION_STATE_FOCUSED);
  if (n == sc.stop_at_frame) descend_to_stopping(inst, s);
  if (n == sc.loss_pending_at_frame) inst.push_state(s, XR_SESSION_STATE_LOSS_PENDING);
}

// The GL entry points of the binding's context: EGL's through the binding's getProcAddress, GLX's
// through libGL's glXGetProcAddressARB (the application's libGL, already loaded).
PFNEGLGETPROCADDRESSPROC g_egl_get = nullptr;
void* egl_get(const char* name) { return reinterpret_cast<void*>(g_egl_get(name)); }
void* glx_get(const char* name) {
  static void* lib = dlopen("libGL.so.1", RTLD_NOW | RTLD_GLOBAL);
  using Get = void* (*)(const unsigned char*);
  static const auto get = lib ? reinterpret_cast<Get>(dlsym(lib, "glXGetProcAddressARB")) : nullptr;
  return get ? get(reinterpret_cast<const unsigned char*>(name)) : nullptr;
}

XrResult create_session(XrInstance handle, const XrSessionCreateInfo* info, XrSession* out) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (!inst->system_got || info->systemId != 1) return XR_ERROR_SYSTEM_INVALID;
  if (!inst->gl_requirements_got) return XR_ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING;
  const auto* egl = reinterpret_cast<const XrGraphicsBindingEGLMNDX*>(
      find_in_chain(info->next, XR_TYPE_GRAPHICS_BINDING_EGL_MNDX));
  const auto* xlib = reinterpret_cast<const XrGraphicsBindingOpenGLXlibKHR*>(
      find_in_chain(info->next, XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR));
  const bool egl_enabled = std::count(inst->extensions.begin(), inst->extensions.end(),
                                      XR_MNDX_EGL_ENABLE_EXTENSION_NAME) > 0;
  const bool egl_ok = egl && egl_enabled && egl->getProcAddress && egl->context != EGL_NO_CONTEXT;
  const bool xlib_ok = xlib && xlib->xDisplay && xlib->glxContext;
  if (egl_ok == xlib_ok) {
    inst->note_error(
        "xrCreateSession needs one XrGraphicsBindingEGLMNDX (with XR_MNDX_egl_enable) "
        "or XrGraphicsBindingOpenGLXlibKHR");
    return XR_ERROR_GRAPHICS_DEVICE_INVALID;
  }
  auto s = std::make_unique<Session>();
  s->instance = inst;
  if (egl_ok) g_egl_get = egl->getProcAddress;
  if (!s->gl.load(egl_ok ? egl_get : glx_get)) {
    inst->note_error("the binding's context lacks GL 3.3 functions");
    return XR_ERROR_GRAPHICS_DEVICE_INVALID;
  }
  inst->record["binding"] = egl_ok ? "egl" : "xlib";
  Session* raw = s.release();
  inst->sessions.insert(raw);
  inst->push_state(*raw, XR_SESSION_STATE_IDLE);
  inst->push_state(*raw, XR_SESSION_STATE_READY);
  *out = reinterpret_cast<XrSession>(raw);
  return XR_SUCCESS;
}

XrResult destroy_session(XrSession handle) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  Instance& inst = *s->instance;
  for (Swapchain* sc : s->swapchains) {
    s->gl.DeleteTextures(static_cast<GLsizei>(sc->textures.size()), sc->textures.data());
    delete sc;
  }
  for (Space* sp : s->spaces) delete sp;
  if (s->read_fbo) s->gl.DeleteFramebuffers(1, &s->read_fbo);
  inst.record["session_destroyed_in_state"] = state_name(s->state);
  inst.record["frames_waited"] = s->frames_waited;
  inst.record["frames_begun"] = s->frames_begun;
  inst.record["frames_ended"] = s->frames_ended;
  inst.record["frames_with_predicted_time"] = s->frames_with_predicted_time;
  inst.record["frames_with_projection"] = s->frames_with_projection;
  inst.sessions.erase(s);
  delete s;
  inst.write_record();
  return XR_SUCCESS;
}

XrResult begin_session(XrSession handle, const XrSessionBeginInfo* info) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (s->running) return XR_ERROR_SESSION_RUNNING;
  if (s->state != XR_SESSION_STATE_READY) return XR_ERROR_SESSION_NOT_READY;
  if (info->primaryViewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  s->running = true;
  s->t0_ns = now_ns();
  s->instance->push_state(*s, XR_SESSION_STATE_SYNCHRONIZED);
  return XR_SUCCESS;
}

XrResult end_session(XrSession handle) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (s->state != XR_SESSION_STATE_STOPPING) return XR_ERROR_SESSION_NOT_STOPPING;
  s->running = false;
  s->instance->push_state(*s, XR_SESSION_STATE_IDLE);
  // The only way out of this headset's sessions is to quit: the application should exit.
  s->instance->push_state(*s, XR_SESSION_STATE_EXITING);
  return XR_SUCCESS;
}

XrResult request_exit_session(XrSession handle) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  s->exit_requested = true;
  // Who ended the session: the tests tell a run the script stopped from one the station ended.
  s->instance->record["exit_requested_at_frame"] = s->frames_ended;
  descend_to_stopping(*s->instance, *s);
  return XR_SUCCESS;
}

XrResult enumerate_reference_spaces(XrSession handle, std::uint32_t capacity, std::uint32_t* count,
                                    XrReferenceSpaceType* types) {
  std::lock_guard lock(runtime_mutex());
  if (!live_session(handle)) return XR_ERROR_HANDLE_INVALID;
  constexpr XrReferenceSpaceType kTypes[] = {
      XR_REFERENCE_SPACE_TYPE_VIEW, XR_REFERENCE_SPACE_TYPE_LOCAL, XR_REFERENCE_SPACE_TYPE_STAGE};
  *count = std::size(kTypes);
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < std::size(kTypes)) return XR_ERROR_SIZE_INSUFFICIENT;
  std::copy(std::begin(kTypes), std::end(kTypes), types);
  return XR_SUCCESS;
}

XrResult create_reference_space(XrSession handle, const XrReferenceSpaceCreateInfo* info,
                                XrSpace* out) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_VIEW &&
      info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_LOCAL &&
      info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_STAGE)
    return XR_ERROR_REFERENCE_SPACE_UNSUPPORTED;
  auto* sp = new Space{s, info->referenceSpaceType, info->poseInReferenceSpace};
  s->spaces.insert(sp);
  *out = reinterpret_cast<XrSpace>(sp);
  return XR_SUCCESS;
}

Space* live_space(XrSpace handle) {
  Instance* inst = current_instance();
  auto* sp = reinterpret_cast<Space*>(handle);
  if (inst)
    for (Session* s : inst->sessions)
      if (s->spaces.count(sp)) return sp;
  return nullptr;
}

XrResult destroy_space(XrSpace handle) {
  std::lock_guard lock(runtime_mutex());
  Space* sp = live_space(handle);
  if (!sp) return XR_ERROR_HANDLE_INVALID;
  sp->session->spaces.erase(sp);
  delete sp;
  return XR_SUCCESS;
}

// The space's pose in LOCAL at `t_ns`.
XrPosef space_in_local(const Space& sp, std::int64_t t_ns) {
  return compose(reference_in_local(*sp.session, sp.type, t_ns), sp.pose_in_reference);
}

XrResult locate_space(XrSpace space, XrSpace base, XrTime time, XrSpaceLocation* location) {
  std::lock_guard lock(runtime_mutex());
  Space *a = live_space(space), *b = live_space(base);
  if (!a || !b) return XR_ERROR_HANDLE_INVALID;
  if (time <= 0) return XR_ERROR_TIME_INVALID;
  location->pose = compose(inverse(space_in_local(*b, time)), space_in_local(*a, time));
  location->locationFlags =
      XR_SPACE_LOCATION_ORIENTATION_VALID_BIT | XR_SPACE_LOCATION_POSITION_VALID_BIT |
      XR_SPACE_LOCATION_ORIENTATION_TRACKED_BIT | XR_SPACE_LOCATION_POSITION_TRACKED_BIT;
  return XR_SUCCESS;
}

XrResult locate_views(XrSession handle, const XrViewLocateInfo* info, XrViewState* state,
                      std::uint32_t capacity, std::uint32_t* count, XrView* views) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  Space* sp = live_space(info->space);
  if (!s || !sp) return XR_ERROR_HANDLE_INVALID;
  if (info->viewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  if (info->displayTime <= 0) return XR_ERROR_TIME_INVALID;
  *count = 2;
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < 2) return XR_ERROR_SIZE_INSUFFICIENT;
  const XrPosef local_in_space = inverse(space_in_local(*sp, info->displayTime));
  const auto eyes = eye_poses(*s, info->displayTime);
  const auto fovs = eye_fovs();
  for (std::size_t i = 0; i < 2; ++i) {
    views[i].pose = compose(local_in_space, eyes[i]);
    views[i].fov = fovs[i];
  }
  state->viewStateFlags = XR_VIEW_STATE_ORIENTATION_VALID_BIT | XR_VIEW_STATE_POSITION_VALID_BIT |
                          XR_VIEW_STATE_ORIENTATION_TRACKED_BIT |
                          XR_VIEW_STATE_POSITION_TRACKED_BIT;
  return XR_SUCCESS;
}

XrResult enumerate_swapchain_formats(XrSession handle, std::uint32_t capacity, std::uint32_t* count,
                                     std::int64_t* formats) {
  std::lock_guard lock(runtime_mutex());
  if (!live_session(handle)) return XR_ERROR_HANDLE_INVALID;
  *count = kFormats.size();
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < kFormats.size()) return XR_ERROR_SIZE_INSUFFICIENT;
  std::copy(kFormats.begin(), kFormats.end(), formats);
  return XR_SUCCESS;
}

// Swapchain functions need the application's context current on the calling thread.
XrResult create_swapchain(XrSession handle, const XrSwapchainCreateInfo* info, XrSwapchain* out) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (std::find(kFormats.begin(), kFormats.end(), info->format) == kFormats.end())
    return XR_ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED;
  if (info->sampleCount != 1 || info->faceCount != 1 || info->arraySize != 1 ||
      info->mipCount != 1 || info->width == 0 || info->height == 0 || info->width > 2048 ||
      info->height > 2048)
    return XR_ERROR_FEATURE_UNSUPPORTED;
  auto* sc = new Swapchain;
  sc->session = s;
  sc->width = info->width;
  sc->height = info->height;
  sc->format = info->format;
  s->gl.GenTextures(static_cast<GLsizei>(sc->textures.size()), sc->textures.data());
  for (GLuint t : sc->textures) {
    s->gl.BindTexture(GL_TEXTURE_2D, t);
    s->gl.TexStorage2D(GL_TEXTURE_2D, 1, static_cast<GLenum>(info->format),
                       static_cast<GLsizei>(info->width), static_cast<GLsizei>(info->height));
  }
  s->gl.BindTexture(GL_TEXTURE_2D, 0);
  s->swapchains.insert(sc);
  *out = reinterpret_cast<XrSwapchain>(sc);
  return XR_SUCCESS;
}

Swapchain* live_swapchain(XrSwapchain handle) {
  Instance* inst = current_instance();
  auto* sc = reinterpret_cast<Swapchain*>(handle);
  if (inst)
    for (Session* s : inst->sessions)
      if (s->swapchains.count(sc)) return sc;
  return nullptr;
}

XrResult destroy_swapchain(XrSwapchain handle) {
  std::lock_guard lock(runtime_mutex());
  Swapchain* sc = live_swapchain(handle);
  if (!sc) return XR_ERROR_HANDLE_INVALID;
  sc->session->gl.DeleteTextures(static_cast<GLsizei>(sc->textures.size()), sc->textures.data());
  sc->session->swapchains.erase(sc);
  delete sc;
  return XR_SUCCESS;
}

XrResult enumerate_swapchain_images(XrSwapchain handle, std::uint32_t capacity,
                                    std::uint32_t* count, XrSwapchainImageBaseHeader* images) {
  std::lock_guard lock(runtime_mutex());
  Swapchain* sc = live_swapchain(handle);
  if (!sc) return XR_ERROR_HANDLE_INVALID;
  *count = sc->textures.size();
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < sc->textures.size()) return XR_ERROR_SIZE_INSUFFICIENT;
  auto* gl_images = reinterpret_cast<XrSwapchainImageOpenGLKHR*>(images);
  for (std::size_t i = 0; i < sc->textures.size(); ++i) {
    if (gl_images[i].type != XR_TYPE_SWAPCHAIN_IMAGE_OPENGL_KHR) return XR_ERROR_VALIDATION_FAILURE;
    gl_images[i].image = sc->textures[i];
  }
  return XR_SUCCESS;
}

XrResult acquire_image(XrSwapchain handle, const XrSwapchainImageAcquireInfo*,
                       std::uint32_t* index) {
  std::lock_guard lock(runtime_mutex());
  Swapchain* sc = live_swapchain(handle);
  if (!sc) return XR_ERROR_HANDLE_INVALID;
  if (sc->acquired.size() == sc->textures.size()) return XR_ERROR_CALL_ORDER_INVALID;
  *index = sc->next;
  sc->acquired.push_back(sc->next);
  sc->next = (sc->next + 1) % sc->textures.size();
  return XR_SUCCESS;
}

XrResult wait_image(XrSwapchain handle, const XrSwapchainImageWaitInfo*) {
  std::lock_guard lock(runtime_mutex());
  Swapchain* sc = live_swapchain(handle);
  if (!sc) return XR_ERROR_HANDLE_INVALID;
  if (sc->acquired.empty() || sc->waited) return XR_ERROR_CALL_ORDER_INVALID;
  sc->waited = true;
  return XR_SUCCESS;
}

XrResult release_image(XrSwapchain handle, const XrSwapchainImageReleaseInfo*) {
  std::lock_guard lock(runtime_mutex());
  Swapchain* sc = live_swapchain(handle);
  if (!sc) return XR_ERROR_HANDLE_INVALID;
  if (!sc->waited) return XR_ERROR_CALL_ORDER_INVALID;
  sc->last_released = sc->acquired.front();
  sc->acquired.pop_front();
  sc->waited = false;
  return XR_SUCCESS;
}

XrResult wait_frame(XrSession handle, const XrFrameWaitInfo*, XrFrameState* state) {
  std::int64_t wake_ns = 0, period_ns = 0;
  {
    std::lock_guard lock(runtime_mutex());
    Session* s = live_session(handle);
    if (!s) return XR_ERROR_HANDLE_INVALID;
    if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
    period_ns = s->instance->script.period_ns;
    const std::int64_t now = now_ns();
    if (s->next_display_ns == 0) s->next_display_ns = now + 2 * period_ns;
    // A late application skips the display slots it missed.
    while (s->next_display_ns - period_ns < now - period_ns) s->next_display_ns += period_ns;
    wake_ns = s->next_display_ns - period_ns;
    state->predictedDisplayTime = s->next_display_ns;
    state->predictedDisplayPeriod = period_ns;
    state->shouldRender =
        s->state == XR_SESSION_STATE_VISIBLE || s->state == XR_SESSION_STATE_FOCUSED;
    s->predicted.insert(s->next_display_ns);
    s->next_display_ns += period_ns;
    s->frame_waited = true;
    ++s->frames_waited;
  }
  const std::int64_t wait = wake_ns - now_ns();
  if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
  return XR_SUCCESS;
}

XrResult begin_frame(XrSession handle, const XrFrameBeginInfo*) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (!s->frame_waited) return XR_ERROR_CALL_ORDER_INVALID;
  s->frame_waited = false;
  ++s->frames_begun;
  const bool discarded = s->frame_begun;
  s->frame_begun = true;
  return discarded ? XR_FRAME_DISCARDED : XR_SUCCESS;
}

// The RGBA pixels of the image the application released last, in the w x h rectangle at (x, y)
// (GL's rows: bottom-up).
std::vector<std::uint8_t> read_released(Session& s, const Swapchain& sc, int x, int y, int w,
                                        int h) {
  GLint previous = 0;
  s.gl.GetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &previous);
  if (!s.read_fbo) s.gl.GenFramebuffers(1, &s.read_fbo);
  s.gl.BindFramebuffer(GL_READ_FRAMEBUFFER, s.read_fbo);
  s.gl.FramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D,
                            sc.textures[sc.last_released], 0);
  std::vector<std::uint8_t> rgba(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
  s.gl.ReadPixels(x, y, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  s.gl.BindFramebuffer(GL_READ_FRAMEBUFFER, static_cast<GLuint>(previous));
  return rgba;
}

// The centre pixel of the image the application released last: proof it drew there.
std::array<int, 4> centre_pixel(Session& s, const Swapchain& sc, const XrRect2Di& rect) {
  const auto px = read_released(s, sc, rect.offset.x + rect.extent.width / 2,
                                rect.offset.y + rect.extent.height / 2, 1, 1);
  return {px[0], px[1], px[2], px[3]};
}

// The image the application released last, within `rect`, as a binary PPM (GL's rows are
// bottom-up: written top row first).
void dump_image(Session& s, const Swapchain& sc, const XrRect2Di& rect, const std::string& path) {
  const auto w = static_cast<std::size_t>(rect.extent.width);
  const auto h = static_cast<std::size_t>(rect.extent.height);
  const auto rgba =
      read_released(s, sc, rect.offset.x, rect.offset.y, rect.extent.width, rect.extent.height);
  std::ofstream out(path, std::ios::binary);
  out << "P6\n" << w << " " << h << "\n255\n";
  for (std::size_t row = h; row-- > 0;)
    for (std::size_t col = 0; col < w; ++col)
      out.write(reinterpret_cast<const char*>(&rgba[(row * w + col) * 4]), 3);
}

XrResult end_frame(XrSession handle, const XrFrameEndInfo* info) {
  std::lock_guard lock(runtime_mutex());
  Session* s = live_session(handle);
  if (!s) return XR_ERROR_HANDLE_INVALID;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (!s->frame_begun) return XR_ERROR_CALL_ORDER_INVALID;
  if (info->environmentBlendMode != XR_ENVIRONMENT_BLEND_MODE_OPAQUE)
    return XR_ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED;
  if (info->displayTime <= 0) return XR_ERROR_TIME_INVALID;
  Instance& inst = *s->instance;
  nlohmann::json frame = {{"display_time_ns", info->displayTime},
                          {"eyes", nlohmann::json::array()}};
  const bool predicted = s->predicted.erase(info->displayTime) > 0;
  // Times older than this one will not come back.
  s->predicted.erase(s->predicted.begin(), s->predicted.lower_bound(info->displayTime));
  frame["predicted"] = predicted;
  bool projection = false;
  for (std::uint32_t l = 0; l < info->layerCount; ++l) {
    if (info->layers[l]->type != XR_TYPE_COMPOSITION_LAYER_PROJECTION) continue;
    const auto* p = reinterpret_cast<const XrCompositionLayerProjection*>(info->layers[l]);
    if (p->viewCount != 2 || !live_space(p->space)) return XR_ERROR_VALIDATION_FAILURE;
    for (std::uint32_t v = 0; v < 2; ++v) {
      const XrSwapchainSubImage& sub = p->views[v].subImage;
      Swapchain* sc = live_swapchain(sub.swapchain);
      if (!sc) return XR_ERROR_HANDLE_INVALID;
      const XrRect2Di& r = sub.imageRect;
      if (r.offset.x < 0 || r.offset.y < 0 || r.extent.width <= 0 || r.extent.height <= 0 ||
          static_cast<std::uint32_t>(r.offset.x + r.extent.width) > sc->width ||
          static_cast<std::uint32_t>(r.offset.y + r.extent.height) > sc->height)
        return XR_ERROR_SWAPCHAIN_RECT_INVALID;
      if (!sc->acquired.empty()) inst.note_error("a layer's swapchain image was not released");
      // The field of view submitted for the eye, beside the one xrLocateViews gave it.
      const XrFovf& f = p->views[v].fov;
      const XrFovf located = eye_fovs()[v];
      // And its orientation (x, y, z, w in the layer's space), beside the located one.
      const XrQuaternionf& q = p->views[v].pose.orientation;
      const XrQuaternionf q_located =
          compose(inverse(space_in_local(*live_space(p->space), info->displayTime)),
                  eye_poses(*s, info->displayTime)[v])
              .orientation;
      frame["eyes"].push_back(
          {{"width", r.extent.width},
           {"height", r.extent.height},
           {"swapchain", {sc->width, sc->height}},
           {"centre_rgba", centre_pixel(*s, *sc, r)},
           {"fov", {f.angleLeft, f.angleRight, f.angleUp, f.angleDown}},
           {"fov_located",
            {located.angleLeft, located.angleRight, located.angleUp, located.angleDown}},
           {"orientation", {q.x, q.y, q.z, q.w}},
           {"orientation_located", {q_located.x, q_located.y, q_located.z, q_located.w}}});
      if (s->frames_with_projection + 1 == inst.script.dump_at_frame &&
          !inst.script.record_path.empty())
        dump_image(*s, *sc, r, inst.script.record_path + ".eye" + std::to_string(v) + ".ppm");
    }
    projection = true;
  }
  s->frame_begun = false;
  ++s->frames_ended;
  if (predicted) ++s->frames_with_predicted_time;
  if (projection) ++s->frames_with_projection;
  if (inst.record["frames"].size() < kRecordedFrames) inst.record["frames"].push_back(frame);
  run_script(inst, *s);
  return XR_SUCCESS;
}

}  // namespace

PFN_xrVoidFunction session_function(const std::string& name) {
#define TELEX_XR_FN(fn) reinterpret_cast<PFN_xrVoidFunction>(fn)
  static const std::map<std::string, PFN_xrVoidFunction> table = {
      {"xrCreateSession", TELEX_XR_FN(create_session)},
      {"xrDestroySession", TELEX_XR_FN(destroy_session)},
      {"xrBeginSession", TELEX_XR_FN(begin_session)},
      {"xrEndSession", TELEX_XR_FN(end_session)},
      {"xrRequestExitSession", TELEX_XR_FN(request_exit_session)},
      {"xrEnumerateReferenceSpaces", TELEX_XR_FN(enumerate_reference_spaces)},
      {"xrCreateReferenceSpace", TELEX_XR_FN(create_reference_space)},
      {"xrDestroySpace", TELEX_XR_FN(destroy_space)},
      {"xrLocateSpace", TELEX_XR_FN(locate_space)},
      {"xrLocateViews", TELEX_XR_FN(locate_views)},
      {"xrEnumerateSwapchainFormats", TELEX_XR_FN(enumerate_swapchain_formats)},
      {"xrCreateSwapchain", TELEX_XR_FN(create_swapchain)},
      {"xrDestroySwapchain", TELEX_XR_FN(destroy_swapchain)},
      {"xrEnumerateSwapchainImages", TELEX_XR_FN(enumerate_swapchain_images)},
      {"xrAcquireSwapchainImage", TELEX_XR_FN(acquire_image)},
      {"xrWaitSwapchainImage", TELEX_XR_FN(wait_image)},
      {"xrReleaseSwapchainImage", TELEX_XR_FN(release_image)},
      {"xrWaitFrame", TELEX_XR_FN(wait_frame)},
      {"xrBeginFrame", TELEX_XR_FN(begin_frame)},
      {"xrEndFrame", TELEX_XR_FN(end_frame)},
  };
#undef TELEX_XR_FN
  const auto it = table.find(name);
  return it == table.end() ? nullptr : it->second;
}

}  // namespace telex::sim::xr
