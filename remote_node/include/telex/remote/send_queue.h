// SPDX-License-Identifier: MIT
// The remote's send queue for one session: depth before video, each with its own bound.
//
// Why two lanes: the depth stream feeds the operator's haptics, the eyes only the view, and an
// H.264 intra pair is tens of datagrams. In one FIFO a burst of video delays every tile behind it
// and, over the frame bound, pushes depth frames out (each costing a key frame). Here depth is
// always taken first and its bound counts depth frames only; video has its own, smaller bound,
// drops its oldest frames first and never touches depth.
//
// Two rules keep the station's reassembler (newest frame wins, message ids counted in order)
// content when depth overtakes video:
// - A video frame once started is finished before depth goes on: its fragments form whole
//   messages, and a depth frame completing in their middle would supersede them at the station.
// - A frame may be packed late: its `pack` callback runs when the frame is first taken, so its
//   message ids, seal sequence numbers and fragment frame id are those of the moment it is sent,
//   in sending order, not of the moment it was queued.
// A pure container (no socket, no clock, no lock): the session's io thread owns it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <vector>

namespace telex::remote {

using Buffer = std::shared_ptr<const std::vector<std::uint8_t>>;

// The messages of one frame, sent in order; dropped whole when its lane is over its bound.
struct OutFrame {
  std::uint32_t frame_id = 0;
  std::vector<Buffer> items;
  std::size_t next = 0;
  bool counts_as_frame = true;  // video frames are not counted in frames_sent
  // false for resent tiles and for tiles streamed ahead of their part's manifest: not counted
  // against the queue's bound and never dropped (each is a few tiles).
  bool trimmable = true;
  // When set, replaces `items` when the frame is first taken (then cleared): packing late.
  std::function<std::vector<Buffer>()> pack;
  // What a frame packed late will hold, in bytes (its whole messages; fragment headers and seals
  // come on top), so resends not yet packed count against the repair bound too.
  std::size_t unpacked_bytes = 0;
};

enum class Lane : std::uint8_t { Depth = 0, Video = 1 };

struct SendQueueLimits {
  std::size_t max_depth_frames = 3;  // trimmable depth frames waiting (ServerConfig's bound)
  std::size_t max_video_frames = 2;  // video frames waiting, besides the one being sent
};

struct SendQueueCounters {
  std::uint64_t depth_frames_dropped = 0;
  std::uint64_t video_frames_dropped = 0;
};

class SendQueue {
 public:
  explicit SendQueue(SendQueueLimits limits = {});

  // Queues a frame in its lane and drops the oldest trimmable frames of that lane not yet started
  // beyond its bound; returns how many it dropped (for depth: the station misses tiles, so the
  // caller asks for a key frame). An untrimmable video frame (a resent pair) goes ahead of the
  // video frames not yet started.
  std::size_t push(Lane lane, OutFrame frame);

  // The next datagram (or TCP message) to send, or null when nothing waits: a started video
  // frame's remainder, else depth, else video. `frame_done` says it is its frame's last,
  // `counts` copies the frame's counts_as_frame and `lane` says whose it is.
  Buffer next_item(bool& frame_done, bool& counts, Lane& lane);

  // Bytes of resends (untrimmable frames: depth tiles and video pairs) still waiting; a frame not
  // packed yet counts its unpacked_bytes.
  std::size_t queued_repair_bytes() const;
  std::size_t depth_frames() const { return depth_.size(); }
  std::size_t video_frames() const { return video_.size(); }
  bool empty() const { return depth_.empty() && video_.empty(); }
  const SendQueueCounters& counters() const { return counters_; }

 private:
  // Takes the next item of the front frame of `q`, packing it first if it is packed late.
  static Buffer take(std::deque<OutFrame>& q, bool& frame_done, bool& counts);

  SendQueueLimits limits_;
  SendQueueCounters counters_;
  std::deque<OutFrame> depth_;
  std::deque<OutFrame> video_;
};

}  // namespace telex::remote
