// SPDX-License-Identifier: MIT
// OpenNI2 depth sources: a live device by URI (including OpenNI2's "Dummy" device) and .oni
// playback.
#include <OpenNI.h>
#include <PS1080.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <thread>

#include "source_impl.h"
#include "telex/remote/openni_record.h"

namespace telex::remote {

namespace {

// OpenNI2 is initialised once per process and never shut down: the Dummy driver's frame thread
// outlives Device::close, and OpenNI::shutdown unloads the driver under it (SIGSEGV seen here).
void ensure_openni() {
  static const std::string error = [] {
    if (openni::OpenNI::initialize() != openni::STATUS_OK)
      return std::string(openni::OpenNI::getExtendedError());
    return std::string();
  }();
  if (!error.empty())
    throw std::runtime_error(fmt::format("OpenNI2 failed to initialise: {}", error));
}

// OpenNI2's Dummy driver (OzStream in DummyDevice.cpp) stops a stream by clearing a flag that its
// frame thread reads once per frame (after a 33 ms sleep); it never joins that thread, and
// VideoStream::destroy deletes the stream at once. A thread still in its sleep then wakes up in a
// deleted object and raises a frame into it: the SIGSEGV inside libDummyDevice.so that killed
// processes which opened the device more than once. Waiting two frame periods between stop and
// destroy lets the thread see the flag and return first.
void let_driver_thread_exit(double fps) {
  const double period_ms = 1000.0 / (fps > 1.0 ? fps : 30.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(2.0 * period_ms) + 10));
}

std::string list_devices() {
  const auto devices = list_openni_devices();
  if (devices.empty()) return "no devices found";
  std::string out = "devices found:";
  for (const auto& d : devices) out += fmt::format(" '{}' ({} {})", d.uri, d.vendor, d.name);
  return out;
}

// Prefers millimetre depth so no per-pixel conversion is needed; 100 um is converted on read.
void choose_depth_mode(openni::VideoStream& stream) {
  const auto& modes = stream.getSensorInfo().getSupportedVideoModes();
  const auto current = stream.getVideoMode();
  if (current.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM) return;
  for (int i = 0; i < modes.getSize(); ++i) {
    if (modes[i].getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM &&
        modes[i].getResolutionX() == current.getResolutionX() &&
        modes[i].getResolutionY() == current.getResolutionY()) {
      stream.setVideoMode(modes[i]);
      return;
    }
  }
}

// The IR stream's mode at the depth's size: GRAY16 (a PS1080's 10-bit IR) or GRAY8. An 8-bit
// capture takes GRAY8 when offered, else GRAY16 scaled down on read.
std::string choose_ir_mode(openni::VideoStream& ir, int bits, int width, int height) {
  const auto& modes = ir.getSensorInfo().getSupportedVideoModes();
  std::string offered;
  int best = -1;
  for (int i = 0; i < modes.getSize(); ++i) {
    const auto f = modes[i].getPixelFormat();
    offered += fmt::format(" {}x{}@{} format {}", modes[i].getResolutionX(),
                           modes[i].getResolutionY(), modes[i].getFps(), static_cast<int>(f));
    if (modes[i].getResolutionX() != width || modes[i].getResolutionY() != height) continue;
    if (f == openni::PIXEL_FORMAT_GRAY8 && bits == 8) best = i;
    if (f == openni::PIXEL_FORMAT_GRAY16 && (best < 0 || bits != 8)) best = i;
  }
  if (best < 0)
    return fmt::format(
        "its IR stream offers no GRAY16 or GRAY8 mode at the depth's {}x{} (it "
        "offers{})",
        width, height, offered.empty() ? " none" : offered);
  if (ir.setVideoMode(modes[best]) != openni::STATUS_OK)
    return fmt::format("its IR stream refused {}x{}: {}", width, height,
                       openni::OpenNI::getExtendedError());
  return {};
}

Intrinsics intrinsics_of(openni::VideoStream& stream, int width, int height) {
  const double hfov = stream.getHorizontalFieldOfView();
  const double vfov = stream.getVerticalFieldOfView();
  // Devices and recordings without a field of view (the Dummy device reports 0) get Kinect v1
  // optics.
  if (!(hfov > 0.01 && vfov > 0.01)) return kinect_v1_intrinsics(width, height);
  Intrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (2.0 * std::tan(hfov / 2.0));
  k.fy = height / (2.0 * std::tan(vfov / 2.0));
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  return k;
}

// OpenNI reports the end of a non-repeating recording only as a device state change.
class EofListener final : public openni::OpenNI::DeviceStateChangedListener {
 public:
  explicit EofListener(std::string uri) : uri_(std::move(uri)) {}
  void onDeviceStateChanged(const openni::DeviceInfo* info, openni::DeviceState state) override {
    if (state == openni::DEVICE_STATE_EOF && info != nullptr && uri_ == info->getUri()) eof_ = true;
  }
  bool eof() const { return eof_; }

 private:
  std::string uri_;
  std::atomic<bool> eof_{false};
};

class OpenNiDepthSource final : public DepthSource {
 public:
  enum class Mode { Live, Playback };
  OpenNiDepthSource(Mode mode, std::string uri, bool loop, bool realtime,
                    bool hardware_registration = false)
      : mode_(mode),
        uri_(std::move(uri)),
        loop_(loop),
        realtime_(realtime),
        hardware_registration_(hardware_registration) {}
  ~OpenNiDepthSource() override {
    stop();
    remove_repaired_copy();
  }

  void start() override {
    if (started_) return;
    if (mode_ == Mode::Playback && !std::filesystem::is_regular_file(uri_))
      throw std::runtime_error(
          fmt::format("oni recording '{}' does not exist or is not a file", uri_));
    ensure_openni();
    std::string open_uri = uri_;
    if (mode_ == Mode::Playback) open_uri = playable_copy();
    const char* uri = open_uri.empty() ? openni::ANY_DEVICE : open_uri.c_str();
    if (device_.open(uri) != openni::STATUS_OK) {
      const std::string err = openni::OpenNI::getExtendedError();
      const std::string devices = list_devices();
      if (mode_ == Mode::Playback)
        throw std::runtime_error(fmt::format("cannot open oni recording '{}': {}", uri_, err));
      throw std::runtime_error(
          fmt::format("cannot open OpenNI2 device '{}': {}; {}. Try 'openni:Dummy' (OpenNI2's test "
                      "device), plug in a "
                      "Kinect/Carmine and check the udev rules (lsusb, "
                      "/lib/udev/rules.d/60-libopenni2-0.rules), or play a "
                      "recording with 'oni:PATH'",
                      uri_.empty() ? "any device" : uri_, err, devices));
    }
    if (stream_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      const std::string err = openni::OpenNI::getExtendedError();
      device_.close();
      throw std::runtime_error(
          fmt::format("OpenNI2 device '{}' has no depth stream: {}", uri_, err));
    }
    choose_depth_mode(stream_);
    if (mode_ == Mode::Live) set_hardware_registration();
    if (mode_ == Mode::Playback) {
      eof_ = std::make_unique<EofListener>(device_.getDeviceInfo().getUri());
      openni::OpenNI::addDeviceStateChangedListener(eof_.get());
      auto* playback = device_.getPlaybackControl();
      if (playback != nullptr) {
        playback->setRepeatEnabled(loop_);
        // realtime: the file driver paces frames by their timestamps (a slow reader misses
        // some, like a live device). fast: -1 is the driver's manual stepping, one frame per
        // wait/read, so every frame arrives, in order, as fast as it is read. Speed 0 ("as fast
        // as possible") would push the whole file through the stream's one-frame slot at once
        // and a reader would see only the last frame.
        playback->setSpeed(realtime_ ? 1.0f : -1.0f);
        frames_in_file_ = playback->getNumberOfFrames(stream_);
      }
    }
    // A device without IR is refused before its depth starts (nothing then runs to be stopped).
    if (ir_ && !device_.hasSensor(openni::SENSOR_IR)) fail_start(no_ir_stream());
    if (stream_.start() != openni::STATUS_OK)
      fail_start(fmt::format("OpenNI2 device '{}' failed to start depth: {}", uri_,
                             openni::OpenNI::getExtendedError()));
    depth_running_ = true;
    if (ir_) start_ir();
    const auto vm = stream_.getVideoMode();
    started_ = true;
    intrinsics_ = intrinsics_of(stream_, vm.getResolutionX(), vm.getResolutionY());
    fps_ = vm.getFps() > 0 ? vm.getFps() : 30.0;
  }

  void stop() override {
    if (!started_) return;
    if (ir_stream_.isValid()) ir_stream_.stop();
    stream_.stop();
    depth_running_ = false;
    if (mode_ == Mode::Live) let_driver_thread_exit(fps_);
    if (ir_stream_.isValid()) ir_stream_.destroy();
    stream_.destroy();
    device_.close();
    if (eof_) openni::OpenNI::removeDeviceStateChangedListener(eof_.get());
    eof_.reset();
    remove_repaired_copy();
    started_ = false;
  }

  ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<DepthFrame> out;
    if (!started_) {
      out.status = ReadStatus::Error;
      out.error = "OpenNI2 source read before start";
      return out;
    }
    if (mode_ == Mode::Playback && !loop_ && frames_in_file_ > 0 &&
        frames_read_ >= static_cast<std::uint64_t>(frames_in_file_)) {
      out.status = ReadStatus::EndOfStream;
      return out;
    }
    openni::VideoStream* streams[] = {&stream_};
    int ready = -1;
    const auto rc =
        openni::OpenNI::waitForAnyStream(streams, 1, &ready, static_cast<int>(timeout.count()));
    if (rc == openni::STATUS_TIME_OUT) {
      out.status = (eof_ && eof_->eof() && !loop_) ? ReadStatus::EndOfStream : ReadStatus::Timeout;
      return out;
    }
    if (rc != openni::STATUS_OK) {
      out.status = ReadStatus::Error;
      out.error =
          fmt::format("OpenNI2 wait on '{}' failed: {}", uri_, openni::OpenNI::getExtendedError());
      return out;
    }
    openni::VideoFrameRef ref;
    if (stream_.readFrame(&ref) != openni::STATUS_OK || !ref.isValid()) {
      out.status = ReadStatus::Error;
      out.error =
          fmt::format("OpenNI2 read on '{}' failed: {}", uri_, openni::OpenNI::getExtendedError());
      return out;
    }
    const int w = ref.getWidth();
    const int h = ref.getHeight();
    const auto format = ref.getVideoMode().getPixelFormat();
    if (format != openni::PIXEL_FORMAT_DEPTH_1_MM && format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      out.status = ReadStatus::Error;
      out.error =
          fmt::format("OpenNI2 '{}' delivers pixel format {} (need DEPTH_1_MM or DEPTH_100_UM)",
                      uri_, static_cast<int>(format));
      return out;
    }
    const cv::Mat1w view(
        h, w, const_cast<std::uint16_t*>(static_cast<const std::uint16_t*>(ref.getData())),
        static_cast<std::size_t>(ref.getStrideInBytes()));
    DepthFrame& f = out.frame;
    if (format == openni::PIXEL_FORMAT_DEPTH_100_UM)
      view.convertTo(f.image.depth_mm, CV_16U, 0.1);
    else
      view.copyTo(f.image.depth_mm);
    f.image.intrinsics = intrinsics_.width == w && intrinsics_.height == h
                             ? intrinsics_
                             : kinect_v1_intrinsics(w, h);
    f.capture_ns = steady_now_ns();
    f.frame_id = ++frames_read_;
    f.scene_time_s = static_cast<double>(ref.getTimestamp()) * 1e-6;
    out.status = ReadStatus::Frame;
    return out;
  }

  Intrinsics intrinsics() const override { return intrinsics_; }
  double nominal_fps() const override { return fps_; }
  std::int64_t frame_count() const override {
    return mode_ == Mode::Playback ? frames_in_file_ : -1;
  }

  void enable_ir(const IrOptions& options) override {
    if (mode_ == Mode::Playback)
      throw std::invalid_argument(
          fmt::format("--ir: {} is a recording; the IR images come from a live sensor (openni:URI)",
                      describe()));
    ir_ = options;
  }
  ReadResult<IrFrame> read_ir(std::chrono::milliseconds timeout) override;
  std::string ir_projector() const override { return projector_; }
  std::string describe() const override {
    if (mode_ == Mode::Playback)
      return fmt::format("oni:{}{}{}", uri_, loop_ ? ",loop" : "",
                         realtime_ ? ",realtime" : ",fast");
    return fmt::format("openni:{}", uri_.empty() ? "ANY" : uri_);
  }

 private:
  // PrimeSense-class sensors (PS1080: Kinect v1, Carmine, Xtion) can register depth to their
  // colour camera in hardware. Only --registration hardware asks for it: otherwise the depth stays
  // in the sensor's own (IR) pixels, where `telex calibrate depth-eye` calibrates the rig's
  // extrinsics, so they are never applied on top of the sensor's own registration.
  void set_hardware_registration() {
    const std::string name = uri_.empty() ? "ANY" : uri_;
    if (!hardware_registration_) {
      if (device_.getImageRegistrationMode() != openni::IMAGE_REGISTRATION_OFF &&
          device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_OFF) != openni::STATUS_OK)
        fail_start(fmt::format("OpenNI2 device '{}' keeps its hardware registration on: {}", name,
                               openni::OpenNI::getExtendedError()));
      return;
    }
    if (!device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR))
      fail_start(fmt::format(
          "--registration hardware: OpenNI2 device '{}' offers no depth-to-colour registration "
          "(IMAGE_REGISTRATION_DEPTH_TO_COLOR); use --registration rig with a calibrated rig, or "
          "none",
          name));
    if (device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) !=
        openni::STATUS_OK)
      fail_start(fmt::format(
          "--registration hardware: OpenNI2 device '{}' refused depth-to-colour registration: {}",
          name, openni::OpenNI::getExtendedError()));
    spdlog::info("openni: '{}' registers depth to its colour camera (--registration hardware)",
                 name);
  }
  // The IR stream beside depth at the depth's size, the projector off where the device allows.
  void start_ir() {
    const std::string name = uri_.empty() ? "ANY" : uri_;
    if (!device_.hasSensor(openni::SENSOR_IR)) fail_start(no_ir_stream());
    if (ir_stream_.create(device_, openni::SENSOR_IR) != openni::STATUS_OK)
      fail_start(fmt::format("--ir: OpenNI2 device '{}' could not open its IR stream: {}", name,
                             openni::OpenNI::getExtendedError()));
    const auto vm = stream_.getVideoMode();
    if (const auto why =
            choose_ir_mode(ir_stream_, ir_->bits, vm.getResolutionX(), vm.getResolutionY());
        !why.empty())
      fail_start(fmt::format("--ir: OpenNI2 device '{}': {}", name, why));
    projector_ = switch_projector_off();
    if (ir_stream_.start() != openni::STATUS_OK)
      fail_start(fmt::format("--ir: OpenNI2 device '{}' failed to start its IR stream: {}", name,
                             openni::OpenNI::getExtendedError()));
  }
  // PS1080's emitter property (PS1080.h, XN_MODULE_PROPERTY_EMITTER_STATE); a device without it
  // keeps its projector on, said in capture.json.
  std::string switch_projector_off() {
    const int off = 0;
    if (device_.setProperty(XN_MODULE_PROPERTY_EMITTER_STATE, off) == openni::STATUS_OK)
      return "off";
    return fmt::format("on (the device has no PS1080 emitter property: {}; cover the projector)",
                       openni::OpenNI::getExtendedError());
  }

  std::string no_ir_stream() const {
    return fmt::format(
        "--ir: OpenNI2 device '{}' has no IR stream (SENSOR_IR); a PrimeSense-class sensor "
        "(Kinect v1, Carmine, Xtion) has one, OpenNI2's Dummy device does not",
        uri_.empty() ? "ANY" : uri_);
  }

  // A start that cannot go on: the streams stopped (and, live, the driver's frame threads let out
  // as stop() does), closed, then the error named.
  [[noreturn]] void fail_start(const std::string& why) {
    if (ir_stream_.isValid()) ir_stream_.stop();
    if (depth_running_) stream_.stop();
    if (depth_running_ && mode_ == Mode::Live) let_driver_thread_exit(30.0);
    depth_running_ = false;
    if (ir_stream_.isValid()) ir_stream_.destroy();
    stream_.destroy();
    device_.close();
    throw std::runtime_error(why);
  }

  // The file driver plays no frame of a recording that lacks a cropping record (see
  // repair_oni_for_playback): such a file is played from a repaired copy in the temp directory.
  std::string playable_copy() {
    int missing = 0;
    try {
      missing = oni_nodes_missing_cropping(uri_);
    } catch (const std::exception& e) {
      // Not a layout the repair understands (older format): let the driver judge the file.
      spdlog::debug("oni: not checked for the cropping record: {}", e.what());
      return uri_;
    }
    if (missing == 0) return uri_;
    static std::atomic<int> counter{0};
    repaired_ = std::filesystem::temp_directory_path() /
                fmt::format("telex_oni_{}_{}.oni", ::getpid(), counter++);
    repair_oni_for_playback(uri_, repaired_);
    spdlog::info(
        "oni: '{}' has {} image stream(s) without the cropping record OpenNI2's file driver "
        "needs to deliver frames; playing a repaired copy '{}'",
        uri_, missing, repaired_.string());
    return repaired_.string();
  }
  void remove_repaired_copy() {
    if (repaired_.empty()) return;
    std::error_code ec;
    std::filesystem::remove(repaired_, ec);
    repaired_.clear();
  }

  Mode mode_;
  std::string uri_;
  bool loop_ = false;
  bool realtime_ = true;
  bool hardware_registration_ = false;
  std::optional<IrOptions> ir_;
  openni::VideoStream ir_stream_;
  bool depth_running_ = false;  // stream_ started, not yet stopped
  std::string projector_ = "on (no IR capture)";
  std::uint64_t ir_frames_read_ = 0;
  bool started_ = false;
  std::unique_ptr<EofListener> eof_;
  openni::Device device_;
  openni::VideoStream stream_;
  Intrinsics intrinsics_;
  double fps_ = 30.0;
  int frames_in_file_ = 0;
  std::uint64_t frames_read_ = 0;
  std::filesystem::path repaired_;
};

ReadResult<IrFrame> OpenNiDepthSource::read_ir(std::chrono::milliseconds timeout) {
  ReadResult<IrFrame> out;
  if (!started_ || !ir_stream_.isValid()) {
    out.status = ReadStatus::Error;
    out.error = fmt::format("{} captures no IR images (enable_ir before start)", describe());
    return out;
  }
  openni::VideoStream* streams[] = {&ir_stream_};
  int ready = -1;
  const auto rc =
      openni::OpenNI::waitForAnyStream(streams, 1, &ready, static_cast<int>(timeout.count()));
  if (rc == openni::STATUS_TIME_OUT) return out;
  openni::VideoFrameRef ref;
  if (rc != openni::STATUS_OK || ir_stream_.readFrame(&ref) != openni::STATUS_OK ||
      !ref.isValid()) {
    out.status = ReadStatus::Error;
    out.error =
        fmt::format("OpenNI2 IR read on '{}' failed: {}", uri_, openni::OpenNI::getExtendedError());
    return out;
  }
  const auto format = ref.getVideoMode().getPixelFormat();
  const auto stride = static_cast<std::size_t>(ref.getStrideInBytes());
  auto* data = const_cast<void*>(ref.getData());
  IrFrame& f = out.frame;
  if (format == openni::PIXEL_FORMAT_GRAY8) {
    cv::Mat1b(ref.getHeight(), ref.getWidth(), static_cast<std::uint8_t*>(data), stride)
        .copyTo(f.image);
    f.bits = 8;
  } else if (format == openni::PIXEL_FORMAT_GRAY16) {
    const cv::Mat1w view(ref.getHeight(), ref.getWidth(), static_cast<std::uint16_t*>(data),
                         stride);
    // A PS1080's IR is 10 bits in 16: an 8-bit capture keeps the top 8 of them.
    if (ir_->bits == 8)
      view.convertTo(f.image, CV_8U, 1.0 / 4.0);
    else
      view.copyTo(f.image);
    f.bits = ir_->bits == 8 ? 8 : 10;
  } else {
    out.status = ReadStatus::Error;
    out.error = fmt::format("OpenNI2 '{}' delivers IR in pixel format {} (need GRAY8 or GRAY16)",
                            uri_, static_cast<int>(format));
    return out;
  }
  f.capture_ns = steady_now_ns();
  f.frame_id = ++ir_frames_read_;
  out.status = ReadStatus::Frame;
  return out;
}

}  // namespace

std::vector<OpenNiDeviceInfo> list_openni_devices() {
  ensure_openni();
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  std::vector<OpenNiDeviceInfo> out;
  for (int i = 0; i < devices.getSize(); ++i)
    out.push_back({devices[i].getUri(), devices[i].getVendor(), devices[i].getName(),
                   devices[i].getUsbVendorId(), devices[i].getUsbProductId()});
  return out;
}

namespace detail {

std::unique_ptr<DepthSource> make_openni_source(const SourceSpec& spec,
                                                const SourceOptions& options) {
  require_options(spec, {});
  return std::make_unique<OpenNiDepthSource>(OpenNiDepthSource::Mode::Live, spec.arg, false, true,
                                             options.hardware_registration);
}

std::unique_ptr<DepthSource> make_oni_source(const SourceSpec& spec, const SourceOptions&) {
  require_options(spec, {"loop", "realtime", "fast"});
  if (spec.arg.empty())
    throw std::invalid_argument("source 'oni' needs a path: oni:PATH[,loop][,realtime|fast]");
  if (spec.has("realtime") && spec.has("fast"))
    throw std::invalid_argument("source 'oni': choose one of 'realtime' and 'fast'");
  return std::make_unique<OpenNiDepthSource>(OpenNiDepthSource::Mode::Playback, spec.arg,
                                             spec.has("loop"), !spec.has("fast"));
}

}  // namespace detail

OniCapture record_oni_frames(const std::string& uri, const std::filesystem::path& path, int frames,
                             std::chrono::milliseconds timeout, bool repair) {
  ensure_openni();
  openni::Device device;
  if (device.open(uri.empty() ? openni::ANY_DEVICE : uri.c_str()) != openni::STATUS_OK)
    throw std::runtime_error(fmt::format("record_oni: cannot open OpenNI2 device '{}': {}; {}", uri,
                                         openni::OpenNI::getExtendedError(), list_devices()));
  openni::VideoStream stream;
  if (stream.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK)
    throw std::runtime_error(fmt::format("record_oni: device '{}' has no depth stream", uri));
  choose_depth_mode(stream);
  openni::Recorder recorder;
  // Lossless: depth goes through the 16z codec either way; the flag only allows JPEG for colour.
  if (recorder.create(path.c_str()) != openni::STATUS_OK ||
      recorder.attach(stream, false) != openni::STATUS_OK)
    throw std::runtime_error(fmt::format("record_oni: cannot record to '{}': {}", path.string(),
                                         openni::OpenNI::getExtendedError()));
  OniCapture capture;
  stream.start();
  recorder.start();
  while (capture.frames() < frames) {
    openni::VideoStream* streams[] = {&stream};
    int ready = -1;
    if (openni::OpenNI::waitForAnyStream(streams, 1, &ready, static_cast<int>(timeout.count())) !=
        openni::STATUS_OK)
      break;
    openni::VideoFrameRef ref;
    if (stream.readFrame(&ref) != openni::STATUS_OK || !ref.isValid()) break;
    const cv::Mat1w view(
        ref.getHeight(), ref.getWidth(),
        const_cast<std::uint16_t*>(static_cast<const std::uint16_t*>(ref.getData())),
        static_cast<std::size_t>(ref.getStrideInBytes()));
    capture.depth_mm.push_back(view.clone());
    capture.device_timestamp_us.push_back(ref.getTimestamp());
  }
  // stop() only stops taking frames; destroy() drains the Recorder's queue, writes the seek table
  // and the end record and closes the file.
  recorder.stop();
  recorder.destroy();
  stream.stop();
  let_driver_thread_exit(stream.getVideoMode().getFps());
  stream.destroy();
  device.close();
  if (repair) repair_oni_for_playback(path, path);
  return capture;
}

int record_oni(const std::string& uri, const std::filesystem::path& path, int frames,
               std::chrono::milliseconds timeout) {
  return record_oni_frames(uri, path, frames, timeout).frames();
}

}  // namespace telex::remote
