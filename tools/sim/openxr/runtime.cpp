// SPDX-License-Identifier: MIT
// telex-sim-openxr: loader negotiation, the instance, the system and its stereo view
// configuration, events, the scripted head path and the record.
#include <time.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>

#include "sim_openxr.h"
#include "telex/sim/head_turns.h"

namespace telex::sim::xr {

// The loader's interface (OpenXR loader documentation, "Runtime Negotiation"); Debian's
// libopenxr-dev does not install loader_interfaces.h, so its structs are spelled out here.
enum LoaderInterfaceStruct {
  kLoaderInfo = 1,
  kRuntimeRequest = 3,
};
struct NegotiateLoaderInfo {
  int structType;
  std::uint32_t structVersion;
  std::size_t structSize;
  std::uint32_t minInterfaceVersion, maxInterfaceVersion;
  XrVersion minApiVersion, maxApiVersion;
};
struct NegotiateRuntimeRequest {
  int structType;
  std::uint32_t structVersion;
  std::size_t structSize;
  std::uint32_t runtimeInterfaceVersion;
  XrVersion runtimeApiVersion;
  PFN_xrGetInstanceProcAddr getInstanceProcAddr;
};

namespace {

constexpr std::uint64_t kSystemId = 1;
constexpr const char* kExtensions[] = {XR_KHR_OPENGL_ENABLE_EXTENSION_NAME,
                                       XR_MNDX_EGL_ENABLE_EXTENSION_NAME};

std::unique_ptr<Instance> g_instance;

XrResult enumerate_extensions(const char* layer, std::uint32_t capacity, std::uint32_t* count,
                              XrExtensionProperties* props) {
  if (layer != nullptr) return XR_ERROR_API_LAYER_NOT_PRESENT;
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  Script script;
  std::string error;
  const std::uint32_t n = load_script(script, error) && !script.offer_egl ? 1 : 2;
  *count = n;
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < n) return XR_ERROR_SIZE_INSUFFICIENT;
  for (std::size_t i = 0; i < n; ++i) {
    std::strncpy(props[i].extensionName, kExtensions[i], XR_MAX_EXTENSION_NAME_SIZE - 1);
    props[i].extensionVersion = 1;
  }
  return XR_SUCCESS;
}

XrResult enumerate_layers(std::uint32_t, std::uint32_t* count, XrApiLayerProperties*) {
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *count = 0;
  return XR_SUCCESS;
}

XrResult create_instance(const XrInstanceCreateInfo* info, XrInstance* out) {
  std::lock_guard lock(runtime_mutex());
  if (info == nullptr || out == nullptr || info->type != XR_TYPE_INSTANCE_CREATE_INFO)
    return XR_ERROR_VALIDATION_FAILURE;
  if (g_instance) return XR_ERROR_LIMIT_REACHED;  // one instance at a time
  auto inst = std::make_unique<Instance>();
  std::string error;
  if (!load_script(inst->script, error)) {
    std::fprintf(stderr, "telex-sim-openxr: %s\n", error.c_str());
    return XR_ERROR_RUNTIME_FAILURE;
  }
  for (std::uint32_t i = 0; i < info->enabledExtensionCount; ++i) {
    const std::string name = info->enabledExtensionNames[i];
    if (std::find(std::begin(kExtensions), std::end(kExtensions), name) == std::end(kExtensions) ||
        (name == XR_MNDX_EGL_ENABLE_EXTENSION_NAME && !inst->script.offer_egl))
      return XR_ERROR_EXTENSION_NOT_PRESENT;
    inst->extensions.push_back(name);
  }
  inst->record["runtime"] = "telex-sim-openxr";
  inst->record["application"] = info->applicationInfo.applicationName;
  inst->record["extensions"] = inst->extensions;
  inst->record["errors"] = nlohmann::json::array();
  inst->record["states"] = nlohmann::json::array();
  inst->record["frames"] = nlohmann::json::array();
  inst->record["recommended"] = {inst->script.width, inst->script.height};
  *out = reinterpret_cast<XrInstance>(inst.get());
  g_instance = std::move(inst);
  return XR_SUCCESS;
}

XrResult destroy_instance(XrInstance handle) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (!inst->sessions.empty()) inst->note_error("instance destroyed with a live session");
  inst->write_record();
  g_instance.reset();
  return XR_SUCCESS;
}

XrResult get_instance_properties(XrInstance handle, XrInstanceProperties* props) {
  std::lock_guard lock(runtime_mutex());
  if (!live_instance(handle)) return XR_ERROR_HANDLE_INVALID;
  props->runtimeVersion = XR_MAKE_VERSION(0, 1, 0);
  std::strncpy(props->runtimeName, "telex-sim-openxr", XR_MAX_RUNTIME_NAME_SIZE - 1);
  return XR_SUCCESS;
}

XrResult poll_event(XrInstance handle, XrEventDataBuffer* out) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (inst->events.empty()) return XR_EVENT_UNAVAILABLE;
  *out = inst->events.front();
  inst->events.pop_front();
  if (out->type == XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED) {
    const auto* e = reinterpret_cast<const XrEventDataSessionStateChanged*>(out);
    // When the application took it, on its clock (XrTime is CLOCK_MONOTONIC here).
    inst->record["states"].push_back({{"state", state_name(e->state)}, {"polled_ns", now_ns()}});
  }
  return XR_SUCCESS;
}

XrResult get_system(XrInstance handle, const XrSystemGetInfo* info, XrSystemId* id) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (info->formFactor != XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY)
    return XR_ERROR_FORM_FACTOR_UNSUPPORTED;
  inst->system_got = true;
  *id = kSystemId;
  return XR_SUCCESS;
}

XrResult get_system_properties(XrInstance handle, XrSystemId id, XrSystemProperties* props) {
  std::lock_guard lock(runtime_mutex());
  if (!live_instance(handle)) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  props->systemId = id;
  props->vendorId = 0;
  std::strncpy(props->systemName, "telex-sim-openxr headset", XR_MAX_SYSTEM_NAME_SIZE - 1);
  props->graphicsProperties = {2048, 2048, 0};
  props->trackingProperties = {XR_TRUE, XR_TRUE};
  return XR_SUCCESS;
}

XrResult enumerate_view_configurations(XrInstance handle, XrSystemId id, std::uint32_t capacity,
                                       std::uint32_t* count, XrViewConfigurationType* types) {
  std::lock_guard lock(runtime_mutex());
  if (!live_instance(handle)) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  *count = 1;
  if (capacity == 0) return XR_SUCCESS;
  types[0] = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
  return XR_SUCCESS;
}

XrResult get_view_configuration_properties(XrInstance handle, XrSystemId id,
                                           XrViewConfigurationType type,
                                           XrViewConfigurationProperties* props) {
  std::lock_guard lock(runtime_mutex());
  if (!live_instance(handle)) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  if (type != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  props->viewConfigurationType = type;
  props->fovMutable = XR_FALSE;
  return XR_SUCCESS;
}

XrResult enumerate_view_configuration_views(XrInstance handle, XrSystemId id,
                                            XrViewConfigurationType type, std::uint32_t capacity,
                                            std::uint32_t* count, XrViewConfigurationView* views) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  if (type != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO)
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  *count = 2;
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < 2) return XR_ERROR_SIZE_INSUFFICIENT;
  for (std::uint32_t i = 0; i < 2; ++i) {
    views[i].recommendedImageRectWidth = inst->script.width;
    views[i].recommendedImageRectHeight = inst->script.height;
    views[i].maxImageRectWidth = 2048;
    views[i].maxImageRectHeight = 2048;
    views[i].recommendedSwapchainSampleCount = 1;
    views[i].maxSwapchainSampleCount = 1;
  }
  return XR_SUCCESS;
}

XrResult enumerate_blend_modes(XrInstance handle, XrSystemId id, XrViewConfigurationType,
                               std::uint32_t capacity, std::uint32_t* count,
                               XrEnvironmentBlendMode* modes) {
  std::lock_guard lock(runtime_mutex());
  if (!live_instance(handle)) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  *count = 1;
  if (capacity == 0) return XR_SUCCESS;
  modes[0] = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
  return XR_SUCCESS;
}

XrResult get_gl_requirements(XrInstance handle, XrSystemId id,
                             XrGraphicsRequirementsOpenGLKHR* req) {
  std::lock_guard lock(runtime_mutex());
  Instance* inst = live_instance(handle);
  if (!inst) return XR_ERROR_HANDLE_INVALID;
  if (id != kSystemId) return XR_ERROR_SYSTEM_INVALID;
  req->minApiVersionSupported = XR_MAKE_VERSION(3, 3, 0);
  req->maxApiVersionSupported = XR_MAKE_VERSION(4, 6, 0);
  inst->gl_requirements_got = true;
  return XR_SUCCESS;
}

XrResult result_to_string(XrInstance, XrResult value, char buffer[XR_MAX_RESULT_STRING_SIZE]) {
  const char* s = value >= 0 ? "XR_SUCCESS_CODE" : "XR_ERROR_CODE";
  std::snprintf(buffer, XR_MAX_RESULT_STRING_SIZE, "%s_%d", s, static_cast<int>(value));
  return XR_SUCCESS;
}

XrResult structure_type_to_string(XrInstance, XrStructureType value,
                                  char buffer[XR_MAX_STRUCTURE_NAME_SIZE]) {
  std::snprintf(buffer, XR_MAX_STRUCTURE_NAME_SIZE, "XR_STRUCTURE_TYPE_%d",
                static_cast<int>(value));
  return XR_SUCCESS;
}

XrResult get_instance_proc_addr(XrInstance instance, const char* name,
                                PFN_xrVoidFunction* function);

#define TELEX_XR_FN(fn) reinterpret_cast<PFN_xrVoidFunction>(fn)
const std::map<std::string, PFN_xrVoidFunction>& instance_functions() {
  static const std::map<std::string, PFN_xrVoidFunction> table = {
      {"xrGetInstanceProcAddr", TELEX_XR_FN(get_instance_proc_addr)},
      {"xrDestroyInstance", TELEX_XR_FN(destroy_instance)},
      {"xrGetInstanceProperties", TELEX_XR_FN(get_instance_properties)},
      {"xrPollEvent", TELEX_XR_FN(poll_event)},
      {"xrResultToString", TELEX_XR_FN(result_to_string)},
      {"xrStructureTypeToString", TELEX_XR_FN(structure_type_to_string)},
      {"xrGetSystem", TELEX_XR_FN(get_system)},
      {"xrGetSystemProperties", TELEX_XR_FN(get_system_properties)},
      {"xrEnumerateViewConfigurations", TELEX_XR_FN(enumerate_view_configurations)},
      {"xrGetViewConfigurationProperties", TELEX_XR_FN(get_view_configuration_properties)},
      {"xrEnumerateViewConfigurationViews", TELEX_XR_FN(enumerate_view_configuration_views)},
      {"xrEnumerateEnvironmentBlendModes", TELEX_XR_FN(enumerate_blend_modes)},
      {"xrGetOpenGLGraphicsRequirementsKHR", TELEX_XR_FN(get_gl_requirements)},
  };
  return table;
}

XrResult get_instance_proc_addr(XrInstance instance, const char* name,
                                PFN_xrVoidFunction* function) {
  if (name == nullptr || function == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *function = nullptr;
  const std::string n = name;
  if (instance == XR_NULL_HANDLE) {
    if (n == "xrEnumerateInstanceExtensionProperties")
      *function = TELEX_XR_FN(enumerate_extensions);
    else if (n == "xrEnumerateApiLayerProperties")
      *function = TELEX_XR_FN(enumerate_layers);
    else if (n == "xrCreateInstance")
      *function = TELEX_XR_FN(create_instance);
    else if (n == "xrGetInstanceProcAddr")
      *function = TELEX_XR_FN(get_instance_proc_addr);
    return *function ? XR_SUCCESS : XR_ERROR_HANDLE_INVALID;
  }
  {
    std::lock_guard lock(runtime_mutex());
    if (!live_instance(instance)) return XR_ERROR_HANDLE_INVALID;
  }
  if (n == "xrEnumerateInstanceExtensionProperties")
    *function = TELEX_XR_FN(enumerate_extensions);
  else if (n == "xrEnumerateApiLayerProperties")
    *function = TELEX_XR_FN(enumerate_layers);
  else if (const auto it = instance_functions().find(n); it != instance_functions().end())
    *function = it->second;
  else
    *function = session_function(n);
  return *function ? XR_SUCCESS : XR_ERROR_FUNCTION_UNSUPPORTED;
}
#undef TELEX_XR_FN

glm::dquat to_glm(const XrQuaternionf& q) { return {q.w, q.x, q.y, q.z}; }
XrQuaternionf to_xr(const glm::dquat& q) {
  return {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z),
          static_cast<float>(q.w)};
}

template <typename T>
void read_key(const nlohmann::json& j, const char* key, T& value) {
  if (j.contains(key)) value = j.at(key).get<T>();
}

}  // namespace

bool Gl::load(void* (*get)(const char*)) {
  const auto f = [get](auto& ptr, const char* name) {
    ptr = reinterpret_cast<std::remove_reference_t<decltype(ptr)>>(get(name));
    return ptr != nullptr;
  };
  return f(GenTextures, "glGenTextures") && f(DeleteTextures, "glDeleteTextures") &&
         f(BindTexture, "glBindTexture") && f(TexStorage2D, "glTexStorage2D") &&
         f(GenFramebuffers, "glGenFramebuffers") && f(DeleteFramebuffers, "glDeleteFramebuffers") &&
         f(BindFramebuffer, "glBindFramebuffer") &&
         f(FramebufferTexture2D, "glFramebufferTexture2D") && f(ReadPixels, "glReadPixels") &&
         f(GetIntegerv, "glGetIntegerv");
}

bool load_script(Script& s, std::string& error) {
  const char* path = std::getenv("TELEX_SIM_OPENXR_CONFIG");
  if (path == nullptr || *path == '\0') return true;
  std::ifstream in(path);
  if (!in) {
    error = std::string("TELEX_SIM_OPENXR_CONFIG: cannot read ") + path;
    return false;
  }
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    double period_ms = static_cast<double>(s.period_ns) / 1e6;
    double yaw_deg = s.yaw_amplitude_rad * 180.0 / M_PI;
    double cant_deg = s.view_cant_rad * 180.0 / M_PI;
    read_key(j, "record", s.record_path);
    read_key(j, "period_ms", period_ms);
    read_key(j, "width", s.width);
    read_key(j, "height", s.height);
    read_key(j, "yaw_amplitude_deg", yaw_deg);
    read_key(j, "yaw_period_s", s.yaw_period_s);
    read_key(j, "ipd_m", s.ipd_m);
    read_key(j, "view_cant_deg", cant_deg);
    if (!(cant_deg >= 0.0 && cant_deg <= 30.0))
      throw std::invalid_argument("view_cant_deg must be in 0..30, not " +
                                  std::to_string(cant_deg));
    std::string head_path = "yaw";
    read_key(j, "head_path", head_path);
    if (head_path != "yaw" && head_path != "turns")
      throw std::invalid_argument("head_path must be \"yaw\" or \"turns\", not \"" + head_path +
                                  "\"");
    s.head_turns = head_path == "turns";
    read_key(j, "offer_egl", s.offer_egl);
    read_key(j, "unfocus_at_frame", s.unfocus_at_frame);
    read_key(j, "refocus_at_frame", s.refocus_at_frame);
    read_key(j, "stop_at_frame", s.stop_at_frame);
    read_key(j, "loss_pending_at_frame", s.loss_pending_at_frame);
    read_key(j, "dump_at_frame", s.dump_at_frame);
    if (!(period_ms > 0.5 && period_ms < 1000.0) || s.width == 0 || s.height == 0 ||
        s.width > 2048 || s.height > 2048 || !(s.yaw_period_s > 0.0))
      throw std::invalid_argument("period_ms, width, height or yaw_period_s out of range");
    s.period_ns = static_cast<std::int64_t>(period_ms * 1e6);
    s.yaw_amplitude_rad = yaw_deg * M_PI / 180.0;
    s.view_cant_rad = cant_deg * M_PI / 180.0;
  } catch (const std::exception& e) {
    error = std::string("TELEX_SIM_OPENXR_CONFIG ") + path + ": " + e.what();
    return false;
  }
  return true;
}

std::mutex& runtime_mutex() {
  static std::mutex m;
  return m;
}

Instance* live_instance(XrInstance handle) {
  return g_instance && reinterpret_cast<Instance*>(handle) == g_instance.get() ? g_instance.get()
                                                                               : nullptr;
}

Instance* current_instance() { return g_instance.get(); }

Session* live_session(XrSession handle) {
  if (!g_instance) return nullptr;
  auto* s = reinterpret_cast<Session*>(handle);
  return g_instance->sessions.count(s) ? s : nullptr;
}

void Instance::push_state(Session& s, XrSessionState state) {
  s.state = state;
  XrEventDataBuffer buffer{XR_TYPE_EVENT_DATA_BUFFER, nullptr, {}};
  auto* e = reinterpret_cast<XrEventDataSessionStateChanged*>(&buffer);
  e->type = XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED;
  e->next = nullptr;
  e->session = reinterpret_cast<XrSession>(&s);
  e->state = state;
  e->time = now_ns();
  events.push_back(buffer);
}

void Instance::note_error(const std::string& what) {
  std::fprintf(stderr, "telex-sim-openxr: %s\n", what.c_str());
  record["errors"].push_back(what);
}

void Instance::write_record() const {
  if (script.record_path.empty()) return;
  const std::string tmp = script.record_path + ".tmp";
  {
    std::ofstream out(tmp);
    out << record.dump(1) << "\n";
  }
  std::rename(tmp.c_str(), script.record_path.c_str());
}

std::int64_t now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

XrPosef compose(const XrPosef& a, const XrPosef& b) {
  const glm::dquat qa = to_glm(a.orientation), qb = to_glm(b.orientation);
  const glm::dvec3 pb(b.position.x, b.position.y, b.position.z);
  const glm::dvec3 p = glm::dvec3(a.position.x, a.position.y, a.position.z) + qa * pb;
  return {to_xr(glm::normalize(qa * qb)),
          {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)}};
}

XrPosef inverse(const XrPosef& a) {
  const glm::dquat qi = glm::conjugate(to_glm(a.orientation));
  const glm::dvec3 p = -(qi * glm::dvec3(a.position.x, a.position.y, a.position.z));
  return {to_xr(qi), {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)}};
}

XrPosef head_pose(const Session& s, std::int64_t t_ns) {
  const Script& sc = s.instance->script;
  if (sc.head_turns) {
    const SimPose X_LocalView = head_turns_view_in_local(static_cast<double>(t_ns) * 1e-9);
    const glm::dvec3& p = X_LocalView.p_m;
    return {to_xr(X_LocalView.q),
            {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)}};
  }
  const double t_s = static_cast<double>(t_ns - s.t0_ns) * 1e-9;
  const double yaw = sc.yaw_amplitude_rad * std::sin(2.0 * M_PI * t_s / sc.yaw_period_s);
  return {to_xr(glm::angleAxis(yaw, glm::dvec3(0.0, 1.0, 0.0))), {0.0f, 0.0f, 0.0f}};
}

std::array<XrPosef, 2> eye_poses(const Session& s, std::int64_t t_ns) {
  const XrPosef head = head_pose(s, t_ns);
  const float half = static_cast<float>(s.instance->script.ipd_m / 2.0);
  // Outward: the left eye turned about +y (its -z axis towards -x), the right one about -y.
  const double cant = s.instance->script.view_cant_rad;
  const XrQuaternionf left = to_xr(glm::angleAxis(cant, glm::dvec3(0.0, 1.0, 0.0)));
  const XrQuaternionf right = to_xr(glm::angleAxis(-cant, glm::dvec3(0.0, 1.0, 0.0)));
  return {compose(head, {left, {-half, 0, 0}}), compose(head, {right, {half, 0, 0}})};
}

std::array<XrFovf, 2> eye_fovs() {
  // Canted outward a little, as headsets' are (left, right, up, down in radians).
  return {XrFovf{-0.87f, 0.75f, 0.82f, -0.87f}, XrFovf{-0.75f, 0.87f, 0.82f, -0.87f}};
}

XrPosef reference_in_local(const Session& s, XrReferenceSpaceType type, std::int64_t t_ns) {
  switch (type) {
    case XR_REFERENCE_SPACE_TYPE_VIEW:
      return head_pose(s, t_ns);
    case XR_REFERENCE_SPACE_TYPE_STAGE: {  // the floor, 1.6 m below the head's start
      const glm::dvec3 p = telex::sim::inverse(head_turns_local_in_stage()).p_m;
      return {{0, 0, 0, 1},
              {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)}};
    }
    default:
      return {{0, 0, 0, 1}, {0, 0, 0}};
  }
}

const char* state_name(XrSessionState state) {
  switch (state) {
    case XR_SESSION_STATE_IDLE:
      return "IDLE";
    case XR_SESSION_STATE_READY:
      return "READY";
    case XR_SESSION_STATE_SYNCHRONIZED:
      return "SYNCHRONIZED";
    case XR_SESSION_STATE_VISIBLE:
      return "VISIBLE";
    case XR_SESSION_STATE_FOCUSED:
      return "FOCUSED";
    case XR_SESSION_STATE_STOPPING:
      return "STOPPING";
    case XR_SESSION_STATE_LOSS_PENDING:
      return "LOSS_PENDING";
    case XR_SESSION_STATE_EXITING:
      return "EXITING";
    default:
      return "UNKNOWN";
  }
}

}  // namespace telex::sim::xr

// The one symbol the loader looks up (the manifest names this library).
extern "C" __attribute__((visibility("default"))) XrResult xrNegotiateLoaderRuntimeInterface(
    const telex::sim::xr::NegotiateLoaderInfo* info,
    telex::sim::xr::NegotiateRuntimeRequest* request) {
  using namespace telex::sim::xr;
  if (info == nullptr || request == nullptr || info->structType != kLoaderInfo ||
      request->structType != kRuntimeRequest || info->minInterfaceVersion > 1 ||
      info->maxInterfaceVersion < 1)
    return XR_ERROR_INITIALIZATION_FAILED;
  request->runtimeInterfaceVersion = 1;
  request->runtimeApiVersion = XR_CURRENT_API_VERSION;
  request->getInstanceProcAddr = get_instance_proc_addr;
  return XR_SUCCESS;
}
