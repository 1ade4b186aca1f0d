// SPDX-License-Identifier: MIT
// A private X server for tests of the on-screen view: Xvfb on a display number it picks itself,
// the screen read back through Xlib, and what a person does to a window (Esc, the close button,
// a resize) sent as X events.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "process.h"

namespace telex::test {

// The Xvfb binary on PATH; empty when it is not installed (Debian: xvfb; tools/setup.sh has it).
std::filesystem::path xvfb_binary();

class Xvfb {
 public:
  // Starts Xvfb with one screen of `size` at 24 bits per pixel and no TCP listener. -displayfd
  // lets the server take the first free display number itself, so tests running at once never
  // race for one. Throws std::runtime_error when it is not accepting connections within 10 s.
  explicit Xvfb(const std::filesystem::path& dir, cv::Size size = {1920, 1080});
  ~Xvfb();  // SIGTERM, then waits for it
  Xvfb(const Xvfb&) = delete;
  Xvfb& operator=(const Xvfb&) = delete;

  const std::string& display() const { return display_; }  // ":N"
  cv::Size size() const { return size_; }

  // The whole screen as BGR, read from the root window with XGetImage.
  cv::Mat3b grab() const;
  // The mapped top-level windows (the root's children), as X window ids.
  std::vector<unsigned long> windows() const;
  // A key press and release of Escape, sent to window `w`.
  void press_escape(unsigned long w) const;
  // A window manager's close button: WM_DELETE_WINDOW, sent to window `w`.
  void request_close(unsigned long w) const;
  // Resizes window `w` (no window manager runs, so the server applies it as asked).
  void resize(unsigned long w, cv::Size size) const;

 private:
  Process proc_;
  std::string display_;
  cv::Size size_;
  void* x_ = nullptr;  // Display*: Xlib's macros stay out of the tests' headers
};

}  // namespace telex::test
