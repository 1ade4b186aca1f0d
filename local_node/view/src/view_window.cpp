// SPDX-License-Identifier: MIT
// The view on a screen: --view parsing, monitor choice, and the GLFW window that blits the newest
// side-by-side image (a texture behind a read framebuffer) letterboxed into its back buffer.
#include "telex/local/view/view_window.h"

#include <epoxy/gl.h>
// After epoxy: GLFW must not include a GL header of its own.
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <mutex>
#include <stdexcept>

#include "telex/base/demand.h"

namespace telex::local {
namespace {

// GLFW reports errors through one process-wide callback; the last one goes into our messages.
std::mutex g_error_mu;
std::string g_last_error;

void record_glfw_error(int code, const char* description) {
  std::lock_guard lock(g_error_mu);
  g_last_error = std::string(description ? description : "no description") + " (GLFW error " +
                 std::to_string(code) + ")";
}

std::string take_glfw_error() {
  std::lock_guard lock(g_error_mu);
  std::string e = g_last_error.empty() ? std::string("GLFW gave no reason") : g_last_error;
  g_last_error.clear();
  return e;
}

std::string flag_of(const ViewSpec& spec) {
  if (spec.kind == ViewSpec::Kind::Hmd)
    return spec.monitor.empty() ? "--view hmd" : "--view hmd:" + spec.monitor;
  return "--view window";
}

const char* const kAlternatives =
    "run it under xvfb-run for a virtual screen, or use --view png:DIR to write the view to files";

std::vector<MonitorInfo> list_monitors() {
  int count = 0;
  GLFWmonitor** monitors = glfwGetMonitors(&count);
  std::vector<MonitorInfo> out;
  for (int i = 0; i < count; ++i) {
    MonitorInfo m;
    const char* name = glfwGetMonitorName(monitors[i]);
    m.name = name ? name : "";
    int x = 0, y = 0;
    glfwGetMonitorPos(monitors[i], &x, &y);
    const GLFWvidmode* mode = glfwGetVideoMode(monitors[i]);
    m.rect = cv::Rect(x, y, mode ? mode->width : 0, mode ? mode->height : 0);
    m.refresh_hz = mode ? mode->refreshRate : 0;
    out.push_back(std::move(m));
  }
  return out;
}

// One ViewWindow at a time: GLFW is one per process.
std::atomic<bool> g_window_open{false};

}  // namespace

ViewSpec ViewSpec::parse(const std::string& text) {
  ViewSpec v;
  if (text.empty() || text == "none") return v;
  if (text == "window") {
    v.kind = Kind::Window;
    return v;
  }
  if (text == "hmd") {
    v.kind = Kind::Hmd;
    return v;
  }
  if (text == "openxr") {
    v.kind = Kind::OpenXr;
    return v;
  }
  if (text.rfind("hmd:", 0) == 0) {
    if (text.size() == 4)
      throw std::invalid_argument(
          "--view 'hmd:' names no monitor: give a monitor name or 0-based index after the colon, "
          "or plain 'hmd' for the last monitor");
    v.kind = Kind::Hmd;
    v.monitor = text.substr(4);
    return v;
  }
  if (text.rfind("png:", 0) == 0) {
    if (text.size() == 4) throw std::invalid_argument("--view 'png:' names no directory");
    v.kind = Kind::Png;
    v.dir = text.substr(4);
    return v;
  }
  throw std::invalid_argument("--view '" + text +
                              "': expected none, png:DIR, window, hmd, hmd:MONITOR or openxr");
}

std::int64_t display_period_ns(const MonitorInfo& monitor) {
  return 1'000'000'000 / (monitor.refresh_hz > 0 ? monitor.refresh_hz : 60);
}

std::string describe_monitors(std::span<const MonitorInfo> monitors) {
  if (monitors.empty()) return "none";
  std::string s;
  for (std::size_t i = 0; i < monitors.size(); ++i) {
    const auto& m = monitors[i];
    if (i) s += "; ";
    s += std::to_string(i) + ": '" + m.name + "' " + std::to_string(m.rect.width) + "x" +
         std::to_string(m.rect.height) + " at " + std::to_string(m.rect.x) + "," +
         std::to_string(m.rect.y);
  }
  return s;
}

std::size_t pick_monitor(std::span<const MonitorInfo> monitors, const std::string& want) {
  const std::string flag = want.empty() ? "--view hmd" : "--view hmd:" + want;
  if (monitors.empty())
    throw std::invalid_argument(flag + ": the display has no monitor connected");
  if (want.empty()) return monitors.size() - 1;
  for (std::size_t i = 0; i < monitors.size(); ++i)
    if (monitors[i].name == want) return i;
  const bool digits = want.size() <= 4 && std::all_of(want.begin(), want.end(),
                                                      [](char c) { return c >= '0' && c <= '9'; });
  if (digits) {
    const std::size_t index = std::stoul(want);
    if (index < monitors.size()) return index;
  }
  throw std::invalid_argument(
      flag + ": no monitor " +
      (digits ? "with index " + want + " or named '" + want + "'" : "named '" + want + "'") +
      "; monitors present: " + describe_monitors(monitors));
}

cv::Rect letterbox(cv::Size image, cv::Size target) {
  if (image.width <= 0 || image.height <= 0 || target.width <= 0 || target.height <= 0) return {};
  const std::int64_t iw = image.width, ih = image.height, tw = target.width, th = target.height;
  std::int64_t w = tw, h = th;
  if (tw * ih <= th * iw)
    h = std::max<std::int64_t>(1, (tw * ih * 2 + iw) / (2 * iw));  // width-bound: bars above, below
  else
    w = std::max<std::int64_t>(1,
                               (th * iw * 2 + ih) / (2 * ih));  // height-bound: bars at the sides
  return {static_cast<int>((tw - w) / 2), static_cast<int>((th - h) / 2), static_cast<int>(w),
          static_cast<int>(h)};
}

struct ViewWindow::Impl {
  GLFWwindow* window = nullptr;
  bool glfw_up = false;
  bool claimed = false;
  MonitorInfo monitor;
  GLuint texture = 0, read_fbo = 0;
  cv::Size image_size;  // of the texture's image; empty before the first
  GLint max_texture_px = 0;
  std::uint64_t shown = 0, uploaded = 0, dropped = 0;
  bool damaged = false;  // exposed or resized since the last draw

  ~Impl() {
    if (window) {
      glfwMakeContextCurrent(window);
      if (read_fbo) glDeleteFramebuffers(1, &read_fbo);
      if (texture) glDeleteTextures(1, &texture);
      glfwMakeContextCurrent(nullptr);
      glfwDestroyWindow(window);
    }
    if (glfw_up) glfwTerminate();
    glfwSetErrorCallback(nullptr);
    if (claimed) g_window_open.store(false);
  }

  void upload(const cv::Mat3b& bgr) {
    if (bgr.cols > max_texture_px || bgr.rows > max_texture_px) {
      ++dropped;
      return;
    }
    const cv::Mat3b packed = bgr.isContinuous() ? bgr : bgr.clone();
    glBindTexture(GL_TEXTURE_2D, texture);
    if (packed.size() != image_size) {
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, packed.cols, packed.rows, 0, GL_BGR, GL_UNSIGNED_BYTE,
                   packed.data);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, read_fbo);
      glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0);
      image_size = packed.size();
    } else {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, packed.cols, packed.rows, GL_BGR, GL_UNSIGNED_BYTE,
                      packed.data);
    }
    ++uploaded;
  }

  void draw() {
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(window, &fw, &fh);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glViewport(0, 0, fw, fh);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    const cv::Rect r = letterbox(image_size, {fw, fh});
    if (!r.empty()) {
      // Image rows run top-down in the texture and GL's window rows bottom-up: the destination's
      // top edge is given first, which flips the copy.
      glBindFramebuffer(GL_READ_FRAMEBUFFER, read_fbo);
      glBlitFramebuffer(0, 0, image_size.width, image_size.height, r.x, fh - r.y, r.x + r.width,
                        fh - r.y - r.height, GL_COLOR_BUFFER_BIT, GL_LINEAR);
    }
    glfwSwapBuffers(window);
    damaged = false;
    ++shown;
  }
};

ViewWindow::ViewWindow(const ViewSpec& spec, const std::string& title)
    : impl_(std::make_unique<Impl>()) {
  TELEX_DEMAND(spec.on_screen());
  TELEX_DEMAND(!g_window_open.exchange(true));
  impl_->claimed = true;
  const std::string flag = flag_of(spec);
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0') {
    const char* wayland = std::getenv("WAYLAND_DISPLAY");
    const bool on_wayland = wayland != nullptr && *wayland != '\0';
    throw std::invalid_argument(
        flag + " needs a display and DISPLAY is not set" +
        (on_wayland ? std::string(" (WAYLAND_DISPLAY is, but the view draws through X11: start "
                                  "XWayland, which sets DISPLAY)")
                    : std::string()) +
        "; " + kAlternatives);
  }
  glfwSetErrorCallback(record_glfw_error);
  if (glfwInit() != GLFW_TRUE)
    throw std::runtime_error(flag + ": cannot open the display DISPLAY=" + display + " (" +
                             take_glfw_error() +
                             "): is an X server running there, and may this user connect "
                             "(XAUTHORITY)? Otherwise " +
                             kAlternatives);
  impl_->glfw_up = true;

  const std::vector<MonitorInfo> monitors = list_monitors();
  GLFWmonitor* full_screen = nullptr;
  const GLFWvidmode* mode = nullptr;
  if (spec.kind == ViewSpec::Kind::Hmd) {
    const std::size_t i = pick_monitor(monitors, spec.monitor);
    int count = 0;
    full_screen = glfwGetMonitors(&count)[i];
    mode = glfwGetVideoMode(full_screen);
    impl_->monitor = monitors[i];
  } else if (GLFWmonitor* primary = glfwGetPrimaryMonitor()) {
    int count = 0;
    GLFWmonitor** all = glfwGetMonitors(&count);
    for (int i = 0; i < count; ++i)
      if (all[i] == primary) impl_->monitor = monitors[static_cast<std::size_t>(i)];
  }

  glfwDefaultWindowHints();
  // EGL, as the stereo renderer's headless context: one GL window system in the process.
  glfwWindowHint(GLFW_CONTEXT_CREATION_API, GLFW_EGL_CONTEXT_API);
  glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_API);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_DEPTH_BITS, 0);
  glfwWindowHint(GLFW_STENCIL_BITS, 0);
  int width = 1280, height = 480;  // the side-by-side pair at 1:1
  if (full_screen != nullptr) {
    // The monitor's current mode: a borderless full screen with no mode switch. An HMD must stay
    // up when the operator clicks on the other monitor.
    glfwWindowHint(GLFW_RED_BITS, mode->redBits);
    glfwWindowHint(GLFW_GREEN_BITS, mode->greenBits);
    glfwWindowHint(GLFW_BLUE_BITS, mode->blueBits);
    glfwWindowHint(GLFW_REFRESH_RATE, mode->refreshRate);
    glfwWindowHint(GLFW_AUTO_ICONIFY, GLFW_FALSE);
    width = mode->width;
    height = mode->height;
  } else {
    glfwWindowHint(GLFW_RESIZABLE, GLFW_TRUE);
  }
  impl_->window = glfwCreateWindow(width, height, title.c_str(), full_screen, nullptr);
  if (impl_->window == nullptr)
    throw std::runtime_error(flag + ": cannot create a window with an OpenGL 3.3 core context " +
                             "through EGL on DISPLAY=" + display + " (" + take_glfw_error() +
                             "); the view needs Mesa's EGL (Debian: libegl1 libegl-mesa0 "
                             "libgl1-mesa-dri)");
  glfwMakeContextCurrent(impl_->window);
  if (epoxy_gl_version() < 33)
    throw std::runtime_error(flag + ": OpenGL " + std::to_string(epoxy_gl_version()) +
                             " is below 3.3 core");
  glfwSwapInterval(1);  // present at the monitor's refresh where the driver syncs
  if (full_screen != nullptr) glfwSetInputMode(impl_->window, GLFW_CURSOR, GLFW_CURSOR_HIDDEN);
  glfwSetKeyCallback(impl_->window, [](GLFWwindow* w, int key, int, int action, int) {
    if (key == GLFW_KEY_ESCAPE && action == GLFW_PRESS) glfwSetWindowShouldClose(w, GLFW_TRUE);
  });

  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &impl_->max_texture_px);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glGenTextures(1, &impl_->texture);
  glBindTexture(GL_TEXTURE_2D, impl_->texture);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glGenFramebuffers(1, &impl_->read_fbo);
  // The window system asks for a redraw when part of the window was uncovered or it was resized.
  glfwSetWindowUserPointer(impl_->window, impl_.get());
  const auto damage = [](GLFWwindow* w) {
    static_cast<Impl*>(glfwGetWindowUserPointer(w))->damaged = true;
  };
  glfwSetWindowRefreshCallback(impl_->window, damage);
  glfwSetFramebufferSizeCallback(impl_->window, [](GLFWwindow* w, int, int) {
    static_cast<Impl*>(glfwGetWindowUserPointer(w))->damaged = true;
  });
  impl_->draw();  // black at once, not whatever the buffer held
  glfwPollEvents();
}

ViewWindow::~ViewWindow() = default;

void ViewWindow::show(const cv::Mat3b& bgr) {
  if (!bgr.empty()) impl_->upload(bgr);
  impl_->draw();
  glfwPollEvents();
}

void ViewWindow::refresh() {
  glfwPollEvents();
  if (impl_->damaged) impl_->draw();
}

bool ViewWindow::should_close() const { return glfwWindowShouldClose(impl_->window) == GLFW_TRUE; }

cv::Rect ViewWindow::client_rect() const {
  int x = 0, y = 0, w = 0, h = 0;
  glfwGetWindowPos(impl_->window, &x, &y);
  glfwGetWindowSize(impl_->window, &w, &h);
  return {x, y, w, h};
}

const MonitorInfo& ViewWindow::monitor() const { return impl_->monitor; }
std::uint64_t ViewWindow::frames_shown() const { return impl_->shown; }
std::uint64_t ViewWindow::images_uploaded() const { return impl_->uploaded; }
std::uint64_t ViewWindow::dropped() const { return impl_->dropped; }

std::string ViewWindow::gl_renderer() const {
  const auto* r = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  return r ? r : "";
}

}  // namespace telex::local
