// SPDX-License-Identifier: MIT
// The remote's network server, transport part: frames and video packed into messages for the
// current session (fragmented into datagrams, sealed with TLS, over UDP; length-prefixed over TCP),
// the send queue (depth before video, send_queue.h), the UDP send loop (one async_send_to in
// flight) and the UDP socket's receive side, which opens what arrives and acts on none of it.
#include "server_impl.h"
#include "telex/proto/fragment.h"
#include "telex/video/frame_header.h"

namespace telex::remote {
std::optional<RemoteServer::Impl::Link> RemoteServer::Impl::link() const {
  std::lock_guard lock(mu_);
  if (!connected_) return std::nullopt;
  return link_;
}

proto::Header RemoteServer::Impl::header(std::uint32_t session_id, std::uint32_t frame_id,
                                         std::int64_t capture_ns, bool key,
                                         std::uint16_t extra_flags) {
  proto::Header h;
  h.session_id = session_id;
  h.seq = seq_++;
  h.frame_id = frame_id;
  h.capture_ns = static_cast<std::uint64_t>(capture_ns);
  h.flags = static_cast<std::uint16_t>((key ? proto::kFlagKeyFrame : 0) | extra_flags);
  return h;
}

// Turns whole messages into what goes on the wire for this link.
OutFrame RemoteServer::Impl::pack(const Link& l, std::uint32_t frame_id,
                                  const std::vector<std::pair<proto::Header, proto::Message>>& msgs,
                                  int copies) {
  OutFrame f;
  f.frame_id = frame_id;
  for (const auto& [h, m] : msgs) {
    if (l.udp) {
      const auto bytes = proto::encode(h, m);
      const auto datagrams = proto::fragment_message(bytes, message_id_++, frame_id);
      // A second copy follows the whole first one, so a burst that takes a fragment of one
      // leaves the other's.
      for (int c = 0; c < copies; ++c) {
        for (const auto& d : datagrams) {
          // Every datagram is sealed on its own (each copy under its own sequence number), so a
          // forged fragment never reaches the reassembler. Sealing happens here, on the io
          // thread, in queue order: sequence numbers rise in sending order (trimmed frames
          // leave gaps, which the replay window allows).
          f.items.push_back(make_buffer(l.sealer ? l.sealer->seal(d) : d));
        }
      }
    } else {
      f.items.push_back(make_buffer(proto::encode_stream(h, m)));
    }
  }
  return f;
}

void RemoteServer::Impl::announce(const Link& l, const ProcessedFrame& frame) {
  proto::StreamConfig sc;
  sc.width = static_cast<std::uint16_t>(frame.grid.frame_width);
  sc.height = static_cast<std::uint16_t>(frame.grid.frame_height);
  sc.fx = frame.intrinsics.fx;
  sc.fy = frame.intrinsics.fy;
  sc.cx = frame.intrinsics.cx;
  sc.cy = frame.intrinsics.cy;
  sc.tile_width = static_cast<std::uint16_t>(frame.grid.tile_width);
  sc.tile_height = static_cast<std::uint16_t>(frame.grid.tile_height);
  sc.grid_cols = static_cast<std::uint16_t>(frame.grid.cols());
  sc.grid_rows = static_cast<std::uint16_t>(frame.grid.rows());
  sc.codec = frame.codec;
  sc.fps = config_.fps;
  if (l.generation == announced_generation_ && sc == announced_) return;
  announced_generation_ = l.generation;
  announced_ = sc;
  auto buf = make_buffer(
      proto::encode_stream(header(l.session_id, frame.frame_id, frame.capture_ns, false), sc));
  // Which registration put the depth in the pixels just announced (docs/PROTOCOL.md, Stats).
  auto said = make_buffer(
      proto::encode_stream(header(l.session_id, frame.frame_id, frame.capture_ns, false),
                           proto::Stats{{{"registration_" + config_.registration, 1}}}));
  asio::post(io_, [this, buf, said, gen = l.generation] {
    if (!active_ || active_generation_ != gen) return;
    send_control(buf);
    send_control(said);
  });
}

std::vector<std::pair<proto::Header, proto::Message>> RemoteServer::Impl::tile_messages(
    const Link& l, const ProcessedFrame& frame, std::size_t from) {
  // An ROI part's messages say so; the rest (or a whole frame) closes the frame and counts it.
  const std::uint16_t part_flag = frame.part == FramePart::RoiPart ? proto::kFlagRoiPart : 0;
  std::vector<std::pair<proto::Header, proto::Message>> msgs;
  msgs.reserve(frame.tiles.size() - from + 1);
  for (std::size_t i = from; i < frame.tiles.size(); ++i)
    msgs.emplace_back(
        header(l.session_id, frame.frame_id, frame.capture_ns, frame.key_frame, part_flag),
        proto::tile_message(frame.tiles[i], frame.codec));
  return msgs;
}

void RemoteServer::Impl::publish_tiles(const ProcessedFrame& part, std::size_t from) {
  const auto l = link();
  if (!l || from >= part.tiles.size()) return;
  announce(*l, part);
  streamed_generation_ = l->generation;
  post_frame(*l, part.frame_id, tile_messages(*l, part, from), false, true, false);
}

void RemoteServer::Impl::publish(const ProcessedFrame& frame) {
  const auto l = link();
  if (!l) return;
  // A frame processed while nobody was connected has no tiles or manifest: a receiver that
  // connected in between waits for the next one (its key frame).
  if (frame.manifest.tile_count == 0) return;
  // Part of this part's tiles went to an earlier session: its manifest means nothing here.
  if (frame.tiles_streamed > 0 && streamed_generation_ != l->generation) return;
  // A new session, or a frame of another shape or codec, announces the stream first (on TCP).
  announce(*l, frame);
  auto msgs = tile_messages(*l, frame, frame.tiles_streamed);
  const std::uint16_t part_flag = frame.part == FramePart::RoiPart ? proto::kFlagRoiPart : 0;
  msgs.emplace_back(
      header(l->session_id, frame.frame_id, frame.capture_ns, frame.key_frame, part_flag),
      frame.manifest);
  if (l->repair && config_.repair_cache_frames > 0) {
    std::lock_guard lock(cache_mu_);
    cache_.add(frame.frame_id, frame.capture_ns, frame.codec, frame.tiles);
  }
  post_frame(*l, frame.frame_id, std::move(msgs), frame.part != FramePart::RoiPart, true);
}

void RemoteServer::Impl::publish_video(std::uint32_t frame_id, std::int64_t capture_ns,
                                       bool is_intra, std::vector<std::uint8_t> encoded_pair) {
  const auto l = link();
  if (!l || !video_wanted_ || encoded_pair.empty()) return;
  if (l->repair) {
    const video::ParsedFrame parsed = video::parse_frame(encoded_pair);
    if (parsed.status == video::HeaderStatus::Ok) {
      std::lock_guard lock(cache_mu_);
      video_cache_.add({parsed.header.encode_seq, frame_id, capture_ns, is_intra,
                        std::make_shared<const std::vector<std::uint8_t>>(encoded_pair)});
    }
  }
  std::vector<std::pair<proto::Header, proto::Message>> msgs;
  msgs.emplace_back(header(l->session_id, frame_id, capture_ns, is_intra),
                    proto::EncodedVideo{std::move(encoded_pair)});
  post_frame(*l, frame_id, std::move(msgs), false, false, true);
}

// Hands a frame's messages to the io thread, which packs them for the session they were made for
// (only): depth as it queues them, video when it is sent (depth may overtake it in the queue, and
// its message ids and seals must still follow the sending order).
void RemoteServer::Impl::post_frame(const Link& l, std::uint32_t frame_id,
                                    std::vector<std::pair<proto::Header, proto::Message>> msgs,
                                    bool counts_as_frame, bool depth, bool trimmable, int copies) {
  asio::post(io_, [this, l, frame_id, msgs = std::move(msgs), counts_as_frame, depth, trimmable,
                   copies]() mutable {
    if (!active_ || active_generation_ != l.generation) return;
    OutFrame f;
    if (depth) {
      f = pack(l, frame_id, msgs);
      newest_queued_frame_id_ = frame_id;
    } else {
      // Video counts its own frames: its datagrams carry the newest depth frame's id when they
      // go (all depth queued before them has gone by then), so the client's reassembler (newest
      // frame wins) neither drops them as stale nor drops depth for them. With 30 fps of video
      // a station built one surface in 5 s: its depth was dropped as stale.
      f.frame_id = frame_id;
      for (const auto& [h, m] : msgs) {
        const auto* v = std::get_if<proto::EncodedVideo>(&m);
        f.unpacked_bytes +=
            (proto::kHeaderSize + (v ? v->frame.size() : 0)) * static_cast<std::size_t>(copies);
      }
      f.pack = [this, l, msgs = std::move(msgs), copies] {
        return pack(l, newest_queued_frame_id_, msgs, copies).items;
      };
    }
    f.counts_as_frame = counts_as_frame;
    f.trimmable = trimmable;
    enqueue_frame(depth ? Lane::Depth : Lane::Video, std::move(f));
  });
}

void RemoteServer::Impl::enqueue_frame(Lane lane, OutFrame f) {
  auto& a = *active_;
  const std::size_t dropped = a.queue.push(lane, std::move(f));
  if (dropped > 0 && lane == Lane::Depth) {
    counters_.frames_dropped += dropped;
    // The receiver misses those tiles: resend everything with the next frame.
    request_key_frame();
  } else if (dropped > 0) {
    // The station sees the gap in the eyes' sequence and asks for what it needs.
    counters_.video_frames_dropped += dropped;
  }
  if (a.over_udp)
    kick_udp(active_);
  else
    kick_tcp(active_);
}

void RemoteServer::Impl::kick_udp(const std::shared_ptr<Session>& a) {
  if (a->udp_sending) return;
  bool frame_done = false, counts = false;
  Lane lane = Lane::Depth;
  Buffer buf = a->queue.next_item(frame_done, counts, lane);
  const bool video = lane == Lane::Video;
  if (!buf) return;
  a->udp_sending = true;
  udp_.async_send_to(
      asio::buffer(*buf), a->udp_peer,
      [this, a, buf, frame_done, counts, video](boost::system::error_code ec, std::size_t n) {
        a->udp_sending = false;
        if (active_ != a) return;
        // A refused or failed datagram is lost like any other; key frames repair it.
        if (!ec) {
          counters_.bytes_sent += n;
          ++counters_.datagrams_sent;
          if (frame_done && counts) ++counters_.frames_sent;
          if (video) counters_.video_bytes_sent += n;
          if (video && frame_done) ++counters_.video_pairs_sent;
        }
        kick_udp(a);
      });
}

void RemoteServer::Impl::udp_receive() {
  udp_.async_receive_from(asio::buffer(udp_rx_), udp_from_,
                          [this](boost::system::error_code ec, std::size_t n) {
                            if (ec == asio::error::operation_aborted || !udp_.is_open()) return;
                            if (!ec) on_udp_datagram({udp_rx_.data(), n});
                            udp_receive();
                          });
}

// No message travels from the station over UDP (yet), so nothing here is acted on; on a sealed
// link each datagram is still opened under the station->remote key, so forged, reflected and
// replayed datagrams are told apart and counted.
void RemoteServer::Impl::on_udp_datagram(std::span<const std::uint8_t> d) {
  if (!active_ || !active_->opener) {
    ++counters_.udp_ignored;
    return;
  }
  const auto why = active_->opener->open(d, udp_plain_);
  switch (why) {
    case proto::OpenError::None:
      ++counters_.udp_ignored;
      return;
    case proto::OpenError::AuthFailed:
      ++counters_.auth_failed;
      break;
    case proto::OpenError::Replayed:
      ++counters_.replayed;
      break;
    case proto::OpenError::Truncated:
    case proto::OpenError::BadMagic:
      ++counters_.unsealed;
      break;
  }
  const auto now = std::chrono::steady_clock::now();
  if (now - last_drop_log_ > std::chrono::seconds(1)) {
    last_drop_log_ = now;
    spdlog::warn(
        "dropped a datagram from {}:{}: {} under this session's station->remote key; "
        "totals: auth_failed {} unsealed {} replayed {}",
        udp_from_.address().to_string(), udp_from_.port(), proto::open_error_name(why),
        counters_.auth_failed.load(), counters_.unsealed.load(), counters_.replayed.load());
  }
}

}  // namespace telex::remote
