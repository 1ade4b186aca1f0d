// SPDX-License-Identifier: MIT
// A private X server for tests of the on-screen view.
#include "xvfb.h"

#include <X11/Xatom.h>
#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/keysym.h>
#include <signal.h>

#include <chrono>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace telex::test {
namespace {

std::vector<std::string> xvfb_argv(cv::Size size) {
  const std::filesystem::path bin = xvfb_binary();
  if (bin.empty()) throw std::runtime_error("Xvfb is not installed (Debian: xvfb)");
  return {bin.string(), "-displayfd",
          "1",          "-screen",
          "0",          std::to_string(size.width) + "x" + std::to_string(size.height) + "x24",
          "-nolisten",  "tcp"};
}

Display* dpy(void* x) { return static_cast<Display*>(x); }

// The bit position of a mask's lowest set bit and its width (a TrueColor visual's channel).
std::pair<int, int> mask_shift(unsigned long mask) {
  int shift = 0, bits = 0;
  while (mask && !(mask & 1)) {
    mask >>= 1;
    ++shift;
  }
  while (mask & 1) {
    mask >>= 1;
    ++bits;
  }
  return {shift, bits};
}

}  // namespace

std::filesystem::path xvfb_binary() {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "/usr/bin:/bin");
  std::string d;
  while (std::getline(dirs, d, ':')) {
    if (d.empty()) continue;
    const auto p = std::filesystem::path(d) / "Xvfb";
    std::error_code ec;
    if (std::filesystem::is_regular_file(p, ec)) return p;
  }
  return {};
}

Xvfb::Xvfb(const std::filesystem::path& dir, cv::Size size)
    : proc_(xvfb_argv(size), dir / "xvfb.out", dir / "xvfb.err"), size_(size) {
  // Xvfb writes its display number to the -displayfd descriptor once it accepts connections.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (std::chrono::steady_clock::now() < deadline) {
    const std::string out = read_text(dir / "xvfb.out");
    if (out.find('\n') != std::string::npos) {
      display_ = ":" + out.substr(0, out.find('\n'));
      break;
    }
    if (!proc_.running())
      throw std::runtime_error("Xvfb exited at start-up: " + proc_.stderr_text());
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  if (display_.empty()) throw std::runtime_error("Xvfb gave no display number within 10 s");
  x_ = XOpenDisplay(display_.c_str());
  if (x_ == nullptr) throw std::runtime_error("cannot connect to Xvfb at " + display_);
}

Xvfb::~Xvfb() {
  if (x_) XCloseDisplay(dpy(x_));
  proc_.signal(SIGTERM);
  proc_.wait(std::chrono::seconds(5));
}

cv::Mat3b Xvfb::grab() const {
  Display* d = dpy(x_);
  XSync(d, False);
  XImage* img = XGetImage(d, DefaultRootWindow(d), 0, 0, static_cast<unsigned>(size_.width),
                          static_cast<unsigned>(size_.height), AllPlanes, ZPixmap);
  if (img == nullptr) throw std::runtime_error("XGetImage of the root window failed");
  const auto [rs, rb] = mask_shift(img->red_mask);
  const auto [gs, gb] = mask_shift(img->green_mask);
  const auto [bs, bb] = mask_shift(img->blue_mask);
  const auto channel = [](unsigned long pixel, int shift, int bits) {
    const unsigned long v = (pixel >> shift) & ((1ul << bits) - 1);
    return static_cast<std::uint8_t>(bits >= 8 ? v >> (bits - 8) : v << (8 - bits));
  };
  cv::Mat3b out(size_);
  for (int y = 0; y < size_.height; ++y)
    for (int x = 0; x < size_.width; ++x) {
      const unsigned long p = XGetPixel(img, x, y);
      out(y, x) = {channel(p, bs, bb), channel(p, gs, gb), channel(p, rs, rb)};
    }
  XDestroyImage(img);
  return out;
}

std::vector<unsigned long> Xvfb::windows() const {
  Display* d = dpy(x_);
  XSync(d, False);
  Window root = 0, parent = 0;
  Window* children = nullptr;
  unsigned count = 0;
  std::vector<unsigned long> out;
  if (!XQueryTree(d, DefaultRootWindow(d), &root, &parent, &children, &count)) return out;
  for (unsigned i = 0; i < count; ++i) {
    XWindowAttributes a;
    if (XGetWindowAttributes(d, children[i], &a) && a.map_state == IsViewable)
      out.push_back(children[i]);
  }
  if (children) XFree(children);
  return out;
}

void Xvfb::press_escape(unsigned long w) const {
  Display* d = dpy(x_);
  XKeyEvent ev{};
  ev.display = d;
  ev.window = w;
  ev.root = DefaultRootWindow(d);
  ev.subwindow = None;
  ev.time = CurrentTime;
  ev.same_screen = True;
  ev.keycode = XKeysymToKeycode(d, XK_Escape);
  for (const int type : {KeyPress, KeyRelease}) {
    ev.type = type;
    XSendEvent(d, w, True, type == KeyPress ? KeyPressMask : KeyReleaseMask,
               reinterpret_cast<XEvent*>(&ev));
  }
  XFlush(d);
}

void Xvfb::request_close(unsigned long w) const {
  Display* d = dpy(x_);
  XEvent ev{};
  ev.xclient.type = ClientMessage;
  ev.xclient.window = w;
  ev.xclient.message_type = XInternAtom(d, "WM_PROTOCOLS", False);
  ev.xclient.format = 32;
  ev.xclient.data.l[0] = static_cast<long>(XInternAtom(d, "WM_DELETE_WINDOW", False));
  ev.xclient.data.l[1] = CurrentTime;
  XSendEvent(d, w, False, NoEventMask, &ev);
  XFlush(d);
}

void Xvfb::resize(unsigned long w, cv::Size size) const {
  Display* d = dpy(x_);
  XResizeWindow(d, w, static_cast<unsigned>(size.width), static_cast<unsigned>(size.height));
  XSync(d, False);
}

}  // namespace telex::test
