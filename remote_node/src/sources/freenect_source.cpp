// SPDX-License-Identifier: MIT
// Kinect v1 through Debian's libfreenect (which drives the sensor over libusb): the raw 11-bit
// disparity mode, converted to millimetres by the PGM loader's formula (kinect_disparity_to_mm),
// so a fakenect replay of a dump gives exactly what `files:...,units=kinect-disparity` gives.
#include <fmt/format.h>
#include <libfreenect.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "source_impl.h"
#include "telex/common/depth_io.h"

namespace telex::remote {

namespace {

constexpr int kWidth = 640, kHeight = 480;  // FREENECT_RESOLUTION_MEDIUM, the only 11-bit size
constexpr std::size_t kDepthBytes = static_cast<std::size_t>(kWidth) * kHeight * 2;
constexpr std::size_t kRgbBytes = static_cast<std::size_t>(kWidth) * kHeight * 3;
// FREENECT_RESOLUTION_MEDIUM in an IR mode: 8 rows taller than depth. The IR images are cut to
// the depth's 480 rows, 4 off each edge, the depth image's rows of the IR camera (Konolige and
// Mihelich measure the IR-to-depth offset at about 4 px).
constexpr int kIrHeight = 488, kIrFirstRow = 4;
constexpr std::size_t kQueueFrames = 4;  // a reader that falls behind loses the oldest, counted

// One line of fakenect's INDEX.txt: "<type>-<seconds>-<timestamp>.<ext>" (record.c's open_dump).
bool parse_index_line(const std::string& line, char& type) {
  if (line.size() < 5 || line[1] != '-') return false;
  type = line[0];
  const char* p = line.data() + 2;
  const char* end = line.data() + line.size();
  const char* dash = std::find(p, end, '-');
  if (dash == end || dash == p) return false;
  char* num_end = nullptr;
  const std::string secs(p, dash);
  std::strtod(secs.c_str(), &num_end);
  if (num_end == secs.c_str() || *num_end != '\0') return false;
  unsigned ts = 0;
  const auto r = std::from_chars(dash + 1, end, ts);
  return r.ec == std::errc{} && r.ptr != dash + 1;
}

}  // namespace

FakenectRecording check_fakenect_recording(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  const fs::path index = dir / "INDEX.txt";
  std::ifstream in(index, std::ios::binary);
  if (!in)
    throw std::runtime_error(fmt::format(
        "fakenect recording {}: no INDEX.txt (fakenect-record writes one per recording)",
        dir.string()));
  FakenectRecording out;
  out.dir = dir;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    const auto where = [&] { return fmt::format("{} line {} ('{}')", index.string(), n, line); };
    char type = 0;
    if (!parse_index_line(line, type))
      throw std::runtime_error(
          fmt::format("{}: not TYPE-SECONDS-TIMESTAMP.EXT as fakenect-record writes", where()));
    if (type != 'd' && type != 'r' && type != 'a')
      throw std::runtime_error(fmt::format(
          "{}: type '{}' is none of d (depth), r (rgb), a (accelerometer)", where(), type));
    const fs::path file = dir / line;
    std::error_code ec;
    const auto size = fs::file_size(file, ec);
    if (ec) throw std::runtime_error(fmt::format("{}: {} cannot be read", where(), file.string()));
    if (type == 'a') {
      ++out.accelerometer;
      continue;
    }
    // fakenect skips exactly one header line, then copies a whole 640x480 frame from after it.
    std::ifstream f(file, std::ios::binary);
    std::string header;
    std::getline(f, header);
    const int ir_bits = header == "P5 640 488 255" ? 8 : header == "P5 640 488 1023" ? 10 : 0;
    const std::string magic = type == 'd' ? "P5 640 480 65535" : "P6 640 480 255";
    if (!f || (header != magic && (type == 'd' || ir_bits == 0)))
      throw std::runtime_error(fmt::format(
          "{}: header '{}' is not fakenect's '{}'{}", where(), header.substr(0, 40), magic,
          type == 'd' ? "" : " nor an IR dump's 'P5 640 488 255' or 'P5 640 488 1023'"));
    const std::size_t need = header.size() + 1 + (type == 'd' ? kDepthBytes : kRgbBytes);
    const char* what = type == 'd' ? "depth" : ir_bits ? "video (IR, padded)" : "rgb";
    if (size < need)
      throw std::runtime_error(
          fmt::format("{}: {} bytes, a {} frame needs {}", where(), size, what, need));
    if (type == 'd') {
      out.depth_files.push_back(file);
    } else if (ir_bits == 0) {
      ++out.rgb;
    } else {
      if (out.ir_bits != 0 && out.ir_bits != ir_bits)
        throw std::runtime_error(
            fmt::format("{}: IR {}-bit after IR {}-bit dumps", where(), ir_bits, out.ir_bits));
      out.ir_bits = ir_bits;
      ++out.ir;
    }
  }
  if (out.depth_files.empty())
    throw std::runtime_error(
        fmt::format("fakenect recording {}: INDEX.txt lists no depth frame", dir.string()));
  return out;
}

namespace {

class FreenectDepthSource final : public DepthSource {
 public:
  FreenectDepthSource(int index, const SourceOptions& options) : index_(index) { (void)options; }
  ~FreenectDepthSource() override { stop(); }

  void start() override {
    if (ctx_) return;
    // Under Debian's `fakenect` wrapper libfreenect is its replay library, which exit()s on a
    // missing or short file: check the recording first so the error names what is wrong.
    if (const char* replay = std::getenv("FAKENECT_PATH")) {
      const FakenectRecording rec = check_fakenect_recording(replay);
      replay_dir_ = replay;
      spdlog::info("freenect: fakenect replay of {} ({} depth frames)", replay,
                   rec.depth_files.size());
      if (ir_ && rec.ir_bits != ir_->bits)
        throw std::runtime_error(fmt::format(
            "freenect:{}: --ir {}-bit, but the fakenect recording {} holds {}", index_, ir_->bits,
            replay,
            rec.ir_bits ? fmt::format("IR {}-bit video", rec.ir_bits)
                        : fmt::format("no IR video ({} rgb dumps: fakenect-record records the "
                                      "colour camera only)",
                                      rec.rgb)));
    }
    if (freenect_init(&ctx_, nullptr) < 0 || !ctx_) {
      ctx_ = nullptr;
      throw std::runtime_error(
          "freenect: libfreenect could not initialise (libusb failed to start)");
    }
    freenect_set_log_level(ctx_, FREENECT_LOG_WARNING);
    freenect_select_subdevices(ctx_, FREENECT_DEVICE_CAMERA);
    const int count = freenect_num_devices(ctx_);
    if (count <= index_) {
      shutdown();
      throw std::runtime_error(fmt::format(
          "freenect:{}: no Kinect v1 at index {} ({} found by libfreenect; check the USB cable, "
          "the power supply and that the user may open the device: `telex devices` lists what is "
          "connected)",
          index_, index_, std::max(count, 0)));
    }
    if (freenect_open_device(ctx_, &dev_, index_) < 0 || !dev_) {
      dev_ = nullptr;
      shutdown();
      throw std::runtime_error(fmt::format(
          "freenect:{}: libfreenect could not open the Kinect (in use by another process, or no "
          "permission on its USB device)",
          index_));
    }
    freenect_set_user(dev_, this);
    const freenect_frame_mode mode =
        freenect_find_depth_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_DEPTH_11BIT);
    if (!mode.is_valid || freenect_set_depth_mode(dev_, mode) < 0) {
      shutdown();
      throw std::runtime_error(
          fmt::format("freenect:{}: the 640x480 11-bit depth mode was refused", index_));
    }
    freenect_set_depth_callback(dev_, &FreenectDepthSource::on_depth);
    if (freenect_start_depth(dev_) < 0) {
      shutdown();
      throw std::runtime_error(fmt::format("freenect:{}: the depth stream did not start", index_));
    }
    if (ir_) start_ir();
    stop_ = false;
    ended_ = false;
    events_ = std::thread([this] { event_loop(); });
  }

  void stop() override {
    if (!ctx_) return;
    stop_ = true;
    if (events_.joinable()) events_.join();
    if (dev_ && ir_) freenect_stop_video(dev_);
    if (dev_) freenect_stop_depth(dev_);
    shutdown();
  }

  void enable_ir(const IrOptions& options) override {
    if (options.bits != 8 && options.bits != 10)
      throw std::invalid_argument(
          fmt::format("--ir-bits {}: libfreenect's IR modes are 8 and 10 bits", options.bits));
    ir_ = options;
  }
  std::string ir_projector() const override { return projector_; }

  ReadResult<IrFrame> read_ir(std::chrono::milliseconds timeout) override {
    ReadResult<IrFrame> r;
    std::unique_lock lock(mu_);
    if (!cv_.wait_for(lock, timeout, [&] { return !ir_queue_.empty() || ended_; })) return r;
    if (ir_queue_.empty()) {
      r.status = replay_dir_.empty() ? ReadStatus::Error : ReadStatus::EndOfStream;
      r.error = fmt::format("freenect:{}: libfreenect stopped delivering (error {})", index_,
                            events_error_);
      return r;
    }
    r.frame = std::move(ir_queue_.front());
    ir_queue_.pop_front();
    r.status = ReadStatus::Frame;
    return r;
  }

  ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) override {
    ReadResult<DepthFrame> r;
    std::unique_lock lock(mu_);
    if (!cv_.wait_for(lock, timeout, [&] { return !queue_.empty() || ended_; })) return r;
    if (queue_.empty()) {
      if (!replay_dir_.empty()) {
        r.status = ReadStatus::EndOfStream;
      } else {
        r.status = ReadStatus::Error;
        r.error = fmt::format("freenect:{}: libfreenect stopped delivering (error {})", index_,
                              events_error_);
      }
      return r;
    }
    Raw raw = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    r.status = ReadStatus::Frame;
    r.frame.image.depth_mm = kinect_disparity_to_mm(raw.disparity);
    r.frame.image.intrinsics = kinect_v1_intrinsics(kWidth, kHeight);
    r.frame.capture_ns = raw.capture_ns;
    r.frame.frame_id = raw.sequence;
    r.frame.scene_time_s = static_cast<double>(raw.capture_ns - first_ns_) * 1e-9;
    return r;
  }

  Intrinsics intrinsics() const override { return kinect_v1_intrinsics(kWidth, kHeight); }
  double nominal_fps() const override { return 30.0; }
  std::string describe() const override {
    return replay_dir_.empty()
               ? fmt::format("freenect:{} (Kinect v1, 11-bit disparity)", index_)
               : fmt::format("freenect:{} (fakenect replay of {})", index_, replay_dir_);
  }

 private:
  struct Raw {
    cv::Mat1w disparity;
    std::int64_t capture_ns = 0;
    std::uint64_t sequence = 0;
  };

  // The Kinect's IR is libfreenect's video channel in an IR mode. Under fakenect the replay
  // library offers no IR mode (its freenect_find_video_mode asserts on one) and hands every video
  // dump over as it was recorded; the recording was checked to hold IR of these bits.
  void start_ir() {
    if (replay_dir_.empty()) {
      const freenect_frame_mode mode = freenect_find_video_mode(
          FREENECT_RESOLUTION_MEDIUM,
          ir_->bits == 8 ? FREENECT_VIDEO_IR_8BIT : FREENECT_VIDEO_IR_10BIT);
      if (!mode.is_valid || mode.width != kWidth || mode.height != kIrHeight ||
          freenect_set_video_mode(dev_, mode) < 0) {
        shutdown();
        throw std::runtime_error(fmt::format(
            "freenect:{}: the 640x488 IR {}-bit video mode was refused", index_, ir_->bits));
      }
    }
    freenect_set_video_callback(dev_, &FreenectDepthSource::on_video);
    if (freenect_start_video(dev_) < 0) {
      shutdown();
      throw std::runtime_error(fmt::format("freenect:{}: the IR stream did not start", index_));
    }
    // libfreenect 0.5 has no control of the Kinect v1's laser.
    projector_ =
        "on (libfreenect cannot switch the Kinect's projector off: cover it for calibration)";
  }

  static void on_video(freenect_device* dev, void* video, std::uint32_t /*timestamp*/) {
    auto* self = static_cast<FreenectDepthSource*>(freenect_get_user(dev));
    IrFrame f;
    f.capture_ns = steady_now_ns();
    f.bits = self->ir_->bits;
    const int type = f.bits == 8 ? CV_8UC1 : CV_16UC1;
    const cv::Mat full(kIrHeight, kWidth, type, video);
    f.image = full.rowRange(kIrFirstRow, kIrFirstRow + kHeight).clone();
    std::lock_guard lock(self->mu_);
    f.frame_id = self->ir_sequence_++;
    if (self->ir_queue_.size() == kQueueFrames) {
      self->ir_queue_.pop_front();
      ++self->dropped_;
    }
    self->ir_queue_.push_back(std::move(f));
    self->cv_.notify_all();
  }

  static void on_depth(freenect_device* dev, void* depth, std::uint32_t /*timestamp*/) {
    auto* self = static_cast<FreenectDepthSource*>(freenect_get_user(dev));
    Raw raw;
    raw.capture_ns = steady_now_ns();
    raw.disparity.create(kHeight, kWidth);
    std::memcpy(raw.disparity.data, depth, kDepthBytes);
    {
      std::lock_guard lock(self->mu_);
      if (self->sequence_ == 0) self->first_ns_ = raw.capture_ns;
      raw.sequence = self->sequence_++;
      if (self->queue_.size() == kQueueFrames) {
        self->queue_.pop_front();
        ++self->dropped_;
      }
      self->queue_.push_back(std::move(raw));
      self->cv_.notify_all();  // under the lock: helgrind flags a signal without it as dubious
    }
  }

  void event_loop() {
    while (!stop_) {
      timeval tv{0, 100000};
      const int rc = freenect_process_events_timeout(ctx_, &tv);
      if (rc < 0) {  // fakenect: the recording ended; a device: libusb lost it
        std::lock_guard lock(mu_);
        events_error_ = rc;
        ended_ = true;
        cv_.notify_all();
        return;
      }
    }
  }

  void shutdown() {
    if (dev_) freenect_close_device(dev_);
    dev_ = nullptr;
    if (ctx_) freenect_shutdown(ctx_);
    ctx_ = nullptr;
    if (dropped_ > 0)
      spdlog::info("freenect:{}: {} frames dropped by a slow reader", index_, dropped_);
  }

  const int index_;
  std::string replay_dir_;
  freenect_context* ctx_ = nullptr;
  freenect_device* dev_ = nullptr;
  std::thread events_;
  std::atomic<bool> stop_{false};
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<Raw> queue_;
  std::optional<IrOptions> ir_;
  std::deque<IrFrame> ir_queue_;
  std::uint64_t ir_sequence_ = 0;
  std::string projector_ = "on (no IR capture)";
  bool ended_ = false;
  int events_error_ = 0;
  std::uint64_t sequence_ = 0, dropped_ = 0;
  std::int64_t first_ns_ = 0;
};

}  // namespace

namespace detail {

std::unique_ptr<DepthSource> make_freenect_source(const SourceSpec& spec,
                                                  const SourceOptions& options) {
  require_options(spec, {});
  int index = 0;
  if (!spec.arg.empty()) {
    const auto r = std::from_chars(spec.arg.data(), spec.arg.data() + spec.arg.size(), index);
    if (r.ec != std::errc{} || r.ptr != spec.arg.data() + spec.arg.size() || index < 0)
      throw std::invalid_argument(
          fmt::format("freenect:{}: the device index must be a number 0, 1, ...", spec.arg));
  }
  return std::make_unique<FreenectDepthSource>(index, options);
}

}  // namespace detail

}  // namespace telex::remote
