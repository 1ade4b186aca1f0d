// SPDX-License-Identifier: MIT
// The surface stage: the network thread's depth events into frames (FrameAssembler, with the
// repair policy asking for lost tiles), and the surface thread's frames into the snapshots the
// haptic loop reads, built only near the fingertips.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <latch>
#include <memory>
#include <mutex>
#include <stop_token>
#include <vector>

#include "faults.h"
#include "station_view.h"
#include "telex/base/latest_slot.h"
#include "telex/base/periodic.h"
#include "telex/base/triple_buffer.h"
#include "telex/local/link/frame_assembler.h"
#include "telex/local/link/repair_policy.h"
#include "telex/local/link/surface_client.h"
#include "telex/local/record/recorder.h"
#include "telex/local/station/station_config.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

class SurfaceStage {
 public:
  // Borrows the view (it draws every surface) and the recorder (null: not recording).
  SurfaceStage(const StationConfig& cfg, StationFaults& faults, StationView& view,
               SessionRecorder* recorder);

  // The depth events of the network thread: config, tiles, manifests.
  void bind(ClientEvents& events);
  // The client the stage asks for repairs and ROIs; set before it starts.
  void attach(SurfaceClient& client) { client_ = &client; }

  // The surface thread's body; warm_up_done() returns once its buffers are warm.
  void run(std::stop_token stop);
  void wait_warm() { warm_.wait(); }
  // Wakes the surface thread for good (its stop was requested).
  void close() { frames_.close(); }

  // Surface thread -> haptic thread: the newest snapshot; haptic thread -> here: the hand.
  TripleBuffer<std::shared_ptr<const Surface>>& surfaces() { return surfaces_; }
  TripleBuffer<HandState>& hand_in() { return hand_in_; }

  std::uint64_t surfaces_built() const { return surfaces_built_.load(); }
  // Distinct captures built (a frame's parts and repairs count once).
  std::uint64_t frames_built() const { return frames_built_.load(); }
  double first_centre_depth_m() const { return first_centre_depth_m_.load(); }
  double build_ms() const { return build_ms_.load(); }
  // What the remote said of its sources this session (its standing Stats, PROTOCOL.md).
  enum RemoteSaid : unsigned { kSourceEnded = 1, kEyesOff = 2, kEyesEnded = 4 };
  unsigned remote_said() const { return remote_said_.load(); }
  void forget_remote_said() { remote_said_.store(0); }  // a new session starts
  // Frames, repair counters, tile ages and latencies; once the network and surface threads have
  // stopped.
  void summarize(StationSummary& s) const;

 private:
  void on_tile(const proto::Header& h, const proto::DepthTile& t);
  void on_manifest(const proto::Header& h, const proto::FrameManifest& m);
  void warm_up();
  // The fingertips of `hand` moved into the camera `frame` was captured with (head teleop).
  void in_frame_camera(const AssembledFrame& frame, HandState& hand) const;
  // The rest (or a repair) of a frame already built that changed no pixel these windows read.
  bool rest_changes_nothing(const AssembledFrame& frame, const std::vector<cv::Rect>& windows);
  void build(AssembledFrame& frame, std::vector<cv::Rect> windows);
  void request_roi(const std::vector<cv::Rect>& windows);

  const StationConfig& cfg_;
  StationFaults& faults_;
  StationView& view_;
  SessionRecorder* recorder_;
  SurfaceClient* client_ = nullptr;
  // How far outside a window the filter and the normals read.
  const int reach_px_;

  // ---- network thread: tiles -> frames ----
  FrameAssembler assembler_;
  RepairPolicy repair_;
  LatestSlot<AssembledFrame> frames_;
  std::mutex watch_mu_;
  // The remote's registration as its Stats said it (a static name; "" until said).
  std::atomic<const char*> remote_registration_{""};
  std::atomic<unsigned> remote_said_{0};
  std::vector<cv::Rect> watch_rects_;  // the fingertip windows as read (surface -> network)

  // ---- surface thread ----
  std::latch warm_{1};  // the surface thread's warm-up is done (or failed)
  TripleBuffer<std::shared_ptr<const Surface>> surfaces_;
  TripleBuffer<HandState> hand_in_;
  HandState hand_{};
  std::vector<cv::Rect> last_windows_;
  std::uint64_t surface_seq_ = 0;
  std::int64_t built_capture_ns_ = -1;
  // Snapshots the haptic loop may still hold are released here, never on the 1 kHz thread.
  std::deque<std::shared_ptr<const Surface>> retired_;
  // Snapshot buffers are recycled once nobody holds them (more than the retired ones + the
  // triple buffer's + the view's), so a frame neither allocates nor zeroes ~5 MB.
  SurfacePool pool_{16};
  std::atomic<std::uint64_t> surfaces_built_{0};
  std::atomic<std::uint64_t> frames_built_{0};
  std::atomic<double> first_centre_depth_m_{0.0};
  std::atomic<double> build_ms_{0.0};
  // Where a new capture's latency goes (read after the thread is joined): capture to the frame's
  // manifest on the station (remote processing + network), and from there to the surface's
  // publication (queue + build).
  Histogram arrive_ms_{0.1, 20'000}, build_wait_ms_{0.1, 20'000};
};

}  // namespace telex::local
