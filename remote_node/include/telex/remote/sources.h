// SPDX-License-Identifier: MIT
// Depth and stereo sources behind interfaces, chosen at start-up by a spec string.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <glm/mat3x3.hpp>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "telex/common/depth_image.h"
#include "telex/proto/messages.h"

namespace telex::bag {
struct CameraIntrinsics;
}

namespace telex::remote {

// One depth frame as the source delivered it. capture_ns is on the host's steady clock so that
// every stage and the stats line can compare it with other host times.
struct DepthFrame {
  DepthImage image;
  std::int64_t capture_ns = 0;
  std::uint64_t frame_id = 0;
  // Time of the scene this frame shows (synthetic and playback sources); equals capture time for
  // live devices. Kept apart so animated synthetic scenes stay deterministic under load.
  double scene_time_s = 0.0;
  // The robot head's measured joints at capture (set by the daemon from its head driver; sent in
  // the frame's manifests).
  proto::HeadJoints head;
};

// A rectified colour pair from the operator-facing cameras (BGR, 8 bit).
struct StereoFrame {
  cv::Mat3b left_bgr;
  cv::Mat3b right_bgr;
  std::int64_t capture_ns = 0;
  std::uint64_t frame_id = 0;
  // The cameras' own JPEGs when they deliver MJPEG (else empty): --video-codec mjpeg sends them
  // as they came, without decoding and encoding again.
  std::vector<std::uint8_t> left_jpeg, right_jpeg;
};

// One image of the depth sensor's own IR camera (`telex capture --ir`, the images `telex
// calibrate depth-eye --ir` finds the board in): 8-bit, or 16-bit holding `bits` significant bits
// (a Kinect's IR 10-bit mode, a PS1080's GRAY16), at the depth image's size.
struct IrFrame {
  cv::Mat image;  // CV_8UC1 or CV_16UC1
  int bits = 8;
  std::int64_t capture_ns = 0;
  std::uint64_t frame_id = 0;
};

// What `telex capture --ir` asks of the sensor: the IR depth in bits (8 or 10). The projector is
// switched off where the device allows, so the board's corners are not speckled.
struct IrOptions {
  int bits = 10;
};

// Result of one read: the running capture loop never throws, it acts on the status.
enum class ReadStatus { Frame, Timeout, EndOfStream, Error };

template <typename FrameT>
struct ReadResult {
  ReadStatus status = ReadStatus::Timeout;
  FrameT frame;
  std::string error;  // set when status == Error
};

class DepthSource {
 public:
  virtual ~DepthSource() = default;
  // Opens the device or files; throws std::runtime_error naming the device and what to try.
  virtual void start() = 0;
  virtual void stop() = 0;
  // Waits at most `timeout` for the next frame; never blocks longer, never throws.
  virtual ReadResult<DepthFrame> read(std::chrono::milliseconds timeout) = 0;
  // Valid after start().
  virtual Intrinsics intrinsics() const = 0;
  // Nominal frame rate, for pacing and for the stats line.
  virtual double nominal_fps() const = 0;
  // Frames in a recording or file sequence (valid after start()); -1 for live and endless sources.
  virtual std::int64_t frame_count() const { return -1; }
  // A file sequence or bag without loop: it plays frame_count() frames once, then ends. It paces
  // from its first read, so the daemon holds it until the first station connects.
  virtual bool plays_once() const { return false; }
  virtual std::string describe() const = 0;

  // The sensor's IR camera beside its depth (`telex capture --ir`); call before start(). Throws
  // std::invalid_argument when the source has no IR camera (only openni:URI and freenect:N do);
  // start() throws std::runtime_error naming the device when it has none or refuses the mode.
  virtual void enable_ir(const IrOptions& options);
  // The next IR image (after enable_ir and start); as read(), never throws.
  virtual ReadResult<IrFrame> read_ir(std::chrono::milliseconds timeout);
  // How the projector was left for the IR images: "off", or "on (why)". Valid after start().
  virtual std::string ir_projector() const { return "on (no IR capture)"; }
};

class StereoSource {
 public:
  virtual ~StereoSource() = default;
  virtual void start() = 0;
  virtual void stop() = 0;
  virtual ReadResult<StereoFrame> read(std::chrono::milliseconds timeout) = 0;
  // As DepthSource's.
  virtual std::int64_t frame_count() const { return -1; }
  virtual bool plays_once() const { return false; }
  virtual std::string describe() const = 0;
};

// "kind:ARG[,opt][,key=value]..." split into its parts. ARG may itself hold commas only for the
// v4l2 stereo spec, which takes two device paths.
struct SourceSpec {
  std::string kind;                            // openni | oni | files | bag | synthetic | v4l2
  std::string arg;                             // URI, path, glob pattern or scene name
  std::map<std::string, std::string> options;  // flags map to "" (e.g. "loop"), key=value otherwise
  std::vector<std::string> flags;  // value-less tokens in order (the right-eye path of v4l2)
  bool has(std::string_view key) const { return options.count(std::string(key)) != 0; }
};

// Throws std::invalid_argument naming the spec and the valid forms.
SourceSpec parse_source_spec(std::string_view spec);

struct SourceOptions {
  // Fallback when the device reports no field of view (OpenNI's Dummy device reports 0).
  bool use_kinect_intrinsics_fallback = true;
  double synthetic_fps = 30.0;
  std::uint64_t seed = 1;
  // --registration hardware: a live OpenNI2 device registers depth to its colour camera
  // (IMAGE_REGISTRATION_DEPTH_TO_COLOR; a device without it fails to start, named). Off: the
  // depth stays in the sensor's own pixels.
  bool hardware_registration = false;
  int width = 640;  // synthetic and stereo render size
  int height = 480;
  // The robot head's camera orientation at a capture time (R_BaseCamera), when a head is driven:
  // the synthetic depth scene is then fixed in the head base's frame and seen from the turned
  // camera, as a real sensor on the head would see the room. Unset or nullopt: not turned.
  std::function<std::optional<glm::dmat3>(std::int64_t capture_ns)> head_orientation;
};

// One registered source scheme: its name (the text before ':'), the spec's form and what it is.
struct SourceScheme {
  std::string_view name;
  std::string_view form;  // e.g. "files:PATTERN[,units=mm|tum|kinect-disparity][,fps=F][,loop]"
  std::string_view help;
};
// The registered schemes, in the order --help lists them.
std::vector<SourceScheme> depth_source_schemes();
std::vector<SourceScheme> stereo_source_schemes();
// "FORM: HELP | FORM: HELP | ...": the --source / --stereo help text.
std::string depth_source_help();
std::string stereo_source_help();

// A depth source by its spec (depth_source_schemes()). Throws std::invalid_argument on a bad spec;
// an unknown scheme's message lists the valid ones. A bag source with colour=T also gives the eye
// view when no stereo source is set.
std::unique_ptr<DepthSource> make_depth_source(std::string_view spec,
                                               const SourceOptions& options = {});

// A stereo (eye view) source by its spec (stereo_source_schemes()); throws as make_depth_source.
std::unique_ptr<StereoSource> make_stereo_source(std::string_view spec,
                                                 const SourceOptions& options = {});

// The eye view of a run: the stereo spec when one is given, else the colour topic of a bag depth
// spec (`bag:FILE,colour=T`), else none (nullptr). The daemon and `telex capture` both use it.
std::unique_ptr<StereoSource> make_eye_source(std::string_view depth_spec,
                                              std::string_view stereo_spec,
                                              const SourceOptions& options = {});

// What `telex devices` lists of the remote's devices.
struct OpenNiDeviceInfo {
  std::string uri;  // e.g. "1d27/0601@3/2" (USB vendor/product@bus/address) or "Dummy"
  std::string vendor, name;
  std::uint16_t usb_vendor_id = 0, usb_product_id = 0;
};
// OpenNI2's device list (every driver it loads, the Dummy device among them). Throws
// std::runtime_error when OpenNI2 cannot initialise.
std::vector<OpenNiDeviceInfo> list_openni_devices();

struct V4l2DeviceInfo {
  std::string path;                  // /dev/videoN
  std::string card, driver, bus;     // VIDIOC_QUERYCAP
  bool capture = false;              // V4L2_CAP_VIDEO_CAPTURE
  std::vector<std::string> formats;  // "YUYV 640x480 1280x720", "MJPG ..." (discrete sizes)
  std::string error;                 // why it could not be opened or queried
};
// The video devices under `dev_dir` (video0, video1, ...) with what they capture.
std::vector<V4l2DeviceInfo> list_v4l2_devices(const std::string& dev_dir = "/dev");

// A libfreenect recording in fakenect's layout (fakenect-record: INDEX.txt naming one file per
// line, TYPE-SECONDS-TIMESTAMP.EXT; depth dumps "P5 640 480 65535\n" and 640x480 host-order u16).
// Video dumps (r-) are fakenect-record's RGB ("P6 640 480 255\n", 640x480x3) or the Kinect's IR
// video mode, which fakenect-record does not write but a recording may hold: "P5 640 488 255\n"
// (IR 8-bit) or "P5 640 488 1023\n" (IR 10-bit, host-order u16), each padded to the 921600 bytes
// libfreenect 0.5's fakenect copies from every video dump.
struct FakenectRecording {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> depth_files;  // in INDEX.txt's order
  int rgb = 0, accelerometer = 0;
  int ir = 0, ir_bits = 0;  // IR video dumps and their depth in bits (8 or 10; 0: none)
};
// Checks every line and file the way fakenect will read them; throws std::runtime_error naming
// INDEX.txt's line and what is wrong (fakenect itself exit()s on a missing or short file).
FakenectRecording check_fakenect_recording(const std::filesystem::path& dir);

// Why a bag's sensor_msgs/CameraInfo cannot be used ("fx (K[0]) = nan is not a finite positive
// number of pixels"), or empty when fx, fy, cx, cy are finite and positive and the size is too.
std::string camera_info_error(const bag::CameraIntrinsics& camera);

// Host steady clock in ns: the single time base of the remote node.
std::int64_t steady_now_ns();

}  // namespace telex::remote
