// SPDX-License-Identifier: MIT
// Depth and stereo sources that run without hardware: image sequences and the synthetic renderer.
#include <fmt/format.h>
#include <glob.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <stdexcept>
#include <thread>

#include "source_impl.h"
#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "telex/remote/synthetic_view.h"
#include "telex/video/frame_counter.h"

namespace telex::remote {

namespace {

std::vector<std::string> expand_glob(const std::string& pattern) {
  glob_t g{};
  const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
  std::vector<std::string> out;
  if (rc == 0)
    for (std::size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
  globfree(&g);
  std::sort(out.begin(), out.end());
  return out;
}

double parse_positive(const SourceSpec& spec, const std::string& key, double fallback) {
  if (!spec.has(key)) return fallback;
  const std::string& text = spec.options.at(key);
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !(v > 0.0) || !std::isfinite(v))
    throw std::invalid_argument(
        fmt::format("source '{}': {}='{}' is not a positive number", spec.kind, key, text));
  return v;
}

// Paces a sequence at a nominal rate: frames are due at start + n / fps on the steady clock.
// Waits at most `timeout`; returns false when the frame is not yet due by then.
class Pacer {
 public:
  explicit Pacer(double fps) : period_ns_(static_cast<std::int64_t>(1e9 / fps)) {}
  bool wait_due(std::chrono::milliseconds timeout) {
    const std::int64_t now = steady_now_ns();
    if (next_ns_ == 0) next_ns_ = now;
    const std::int64_t wait = next_ns_ - now;
    if (wait > std::chrono::duration_cast<std::chrono::nanoseconds>(timeout).count()) {
      std::this_thread::sleep_for(timeout);
      return false;
    }
    if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
    // A consumer that fell behind does not get a burst of catch-up frames.
    next_ns_ = std::max(next_ns_ + period_ns_, steady_now_ns());
    return true;
  }
  void reset() { next_ns_ = 0; }

 private:
  std::int64_t period_ns_;
  std::int64_t next_ns_ = 0;
};

// Where the file sources are in their sorted file list: paced at the nominal rate, looping or
// ending after the last file.
class FileCursor {
 public:
  FileCursor(double fps, bool loop) : pacer_(fps), loop_(loop) {}
  void restart() {
    next_ = 0;
    pacer_.reset();
  }
  // The index of the next of `count` files, or nothing with `out` saying why: not started (an
  // error naming `what`), end of stream, or not due within `timeout` (a timeout).
  template <typename T>
  std::optional<std::size_t> take(std::size_t count, std::chrono::milliseconds timeout,
                                  const char* what, ReadResult<T>& out) {
    if (count == 0) {
      out.status = ReadStatus::Error;
      out.error = std::string(what) + " read before start";
      return std::nullopt;
    }
    if (next_ >= count) {
      if (!loop_) {
        out.status = ReadStatus::EndOfStream;
        return std::nullopt;
      }
      next_ = 0;
    }
    if (!pacer_.wait_due(timeout)) return std::nullopt;  // Timeout
    return next_++;
  }
  bool loop() const { return loop_; }

 private:
  Pacer pacer_;
  bool loop_;
  std::size_t next_ = 0;
};

// A looping replay decodes each file once and keeps it while the frames fit in 256 MiB, as a
// camera hands frames over without decoding a PNG (3.3 ms per 640x480 depth frame and about 7 ms
// per colour one on the bench machine, on the CPUs the pipeline and the encoder run on). Frames
// go in and out as deep copies: the pipeline works on what it is handed in place.
template <typename Frame>
class DecodedFrames {
 public:
  DecodedFrames(Frame (*copy)(const Frame&), std::size_t (*bytes)(const Frame&))
      : copy_(copy), bytes_of_(bytes) {}
  void reset(std::size_t count) {
    frames_.assign(count, std::nullopt);
    bytes_ = 0;
  }
  std::optional<Frame> find(std::size_t i) const {
    if (i >= frames_.size() || !frames_[i]) return std::nullopt;
    return copy_(*frames_[i]);
  }
  void keep(std::size_t i, const Frame& frame) {
    const std::size_t bytes = bytes_of_(frame);
    if (i >= frames_.size() || frames_[i] || bytes_ + bytes > kBudgetBytes) return;
    frames_[i] = copy_(frame);
    bytes_ += bytes;
  }

 private:
  static constexpr std::size_t kBudgetBytes = std::size_t{256} << 20;
  Frame (*copy_)(const Frame&);
  std::size_t (*bytes_of_)(const Frame&);
  std::vector<std::optional<Frame>> frames_;  // by file index
  std::size_t bytes_ = 0;
};

DepthImage copy_depth(const DepthImage& d) {
  DepthImage out = d;
  out.depth_mm = d.depth_mm.clone();
  return out;
}
std::size_t depth_bytes(const DepthImage& d) { return d.depth_mm.total() * d.depth_mm.elemSize(); }

StereoFrame copy_pair(const StereoFrame& f) {
  StereoFrame out = f;
  out.left_bgr = f.left_bgr.clone();
  out.right_bgr = f.right_bgr.clone();
  return out;
}
std::size_t pair_bytes(const StereoFrame& f) {
  return f.left_bgr.total() * f.left_bgr.elemSize() + f.right_bgr.total() * f.right_bgr.elemSize();
}

class FilesDepthSource final : public DepthSource {
 public:
  FilesDepthSource(std::string pattern, DepthUnits units, double fps, bool loop)
      : pattern_(std::move(pattern)), units_(units), fps_(fps), cursor_(fps, loop) {}

  void start() override {
    files_ = expand_glob(pattern_);
    if (files_.empty())
      throw std::runtime_error(fmt::format(
          "depth files '{}' match no file (quote the pattern so the shell does not expand it)",
          pattern_));
    // Load the first frame now so a bad file or unit fails at start-up, not in the loop.
    const DepthImage first = load_depth(files_.front(), units_);
    intrinsics_ = first.intrinsics;
    decoded_.reset(cursor_.loop() ? files_.size() : 0);
    frames_ = 0;
    cursor_.restart();
  }
  void stop() override {}

  ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<DepthFrame> out;
    const auto next = cursor_.take(files_.size(), timeout, "files source", out);
    if (!next) return out;
    const std::string& file = files_[*next];
    if (auto kept = decoded_.find(*next)) {
      out.frame.image = std::move(*kept);
    } else {
      try {
        out.frame.image = load_depth(file, units_);
      } catch (const std::exception& e) {
        out.status = ReadStatus::Error;
        out.error = e.what();
        return out;
      }
      decoded_.keep(*next, out.frame.image);
    }
    out.frame.capture_ns = steady_now_ns();
    out.frame.frame_id = ++frames_;
    out.frame.scene_time_s = static_cast<double>(frames_ - 1) / fps_;
    out.status = ReadStatus::Frame;
    return out;
  }

  Intrinsics intrinsics() const override { return intrinsics_; }
  double nominal_fps() const override { return fps_; }
  std::int64_t frame_count() const override { return static_cast<std::int64_t>(files_.size()); }
  bool plays_once() const override { return !cursor_.loop(); }
  std::string describe() const override {
    return fmt::format("files:{} ({} files, {}, {} fps{})", pattern_, files_.size(),
                       to_string(units_), fps_, cursor_.loop() ? ", loop" : "");
  }

 private:
  std::string pattern_;
  DepthUnits units_;
  double fps_;
  FileCursor cursor_;
  std::vector<std::string> files_;
  DecodedFrames<DepthImage> decoded_{copy_depth, depth_bytes};  // while looping
  std::uint64_t frames_ = 0;
  Intrinsics intrinsics_;
};

// What the synthetic depth and eye sources share: the scene by name, its time (from the frame
// count, not the wall clock, so a run is reproducible), the pace and the camera.
struct SyntheticClock {
  SyntheticClock(std::string name, bool animate_scene, const SourceOptions& options)
      : scene_name(std::move(name)),
        animate(animate_scene),
        fps(options.synthetic_fps),
        pacer(options.synthetic_fps),
        intrinsics(kinect_v1_intrinsics(options.width, options.height)) {}
  void start() {
    scene = synth::Scene::named(scene_name);  // throws naming the valid scenes
    frames = 0;
    pacer.reset();
  }
  // The next frame's scene time once it is due within `timeout`; nothing at the timeout.
  std::optional<double> due(std::chrono::milliseconds timeout) {
    if (!pacer.wait_due(timeout)) return std::nullopt;
    return animate ? static_cast<double>(frames) / fps : 0.0;
  }
  std::string name_suffix() const { return scene_name + (animate ? ",animate" : ""); }

  std::string scene_name;
  bool animate;
  double fps;
  Pacer pacer;
  Intrinsics intrinsics;
  synth::Scene scene;
  std::uint64_t frames = 0;
};

class SyntheticDepthSource final : public DepthSource {
 public:
  SyntheticDepthSource(std::string scene_name, bool animate, bool noise,
                       const SourceOptions& options)
      : clock_(std::move(scene_name), animate, options),
        head_orientation_(options.head_orientation) {
    sensor_ = noise ? synth::SensorModel{} : synth::SensorModel::ideal();
    sensor_.seed = options.seed;
  }

  void start() override {
    clock_.start();
    // The incremental renderer re-casts only what moved: a static scene costs the sensor pass
    // alone per frame, with output identical to render() (SyntheticRenderer tests).
    renderer_.emplace(clock_.intrinsics, sensor_);
  }
  void stop() override {}

  ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<DepthFrame> out;
    const std::optional<double> due = clock_.due(timeout);
    if (!due) return out;
    const double t_s = *due;
    if (!renderer_) renderer_.emplace(clock_.intrinsics, sensor_);
    const std::int64_t capture_ns = steady_now_ns();
    synth::Scene scene = clock_.scene.at_time(t_s);
    // On a driven head the scene stays in the head base's frame: the camera turns (a full render:
    // every object moved in the camera's frame).
    if (head_orientation_)
      if (const auto R_BaseCamera = head_orientation_(capture_ns))
        scene = scene.seen_from(glm::transpose(*R_BaseCamera));
    auto rendered = renderer_->render(scene, clock_.frames);
    out.frame.image = std::move(rendered.depth);
    out.frame.capture_ns = capture_ns;
    out.frame.frame_id = ++clock_.frames;
    out.frame.scene_time_s = t_s;
    out.status = ReadStatus::Frame;
    return out;
  }

  Intrinsics intrinsics() const override { return clock_.intrinsics; }
  double nominal_fps() const override { return clock_.fps; }
  std::string describe() const override {
    return fmt::format("synthetic:{} ({}x{} @ {} fps)", clock_.name_suffix(),
                       clock_.intrinsics.width, clock_.intrinsics.height, clock_.fps);
  }

 private:
  SyntheticClock clock_;
  synth::SensorModel sensor_;
  std::optional<synth::Renderer> renderer_;
  std::function<std::optional<glm::dmat3>(std::int64_t)> head_orientation_;
};

class FilesStereoSource final : public StereoSource {
 public:
  FilesStereoSource(std::string left, std::string right, double fps, bool loop)
      : left_pattern_(std::move(left)), right_pattern_(std::move(right)), cursor_(fps, loop) {}
  void start() override {
    left_ = expand_glob(left_pattern_);
    right_ = expand_glob(right_pattern_);
    if (left_.empty())
      throw std::runtime_error(fmt::format("left images '{}' match no file", left_pattern_));
    if (right_.empty())
      throw std::runtime_error(fmt::format("right images '{}' match no file", right_pattern_));
    if (left_.size() != right_.size())
      throw std::runtime_error(
          fmt::format("left images '{}' ({}) and right images '{}' ({}) differ in count",
                      left_pattern_, left_.size(), right_pattern_, right_.size()));
    decoded_.reset(cursor_.loop() ? left_.size() : 0);
    cursor_.restart();
  }
  void stop() override {}
  ReadResult<StereoFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<StereoFrame> out;
    const auto next = cursor_.take(left_.size(), timeout, "files stereo source", out);
    if (!next) return out;
    const std::size_t i = *next;
    if (auto kept = decoded_.find(i)) {
      out.frame = std::move(*kept);
    } else {
      out.frame.left_bgr = cv::imread(left_[i], cv::IMREAD_COLOR);
      out.frame.right_bgr = cv::imread(right_[i], cv::IMREAD_COLOR);
      if (out.frame.left_bgr.empty() || out.frame.right_bgr.empty()) {
        out.status = ReadStatus::Error;
        out.error = fmt::format("cannot read image '{}'",
                                out.frame.left_bgr.empty() ? left_[i] : right_[i]);
        return out;
      }
      decoded_.keep(i, out.frame);
    }
    out.frame.capture_ns = steady_now_ns();
    out.frame.frame_id = ++frames_;
    out.status = ReadStatus::Frame;
    return out;
  }
  std::int64_t frame_count() const override { return static_cast<std::int64_t>(left_.size()); }
  bool plays_once() const override { return !cursor_.loop(); }
  std::string describe() const override {
    return fmt::format("files:{},{} ({} pairs{})", left_pattern_, right_pattern_, left_.size(),
                       cursor_.loop() ? ", loop" : "");
  }

 private:
  std::string left_pattern_, right_pattern_;
  FileCursor cursor_;
  std::vector<std::string> left_, right_;
  DecodedFrames<StereoFrame> decoded_{copy_pair, pair_bytes};  // while looping
  std::uint64_t frames_ = 0;
};

class SyntheticStereoSource final : public StereoSource {
 public:
  SyntheticStereoSource(std::string scene_name, bool animate, const SourceOptions& options)
      : clock_(std::move(scene_name), animate, options) {}
  void start() override {
    clock_.start();
    still_.reset();
  }
  void stop() override {}
  ReadResult<StereoFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<StereoFrame> out;
    const std::optional<double> due = clock_.due(timeout);
    if (!due) return out;
    const double t_s = *due;
    // A still scene is ray-cast once (two full renders cost far more than a frame period); each
    // frame then gets its own copy.
    std::optional<StereoViews> moving;
    if (clock_.animate)
      moving = render_stereo_views(clock_.scene.at_time(t_s), clock_.intrinsics);
    else if (!still_)
      still_ = render_stereo_views(clock_.scene.at_time(0.0), clock_.intrinsics);
    const StereoViews& views = clock_.animate ? *moving : *still_;
    out.frame.left_bgr = views.left_bgr.clone();
    out.frame.right_bgr = views.right_bgr.clone();
    out.frame.capture_ns = steady_now_ns();
    out.frame.frame_id = ++clock_.frames;
    // Glass to glass: the frame id in both eyes' top-left corner, for the station to read back
    // from what it shows (telex/video/frame_counter.h; the low 32 bits).
    const auto counter = static_cast<std::uint32_t>(out.frame.frame_id);
    video::stamp_frame_counter(out.frame.left_bgr, counter);
    video::stamp_frame_counter(out.frame.right_bgr, counter);
    out.status = ReadStatus::Frame;
    return out;
  }
  std::string describe() const override {
    return fmt::format("synthetic:{} stereo", clock_.name_suffix());
  }

 private:
  SyntheticClock clock_;
  std::optional<StereoViews> still_;
};

// The default scene animates; a named static scene animates only when asked.
bool wants_animation(const SourceSpec& spec, const std::string& scene) {
  return spec.has("animate") || scene == "moving";
}

}  // namespace

namespace detail {

std::unique_ptr<DepthSource> make_files_depth_source(const SourceSpec& spec, const SourceOptions&) {
  require_options(spec, {"units", "fps", "loop"});
  if (spec.arg.empty())
    throw std::invalid_argument(
        "source 'files' needs a pattern: files:PATTERN[,units=mm|tum|kinect-disparity]");
  const DepthUnits units =
      spec.has("units") ? parse_depth_units(spec.options.at("units")) : DepthUnits::Millimetres;
  return std::make_unique<FilesDepthSource>(spec.arg, units, parse_positive(spec, "fps", 30.0),
                                            spec.has("loop"));
}

std::unique_ptr<DepthSource> make_synthetic_depth_source(const SourceSpec& spec,
                                                         const SourceOptions& options) {
  require_options(spec, {"animate", "noise"});
  const std::string scene = spec.arg.empty() ? "moving" : spec.arg;
  const auto names = synth::Scene::names();
  if (std::find(names.begin(), names.end(), scene) == names.end())
    synth::Scene::named(scene);  // throws the renderer's message listing the valid scenes
  bool noise = true;
  if (spec.has("noise")) {
    const auto& v = spec.options.at("noise");
    if (v != "on" && v != "off")
      throw std::invalid_argument(
          fmt::format("source 'synthetic': noise='{}' is not on or off", v));
    noise = v == "on";
  }
  return std::make_unique<SyntheticDepthSource>(scene, wants_animation(spec, scene), noise,
                                                options);
}

std::unique_ptr<StereoSource> make_files_stereo_source(const SourceSpec& spec,
                                                       const SourceOptions&) {
  if (spec.arg.empty() || spec.flags.empty())
    throw std::invalid_argument(
        "stereo source 'files' needs two patterns: files:LEFT_PATTERN,RIGHT_PATTERN");
  const std::string right = spec.flags[0];
  SourceSpec rest = spec;
  rest.options.erase(right);
  require_options(rest, {"fps", "loop"});
  return std::make_unique<FilesStereoSource>(spec.arg, right, parse_positive(spec, "fps", 30.0),
                                             spec.has("loop"));
}

std::unique_ptr<StereoSource> make_synthetic_stereo_source(const SourceSpec& spec,
                                                           const SourceOptions& options) {
  require_options(spec, {"animate"});
  const std::string scene = spec.arg.empty() ? "moving" : spec.arg;
  synth::Scene::named(scene);
  return std::make_unique<SyntheticStereoSource>(scene, wants_animation(spec, scene), options);
}

}  // namespace detail

}  // namespace telex::remote
