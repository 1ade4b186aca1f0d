// SPDX-License-Identifier: MIT
// ROS 1 bags as a depth source (sensor_msgs/Image 16UC1 or 32FC1 with its CameraInfo) and as the
// eye view (a colour Image topic), played at the recorded pace by header stamps.
#include <fmt/format.h>

#include <cmath>
#include <optional>
#include <stdexcept>
#include <thread>

#include "source_impl.h"
#include "telex/bag/bag.h"

namespace telex::remote {

namespace {

bool is_depth_encoding(const std::string& e) {
  return e == "16UC1" || e == "mono16" || e == "32FC1";
}

const bag::TopicInfo* find_topic(const bag::Reader& r, const std::string& name) {
  for (const auto& t : r.topics())
    if (t.topic == name) return &t;
  return nullptr;
}

// The depth topic: the one asked for, or the only Image topic with a depth encoding.
std::string choose_depth_topic(const bag::Reader& r, const std::string& asked) {
  if (!asked.empty()) {
    const auto* t = find_topic(r, asked);
    if (t == nullptr)
      throw std::runtime_error(
          fmt::format("bag {} has no topic {}; it holds {}", r.path(), asked, r.describe_topics()));
    if (t->type != "sensor_msgs/Image" || !is_depth_encoding(t->encoding))
      throw std::runtime_error(fmt::format(
          "bag {} topic {} is {} {}, not a depth image (sensor_msgs/Image 16UC1 in millimetres "
          "or 32FC1 in metres); it holds {}",
          r.path(), asked, t->type, t->encoding, r.describe_topics()));
    return asked;
  }
  std::vector<std::string> depth;
  for (const auto& t : r.topics())
    if (t.type == "sensor_msgs/Image" && is_depth_encoding(t.encoding)) depth.push_back(t.topic);
  if (depth.empty())
    throw std::runtime_error(
        fmt::format("bag {} holds no depth image topic (sensor_msgs/Image 16UC1 or 32FC1); it "
                    "holds {}",
                    r.path(), r.describe_topics()));
  if (depth.size() > 1)
    throw std::runtime_error(
        fmt::format("bag {} holds {} depth image topics; choose one with topic=T (it holds {})",
                    r.path(), depth.size(), r.describe_topics()));
  return depth.front();
}

// The CameraInfo topic: the one asked for, the depth topic's sibling camera_info, or the only one.
std::string choose_info_topic(const bag::Reader& r, const std::string& asked,
                              const std::string& depth_topic) {
  if (!asked.empty()) {
    const auto* t = find_topic(r, asked);
    if (t == nullptr || t->type != "sensor_msgs/CameraInfo")
      throw std::runtime_error(
          fmt::format("bag {} has no sensor_msgs/CameraInfo topic {}; it holds {}", r.path(), asked,
                      r.describe_topics()));
    return asked;
  }
  const std::string sibling = depth_topic.substr(0, depth_topic.rfind('/') + 1) + "camera_info";
  std::vector<std::string> infos;
  for (const auto& t : r.topics()) {
    if (t.type != "sensor_msgs/CameraInfo") continue;
    if (t.topic == sibling) return sibling;
    infos.push_back(t.topic);
  }
  if (infos.size() == 1) return infos.front();
  throw std::runtime_error(fmt::format(
      "bag {}: no intrinsics for {}: {} sensor_msgs/CameraInfo topics and none is {}; choose one "
      "with info=T (it holds {})",
      r.path(), depth_topic, infos.size(), sibling, r.describe_topics()));
}

// Metres (NaN, Inf, <= 0 or beyond 65.535 m = no data) to millimetres.
cv::Mat1w millimetres(const cv::Mat& image) {
  if (image.type() == CV_16UC1) return image;
  cv::Mat1w out(image.size());
  for (int r = 0; r < image.rows; ++r) {
    const float* in = image.ptr<float>(r);
    auto* o = out.ptr<std::uint16_t>(r);
    for (int c = 0; c < image.cols; ++c) {
      const double mm = std::round(static_cast<double>(in[c]) * 1000.0);
      o[c] = (std::isfinite(mm) && mm > 0 && mm <= 65535) ? static_cast<std::uint16_t>(mm) : 0;
    }
  }
  return out;
}

double parse_rate(const SourceSpec& spec) {
  if (!spec.has("rate")) return 1.0;
  const std::string& text = spec.options.at("rate");
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !(v > 0.0) || !std::isfinite(v))
    throw std::invalid_argument(fmt::format(
        "source 'bag': rate='{}' is not a positive number (1 = the recorded pace)", text));
  return v;
}

}  // namespace

// Empty when the intrinsics can project: fx, fy, cx, cy finite and positive, a positive size.
std::string camera_info_error(const bag::CameraIntrinsics& c) {
  const std::pair<const char*, double> values[] = {
      {"fx (K[0])", c.fx}, {"fy (K[4])", c.fy}, {"cx (K[2])", c.cx}, {"cy (K[5])", c.cy}};
  for (const auto& [name, v] : values)
    if (!std::isfinite(v) || !(v > 0.0))
      return fmt::format("{} = {} is not a finite positive number of pixels", name, v);
  if (c.width <= 0 || c.height <= 0)
    return fmt::format("width x height = {}x{} is not a positive image size", c.width, c.height);
  return {};
}

namespace {

// Messages of one image topic (and optionally its CameraInfo) in order, each due at the recorded
// pace: first one now, the n-th at (stamp_n - stamp_0) / rate later. Looping restarts the pace
// one recorded period after the last frame.
class BagImageStream {
 public:
  BagImageStream(std::string path, double rate, bool fast, bool loop)
      : path_(std::move(path)), rate_(rate), fast_(fast), loop_(loop) {}

  void open(const std::string& image_topic, const std::string& info_topic) {
    reader_ = std::make_unique<bag::Reader>(path_);
    image_topic_ = image_topic;
    info_topic_ = info_topic;
    rewind();
    origin_wall_ns_ = 0;
  }
  bag::Reader& reader() { return *reader_; }

  // The next image message, waiting for its time. Timeout when not due within `timeout`.
  ReadStatus next(std::chrono::milliseconds timeout, bag::Message& out, std::string& error) {
    try {
      if (!pending_) {
        bag::Message m;
        for (;;) {
          if (!reader_->next(m)) {
            if (!loop_ || images_ == 0) return ReadStatus::EndOfStream;
            // Play on one recorded period after the last frame.
            loop_offset_ns_ += last_stamp_ns_ - first_stamp_ns_ + period_ns_;
            rewind();
            continue;
          }
          if (m.kind == bag::Message::Kind::CameraInfo) {
            camera_ = m.camera;
            continue;
          }
          if (m.topic == image_topic_ && m.kind == bag::Message::Kind::Image) break;
        }
        if (images_ == 0 && loop_offset_ns_ == 0) first_stamp_ns_ = m.stamp_ns;
        if (images_ > 0 && m.stamp_ns > last_stamp_ns_) period_ns_ = m.stamp_ns - last_stamp_ns_;
        last_stamp_ns_ = m.stamp_ns;
        ++images_;
        pending_ = std::move(m);
      }
      if (!fast_) {
        const std::int64_t now = steady_now_ns();
        const std::int64_t recorded = pending_->stamp_ns - first_stamp_ns_ + loop_offset_ns_;
        if (origin_wall_ns_ == 0)
          origin_wall_ns_ = now - static_cast<std::int64_t>(recorded / rate_);
        const std::int64_t due = origin_wall_ns_ + static_cast<std::int64_t>(recorded / rate_);
        const std::int64_t wait = due - now;
        if (wait > std::chrono::duration_cast<std::chrono::nanoseconds>(timeout).count()) {
          std::this_thread::sleep_for(timeout);
          return ReadStatus::Timeout;
        }
        if (wait > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(wait));
      }
      out = std::move(*pending_);
      pending_.reset();
      scene_time_s_ = static_cast<double>(out.stamp_ns - first_stamp_ns_ + loop_offset_ns_) / 1e9;
      return ReadStatus::Frame;
    } catch (const std::exception& e) {
      error = e.what();
      return ReadStatus::Error;
    }
  }
  const bag::CameraIntrinsics& camera() const { return camera_; }
  double scene_time_s() const { return scene_time_s_; }
  std::string pace() const {
    return fast_ ? "as fast as read" : rate_ == 1.0 ? "recorded pace" : fmt::format("{}x", rate_);
  }
  bool loop() const { return loop_; }

 private:
  void rewind() {
    std::vector<std::string> topics{image_topic_};
    if (!info_topic_.empty()) topics.push_back(info_topic_);
    reader_->select(topics);
    pending_.reset();
  }

  std::string path_;
  double rate_;
  bool fast_, loop_;
  std::unique_ptr<bag::Reader> reader_;
  std::string image_topic_, info_topic_;
  std::optional<bag::Message> pending_;
  bag::CameraIntrinsics camera_;
  std::uint64_t images_ = 0;
  std::int64_t first_stamp_ns_ = 0, last_stamp_ns_ = 0, period_ns_ = 33'333'333;
  std::int64_t loop_offset_ns_ = 0, origin_wall_ns_ = 0;
  double scene_time_s_ = 0;
};

class BagDepthSource final : public DepthSource {
 public:
  BagDepthSource(const SourceSpec& spec)
      : spec_(spec),
        stream_(spec.arg, parse_rate(spec), spec.has("fast"), spec.has("loop")),
        asked_topic_(spec.has("topic") ? spec.options.at("topic") : ""),
        asked_info_(spec.has("info") ? spec.options.at("info") : ""),
        rate_(parse_rate(spec)) {}

  void start() override {
    // Choose the topics with a reader of its own, then stream with the stream's.
    bag::Reader r(spec_.arg);
    topic_ = choose_depth_topic(r, asked_topic_);
    info_ = choose_info_topic(r, asked_info_, topic_);
    for (const auto& t : r.topics())
      if (t.topic == topic_) {
        messages_ = t.messages;
        encoding_ = t.encoding;
        fps_ = t.rate_hz() > 0 ? t.rate_hz() : 30.0;
      }
    // The intrinsics are known before the first frame: the first CameraInfo of the topic.
    r.select({info_});
    bag::Message m;
    if (!r.next(m))
      throw std::runtime_error(
          fmt::format("bag {}: CameraInfo topic {} holds no message", spec_.arg, info_));
    if (const std::string bad = camera_info_error(m.camera); !bad.empty())
      throw std::runtime_error(
          fmt::format("bag {}: CameraInfo topic {}: {}", spec_.arg, info_, bad));
    intrinsics_ = to_intrinsics(m.camera);
    stream_.open(topic_, info_);
    frames_ = 0;
  }
  void stop() override {}

  ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<DepthFrame> out;
    bag::Message m;
    out.status = stream_.next(timeout, m, out.error);
    if (out.status != ReadStatus::Frame) return out;
    if (m.image.empty()) {
      out.status = ReadStatus::Error;
      out.error = fmt::format("bag {} topic {}: unsupported encoding '{}' (16UC1 or 32FC1)",
                              spec_.arg, topic_, m.encoding);
      return out;
    }
    if (const std::string bad = camera_info_error(stream_.camera()); !bad.empty()) {
      out.status = ReadStatus::Error;
      out.error = fmt::format("bag {}: CameraInfo topic {}: {}", spec_.arg, info_, bad);
      return out;
    }
    const Intrinsics k = to_intrinsics(stream_.camera());
    if (k.width != m.image.cols || k.height != m.image.rows) {
      out.status = ReadStatus::Error;
      out.error =
          fmt::format("bag {} topic {}: image {}x{} but CameraInfo {} says {}x{}", spec_.arg,
                      topic_, m.image.cols, m.image.rows, info_, k.width, k.height);
      return out;
    }
    out.frame.image.depth_mm = millimetres(m.image);
    out.frame.image.intrinsics = k;
    out.frame.capture_ns = steady_now_ns();
    out.frame.frame_id = ++frames_;
    out.frame.scene_time_s = stream_.scene_time_s();
    return out;
  }

  Intrinsics intrinsics() const override { return intrinsics_; }
  // The recorded rate, scaled by rate=R (the pipeline's pacing and the stats line use it).
  double nominal_fps() const override { return fps_ * rate_; }
  std::int64_t frame_count() const override { return static_cast<std::int64_t>(messages_); }
  bool plays_once() const override { return !stream_.loop(); }
  std::string describe() const override {
    return fmt::format("bag:{} ({} {}, {} frames, intrinsics from {}, {}{})", spec_.arg, topic_,
                       encoding_, messages_, info_, stream_.pace(), stream_.loop() ? ", loop" : "");
  }

 private:
  static Intrinsics to_intrinsics(const bag::CameraIntrinsics& c) {
    Intrinsics k;
    k.fx = c.fx;
    k.fy = c.fy;
    k.cx = c.cx;
    k.cy = c.cy;
    k.width = c.width;
    k.height = c.height;
    return k;
  }

  SourceSpec spec_;
  BagImageStream stream_;
  std::string asked_topic_, asked_info_;
  double rate_;
  std::string topic_, info_, encoding_;
  std::uint64_t messages_ = 0, frames_ = 0;
  double fps_ = 30.0;
  Intrinsics intrinsics_;
};

// A colour topic as the eye view: one camera, so both eyes see the same image.
class BagColourSource final : public StereoSource {
 public:
  explicit BagColourSource(const SourceSpec& spec)
      : spec_(spec),
        stream_(spec.arg, parse_rate(spec), spec.has("fast"), spec.has("loop")),
        topic_(spec.options.at("colour")) {}
  void start() override {
    bag::Reader r(spec_.arg);
    const auto* t = find_topic(r, topic_);
    if (t == nullptr || t->type != "sensor_msgs/Image")
      throw std::runtime_error(fmt::format("bag {} has no sensor_msgs/Image topic {}; it holds {}",
                                           spec_.arg, topic_, r.describe_topics()));
    messages_ = t->messages;
    stream_.open(topic_, "");
  }
  void stop() override {}
  ReadResult<StereoFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<StereoFrame> out;
    bag::Message m;
    out.status = stream_.next(timeout, m, out.error);
    if (out.status != ReadStatus::Frame) return out;
    if (m.image.type() != CV_8UC3) {
      out.status = ReadStatus::Error;
      out.error = fmt::format("bag {} topic {}: encoding '{}' is not colour (bgr8, rgb8, ...)",
                              spec_.arg, topic_, m.encoding);
      return out;
    }
    out.frame.left_bgr = m.image;
    out.frame.right_bgr = m.image;
    out.frame.capture_ns = steady_now_ns();
    out.frame.frame_id = ++frames_;
    return out;
  }
  std::int64_t frame_count() const override { return static_cast<std::int64_t>(messages_); }
  bool plays_once() const override { return !stream_.loop(); }
  std::string describe() const override {
    return fmt::format("bag:{} colour {} (both eyes{})", spec_.arg, topic_,
                       stream_.loop() ? ", loop" : "");
  }

 private:
  SourceSpec spec_;
  BagImageStream stream_;
  std::string topic_;
  std::uint64_t frames_ = 0, messages_ = 0;
};

void check_bag_spec(const SourceSpec& spec) {
  detail::require_options(spec, {"topic", "info", "colour", "loop", "rate", "fast"});
  if (spec.arg.empty())
    throw std::invalid_argument(
        "source 'bag' needs a file: bag:FILE[,topic=T][,info=T][,colour=T][,loop][,rate=R|fast]");
  if (spec.has("rate") && spec.has("fast"))
    throw std::invalid_argument("source 'bag': choose one of rate=R and fast");
  parse_rate(spec);
}

}  // namespace

namespace detail {

std::unique_ptr<DepthSource> make_bag_depth_source(const SourceSpec& spec, const SourceOptions&) {
  check_bag_spec(spec);
  return std::make_unique<BagDepthSource>(spec);
}

std::unique_ptr<StereoSource> make_bag_colour_source(const SourceSpec& spec, const SourceOptions&) {
  check_bag_spec(spec);
  if (!spec.has("colour") || spec.options.at("colour").empty())
    throw std::invalid_argument("stereo source 'bag' needs colour=TOPIC (the eye view's topic)");
  return std::make_unique<BagColourSource>(spec);
}

}  // namespace detail

}  // namespace telex::remote
