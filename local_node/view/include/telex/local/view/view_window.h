// SPDX-License-Identifier: MIT
// The operator's view on a screen: the --view grammar (none | png:DIR | window | hmd[:MONITOR] |
// openxr)
// and a GLFW window on the station's main thread that shows the side-by-side stereo image,
// letterboxed, in a desktop window or full screen on the head-mounted display's monitor.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

namespace telex::local {

// What --view asks for. One parser for telex-local's flag check and the station.
struct ViewSpec {
  // OpenXr: a headset through its OpenXR runtime
  // (local_node/view/include/telex/local/view/openxr_output.h), no window.
  enum class Kind { None, Png, Window, Hmd, OpenXr };
  Kind kind = Kind::None;
  std::filesystem::path dir;  // Png: left.png, right.png, sbs.png and view.png go here
  std::string monitor;        // Hmd: a GLFW monitor name or a 0-based index; empty: the last one

  // "none" (or ""), "png:DIR", "window", "hmd", "hmd:MONITOR", "openxr". Throws
  // std::invalid_argument naming the text and the forms accepted.
  static ViewSpec parse(const std::string& text);
  bool on_screen() const { return kind == Kind::Window || kind == Kind::Hmd; }
  bool stereo() const { return kind != Kind::None; }  // the stereo view thread runs
};

// A monitor as GLFW reports it (on X11 the RandR output's name, as `xrandr` lists it).
struct MonitorInfo {
  std::string name;
  cv::Rect rect;       // on the virtual desktop, pixels: position and current mode's size
  int refresh_hz = 0;  // the current mode's refresh rate; 0: the window system does not say
};

// The period a view on `monitor` draws at: its refresh's, or 60 Hz's when it does not say.
std::int64_t display_period_ns(const MonitorInfo& monitor);

// The monitor `want` names among `monitors`: an exact name first, then a 0-based index; an empty
// `want` picks the last (an HMD is usually the secondary monitor). Throws std::invalid_argument
// naming `want` and listing the monitors present.
std::size_t pick_monitor(std::span<const MonitorInfo> monitors, const std::string& want);

// "0: 'HDMI-1' 1920x1080 at 0,0; 1: ..." (or "none"), for error messages and logs.
std::string describe_monitors(std::span<const MonitorInfo> monitors);

// The largest rectangle of `image`'s aspect ratio centred in `target` (bars above and below, or
// left and right), in target pixels with the origin at the top left. Empty when either is empty.
cv::Rect letterbox(cv::Size image, cv::Size target);

// A GLFW window with an OpenGL 3.3 core context made through EGL (the stereo renderer's headless
// context is EGL too, so one process never mixes GLX and EGL under libepoxy). GLFW must be used
// from the process's main thread: construct, call and destroy a ViewWindow there, one at a time.
class ViewWindow {
 public:
  // Window: a resizable 1280x480 window (the side-by-side pair's size). Hmd: full screen at the
  // monitor's current mode (no mode switch), no cursor, not iconified when it loses focus.
  // Throws std::invalid_argument when DISPLAY is not set or the monitor is unknown (the message
  // lists the monitors), std::runtime_error when the X server refuses or no context can be made.
  explicit ViewWindow(const ViewSpec& spec, const std::string& title = "telex-local");
  ~ViewWindow();
  ViewWindow(const ViewWindow&) = delete;
  ViewWindow& operator=(const ViewWindow&) = delete;

  // Draws `bgr` (BGR, top row first; empty: the last image again, black before the first)
  // letterboxed into the window at its current size, swaps buffers (waiting for the monitor's
  // refresh where the driver syncs) and handles the window's events. Never throws: an image
  // larger than the GL's texture limit is counted in dropped() and not shown.
  void show(const cv::Mat3b& bgr);
  // Handles pending events (Esc, close, resize), and draws the last image again only when the
  // window system asked for it (uncovered, resized): a GPU-less machine pays 30-80 ms for a full
  // HD swap, so nothing is redrawn unasked.
  void refresh();
  // Esc was pressed or the window was closed.
  bool should_close() const;

  cv::Rect client_rect() const;        // the drawable area on the virtual desktop
  const MonitorInfo& monitor() const;  // Hmd: the monitor it fills; Window: the one it opened on
  std::uint64_t frames_shown() const;  // swaps
  std::uint64_t images_uploaded() const;
  std::uint64_t dropped() const;
  std::string gl_renderer() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace telex::local
