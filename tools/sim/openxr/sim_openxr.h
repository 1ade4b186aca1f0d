// SPDX-License-Identifier: MIT
// telex-sim-openxr: the project's own small OpenXR runtime (loaded through XR_RUNTIME_JSON), for
// the station's --view openxr tests. Headless: swapchain images are GL textures in the
// application's own EGL context, frames are paced at a fixed period, the head follows a scripted
// yaw sine (or telex/sim/head_turns.h's turns), and session state changes (focus loss, stopping,
// loss pending) follow a script read from TELEX_SIM_OPENXR_CONFIG (JSON). What the application
// submitted is written as JSON to the script's "record" path when the instance (or session) is
// destroyed; "exit_requested_at_frame" in it, when the application called xrRequestExitSession.
#pragma once

#define XR_USE_PLATFORM_EGL
#define XR_USE_PLATFORM_XLIB
#define XR_USE_GRAPHICS_API_OPENGL
// libepoxy for the EGL and GL types and enums only (it is not linked: see Gl).
#include <epoxy/egl.h>
#include <epoxy/gl.h>
#include <epoxy/glx.h>
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>

#include <array>
#include <cstdint>
#include <deque>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

namespace telex::sim::xr {

// What the script (TELEX_SIM_OPENXR_CONFIG) sets; every key is optional.
struct Script {
  std::string record_path;                   // "record": where the JSON record goes; empty: nowhere
  std::int64_t period_ns = 11'111'111;       // "period_ms": the display's frame period
  std::uint32_t width = 960, height = 1080;  // "width", "height": recommended per eye
  double yaw_amplitude_rad = 0.35;           // "yaw_amplitude_deg"
  double yaw_period_s = 4.0;                 // "yaw_period_s"
  double ipd_m = 0.064;                      // "ipd_m"
  // "view_cant_deg": each eye's view turned outward about the head's y by this angle (0..30), as
  // a canted display's (Pimax, Valve Index, Varjo): the left eye's axis to the left, the right's to
  // the right. 0: parallel eyes.
  double view_cant_rad = 0.0;
  // "head_path": "yaw" (the sine above, from the session's creation) or "turns"
  // (telex/sim/head_turns.h: yaw, pitch, roll and sway on CLOCK_MONOTONIC, the motion
  // telex-sim-natnet --motion head-turns reports for the head body).
  bool head_turns = false;
  // Frames ended (counted from 1) at which the state changes: FOCUSED -> VISIBLE at
  // "unfocus_at_frame", back at "refocus_at_frame"; "stop_at_frame": down to STOPPING (the user
  // quit); "loss_pending_at_frame": LOSS_PENDING. 0: never.
  // "offer_egl": false offers XR_KHR_opengl_enable alone, whose Xlib binding the application
  // must then use (as with SteamVR): the path Khronos' core validation layer can check, as it
  // rejects XrGraphicsBindingEGLMNDX (KhronosGroup/OpenXR-SDK-Source#570).
  bool offer_egl = true;
  std::uint64_t unfocus_at_frame = 0, refocus_at_frame = 0, stop_at_frame = 0,
                loss_pending_at_frame = 0;
  // "dump_at_frame": the eyes' images of the Nth frame ended with a projection layer (counted
  // from 1) as binary PPMs (top row first) at the record's path + ".eye0.ppm" (left) and
  // ".eye1.ppm". 0: none.
  std::uint64_t dump_at_frame = 0;
};
// Reads the script from TELEX_SIM_OPENXR_CONFIG (unset: the defaults). False with `error` set
// for an unreadable file or a key of the wrong type.
bool load_script(Script& script, std::string& error);

// The GL calls the runtime makes in the application's context, through the binding's
// getProcAddress (the runtime links no GL library).
struct Gl {
  PFNGLGENTEXTURESPROC GenTextures = nullptr;
  PFNGLDELETETEXTURESPROC DeleteTextures = nullptr;
  PFNGLBINDTEXTUREPROC BindTexture = nullptr;
  PFNGLTEXSTORAGE2DPROC TexStorage2D = nullptr;
  PFNGLGENFRAMEBUFFERSPROC GenFramebuffers = nullptr;
  PFNGLDELETEFRAMEBUFFERSPROC DeleteFramebuffers = nullptr;
  PFNGLBINDFRAMEBUFFERPROC BindFramebuffer = nullptr;
  PFNGLFRAMEBUFFERTEXTURE2DPROC FramebufferTexture2D = nullptr;
  PFNGLREADPIXELSPROC ReadPixels = nullptr;
  PFNGLGETINTEGERVPROC GetIntegerv = nullptr;
  bool load(void* (*get)(const char*));
};

struct Instance;
struct Session;

struct Space {
  Session* session = nullptr;
  XrReferenceSpaceType type = XR_REFERENCE_SPACE_TYPE_LOCAL;
  XrPosef pose_in_reference{};
};

struct Swapchain {
  Session* session = nullptr;
  std::uint32_t width = 0, height = 0;
  std::int64_t format = 0;
  std::array<GLuint, 3> textures{};
  std::deque<std::uint32_t> acquired;  // acquired, not yet released, in order
  bool waited = false;                 // the oldest acquired one has been waited on
  std::uint32_t next = 0;
  std::uint32_t last_released = 0;
};

struct Session {
  Instance* instance = nullptr;
  Gl gl;
  XrSessionState state = XR_SESSION_STATE_UNKNOWN;
  bool running = false;  // between xrBeginSession and xrEndSession
  bool exit_requested = false;
  std::int64_t t0_ns = 0;  // the head path's time zero
  std::int64_t next_display_ns = 0;
  std::set<std::int64_t> predicted;  // display times given out and not yet ended
  bool frame_waited = false, frame_begun = false;
  std::uint64_t frames_waited = 0, frames_begun = 0, frames_ended = 0;
  std::uint64_t frames_with_predicted_time = 0, frames_with_projection = 0;
  GLuint read_fbo = 0;
  std::set<Space*> spaces;
  std::set<Swapchain*> swapchains;
};

struct Instance {
  Script script;
  std::vector<std::string> extensions;
  std::deque<XrEventDataBuffer> events;
  std::set<Session*> sessions;
  bool system_got = false;
  bool gl_requirements_got = false;
  nlohmann::json record = nlohmann::json::object();
  void push_state(Session& s, XrSessionState state);
  void note_error(const std::string& what);  // a misuse the runtime saw, in the record
  void write_record() const;
};

// One lock for the whole runtime: the loader and layers may call from any thread.
std::mutex& runtime_mutex();
Instance* live_instance(XrInstance handle);
Instance* current_instance();  // the one instance, or null
Session* live_session(XrSession handle);

// The head's pose (LOCAL space: the head starts at the origin looking down -z) at `t_ns`, and the
// eyes' poses (each turned outward by the script's view_cant_rad) and fields of view.
XrPosef head_pose(const Session& s, std::int64_t t_ns);
std::array<XrPosef, 2> eye_poses(const Session& s, std::int64_t t_ns);
std::array<XrFovf, 2> eye_fovs();
XrPosef compose(const XrPosef& a, const XrPosef& b);  // a * b
XrPosef inverse(const XrPosef& p);
// The reference space's origin in the LOCAL space at `t_ns`.
XrPosef reference_in_local(const Session& s, XrReferenceSpaceType type, std::int64_t t_ns);
const char* state_name(XrSessionState state);
std::int64_t now_ns();

// The session, space, swapchain and frame functions (session.cpp), looked up by name.
PFN_xrVoidFunction session_function(const std::string& name);

}  // namespace telex::sim::xr
