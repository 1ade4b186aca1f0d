// SPDX-License-Identifier: MIT
// The view on a screen: the --view grammar, the monitor choice, the letterbox, and the GLFW window
// on a private Xvfb, read back from the X server's screen: the image lands letterboxed where the
// window is, full screen in hmd mode, follows a resize; Esc and the close button close it; the
// stereo renderer's EGL context on another thread coexists with the window's; no display and an
// unknown monitor are errors that say what to do.
#include "telex/local/view/view_window.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <thread>

#include "process.h"
#include "telex/base/latest_slot.h"
#include "telex/local/view/stereo_renderer.h"
#include "test_support.h"
#include "xvfb.h"

namespace telex::local {
namespace {

using namespace std::chrono_literals;

TEST(ViewSpec, ParsesEveryForm) {
  EXPECT_EQ(ViewSpec::parse("none").kind, ViewSpec::Kind::None);
  EXPECT_EQ(ViewSpec::parse("").kind, ViewSpec::Kind::None);
  const ViewSpec png = ViewSpec::parse("png:out/view");
  EXPECT_EQ(png.kind, ViewSpec::Kind::Png);
  EXPECT_EQ(png.dir, std::filesystem::path("out/view"));
  EXPECT_EQ(ViewSpec::parse("window").kind, ViewSpec::Kind::Window);
  const ViewSpec hmd = ViewSpec::parse("hmd");
  EXPECT_EQ(hmd.kind, ViewSpec::Kind::Hmd);
  EXPECT_TRUE(hmd.monitor.empty());
  const ViewSpec named = ViewSpec::parse("hmd:HDMI-A-1");
  EXPECT_EQ(named.kind, ViewSpec::Kind::Hmd);
  EXPECT_EQ(named.monitor, "HDMI-A-1");
  EXPECT_EQ(ViewSpec::parse("hmd:1").monitor, "1");
  EXPECT_TRUE(hmd.on_screen() && hmd.stereo());
  EXPECT_TRUE(!png.on_screen() && png.stereo());
  EXPECT_FALSE(ViewSpec::parse("none").stereo());
}

TEST(ViewSpec, RejectsWhatItDoesNotKnowNamingIt) {
  for (const char* bad : {"windows", "png:", "hmd:", "glfw", "window:1", "PNG:x"}) {
    try {
      ViewSpec::parse(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  try {
    ViewSpec::parse("glfw");
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("hmd:MONITOR"), std::string::npos) << e.what();
  }
}

std::vector<MonitorInfo> two_monitors() {
  return {{"eDP-1", {0, 0, 2560, 1600}}, {"HDMI-1", {2560, 0, 2160, 1200}}};
}

TEST(PickMonitor, ByNameByIndexAndTheLastByDefault) {
  const auto m = two_monitors();
  EXPECT_EQ(pick_monitor(m, ""), 1u);  // an HMD is usually the secondary monitor
  EXPECT_EQ(pick_monitor(m, "eDP-1"), 0u);
  EXPECT_EQ(pick_monitor(m, "HDMI-1"), 1u);
  EXPECT_EQ(pick_monitor(m, "0"), 0u);
  EXPECT_EQ(pick_monitor(m, "1"), 1u);
  // A monitor whose name is a number is found by its name first.
  const std::vector<MonitorInfo> numbered{{"1", {0, 0, 800, 600}}, {"0", {800, 0, 800, 600}}};
  EXPECT_EQ(pick_monitor(numbered, "0"), 1u);
}

TEST(DisplayPeriod, TheMonitorsRefreshOr60HzWhenItDoesNotSay) {
  EXPECT_EQ(display_period_ns({"HDMI-1", {0, 0, 1920, 1080}, 90}), 11'111'111);
  EXPECT_EQ(display_period_ns({"eDP-1", {0, 0, 2560, 1600}, 144}), 6'944'444);
  EXPECT_EQ(display_period_ns({"screen", {0, 0, 1920, 1080}, 0}), 16'666'666);
}

TEST(PickMonitor, AnUnknownMonitorIsNamedAndThoseThereAreListed) {
  const auto m = two_monitors();
  for (const std::string want : {"DP-3", "2", "hdmi-1"}) {
    try {
      pick_monitor(m, want);
      ADD_FAILURE() << "picked a monitor for '" << want << "'";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("--view hmd:" + want), std::string::npos) << what;
      EXPECT_NE(what.find("0: 'eDP-1' 2560x1600 at 0,0"), std::string::npos) << what;
      EXPECT_NE(what.find("1: 'HDMI-1' 2160x1200 at 2560,0"), std::string::npos) << what;
    }
  }
  EXPECT_THROW(pick_monitor({}, ""), std::invalid_argument);
}

TEST(Letterbox, KeepsTheAspectCentredWithBars) {
  // The side-by-side pair (8:3) on a 16:9 screen: bars above and below.
  EXPECT_EQ(letterbox({1280, 480}, {1920, 1080}), cv::Rect(0, 180, 1920, 720));
  // On a tall window: bars above and below; on a wide one: at the sides.
  EXPECT_EQ(letterbox({1280, 480}, {640, 480}), cv::Rect(0, 120, 640, 240));
  EXPECT_EQ(letterbox({1280, 480}, {2000, 480}), cv::Rect(360, 0, 1280, 480));
  EXPECT_EQ(letterbox({1280, 480}, {1280, 480}), cv::Rect(0, 0, 1280, 480));
  // Rounded to the nearest pixel, never empty for a non-empty target.
  EXPECT_EQ(letterbox({1280, 480}, {1000, 1}), cv::Rect(498, 0, 3, 1));
  EXPECT_EQ(letterbox({1280, 480}, {1, 1000}), cv::Rect(0, 499, 1, 1));
  EXPECT_TRUE(letterbox({0, 480}, {640, 480}).empty());
  EXPECT_TRUE(letterbox({1280, 480}, {0, 0}).empty());
}

// Sets an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value)
      setenv(name, value, 1);
    else
      unsetenv(name);
  }
  ~ScopedEnv() {
    if (old_)
      setenv(name_, old_->c_str(), 1);
    else
      unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

TEST(ViewWindow, WithoutDisplayItNamesDisplayAndSaysWhatToDo) {
  ScopedEnv display("DISPLAY", nullptr), wayland("WAYLAND_DISPLAY", nullptr);
  for (const char* spec : {"window", "hmd"}) {
    try {
      ViewWindow w(ViewSpec::parse(spec));
      ADD_FAILURE() << "opened a window with no DISPLAY";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("--view ") + spec), std::string::npos) << what;
      EXPECT_NE(what.find("DISPLAY is not set"), std::string::npos) << what;
      EXPECT_NE(what.find("--view png:DIR"), std::string::npos) << what;
      EXPECT_NE(what.find("xvfb-run"), std::string::npos) << what;
    }
  }
}

TEST(ViewWindow, ARefusingXServerIsNamedWithItsDisplay) {
  // A display number with no server behind it (Xvfb's sockets live in /tmp/.X11-unix).
  int n = 997;
  while (std::filesystem::exists("/tmp/.X11-unix/X" + std::to_string(n))) --n;
  const std::string name = ":" + std::to_string(n);
  ScopedEnv display("DISPLAY", name.c_str());
  try {
    ViewWindow w(ViewSpec::parse("window"));
    ADD_FAILURE() << "opened a window on " << name;
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("DISPLAY=" + name), std::string::npos) << what;
    EXPECT_NE(what.find("--view png:DIR"), std::string::npos) << what;
    EXPECT_NE(what.find("xvfb-run"), std::string::npos) << what;
  }
}

// A test pattern: the left half red, the right half green, a blue square in the left half and a
// white one in the right, and a grey gradient along the bottom (so a flipped or shifted copy
// shows).
cv::Mat3b pattern() {
  cv::Mat3b img(480, 1280, cv::Vec3b(0, 0, 255));
  img(cv::Rect(640, 0, 640, 480)).setTo(cv::Vec3b(0, 255, 0));
  img(cv::Rect(100, 100, 80, 80)).setTo(cv::Vec3b(255, 0, 0));
  img(cv::Rect(1000, 300, 80, 80)).setTo(cv::Vec3b(255, 255, 255));
  for (int x = 0; x < img.cols; ++x)
    img(cv::Rect(x, 440, 1, 40)).setTo(cv::Vec3b::all(static_cast<std::uint8_t>(x * 255 / 1279)));
  return img;
}

// The screen's pixel where image point `p` (image pixels) lands in letterbox rectangle `r`.
cv::Vec3b screen_at(const cv::Mat3b& screen, const cv::Rect& r, cv::Size image, cv::Point2d p) {
  const double sx = static_cast<double>(r.width) / image.width;
  const double sy = static_cast<double>(r.height) / image.height;
  return screen(static_cast<int>(r.y + (p.y + 0.5) * sy), static_cast<int>(r.x + (p.x + 0.5) * sx));
}

// Mean absolute difference per channel between the screen's rectangle `r`, scaled back to the
// image's size, and the image.
double mean_difference(const cv::Mat3b& screen, const cv::Rect& r, const cv::Mat3b& image) {
  cv::Mat3b back;
  cv::resize(screen(r), back, image.size(), 0, 0, cv::INTER_AREA);
  cv::Mat diff;
  cv::absdiff(back, image, diff);
  const cv::Scalar m = cv::mean(diff);
  return (m[0] + m[1] + m[2]) / 3.0;
}

// Checks that `screen` shows `image` letterboxed in `client` (screen coordinates): black bars,
// each region's colour where it should be, and the whole scaled back close to the image.
void expect_shown(const cv::Mat3b& screen, const cv::Rect& client, const cv::Mat3b& image,
                  const std::string& what) {
  SCOPED_TRACE(what);
  const cv::Rect lb = letterbox(image.size(), client.size()) + client.tl();
  const cv::Vec3b black(0, 0, 0);
  if (lb.y > client.y) {
    EXPECT_EQ(screen(client.y + 2, client.x + client.width / 2), black);
    EXPECT_EQ(screen(client.br().y - 3, client.x + client.width / 2), black);
  }
  if (lb.x > client.x) {
    EXPECT_EQ(screen(client.y + client.height / 2, client.x + 2), black);
    EXPECT_EQ(screen(client.y + client.height / 2, client.br().x - 3), black);
  }
  EXPECT_EQ(screen_at(screen, lb, image.size(), {320, 50}), cv::Vec3b(0, 0, 255));   // red
  EXPECT_EQ(screen_at(screen, lb, image.size(), {960, 50}), cv::Vec3b(0, 255, 0));   // green
  EXPECT_EQ(screen_at(screen, lb, image.size(), {140, 140}), cv::Vec3b(255, 0, 0));  // blue
  EXPECT_EQ(screen_at(screen, lb, image.size(), {1040, 340}), cv::Vec3b(255, 255, 255));
  // The gradient's dark end is on the left, at the bottom (not flipped either way).
  EXPECT_LT(screen_at(screen, lb, image.size(), {20, 470})[0], 30);
  EXPECT_GT(screen_at(screen, lb, image.size(), {1260, 470})[0], 225);
  EXPECT_LT(mean_difference(screen, lb, image), 3.0);
}

// One private X server for the suite, with DISPLAY pointing at it while the suite runs.
class OnXvfb : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (test::xvfb_binary().empty()) return;
    // One folder per process: ctest runs each test as its own process, in parallel, and a shared
    // folder let one test read another's display number (and lose it when that one ended).
    dir_ = new std::filesystem::path(
        test::scratch_dir("view_window_xvfb_" + std::to_string(::getpid())));
    xvfb_ = new test::Xvfb(*dir_);
    display_ = new ScopedEnv("DISPLAY", xvfb_->display().c_str());
  }
  static void TearDownTestSuite() {
    delete display_;
    delete xvfb_;
    delete dir_;
    display_ = nullptr;
    xvfb_ = nullptr;
    dir_ = nullptr;
  }
  void SetUp() override {
    TELEX_SKIP_UNLESS(xvfb_ != nullptr,
                      "Xvfb is not installed (Debian: xvfb, which tools/setup.sh installs)");
  }
  // The one window on the screen (no window manager runs: the view's is the only one).
  unsigned long only_window() const {
    const auto w = xvfb_->windows();
    EXPECT_EQ(w.size(), 1u);
    return w.empty() ? 0 : w.front();
  }
  // The screen once `image` shows letterboxed in `client` (the swap's image reaches the X server
  // on the view's own connection, which the server need not serve before this one), or after 3 s.
  cv::Mat3b grab_showing(const cv::Rect& client, const cv::Mat3b& image) const {
    const cv::Rect lb = letterbox(image.size(), client.size()) + client.tl();
    cv::Mat3b screen;
    test::eventually(3s, [&] {
      screen = xvfb_->grab();
      return mean_difference(screen, lb, image) < 3.0;
    });
    return screen;
  }
  void save(const cv::Mat3b& screen, const std::string& name) const {
    cv::imwrite((*dir_ / (name + ".png")).string(), screen);
  }
  static std::filesystem::path* dir_;
  static test::Xvfb* xvfb_;
  static ScopedEnv* display_;
};
std::filesystem::path* OnXvfb::dir_ = nullptr;
test::Xvfb* OnXvfb::xvfb_ = nullptr;
ScopedEnv* OnXvfb::display_ = nullptr;

TEST_F(OnXvfb, HmdFillsTheLastMonitorAndShowsThePairLetterboxed) {
  ViewWindow w(ViewSpec::parse("hmd"));
  std::cout << "GL renderer: " << w.gl_renderer() << "; monitor '" << w.monitor().name << "'\n";
  EXPECT_EQ(w.monitor().rect, cv::Rect(0, 0, 1920, 1080));
  EXPECT_EQ(w.client_rect(), cv::Rect(0, 0, 1920, 1080));
  const cv::Mat3b img = pattern();
  w.show(img);
  const cv::Mat3b screen = grab_showing(w.client_rect(), img);
  save(screen, "hmd");
  expect_shown(screen, {0, 0, 1920, 1080}, img, "hmd");
  EXPECT_EQ(w.images_uploaded(), 1u);
  EXPECT_FALSE(w.should_close());
}

TEST_F(OnXvfb, HmdByNameAndByIndexFindTheSameMonitor) {
  std::string name;
  {
    ViewWindow w(ViewSpec::parse("hmd:0"));
    name = w.monitor().name;
    EXPECT_EQ(w.client_rect(), cv::Rect(0, 0, 1920, 1080));
  }
  ASSERT_FALSE(name.empty());
  ViewWindow w(ViewSpec::parse("hmd:" + name));
  EXPECT_EQ(w.monitor().name, name);
  EXPECT_EQ(w.client_rect(), cv::Rect(0, 0, 1920, 1080));
}

TEST_F(OnXvfb, AnUnknownHmdMonitorIsNamedAndXvfbsMonitorListed) {
  for (const char* want : {"HDMI-9", "3"}) {
    try {
      ViewWindow w(ViewSpec::parse(std::string("hmd:") + want));
      ADD_FAILURE() << "opened hmd:" << want;
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string("--view hmd:") + want), std::string::npos) << what;
      EXPECT_NE(what.find("monitors present: 0: '"), std::string::npos) << what;
      EXPECT_NE(what.find("1920x1080 at 0,0"), std::string::npos) << what;
    }
  }
  // The failed attempts left GLFW closed: a window opens afterwards.
  ViewWindow w(ViewSpec::parse("hmd"));
  EXPECT_EQ(w.client_rect().size(), cv::Size(1920, 1080));
}

TEST_F(OnXvfb, AWindowShowsThePairAtItsSizeFollowsAResizeAndClosesOnEsc) {
  ViewWindow w(ViewSpec::parse("window"));
  const cv::Rect client = w.client_rect();
  ASSERT_EQ(client.size(), cv::Size(1280, 480));
  const cv::Mat3b img = pattern();
  w.show(img);
  cv::Mat3b screen = grab_showing(client, img);
  save(screen, "window");
  // 1:1: every pixel as sent.
  cv::Mat diff;
  cv::absdiff(screen(client), img, diff);
  double max_diff = 0;
  cv::minMaxLoc(diff.reshape(1), nullptr, &max_diff);
  EXPECT_LE(max_diff, 1.0);

  // Half as wide: the pair keeps its aspect, with bars above and below.
  const unsigned long id = only_window();
  xvfb_->resize(id, {640, 480});
  ASSERT_TRUE(test::eventually(2s, [&] {
    w.refresh();
    return w.client_rect().size() == cv::Size(640, 480);
  }));
  // Redrawn unasked: the resize damaged the window.
  screen = grab_showing(w.client_rect(), img);
  save(screen, "window_resized");
  expect_shown(screen, w.client_rect(), img, "resized to 640x480");
  // Wider than the pair: bars at the sides.
  xvfb_->resize(id, {1600, 400});
  ASSERT_TRUE(test::eventually(2s, [&] {
    w.refresh();
    return w.client_rect().size() == cv::Size(1600, 400);
  }));
  w.show({});
  expect_shown(grab_showing(w.client_rect(), img), w.client_rect(), img, "resized to 1600x400");

  EXPECT_FALSE(w.should_close());
  xvfb_->press_escape(id);
  EXPECT_TRUE(test::eventually(2s, [&] {
    w.refresh();
    return w.should_close();
  }));
}

TEST_F(OnXvfb, TheCloseButtonClosesIt) {
  ViewWindow w(ViewSpec::parse("window"));
  w.show(pattern());
  xvfb_->request_close(only_window());
  EXPECT_TRUE(test::eventually(2s, [&] {
    w.refresh();
    return w.should_close();
  }));
}

// The station's arrangement: the stereo renderer's headless EGL context on its own thread hands
// each frame to the main thread, whose window context shows it; both render at once, with
// libepoxy resolving GL for both.
TEST_F(OnXvfb, TheStereoRenderersThreadFeedsTheWindowOnTheMainThread) {
  ViewWindow w(ViewSpec::parse("hmd"));
  LatestSlot<cv::Mat3b> frames;
  constexpr int kFrames = 20;
  std::atomic<bool> done{false};
  std::exception_ptr error;
  std::thread renderer([&] {
    try {
      StereoRenderer r(640, 480);
      EyeView e;
      e.k = kinect_v1_intrinsics(640, 480);
      for (int i = 0; i < kFrames; ++i) {
        // The background's blue counts the frames; a capsule sits in front of the eye.
        e.background = cv::Mat3b(480, 640, cv::Vec3b(static_cast<std::uint8_t>(10 * i), 60, 30));
        const std::vector<Capsule> body{{{-0.1, 0.0, 0.8}, {0.1, 0.0, 0.8}, 0.05, {40, 90, 250}}};
        const cv::Mat3b eye = r.render(e, body);
        cv::Mat3b sbs;
        cv::hconcat(eye, eye, sbs);
        frames.put(sbs);
        std::this_thread::sleep_for(10ms);
      }
    } catch (...) {
      error = std::current_exception();
    }
    done.store(true);
  });
  cv::Mat3b last;
  int shown = 0;
  for (;;) {
    const bool finished = done.load();  // read first: a frame put before it is taken below
    if (auto f = frames.take(20ms)) {
      w.show(*f);
      last = *f;
      ++shown;
    } else if (finished) {
      break;
    }
  }
  renderer.join();
  if (error) std::rethrow_exception(error);
  ASSERT_FALSE(last.empty());
  EXPECT_GT(shown, 1);
  EXPECT_EQ(last(5, 5), cv::Vec3b(static_cast<std::uint8_t>(10 * (kFrames - 1)), 60,
                                  30));  // the last frame came through
  const cv::Mat3b screen = grab_showing({0, 0, 1920, 1080}, last);
  save(screen, "renderer_thread");
  const cv::Rect lb = letterbox(last.size(), {1920, 1080});
  EXPECT_LT(mean_difference(screen, lb, last), 3.0);
  // The capsule (red above blue) in both halves on the screen; the window's scaling blends
  // neighbouring pixels, and the body's light varies across it, so within a few levels.
  for (const double cx : {320.0, 960.0}) {
    const cv::Vec3b got = screen_at(screen, lb, last.size(), {cx, 240});
    const cv::Vec3b want = last(240, static_cast<int>(cx));
    EXPECT_GT(want[2], want[0] + 60) << "the capsule is not at the frame's centre";
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 3) << "channel " << c;
  }
}

}  // namespace
}  // namespace telex::local
