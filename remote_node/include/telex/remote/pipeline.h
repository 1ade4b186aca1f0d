// SPDX-License-Identifier: MIT
// Remote processing pipeline: register, fill, stabilise, tile, skip unchanged tiles, encode; each
// stage timed.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string_view>
#include <vector>

#include "telex/common/hole_fill.h"
#include "telex/common/registration.h"
#include "telex/common/stabilise.h"
#include "telex/common/stage_clock.h"
#include "telex/common/temporal_fill.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/messages.h"
#include "telex/remote/sources.h"

namespace telex::remote {

// Registration of the depth frame into the operator's right-eye camera, the first stage (before
// fill, so fill and the haptic surface work in the eye's pixels). none: the frame passes as it is;
// the OpenNI sources (live and .oni) deliver depth that the sensor has already registered
// (PS1080 hardware registration), so none is the default. shift: shift+scale exact at
// nominal_depth_m (cheap, wrong by fx*b*|1/Z - 1/Z0| px away from it); full: per-pixel
// reprojection with a z-buffer and crack fill (telex/common/registration.h).
enum class RegisterMode { None, Shift, Full };
// "none" | "shift" | "full" (the flag text is parsed beside telex-remote's main:
// remote_node/flags.h).
std::string_view register_mode_name(RegisterMode mode);

// Which registration brings the depth to the operator (--registration), one per run: none (depth
// in the sensor's own pixels), hardware (the sensor registers depth to its own colour camera:
// PS1080's IMAGE_REGISTRATION_DEPTH_TO_COLOR), rig (the calibrated extrinsics: depth in the right
// eye, by the registration stage below).
enum class DepthRegistration { None, Hardware, Rig };
std::string_view depth_registration_name(DepthRegistration registration);

struct RegistrationConfig {
  RegisterMode mode = RegisterMode::None;
  // Intrinsics of the eye camera; width == 0 means the depth source's own intrinsics (same
  // optics, moved by the extrinsics).
  Intrinsics eye{0.0, 0.0, 0.0, 0.0, 0, 0};
  // Extrinsics: p_eye = rotation * p_depth + translation, metres. The default is an eye whose
  // centre sits 2.5 cm to the right of the depth camera (the Kinect v1 depth-to-RGB baseline).
  RigidTransform X_EyeDepth{glm::dmat3(1.0), glm::dvec3(-0.025, 0.0, 0.0)};
  double nominal_depth_m = 1.0;  // shift: the depth at which shift+scale is exact
  // The depth sensor's calibrated intrinsics (the rig's depth key), scaled to each frame's size;
  // nullopt: the source's own.
  std::optional<Intrinsics> depth;
};

struct PipelineConfig {
  RegistrationConfig registration;
  bool fill = true;  // windowed-mode spatial fill, then temporal fill of what is left
  HoleFillOptions hole_fill;
  bool temporal_fill = true;
  TemporalFillOptions temporal;
  double stabilise_k_sigma = 0.0;  // 0 = off (bit-exact)
  int stabilise_confirm_frames = 2;
  int tile_width = 80;  // 640x480 -> 8x8 grid
  int tile_height = 60;
  int key_frame_every = 30;  // frames between key frames (1 = every frame)
  int background_every =
      2;  // tiles outside any ROI are considered every Nth frame while an ROI is set
  proto::Codec codec = proto::Codec::Zip;
  int zip_level = proto::kDefaultZipLevel;
  // With a tile sink set (FramePipeline::set_tile_sink), every this many encoded tiles of a part
  // are handed to it before the part is done, so the network (and the receiver's decoder) work
  // while the rest is encoded. 0: each part is returned whole.
  int stream_tiles = 8;
  StageClock clock_ms = steady_clock_ms;  // stage times (the bench passes thread_cpu_ms)
};

// What the receiver asked for, sampled by the processing thread once per frame.
struct FrameRequest {
  bool force_key_frame = false;       // new receiver or explicit request
  std::vector<proto::RoiRect> rois;   // in pixels of the frame as sent
  std::optional<proto::Codec> codec;  // negotiated codec (overrides the config)
  bool select_tiles = true;           // false: no receiver, stop after the stabiliser
  bool frame_parts =
      false;  // the receiver takes a frame as an ROI part and a rest (kCapFrameParts)
};

// Milliseconds by PipelineConfig::clock_ms. fill_ms covers the spatial fill, the temporal fill
// (temporal_ms, counted in fill_ms as well) and the hole count.
struct StageTimes {
  double register_ms = 0, fill_ms = 0, temporal_ms = 0, stabilise_ms = 0, tile_ms = 0,
         encode_ms = 0, total_ms = 0;

  StageTimes& operator+=(const StageTimes& o) {
    register_ms += o.register_ms;
    fill_ms += o.fill_ms;
    temporal_ms += o.temporal_ms;
    stabilise_ms += o.stabilise_ms;
    tile_ms += o.tile_ms;
    encode_ms += o.encode_ms;
    total_ms += o.total_ms;
    return *this;
  }
};

// Which part of a frame a ProcessedFrame carries (ROI first; docs/PROTOCOL.md "Frame parts").
enum class FramePart : std::uint8_t {
  Whole,    // the whole frame: its manifest closes it
  RoiPart,  // only the tiles of the requested ROIs; the rest of the same frame follows
  Rest,     // the tiles outside the ROIs; its manifest closes the frame and lists both parts' tiles
};

struct ProcessedFrame {
  FramePart part = FramePart::Whole;
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;
  bool key_frame = false;
  Intrinsics intrinsics;
  proto::TileGrid grid;
  proto::Codec codec = proto::Codec::Zip;
  cv::Mat1w sent_view_mm;  // what a receiver that got every message of every frame now holds
  std::vector<proto::EncodedTile> tiles;  // tiles to send, increasing index
  // tiles[0, tiles_streamed) went to the tile sink while the part was encoded; the rest and the
  // manifest go when the part is returned. 0 in the merged set process() returns for a frame sent
  // in two parts (its parts streamed).
  std::size_t tiles_streamed = 0;
  proto::FrameManifest manifest;
  bool rest_cut = false;  // a Rest cut short for a newer frame: its unsent tiles go with the next
  std::size_t tiles_skipped = 0;  // unchanged, or not due (outside ROI on a background-skip frame)
  std::size_t holes_in = 0, holes_out = 0;  // over the pixels this part processed
  std::size_t pixels_processed = 0;         // pixels through fill, temporal fill and stabiliser
  StageTimes times;
  double first_part_ms = 0;  // process(): times.total_ms of the frame's first part
};

// Tiles of `grid` that intersect any of `rois`, as a mask indexed by tile.
std::vector<bool> tiles_in_rois(const proto::TileGrid& grid,
                                const std::vector<proto::RoiRect>& rois);

// Single-threaded: owned by the processing thread. Reads no clock except to time its own stages.
//
// process() is the one entry point. ROI first: with ROIs requested, the ROI part fills,
// temporally fills, stabilises, selects and encodes only the tiles that intersect an ROI. On
// frames where the rest is due (key frames, and every `background_every`th frame) the other tiles
// follow as a second part of the same frame (FramePart::Rest). On other frames the ROI tiles are
// the whole frame and no pixel outside them is touched: their fill, temporal history and
// stabiliser state wait for the next frame whose rest is due. Without ROIs (or without a
// receiver) the whole frame is processed at once.
class FramePipeline {
 public:
  explicit FramePipeline(PipelineConfig config);
  // Receives each message set to send, on the processing thread, as soon as it is finished.
  using PartHandler = std::function<void(const ProcessedFrame& part)>;
  // One frame through every stage. Returns the whole frame as one message set: every tile sent
  // for it in index order, the manifest that closes it, counters and stage times of all its parts
  // summed (first_part_ms: the time until the first part was done).
  // With request.frame_parts, a frame with a rest is handed to `on_part` as two parts: the
  // RoiPart (streamed to the tile sink as it is encoded), then the Rest. `preempt`, polled
  // between tiles of the rest, cuts it short when it returns true (a newer frame is waiting):
  // the tiles not yet encoded stay due and go out with the next frame's rest (a cut key frame
  // makes the next frame a key frame); two rests in a row are never cut, so the background
  // always progresses. Without frame_parts, `on_part` receives the returned set once, nothing
  // streams and nothing is cut.
  ProcessedFrame process(const DepthFrame& frame, const FrameRequest& request,
                         const PartHandler& on_part = {},
                         const std::function<bool()>& preempt = {});
  const PipelineConfig& config() const { return config_; }
  // Receives a part's tiles as they are encoded: `part` carries the frame's id, capture time,
  // part, key flag, codec and grid, and tiles[from, part.tiles.size()) are new. Called on the
  // processing thread, between tiles; the part is not finished (no manifest yet). Only frames
  // processed with request.frame_parts stream.
  using TileSink = std::function<void(const ProcessedFrame& part, std::size_t from)>;
  void set_tile_sink(TileSink sink) { sink_ = std::move(sink); }
  // The registration stage alone: `in` itself when the mode is none, else the frame in the eye
  // camera (valid until the next call).
  const DepthImage& register_frame(const DepthImage& in);

 private:
  ProcessedFrame start_frame(const DepthFrame& frame, const FrameRequest& request,
                             const DepthImage& image);
  // The ROI part (a whole frame without ROIs or receiver); pending_ says whether a rest follows.
  ProcessedFrame first_part(const DepthFrame& frame, const FrameRequest& request);
  // The rest of the frame first_part() just returned a RoiPart of (TELEX_DEMAND).
  ProcessedFrame rest_part(const DepthFrame& frame, const std::function<bool()>& preempt);
  ProcessedFrame whole_frame(const DepthFrame& frame, const FrameRequest& request);
  // Both parts as one message set, in `rest`.
  static void merge_into_rest(ProcessedFrame&& roi, ProcessedFrame& rest);
  // Key-frame decision for the next frame sent to a receiver (counts the frame).
  bool next_frame_is_key(cv::Size size, const FrameRequest& request);

  // One part of a frame: which tiles, and how the stages treat them.
  struct TileJob {
    const std::vector<int>* tiles = nullptr;  // increasing index
    // Spatial fill only around these (widened to whole tiles); null: the whole frame.
    const std::vector<cv::Rect>* fill_rois = nullptr;
    bool new_frame = true;  // the first part of this frame: the temporal fill's clock advances
    bool select = true;     // false: stop after the stabiliser (no receiver)
    bool key = false;       // send every tile, changed or not
    const std::function<bool()>* preempt = nullptr;  // polled between tiles; true cuts the encode
  };
  // Fill, temporal fill, hole count, stabilise, select and encode `job.tiles` into `out` (times
  // and counters add up); returns the tiles sent. Every part of every frame goes through here.
  std::vector<int> process_tiles(const DepthFrame& frame, const cv::Mat1w& in, const TileJob& job,
                                 ProcessedFrame& out);

  struct Pending {
    bool active = false;
    std::uint64_t frame_id = 0;
    bool key = false;
    std::vector<bool> in_roi;             // tiles the ROI part processed
    std::vector<std::uint16_t> roi_sent;  // tiles the ROI part sent
    proto::Codec codec = proto::Codec::Zip;
  };

  PipelineConfig config_;
  TileSink sink_;
  DepthImage registered_;
  ShiftScale shift_scale_;
  std::optional<Intrinsics> shift_scale_for_;  // source intrinsics shift_scale_ was derived for
  Pending pending_;
  TemporalFill temporal_;
  Stabiliser stabiliser_;
  cv::Mat1w filled_, temporal_out_, stabilised_, sent_view_;
  std::uint64_t frames_ = 0;
  std::uint64_t since_key_ = 0;
  bool rest_owed_ = false;  // the last rest was cut: the next frame has a rest
  bool key_owed_ = false;   // ...and it was a key frame's: the next frame is a key frame
  bool last_rest_cut_ = false;
  bool stream_parts_ = false;  // this frame goes out in parts: the tile sink streams them
};

}  // namespace telex::remote
