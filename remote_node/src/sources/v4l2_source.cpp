// SPDX-License-Identifier: MIT
// V4L2 stereo source: two cameras through libv4l2, mmap streaming, YUYV or MJPEG.
#include <fcntl.h>
#include <fmt/format.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "source_impl.h"
#include "telex/remote/v4l2_convert.h"
#include "telex/video/eye_pairer.h"

namespace telex::remote {

namespace {

int xioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = v4l2_ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

// One camera: opened, format negotiated, buffers mapped and queued by start().
class V4l2Camera {
 public:
  V4l2Camera(std::string path, int width, int height, std::uint32_t want_format)
      : path_(std::move(path)), width_(width), height_(height), want_format_(want_format) {}
  ~V4l2Camera() { stop(); }

  void start() {
    struct stat st {};
    if (::stat(path_.c_str(), &st) != 0)
      throw std::runtime_error(
          fmt::format("V4L2 device '{}' does not exist ({}); list cameras with "
                      "'v4l2-ctl --list-devices' or use 'files:' or 'synthetic' stereo",
                      path_, std::strerror(errno)));
    if (!S_ISCHR(st.st_mode))
      throw std::runtime_error(fmt::format("V4L2 device '{}' is not a device node", path_));
    fd_ = v4l2_open(path_.c_str(), O_RDWR | O_NONBLOCK);
    if (fd_ < 0)
      throw std::runtime_error(
          fmt::format("cannot open V4L2 device '{}': {}", path_, std::strerror(errno)));
    v4l2_capability cap{};
    if (xioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0 || !(cap.capabilities & V4L2_CAP_VIDEO_CAPTURE) ||
        !(cap.capabilities & V4L2_CAP_STREAMING))
      fail("is not a streaming video capture device");
    // Preference: the requested format, then MJPEG (USB bandwidth for two cameras), then YUYV.
    std::vector<std::uint32_t> order;
    if (want_format_ != 0) order.push_back(want_format_);
    for (auto f : {kFourccMjpeg, kFourccYuyv})
      if (f != want_format_) order.push_back(f);
    bool negotiated = false;
    for (auto f : order) {
      v4l2_format fmt_req{};
      fmt_req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      fmt_req.fmt.pix.width = static_cast<unsigned>(width_);
      fmt_req.fmt.pix.height = static_cast<unsigned>(height_);
      fmt_req.fmt.pix.pixelformat = f;
      fmt_req.fmt.pix.field = V4L2_FIELD_NONE;
      if (xioctl(fd_, VIDIOC_S_FMT, &fmt_req) == 0 && fmt_req.fmt.pix.pixelformat == f) {
        format_ = f;
        width_ = static_cast<int>(fmt_req.fmt.pix.width);
        height_ = static_cast<int>(fmt_req.fmt.pix.height);
        bytes_per_line_ = static_cast<int>(fmt_req.fmt.pix.bytesperline);
        negotiated = true;
        break;
      }
    }
    if (!negotiated) fail("offers neither MJPEG nor YUYV");
    v4l2_requestbuffers req{};
    req.count = 4;
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_REQBUFS, &req) != 0 || req.count < 2) fail("refused mmap buffers");
    for (unsigned i = 0; i < req.count; ++i) {
      v4l2_buffer buf{};
      buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buf.memory = V4L2_MEMORY_MMAP;
      buf.index = i;
      if (xioctl(fd_, VIDIOC_QUERYBUF, &buf) != 0) fail("QUERYBUF failed");
      void* p =
          v4l2_mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
      if (p == MAP_FAILED) fail("mmap failed");
      buffers_.push_back({p, buf.length});
      if (xioctl(fd_, VIDIOC_QBUF, &buf) != 0) fail("QBUF failed");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_STREAMON, &type) != 0) fail("STREAMON failed");
  }

  void stop() {
    if (fd_ < 0) return;
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(fd_, VIDIOC_STREAMOFF, &type);
    for (auto& b : buffers_) v4l2_munmap(b.data, b.length);
    buffers_.clear();
    v4l2_close(fd_);
    fd_ = -1;
  }

  // Dequeues one frame within the timeout: BGR image plus the driver's timestamp (monotonic ns).
  // An MJPEG camera's JPEG is kept in `jpeg` as it came (for pass-through); else it is cleared.
  ReadStatus read(std::chrono::milliseconds timeout, cv::Mat3b& bgr,
                  std::vector<std::uint8_t>& jpeg, std::int64_t& stamp_ns, std::string& error) {
    pollfd pfd{fd_, POLLIN, 0};
    const int pr = ::poll(&pfd, 1, static_cast<int>(timeout.count()));
    if (pr == 0) return ReadStatus::Timeout;
    if (pr < 0) {
      error = fmt::format("poll on '{}' failed: {}", path_, std::strerror(errno));
      return ReadStatus::Error;
    }
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_DQBUF, &buf) != 0) {
      if (errno == EAGAIN) return ReadStatus::Timeout;
      error = fmt::format("DQBUF on '{}' failed: {}", path_, std::strerror(errno));
      return ReadStatus::Error;
    }
    const auto& mapped = buffers_.at(buf.index);
    const std::span<const std::uint8_t> bytes(static_cast<const std::uint8_t*>(mapped.data),
                                              buf.bytesused);
    auto converted = convert_v4l2_buffer(format_, bytes, width_, height_, bytes_per_line_);
    if (format_ == kFourccMjpeg)
      jpeg.assign(bytes.begin(), bytes.end());
    else
      jpeg.clear();
    // Drivers stamp with CLOCK_MONOTONIC, the same clock as steady_clock on Linux.
    const bool monotonic =
        (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    stamp_ns = monotonic ? static_cast<std::int64_t>(buf.timestamp.tv_sec) * 1'000'000'000 +
                               buf.timestamp.tv_usec * 1000
                         : steady_now_ns();
    xioctl(fd_, VIDIOC_QBUF, &buf);
    if (!converted.ok()) {
      error = fmt::format("'{}': {}", path_, converted.error);
      return ReadStatus::Error;
    }
    bgr = converted.bgr;
    return ReadStatus::Frame;
  }

  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(std::string_view what) {
    const std::string msg =
        fmt::format("V4L2 device '{}' {} ({})", path_, what, std::strerror(errno));
    stop();
    throw std::runtime_error(msg);
  }

  struct Mapped {
    void* data;
    std::size_t length;
  };
  std::string path_;
  int width_, height_;
  std::uint32_t want_format_;
  std::uint32_t format_ = 0;
  int bytes_per_line_ = 0;
  int fd_ = -1;
  std::vector<Mapped> buffers_;
};

class V4l2StereoSource final : public StereoSource {
 public:
  V4l2StereoSource(std::string left, std::string right, int w, int h, std::uint32_t format)
      : left_(std::move(left), w, h, format), right_(std::move(right), w, h, format) {}
  void start() override {
    left_.start();
    right_.start();
  }
  void stop() override {
    left_.stop();
    right_.stop();
  }
  // The two cameras run free: each eye's frames are paired by their driver timestamps within half
  // a 30 Hz period (video::EyePairer); a frame the other eye has no partner for is dropped. The
  // eye with fewer frames waiting is read next, so a pair needs two reads when both keep time.
  ReadResult<StereoFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<StereoFrame> out;
    for (int reads = 0; reads < 4; ++reads) {
      const auto eye = pairer_.waiting(video::Eye::Left) <= pairer_.waiting(video::Eye::Right)
                           ? video::Eye::Left
                           : video::Eye::Right;
      EyeImage image;
      std::int64_t stamp_ns = 0;
      out.status = (eye == video::Eye::Left ? left_ : right_)
                       .read(timeout, image.bgr, image.jpeg, stamp_ns, out.error);
      if (out.status != ReadStatus::Frame) return out;
      auto pair = pairer_.push(eye, std::move(image), stamp_ns);
      if (!pair) continue;
      out.frame.left_bgr = pair->left.bgr;
      out.frame.right_bgr = pair->right.bgr;
      out.frame.left_jpeg = std::move(pair->left.jpeg);
      out.frame.right_jpeg = std::move(pair->right.jpeg);
      out.frame.capture_ns = pair->capture_ns;  // the older eye's
      out.frame.frame_id = ++frames_;
      return out;
    }
    out.status = ReadStatus::Timeout;  // no pair yet: the eyes' clocks disagree, or one stalls
    return out;
  }
  std::string describe() const override {
    return fmt::format("v4l2:{},{}", left_.path(), right_.path());
  }

 private:
  struct EyeImage {
    cv::Mat3b bgr;
    std::vector<std::uint8_t> jpeg;  // MJPEG cameras: the JPEG as it came
  };
  V4l2Camera left_, right_;
  video::EyePairer<EyeImage> pairer_{1'000'000'000 / 30};
  std::uint64_t frames_ = 0;
};

}  // namespace

namespace detail {

std::unique_ptr<StereoSource> make_v4l2_stereo_source(const SourceSpec& spec,
                                                      const SourceOptions& options) {
  if (spec.arg.empty() || spec.flags.size() != 1)
    throw std::invalid_argument(
        "source 'v4l2' needs two devices: "
        "v4l2:/dev/videoL,/dev/videoR[,size=WxH][,format=yuyv|mjpeg]");
  const std::string right = spec.flags[0];
  SourceSpec rest = spec;
  rest.options.erase(right);
  require_options(rest, {"size", "format"});
  int w = options.width, h = options.height;
  if (spec.has("size") && std::sscanf(spec.options.at("size").c_str(), "%dx%d", &w, &h) != 2)
    throw std::invalid_argument(
        fmt::format("source 'v4l2': size '{}' is not WxH", spec.options.at("size")));
  std::uint32_t format = 0;
  if (spec.has("format")) {
    const auto& f = spec.options.at("format");
    if (f == "yuyv")
      format = kFourccYuyv;
    else if (f == "mjpeg")
      format = kFourccMjpeg;
    else
      throw std::invalid_argument(
          fmt::format("source 'v4l2': format '{}' is not yuyv or mjpeg", f));
  }
  return std::make_unique<V4l2StereoSource>(spec.arg, right, w, h, format);
}

}  // namespace detail

std::vector<V4l2DeviceInfo> list_v4l2_devices(const std::string& dev_dir) {
  std::vector<std::filesystem::path> paths;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dev_dir, ec))
    if (e.path().filename().string().rfind("video", 0) == 0) paths.push_back(e.path());
  std::sort(paths.begin(), paths.end());
  std::vector<V4l2DeviceInfo> out;
  for (const auto& p : paths) {
    V4l2DeviceInfo info;
    info.path = p.string();
    const int fd = v4l2_open(info.path.c_str(), O_RDWR | O_NONBLOCK);
    if (fd < 0) {
      info.error = fmt::format("cannot open as a video device: {}", std::strerror(errno));
      out.push_back(info);
      continue;
    }
    v4l2_capability cap{};
    if (xioctl(fd, VIDIOC_QUERYCAP, &cap) != 0) {
      info.error = fmt::format("VIDIOC_QUERYCAP: {}", std::strerror(errno));
    } else {
      info.card = reinterpret_cast<const char*>(cap.card);
      info.driver = reinterpret_cast<const char*>(cap.driver);
      info.bus = reinterpret_cast<const char*>(cap.bus_info);
      const std::uint32_t caps =
          (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
      info.capture = (caps & V4L2_CAP_VIDEO_CAPTURE) != 0;
      for (std::uint32_t i = 0; info.capture; ++i) {
        v4l2_fmtdesc fmt{};
        fmt.index = i;
        fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (xioctl(fd, VIDIOC_ENUM_FMT, &fmt) != 0) break;
        std::string line;
        for (int b = 0; b < 4; ++b) line += static_cast<char>((fmt.pixelformat >> (8 * b)) & 0xFF);
        for (std::uint32_t k = 0;; ++k) {
          v4l2_frmsizeenum size{};
          size.index = k;
          size.pixel_format = fmt.pixelformat;
          if (xioctl(fd, VIDIOC_ENUM_FRAMESIZES, &size) != 0) break;
          if (size.type == V4L2_FRMSIZE_TYPE_DISCRETE)
            line += fmt::format(" {}x{}", size.discrete.width, size.discrete.height);
          else
            line += fmt::format(" {}x{}..{}x{}", size.stepwise.min_width, size.stepwise.min_height,
                                size.stepwise.max_width, size.stepwise.max_height);
          if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
        }
        info.formats.push_back(line);
      }
    }
    v4l2_close(fd);
    out.push_back(info);
  }
  return out;
}

}  // namespace telex::remote
