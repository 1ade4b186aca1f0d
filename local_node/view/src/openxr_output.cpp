// SPDX-License-Identifier: MIT
// --view openxr: instance, system, session, swapchains and the frame loop.
#define XR_USE_PLATFORM_EGL
#define XR_USE_PLATFORM_XLIB
#define XR_USE_GRAPHICS_API_OPENGL
#include "telex/local/view/openxr_output.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <epoxy/glx.h>
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>
#include <openxr/openxr_reflection.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string_view>

#include "telex/base/periodic.h"

namespace telex::local {
namespace {

// An OpenXR struct zeroed, with its type set (the rest of -Wextra's missing initializers).
template <typename T>
T xr_struct(XrStructureType type) {
  T s{};
  s.type = type;
  return s;
}

// A failed OpenXR call: step() ends the session on it (other exceptions, e.g. the renderer's,
// go to the caller).
struct XrCallError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* result_name(XrResult r) {
  switch (r) {
#define TELEX_XR_RESULT(name, value) \
  case name:                         \
    return #name;
    XR_LIST_ENUM_XrResult(TELEX_XR_RESULT)
#undef TELEX_XR_RESULT
        default : return "XR_RESULT_UNKNOWN";
  }
}

}  // namespace

std::string openxr_runtime_manifest() {
  if (const char* env = std::getenv("XR_RUNTIME_JSON"); env && *env) {
    if (!std::filesystem::exists(env))
      throw std::runtime_error(std::string("openxr view: XR_RUNTIME_JSON=") + env +
                               " does not exist: point it at the runtime's manifest (SteamVR: "
                               "~/.steam/steam/steamapps/common/SteamVR/steamxr_linux64.json, "
                               "Monado: /usr/share/openxr/1/openxr_monado.json)");
    return std::string("XR_RUNTIME_JSON=") + env;
  }
  std::vector<std::filesystem::path> dirs;
  if (const char* c = std::getenv("XDG_CONFIG_HOME"); c && *c)
    dirs.emplace_back(c);
  else if (const char* h = std::getenv("HOME"); h && *h)
    dirs.emplace_back(std::filesystem::path(h) / ".config");
  dirs.emplace_back("/etc/xdg");
  dirs.emplace_back("/etc");
  for (const auto& d : dirs)
    if (const auto p = d / "openxr/1/active_runtime.json"; std::filesystem::exists(p))
      return p.string();
  throw std::runtime_error(
      "openxr view: no OpenXR runtime is installed (no XR_RUNTIME_JSON and no "
      "openxr/1/active_runtime.json under ~/.config, /etc/xdg or /etc): start SteamVR or Monado "
      "(each makes itself the active runtime), or set XR_RUNTIME_JSON to a runtime's manifest");
}

Intrinsics pinhole_from_fov(const XrEyeFov& fov, int width, int height) {
  const double left = std::tan(fov.angle_left_rad), right = std::tan(fov.angle_right_rad);
  const double up = std::tan(fov.angle_up_rad), down = std::tan(fov.angle_down_rad);
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (right - left);
  k.fy = height / (up - down);
  k.cx = -left * k.fx - 0.5;  // y down: the top edge is `up`
  k.cy = up * k.fy - 0.5;
  return k;
}

glm::dmat3 camera_rotation_from_openxr(const glm::dquat& q_AB) {
  const glm::dmat3 C(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
  return C * glm::mat3_cast(glm::normalize(q_AB)) * C;
}

struct OpenXrOutput::Xr {
  XrInstance instance = XR_NULL_HANDLE;
  XrSystemId system = XR_NULL_SYSTEM_ID;
  XrSession session = XR_NULL_HANDLE;
  XrSpace base = XR_NULL_HANDLE, view = XR_NULL_HANDLE;
  XrSessionState state = XR_SESSION_STATE_UNKNOWN;
  bool running = false;  // between xrBeginSession and xrEndSession
  std::array<XrSwapchain, 2> swapchains{XR_NULL_HANDLE, XR_NULL_HANDLE};
  std::array<std::vector<XrSwapchainImageOpenGLKHR>, 2> images;
  std::string runtime;  // for messages

  // Throws naming the call, the runtime and the result.
  void check(XrResult r, const char* call) const {
    if (XR_FAILED(r))
      throw XrCallError(std::string("openxr view: ") + call + " failed with " + result_name(r) +
                        " (runtime " + runtime + ")");
  }
};

// XR_ENABLE_API_LAYERS names Khronos' core validation layer.
static bool validation_layer_enabled() {
  const char* layers = std::getenv("XR_ENABLE_API_LAYERS");
  return layers != nullptr && std::string_view(layers).find("XR_APILAYER_LUNARG_core_validation") !=
                                  std::string_view::npos;
}

void prepare_openxr_environment() {
  if (validation_layer_enabled() && std::getenv("XR_CORE_VALIDATION_FILE_NAME") == nullptr) {
    ::setenv("XR_CORE_VALIDATION_EXPORT_TYPE", "text", 0);
    ::setenv("XR_CORE_VALIDATION_FILE_NAME", "/dev/stderr", 1);
  }
}

OpenXrOutput::OpenXrOutput() : xr_(std::make_unique<Xr>()) {
  xr_->runtime = openxr_runtime_manifest();
  std::uint32_t n = 0;
  XrResult r = xrEnumerateInstanceExtensionProperties(nullptr, 0, &n, nullptr);
  if (XR_FAILED(r))
    throw std::runtime_error(
        std::string("openxr view: the OpenXR loader cannot load the runtime (") + xr_->runtime +
        "): " + result_name(r) + "; is the manifest's library_path there and loadable?");
  std::vector<XrExtensionProperties> exts(
      n, xr_struct<XrExtensionProperties>(XR_TYPE_EXTENSION_PROPERTIES));
  xr_->check(xrEnumerateInstanceExtensionProperties(nullptr, n, &n, exts.data()),
             "xrEnumerateInstanceExtensionProperties");
  const auto offered = [&exts](const char* name) {
    return std::any_of(exts.begin(), exts.end(),
                       [name](const auto& e) { return std::strcmp(e.extensionName, name) == 0; });
  };
  if (!offered(XR_KHR_OPENGL_ENABLE_EXTENSION_NAME))
    throw std::runtime_error("openxr view: the runtime (" + xr_->runtime +
                             ") offers no OpenGL binding (neither XR_MNDX_egl_enable nor "
                             "XR_KHR_opengl_enable); the station draws with OpenGL only");
  // Khronos' core validation layer (1.0.20) does not know XR_MNDX_egl_enable and fails
  // xrCreateSession with its binding: with the layer on and an X display, take the Xlib binding,
  // which it checks; the layer's text goes to stderr unless its file is named, so that stdout
  // keeps --json-summary alone (issue 50).
  const bool validating = validation_layer_enabled();
  const char* display = std::getenv("DISPLAY");
  const bool x_display = display != nullptr && *display != '\0';
  binding_ = offered(XR_MNDX_EGL_ENABLE_EXTENSION_NAME) && !(validating && x_display)
                 ? Binding::Egl
                 : Binding::Xlib;
  egl_under_validation_ = binding_ == Binding::Egl && validating;
  std::vector<const char*> enable{XR_KHR_OPENGL_ENABLE_EXTENSION_NAME};
  if (binding_ == Binding::Egl) enable.push_back(XR_MNDX_EGL_ENABLE_EXTENSION_NAME);

  auto ci = xr_struct<XrInstanceCreateInfo>(XR_TYPE_INSTANCE_CREATE_INFO);
  std::strncpy(ci.applicationInfo.applicationName, "telex-local", XR_MAX_APPLICATION_NAME_SIZE - 1);
  ci.applicationInfo.applicationVersion = 1;
  std::strncpy(ci.applicationInfo.engineName, "telex", XR_MAX_ENGINE_NAME_SIZE - 1);
  ci.applicationInfo.apiVersion = XR_CURRENT_API_VERSION;
  ci.enabledExtensionCount = static_cast<std::uint32_t>(enable.size());
  ci.enabledExtensionNames = enable.data();
  xr_->check(xrCreateInstance(&ci, &xr_->instance), "xrCreateInstance");
  auto props = xr_struct<XrInstanceProperties>(XR_TYPE_INSTANCE_PROPERTIES);
  xr_->check(xrGetInstanceProperties(xr_->instance, &props), "xrGetInstanceProperties");
  runtime_name_ = props.runtimeName;
  xr_->runtime = runtime_name_ + ", " + xr_->runtime;

  auto si = xr_struct<XrSystemGetInfo>(XR_TYPE_SYSTEM_GET_INFO);
  si.formFactor = XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY;
  r = xrGetSystem(xr_->instance, &si, &xr_->system);
  if (r == XR_ERROR_FORM_FACTOR_UNAVAILABLE)
    throw std::runtime_error("openxr view: the runtime (" + xr_->runtime +
                             ") sees no headset: is it connected and switched on?");
  xr_->check(r, "xrGetSystem");
  std::uint32_t views = 0;
  xr_->check(xrEnumerateViewConfigurationViews(xr_->instance, xr_->system,
                                               XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &views,
                                               nullptr),
             "xrEnumerateViewConfigurationViews");
  if (views != 2)
    throw std::runtime_error("openxr view: the headset's stereo configuration has " +
                             std::to_string(views) + " views, not 2 (runtime " + xr_->runtime +
                             ")");
  const auto vcv = xr_struct<XrViewConfigurationView>(XR_TYPE_VIEW_CONFIGURATION_VIEW);
  std::array<XrViewConfigurationView, 2> vc{vcv, vcv};
  xr_->check(xrEnumerateViewConfigurationViews(xr_->instance, xr_->system,
                                               XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 2, &views,
                                               vc.data()),
             "xrEnumerateViewConfigurationViews");
  recommended_w_ = static_cast<int>(vc[0].recommendedImageRectWidth);
  recommended_h_ = static_cast<int>(vc[0].recommendedImageRectHeight);
}

OpenXrOutput::~OpenXrOutput() {
  if (xr_->session != XR_NULL_HANDLE) end("the station stopped");
  if (xr_->instance != XR_NULL_HANDLE) xrDestroyInstance(xr_->instance);
}

void OpenXrOutput::start(const EglHandles& egl) {
  if (binding_ != Binding::Egl)
    throw std::logic_error("openxr view: an EGL context for a runtime without XR_MNDX_egl_enable");
  auto b = xr_struct<XrGraphicsBindingEGLMNDX>(XR_TYPE_GRAPHICS_BINDING_EGL_MNDX);
  b.getProcAddress = eglGetProcAddress;
  b.display = static_cast<EGLDisplay>(egl.display);
  b.config = static_cast<EGLConfig>(egl.config);
  b.context = static_cast<EGLContext>(egl.context);
  create_session(&b);
}

void OpenXrOutput::start(const GlxHandles& glx) {
  auto b = xr_struct<XrGraphicsBindingOpenGLXlibKHR>(XR_TYPE_GRAPHICS_BINDING_OPENGL_XLIB_KHR);
  b.xDisplay = static_cast<Display*>(glx.x_display);
  b.visualid = static_cast<std::uint32_t>(glx.visual_id);
  b.glxFBConfig = static_cast<GLXFBConfig>(glx.fb_config);
  b.glxDrawable = glx.drawable;
  b.glxContext = static_cast<GLXContext>(glx.context);
  create_session(&b);
}

void OpenXrOutput::create_session(const void* binding) {
  Xr& x = *xr_;
  PFN_xrGetOpenGLGraphicsRequirementsKHR requirements = nullptr;
  x.check(xrGetInstanceProcAddr(x.instance, "xrGetOpenGLGraphicsRequirementsKHR",
                                reinterpret_cast<PFN_xrVoidFunction*>(&requirements)),
          "xrGetInstanceProcAddr(xrGetOpenGLGraphicsRequirementsKHR)");
  auto req = xr_struct<XrGraphicsRequirementsOpenGLKHR>(XR_TYPE_GRAPHICS_REQUIREMENTS_OPENGL_KHR);
  x.check(requirements(x.instance, x.system, &req), "xrGetOpenGLGraphicsRequirementsKHR");
  const int gl = epoxy_gl_version();
  const XrVersion have = XR_MAKE_VERSION(gl / 10, gl % 10, 0);
  if (have < req.minApiVersionSupported)
    throw std::runtime_error("openxr view: the runtime (" + x.runtime + ") needs OpenGL " +
                             std::to_string(XR_VERSION_MAJOR(req.minApiVersionSupported)) + "." +
                             std::to_string(XR_VERSION_MINOR(req.minApiVersionSupported)) +
                             ", the context has " + std::to_string(gl / 10) + "." +
                             std::to_string(gl % 10));
  auto sci = xr_struct<XrSessionCreateInfo>(XR_TYPE_SESSION_CREATE_INFO);
  sci.next = binding;
  sci.systemId = x.system;
  const XrResult r = xrCreateSession(x.instance, &sci, &x.session);
  if (r == XR_ERROR_VALIDATION_FAILURE && egl_under_validation_)
    throw XrCallError(
        "openxr view: xrCreateSession failed with XR_ERROR_VALIDATION_FAILURE: "
        "the core validation layer (XR_ENABLE_API_LAYERS) does not know the "
        "headless EGL binding (XR_MNDX_egl_enable) of the runtime (" +
        x.runtime +
        "); run the station under an X display (xvfb-run) so it takes the Xlib "
        "binding, which the layer checks, or leave the layer out");
  x.check(r, "xrCreateSession");

  std::uint32_t n = 0;
  x.check(xrEnumerateReferenceSpaces(x.session, 0, &n, nullptr), "xrEnumerateReferenceSpaces");
  std::vector<XrReferenceSpaceType> spaces(n);
  x.check(xrEnumerateReferenceSpaces(x.session, n, &n, spaces.data()),
          "xrEnumerateReferenceSpaces");
  const bool stage = std::count(spaces.begin(), spaces.end(), XR_REFERENCE_SPACE_TYPE_STAGE) > 0;
  auto rs = xr_struct<XrReferenceSpaceCreateInfo>(XR_TYPE_REFERENCE_SPACE_CREATE_INFO);
  rs.poseInReferenceSpace.orientation.w = 1.0f;
  rs.referenceSpaceType = stage ? XR_REFERENCE_SPACE_TYPE_STAGE : XR_REFERENCE_SPACE_TYPE_LOCAL;
  x.check(xrCreateReferenceSpace(x.session, &rs, &x.base), "xrCreateReferenceSpace");
  rs.referenceSpaceType = XR_REFERENCE_SPACE_TYPE_VIEW;
  x.check(xrCreateReferenceSpace(x.session, &rs, &x.view), "xrCreateReferenceSpace(VIEW)");

  x.check(xrEnumerateSwapchainFormats(x.session, 0, &n, nullptr), "xrEnumerateSwapchainFormats");
  std::vector<std::int64_t> formats(n);
  x.check(xrEnumerateSwapchainFormats(x.session, n, &n, formats.data()),
          "xrEnumerateSwapchainFormats");
  // The renderer's colours are sRGB-encoded already: an sRGB swapchain takes them as they are.
  std::int64_t format = 0;
  for (const std::int64_t want : {std::int64_t{GL_SRGB8_ALPHA8}, std::int64_t{GL_RGBA8}})
    if (!format && std::count(formats.begin(), formats.end(), want)) format = want;
  if (!format)
    throw std::runtime_error("openxr view: the runtime (" + x.runtime +
                             ") offers neither GL_SRGB8_ALPHA8 nor GL_RGBA8 swapchains");
  for (std::size_t eye = 0; eye < 2; ++eye) {
    auto sc = xr_struct<XrSwapchainCreateInfo>(XR_TYPE_SWAPCHAIN_CREATE_INFO);
    sc.usageFlags = XR_SWAPCHAIN_USAGE_COLOR_ATTACHMENT_BIT | XR_SWAPCHAIN_USAGE_TRANSFER_DST_BIT;
    sc.format = format;
    sc.sampleCount = 1;
    sc.width = static_cast<std::uint32_t>(recommended_w_);
    sc.height = static_cast<std::uint32_t>(recommended_h_);
    sc.faceCount = sc.arraySize = sc.mipCount = 1;
    x.check(xrCreateSwapchain(x.session, &sc, &x.swapchains[eye]), "xrCreateSwapchain");
    x.check(xrEnumerateSwapchainImages(x.swapchains[eye], 0, &n, nullptr),
            "xrEnumerateSwapchainImages");
    x.images[eye].assign(n,
                         xr_struct<XrSwapchainImageOpenGLKHR>(XR_TYPE_SWAPCHAIN_IMAGE_OPENGL_KHR));
    x.check(xrEnumerateSwapchainImages(
                x.swapchains[eye], n, &n,
                reinterpret_cast<XrSwapchainImageBaseHeader*>(x.images[eye].data())),
            "xrEnumerateSwapchainImages");
  }
  spdlog::info("openxr view: runtime {} ({} binding), {} swapchains of {}x{} per eye, {} space",
               x.runtime, binding_ == Binding::Egl ? "EGL" : "Xlib",
               format == GL_SRGB8_ALPHA8 ? "sRGB" : "RGBA8", recommended_w_, recommended_h_,
               stage ? "STAGE" : "LOCAL");
}

}  // namespace telex::local

namespace telex::local {

void OpenXrOutput::set_phase(Phase p) {
  if (p == phase_) return;
  phase_ = p;
  if (on_phase_) on_phase_(p);
}

OpenXrOutput::Phase OpenXrOutput::step(const Draw& draw) {
  if (phase_ == Phase::Ended) return phase_;
  try {
    handle_events();
    if (xr_->running && phase_ != Phase::Ended) frame(draw);
  } catch (const XrCallError& e) {
    end(e.what());
  }
  return phase_;
}

void OpenXrOutput::request_exit() {
  if (exit_requested_ || phase_ == Phase::Ended) return;
  exit_requested_ = true;
  if (!xr_->running) {
    end("the station stopped");
    return;
  }
  const XrResult r = xrRequestExitSession(xr_->session);
  if (XR_FAILED(r)) end(std::string("xrRequestExitSession failed with ") + result_name(r));
}

void OpenXrOutput::handle_events() {
  Xr& x = *xr_;
  for (;;) {
    auto ev = xr_struct<XrEventDataBuffer>(XR_TYPE_EVENT_DATA_BUFFER);
    const XrResult r = xrPollEvent(x.instance, &ev);
    if (r == XR_EVENT_UNAVAILABLE) return;
    x.check(r, "xrPollEvent");
    if (ev.type == XR_TYPE_EVENT_DATA_INSTANCE_LOSS_PENDING) {
      end("the runtime is going away (instance loss pending)");
      return;
    }
    if (ev.type != XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED) continue;
    const auto& sc = reinterpret_cast<const XrEventDataSessionStateChanged&>(ev);
    x.state = sc.state;
    switch (sc.state) {
      case XR_SESSION_STATE_READY: {
        auto bi = xr_struct<XrSessionBeginInfo>(XR_TYPE_SESSION_BEGIN_INFO);
        bi.primaryViewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
        x.check(xrBeginSession(x.session, &bi), "xrBeginSession");
        x.running = true;
        set_phase(Phase::Running);
        break;
      }
      case XR_SESSION_STATE_SYNCHRONIZED:
      case XR_SESSION_STATE_VISIBLE:
        set_phase(Phase::Running);  // shown, maybe, but the operator's input is elsewhere
        break;
      case XR_SESSION_STATE_FOCUSED:
        set_phase(Phase::Focused);
        break;
      case XR_SESSION_STATE_STOPPING:
        set_phase(Phase::Running);
        x.check(xrEndSession(x.session), "xrEndSession");
        x.running = false;
        end(exit_requested_ ? "the station stopped" : "the headset's user stopped the session");
        return;
      case XR_SESSION_STATE_EXITING:
        end("the runtime asked the station to exit");
        return;
      case XR_SESSION_STATE_LOSS_PENDING:
        end("the runtime is losing the session (loss pending)");
        return;
      default:
        break;
    }
  }
}

void OpenXrOutput::frame(const Draw& draw) {
  Xr& x = *xr_;
  auto fs = xr_struct<XrFrameState>(XR_TYPE_FRAME_STATE);
  auto wi = xr_struct<XrFrameWaitInfo>(XR_TYPE_FRAME_WAIT_INFO);
  x.check(xrWaitFrame(x.session, &wi, &fs), "xrWaitFrame");
  auto bi = xr_struct<XrFrameBeginInfo>(XR_TYPE_FRAME_BEGIN_INFO);
  x.check(xrBeginFrame(x.session, &bi), "xrBeginFrame");

  auto head = xr_struct<XrSpaceLocation>(XR_TYPE_SPACE_LOCATION);
  head_.located_ns = monotonic_ns();
  x.check(xrLocateSpace(x.view, x.base, fs.predictedDisplayTime, &head), "xrLocateSpace");
  constexpr XrSpaceLocationFlags kPose =
      XR_SPACE_LOCATION_ORIENTATION_VALID_BIT | XR_SPACE_LOCATION_POSITION_VALID_BIT;
  head_.valid = (head.locationFlags & kPose) == kPose;
  head_.display_time_ns = fs.predictedDisplayTime;
  const XrQuaternionf& q = head.pose.orientation;
  head_.q_StageHead = glm::dquat(q.w, q.x, q.y, q.z);
  head_.p_StageHead_m = {head.pose.position.x, head.pose.position.y, head.pose.position.z};

  auto vli = xr_struct<XrViewLocateInfo>(XR_TYPE_VIEW_LOCATE_INFO);
  vli.viewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
  vli.displayTime = fs.predictedDisplayTime;
  vli.space = x.base;
  auto vs = xr_struct<XrViewState>(XR_TYPE_VIEW_STATE);
  const auto view = xr_struct<XrView>(XR_TYPE_VIEW);
  std::array<XrView, 2> views{view, view};
  std::uint32_t n = 0;
  x.check(xrLocateViews(x.session, &vli, &vs, 2, &n, views.data()), "xrLocateViews");
  constexpr XrViewStateFlags kViews =
      XR_VIEW_STATE_ORIENTATION_VALID_BIT | XR_VIEW_STATE_POSITION_VALID_BIT;
  const bool located = (vs.viewStateFlags & kViews) == kViews && n == 2;
  // The same views in the head (VIEW space): each eye's orientation there, whether the head is
  // tracked or not (a canted display's eyes are turned in the head, not in the room).
  vli.space = x.view;
  auto vs_head = xr_struct<XrViewState>(XR_TYPE_VIEW_STATE);
  std::array<XrView, 2> views_head{view, view};
  std::uint32_t n_head = 0;
  x.check(xrLocateViews(x.session, &vli, &vs_head, 2, &n_head, views_head.data()),
          "xrLocateViews (VIEW space)");
  const bool in_head =
      (vs_head.viewStateFlags & XR_VIEW_STATE_ORIENTATION_VALID_BIT) != 0 && n_head == 2;

  const auto pv0 =
      xr_struct<XrCompositionLayerProjectionView>(XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW);
  std::array<XrCompositionLayerProjectionView, 2> pv{pv0, pv0};
  bool drawn = false;
  if (fs.shouldRender && located) {
    std::array<XrEyeTarget, 2> targets;
    for (std::size_t eye = 0; eye < 2; ++eye) {
      std::uint32_t index = 0;
      auto ai = xr_struct<XrSwapchainImageAcquireInfo>(XR_TYPE_SWAPCHAIN_IMAGE_ACQUIRE_INFO);
      x.check(xrAcquireSwapchainImage(x.swapchains[eye], &ai, &index), "xrAcquireSwapchainImage");
      auto wait = xr_struct<XrSwapchainImageWaitInfo>(XR_TYPE_SWAPCHAIN_IMAGE_WAIT_INFO);
      wait.timeout = XR_INFINITE_DURATION;
      x.check(xrWaitSwapchainImage(x.swapchains[eye], &wait), "xrWaitSwapchainImage");
      const XrFovf& f = views[eye].fov;
      const XrQuaternionf& q_HeadEye = views_head[eye].pose.orientation;
      targets[eye] = {x.images[eye][index].image, recommended_w_, recommended_h_,
                      XrEyeFov{f.angleLeft, f.angleRight, f.angleUp, f.angleDown},
                      in_head ? camera_rotation_from_openxr(
                                    glm::dquat(q_HeadEye.w, q_HeadEye.x, q_HeadEye.y, q_HeadEye.z))
                              : glm::dmat3(1.0)};
    }
    drawn = draw(targets);
    for (std::size_t eye = 0; eye < 2; ++eye) {
      auto ri = xr_struct<XrSwapchainImageReleaseInfo>(XR_TYPE_SWAPCHAIN_IMAGE_RELEASE_INFO);
      x.check(xrReleaseSwapchainImage(x.swapchains[eye], &ri), "xrReleaseSwapchainImage");
      // Where the headset will be and what each eye will see then, as located: the image was
      // drawn with this field of view.
      pv[eye].pose = views[eye].pose;
      pv[eye].fov = views[eye].fov;
      pv[eye].subImage.swapchain = x.swapchains[eye];
      pv[eye].subImage.imageRect = {{0, 0}, {recommended_w_, recommended_h_}};
    }
  }
  auto layer = xr_struct<XrCompositionLayerProjection>(XR_TYPE_COMPOSITION_LAYER_PROJECTION);
  layer.space = x.base;
  layer.viewCount = 2;
  layer.views = pv.data();
  const XrCompositionLayerBaseHeader* layers[] = {
      reinterpret_cast<const XrCompositionLayerBaseHeader*>(&layer)};
  auto ei = xr_struct<XrFrameEndInfo>(XR_TYPE_FRAME_END_INFO);
  ei.displayTime = fs.predictedDisplayTime;
  ei.environmentBlendMode = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
  ei.layerCount = drawn ? 1 : 0;
  ei.layers = drawn ? layers : nullptr;
  x.check(xrEndFrame(x.session, &ei), "xrEndFrame");
  if (drawn) ++frames_submitted_;
}

void OpenXrOutput::end(const std::string& why) {
  Xr& x = *xr_;
  if (end_reason_.empty()) end_reason_ = why;
  for (XrSwapchain& s : x.swapchains)
    if (s != XR_NULL_HANDLE) xrDestroySwapchain(std::exchange(s, XR_NULL_HANDLE));
  for (XrSpace* s : {&x.view, &x.base})
    if (*s != XR_NULL_HANDLE) xrDestroySpace(std::exchange(*s, XR_NULL_HANDLE));
  if (x.session != XR_NULL_HANDLE) xrDestroySession(std::exchange(x.session, XR_NULL_HANDLE));
  x.running = false;
  set_phase(Phase::Ended);
}

}  // namespace telex::local
