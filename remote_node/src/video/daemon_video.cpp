// SPDX-License-Identifier: MIT
// The remote daemon's eyes: the video thread (pair -> EyeStream -> the server) and the station's
// receiver reports, where the rate controller plugs in.
#include <array>
#include <chrono>

#include "telex/remote/daemon.h"

namespace telex::remote {

using namespace std::chrono_literals;

void RemoteDaemon::open_eyes() {
  EyeStreamConfig v;
  v.codec = config_.video_codec;
  v.bitrate_bps = config_.video_bitrate_bps;
  v.jpeg_quality = config_.jpeg_quality;
  v.width_px = config_.video_width;
  v.height_px = config_.video_height;
  v.frame_rate_hz = config_.source_options.synthetic_fps;
  // Opened now for the size expected, so an encoder that cannot open stops the start (exit 2).
  eye_stream_ =
      std::make_unique<EyeStream>(v, v.width_px > 0 ? v.width_px : config_.source_options.width,
                                  v.width_px > 0 ? v.height_px : config_.source_options.height);
  eye_rate_ = std::make_unique<EyeRate>(config_.video_bitrate_bps);
  config_.server.on_picture_loss = [this](const proto::PictureLoss&) {
    eye_stream_->request_intra();
  };
  config_.server.on_receiver_report = [this](const proto::ReceiverReport& r, std::int64_t t) {
    on_receiver_report(r, t);
  };
}

void RemoteDaemon::video_loop() {
  std::vector<std::uint8_t> encoded;
  while (running_) {
    auto frame = stereo_slot_.take(100ms);
    // Encoding costs CPU: only when the operator asked for video.
    if (!frame || !server_->video_wanted()) continue;
    bool is_intra = false;
    const bool ok = eye_stream_->encode(*frame, encoded, is_intra);
    if (ok && head_driven_) stamp_head_pose(encoded);
    if (ok)
      server_->publish_video(static_cast<std::uint32_t>(frame->frame_id), frame->capture_ns,
                             is_intra, std::move(encoded));
    encoded.clear();
    std::lock_guard lock(stats_mu_);
    if (ok) ++stats_.video_frames;
    stats_.video_failed = eye_stream_->counters().failed;
    stats_.video_intra_requests = eye_stream_->counters().intra_requests;
  }
}

// The head's joints when the pair was captured, interpolated between the head loop's readings as
// for a depth frame (head_pose_at), go in the pair's header: the station warps the video from
// them. The header's capture time is the pair's (a buffering encoder's output is an older pair).
void RemoteDaemon::stamp_head_pose(std::vector<std::uint8_t>& encoded) const {
  const video::ParsedFrame parsed = video::parse_frame(encoded);
  if (parsed.status != video::HeaderStatus::Ok) return;
  const HeadPose h = head_pose_at(parsed.header.capture_ns);
  if (!h.valid) return;
  std::array<float, 3> joint_rad{};
  for (std::size_t j = 0; j < kHeadJoints; ++j) joint_rad[j] = static_cast<float>(h.joint_rad[j]);
  video::stamp_head_pose(encoded, joint_rad);
}

void RemoteDaemon::on_receiver_report(const proto::ReceiverReport& report,
                                      std::int64_t received_ns) {
  // The link's budget less the depth's rate, capped by --video-bitrate (eye_rate.h).
  if (eye_stream_ && eye_rate_) eye_stream_->set_bitrate(eye_rate_->on_report(report, received_ns));
  std::lock_guard lock(stats_mu_);
  stats_.last_report = report;
}

}  // namespace telex::remote
