// SPDX-License-Identifier: MIT
// The remote's network server, session part (Asio's chat_session): the operator's TCP read loop
// through proto::StreamParser, Hello/Accept, heartbeats, ROI requests, key-frame requests, Bye,
// dropped messages, and the TCP write queue (one async_write in flight, control first).
#include "server_impl.h"

namespace telex::remote {

// Reads a pending connection up to its Hello and the operator's session after it.
void RemoteServer::Impl::do_read(std::shared_ptr<Session> a) {
  a->link->async_read_some(
      asio::buffer(a->rx), [this, a](boost::system::error_code ec, std::size_t n) {
        if (!a->open) return;
        if (ec) {
          close_session(a, SessionEnd::ConnectionLost);
          return;
        }
        if (!a->first_bytes_seen) {
          a->first_bytes_seen = true;
          // A TLS record (handshake 0x16, version 3.x) where a plain length prefix belongs.
          if (!a->link->tls() && n >= 2 && a->rx[0] == 0x16 && a->rx[1] == 0x03) {
            ++counters_.auth_failed;
            if (log_allowed(last_auth_log_, auth_logs_held_))
              spdlog::warn(
                  "connection from {} speaks TLS but this telex-remote has no --psk key or "
                  "certificates",
                  a->peer);
            refuse_session(a, proto::RejectReason::AuthFailed,
                           "this telex-remote has no --psk key or certificates but the station "
                           "speaks TLS: start both daemons with the same --psk FILE, or neither",
                           true, true);
            return;
          }
        }
        std::size_t off = 0;
        while (off < n) {
          const std::size_t took =
              a->parser.feed(std::span<const std::uint8_t>(a->rx.data() + off, n - off));
          off += took;
          while (auto r = a->parser.next()) {
            if (!r->ok()) {
              on_bad_message(a, *r);
              if (!a->open) return;
              continue;
            }
            // Only a message that decoded (over TLS when configured) keeps the session alive.
            a->last_rx = std::chrono::steady_clock::now();
            handle(a, *r->envelope);
            if (!a->open) return;
          }
          if (a->parser.failed()) {
            ++counters_.malformed_in;
            close_session(a, SessionEnd::Unparseable);
            return;
          }
          if (took == 0) break;
        }
        do_read(a);
      });
}

void RemoteServer::Impl::handle(const std::shared_ptr<Session>& a, const proto::Envelope& env) {
  if (!a->hello_done) {
    const auto* hello = std::get_if<proto::Hello>(&env.message);
    if (hello == nullptr) {
      ++counters_.malformed_in;
      refuse_session(a, proto::RejectReason::BadRequest, "the first message must be Hello");
      return;
    }
    on_hello(a, *hello);
    return;
  }
  std::visit(
      [&](const auto& m) {
        using T = std::decay_t<decltype(m)>;
        if constexpr (std::is_same_v<T, proto::Heartbeat>) {
          // Only probes (t2 = 0) are answered: an answer to an answer would ping-pong forever.
          if (m.t2_ns != 0) return on_probe_answer(a, m);
          // A station that probes but does not read would grow the control queue by one answer
          // per probe: answer only while few are waiting (an unanswered probe is a lost one).
          if (a->control.size() >= kMaxHeartbeatBacklog) {
            ++counters_.control_dropped;
            return;
          }
          proto::Heartbeat reply = m;
          reply.t2_ns = static_cast<std::uint64_t>(steady_now_ns());
          reply.t3_ns = static_cast<std::uint64_t>(steady_now_ns());
          send_control(make_buffer(
              proto::encode_stream(header(session_id_, 0, steady_now_ns(), false), reply)));
        } else if constexpr (std::is_same_v<T, proto::RoiRequest>) {
          std::lock_guard lock(mu_);
          request_.rois = m.rects;
        } else if constexpr (std::is_same_v<T, proto::Stats>) {
          for (const auto& [key, value] : m.counters)
            if (key == "key_frame_request" && value != 0) {
              ++counters_.key_frame_requests;
              request_key_frame();
            }
        } else if constexpr (std::is_same_v<T, proto::TileNack>) {
          on_nack(m);
        } else if constexpr (std::is_same_v<T, proto::VideoNack>) {
          on_video_nack(m);
        } else if constexpr (std::is_same_v<T, proto::HeadCommand>) {
          ++counters_.head_commands_in;
          const std::int64_t now = steady_now_ns();
          if (config_.on_head_command) config_.on_head_command(m, now, a->clock.station_time(now));
        } else if constexpr (std::is_same_v<T, proto::PictureLoss>) {
          ++counters_.plis_in;
          if (config_.on_picture_loss) config_.on_picture_loss(m);
        } else if constexpr (std::is_same_v<T, proto::ReceiverReport>) {
          ++counters_.receiver_reports_in;
          if (config_.on_receiver_report) config_.on_receiver_report(m, steady_now_ns());
        } else if constexpr (std::is_same_v<T, proto::Bye>) {
          end_session(SessionEnd::ClientBye);
        } else {
          ++counters_.malformed_in;  // a message only the server sends
        }
      },
      env.message);
}

void RemoteServer::Impl::probe(const std::shared_ptr<Session>& a) {
  const auto now = std::chrono::steady_clock::now();
  if (!a->hello_done || now - a->last_probe < kProbeInterval ||
      a->control.size() >= kMaxHeartbeatBacklog)
    return;
  a->last_probe = now;
  proto::Heartbeat hb;
  hb.t1_ns = static_cast<std::uint64_t>(steady_now_ns());
  send_control(
      make_buffer(proto::encode_stream(header(session_id_, 0, steady_now_ns(), false), hb)));
}

// An answer to one of our probes (it echoes our t1). Stamps that are no answer are not believed
// (OperatorClock::add); the station answers as soon as it reads the probe (its t2, t3).
void RemoteServer::Impl::on_probe_answer(const std::shared_ptr<Session>& a,
                                         const proto::Heartbeat& m) {
  const std::int64_t t4 = steady_now_ns();
  const auto t1 = static_cast<std::int64_t>(m.t1_ns);
  if (!a->clock.add(t1, static_cast<std::int64_t>(m.t2_ns), static_cast<std::int64_t>(m.t3_ns),
                    t4) ||
      a->clock_logged)
    return;
  a->clock_logged = true;
  spdlog::info("station {}: its clock is {:+.3f} ms from ours (round trip {:.3f} ms)", a->peer,
               static_cast<double>(*a->clock.offset_ns()) * 1e-6,
               static_cast<double>(a->clock.delay_ns()) * 1e-6);
}

// Counts a rejected message and logs at most once a second. Authenticity is TLS's: whatever
// reaches the parser came from the peer that passed the handshake.
void RemoteServer::Impl::on_bad_message(const std::shared_ptr<Session>& a, const proto::Result& r) {
  ++counters_.malformed_in;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_drop_log_ > std::chrono::seconds(1)) {
    last_drop_log_ = now;
    spdlog::warn("dropped a message from {}: {} ({}); malformed {}", a->peer,
                 proto::error_reason_name(r.error), r.detail, counters_.malformed_in.load());
  }
}

// Refuses the operator's session or a pending connection (before its Hello, whoever it is: the log
// line is rate-limited).
void RemoteServer::Impl::refuse_session(const std::shared_ptr<Session>& a,
                                        proto::RejectReason reason, std::string text, bool send,
                                        bool plain) {
  ++counters_.sessions_ended[static_cast<std::size_t>(SessionEnd::Refused)];
  if (a == active_) {
    spdlog::info("session with {} refused: {}", a->peer, text);
    active_.reset();
    std::lock_guard lock(mu_);
    connected_ = false;
  } else {
    if (log_allowed(last_auth_log_, auth_logs_held_))
      spdlog::info("connection from {} refused: {}", a->peer, text);
    pending_.remove(a);
  }
  a->open = false;
  if (!send) {
    ++counters_.clients_rejected;
    a->link->close();
    return;
  }
  // In clear text on the socket under a failed TLS layer: a plain station can read it.
  auto link = plain ? std::make_shared<proto::LinkStream>(std::move(a->link->socket())) : a->link;
  reject(std::move(link), reason, std::move(text));
}

void RemoteServer::Impl::on_hello(const std::shared_ptr<Session>& a, const proto::Hello& hello) {
  if (hello.version != proto::kProtocolVersion) {
    refuse_session(a, proto::RejectReason::VersionMismatch,
                   fmt::format("server speaks protocol version {}, client {}",
                               proto::kProtocolVersion, hello.version));
    return;
  }
  // The slot is taken here, after the handshake and an authenticated Hello, never at accept.
  if (active_) {
    refuse_session(a, proto::RejectReason::Busy,
                   fmt::format("another operator is connected from {}; try again when it "
                               "disconnects",
                               active_->peer));
    return;
  }
  promote(a);
  proto::Codec codec = config_.codec;
  if (!hello.codecs.empty() &&
      std::find(hello.codecs.begin(), hello.codecs.end(), codec) == hello.codecs.end())
    codec = hello.codecs.front();
  a->over_udp =
      !config_.force_tcp && (hello.capabilities & proto::kCapDepthUdp) && hello.udp_port != 0;
  boost::system::error_code ec;
  if (a->over_udp)
    a->udp_peer = udp::endpoint(a->link->socket().remote_endpoint(ec).address(), hello.udp_port);
  a->hello_done = true;
  session_id_ = next_session_id_++;
  const proto::Header accept_header = header(session_id_, 0, steady_now_ns(), false);
  proto::Accept acc;
  acc.session_id = session_id_;
  acc.codec = codec;
  acc.transport = a->over_udp ? proto::Transport::Udp : proto::Transport::Tcp;
  acc.udp_port = a->over_udp ? udp_.local_endpoint().port() : 0;
  send_control(make_buffer(proto::encode_stream(accept_header, acc)));
  probe(a);  // the first one with the Accept: HeadCommands are judged from its answer on
  send_told(!config_.video_available && (hello.capabilities & proto::kCapVideo));
  ++counters_.clients_accepted;
  std::lock_guard lock(mu_);
  connected_ = true;
  video_wanted_ = config_.video_available && (hello.capabilities & proto::kCapVideo);
  frame_parts_ = (hello.capabilities & proto::kCapFrameParts) != 0;
  const bool repair = (hello.capabilities & proto::kCapRepair) != 0;
  link_ = Link{session_id_, active_generation_, a->over_udp, repair, a->sealer};
  {
    std::lock_guard cache_lock(cache_mu_);
    cache_.clear();  // tiles sent to an earlier session were encoded against its frames
    video_cache_.clear();
  }
  request_ = FrameRequest{};
  request_.force_key_frame = true;  // a new receiver holds nothing
  request_.codec = codec;
  request_.frame_parts = frame_parts_;
}

void RemoteServer::Impl::request_key_frame() {
  std::lock_guard lock(mu_);
  request_.force_key_frame = true;
}

// Whether a resend of `bytes` may go (issue 27's bounds): under kMaxQueuedRepairBytes with what is
// `queued` (which it then grows), not sent again within the dedup interval (`slot` and `id` name
// it), within the byte budget. Each refusal is counted; one over the queue bound in `over_queue`
// (tiles and pairs apart: a station that stops reading meets it with either).
bool RemoteServer::Impl::admit_repair(std::size_t& queued, std::uint16_t slot, std::uint32_t id,
                                      std::size_t bytes, std::int64_t now_ns,
                                      std::atomic<std::uint64_t>& over_queue) {
  if (queued + bytes > kMaxQueuedRepairBytes) {
    ++over_queue;
    return false;
  }
  switch (active_->repair.admit(slot, id, bytes, now_ns)) {
    case RepairLimiter::Verdict::Duplicate:
      ++counters_.repair_duplicates;
      return false;
    case RepairLimiter::Verdict::OverBudget:
      ++counters_.repair_over_budget;
      return false;
    case RepairLimiter::Verdict::Send:
      break;
  }
  queued += bytes;
  return true;
}

// A TileNack (PROTOCOL.md 2.5): each tile it lists goes out again once, as cached, behind the
// frames already queued (at most max_queued_frames); a tile the cache no longer holds is counted
// and the next frame is a key frame.
void RemoteServer::Impl::on_nack(const proto::TileNack& nack) {
  ++counters_.nacks_in;
  const auto l = link();
  if (!l || !l->repair) {
    ++counters_.malformed_in;  // only a client that announced kCapRepair may ask
    return;
  }
  NackAnswer answer;
  {
    std::lock_guard lock(cache_mu_);
    answer = cache_.answer(nack);
  }
  counters_.repair_unavailable += answer.unavailable.size();
  if (!answer.unavailable.empty()) request_key_frame();
  if (answer.resend.empty()) return;
  // Bounded (issue 27): each tile once per dedup interval, within the byte budget, and never
  // more than kMaxQueuedRepairBytes of resends waiting for a station that does not read.
  std::size_t queued = active_ ? queued_repair_bytes(*active_) : 0;
  const std::int64_t now = steady_now_ns();
  std::vector<std::pair<proto::Header, proto::Message>> msgs;
  msgs.reserve(answer.resend.size());
  for (const auto& c : answer.resend) {
    if (!admit_repair(queued, c.tile->index, c.frame_id, c.tile->bytes.size(), now,
                      counters_.repair_over_queue))
      continue;
    msgs.emplace_back(header(l->session_id, c.frame_id, c.capture_ns, false, proto::kFlagRepair),
                      proto::tile_message(*c.tile, c.codec));
  }
  if (msgs.empty()) return;
  counters_.repair_tiles_sent += msgs.size();
  OutFrame f = pack(*l, newest_queued_frame_id_, msgs);
  f.counts_as_frame = false;
  f.trimmable = false;
  enqueue_frame(Lane::Depth, std::move(f));
}

// A VideoNack (PROTOCOL.md 2.7): each pair it lists that the cache still holds goes out again,
// in the video lane ahead of the pairs not yet started, under the same bounds as tiles. Over UDP
// it goes twice under one message id, so it is lost only if one of its fragments is lost in both
// copies: at 5 % loss a pair of 10 fragments is lost 40 % of the time in one copy, 2.5 % in two.
void RemoteServer::Impl::on_video_nack(const proto::VideoNack& nack) {
  ++counters_.video_nacks_in;
  const auto l = link();
  if (!l || !l->repair || !active_) {
    ++counters_.malformed_in;  // only a client that announced kCapRepair may ask
    return;
  }
  std::size_t queued = queued_repair_bytes(*active_);
  const std::int64_t now = steady_now_ns();
  const int copies = l->udp ? 2 : 1;
  for (std::uint32_t i = 0; i < nack.count; ++i) {
    const std::uint32_t seq = nack.first_seq + i;
    std::optional<VideoRepairCache::Pair> p;
    {
      std::lock_guard lock(cache_mu_);
      p = video_cache_.find(seq);
    }
    if (!p) {
      ++counters_.video_repair_unavailable;
      continue;
    }
    // Pairs share the limiter with tiles: their dedup slots follow the tiles' index range.
    const auto slot = static_cast<std::uint16_t>(proto::kMaxManifestTiles + seq % 64);
    if (!admit_repair(queued, slot, seq, p->frame->size() * static_cast<std::size_t>(copies), now,
                      counters_.video_repair_over_queue))
      continue;
    ++counters_.video_pairs_resent;
    std::vector<std::pair<proto::Header, proto::Message>> msgs;
    msgs.emplace_back(
        header(l->session_id, p->frame_id, p->capture_ns, p->is_intra, proto::kFlagRepair),
        proto::EncodedVideo{*p->frame});
    post_frame(*l, p->frame_id, std::move(msgs), false, false, false, copies);
  }
}

// Resends (untrimmable frames) still waiting in `s`'s queue, in bytes.
std::size_t RemoteServer::Impl::queued_repair_bytes(const Session& s) const {
  return s.queue.queued_repair_bytes();
}

void RemoteServer::Impl::tell(const std::string& key) {
  asio::post(io_, [this, key] {
    if (std::find(told_.begin(), told_.end(), key) != told_.end()) return;
    told_.push_back(key);
    if (active_ && active_->hello_done)
      send_control(make_buffer(proto::encode_stream(header(session_id_, 0, steady_now_ns(), false),
                                                    proto::Stats{{{key, 1}}})));
  });
}

void RemoteServer::Impl::send_told(bool eyes_off) {
  proto::Stats facts;
  for (const auto& key : told_) facts.counters.emplace_back(key, 1);
  if (eyes_off) facts.counters.emplace_back("eyes_off", 1);
  if (facts.counters.empty()) return;
  send_control(
      make_buffer(proto::encode_stream(header(session_id_, 0, steady_now_ns(), false), facts)));
}

void RemoteServer::Impl::send_control(Buffer buf) {
  if (!active_) return;
  if (active_->control.size() >= kMaxControlQueue) {
    ++counters_.control_dropped;
    return;
  }
  active_->control.push_back(std::move(buf));
  kick_tcp(active_);
}

void RemoteServer::Impl::kick_tcp(const std::shared_ptr<Session>& a) {
  if (a->tcp_writing) return;
  Buffer buf;
  bool frame_done = false, counts = false, is_data = false, video = false;
  Lane lane = Lane::Depth;
  if (!a->control.empty()) {
    buf = a->control.front();
    a->control.pop_front();
  } else if (!a->over_udp) {
    buf = a->queue.next_item(frame_done, counts, lane);
    video = lane == Lane::Video;
    is_data = true;
  }
  if (!buf) return;
  a->tcp_writing = true;
  a->link->async_write(asio::buffer(*buf), [this, a, buf, frame_done, counts, is_data, video](
                                               boost::system::error_code ec, std::size_t n) {
    a->tcp_writing = false;
    if (active_ != a) return;
    if (ec) {
      end_session(SessionEnd::WriteFailed);
      return;
    }
    if (is_data) {
      counters_.bytes_sent += n;
      ++counters_.messages_sent;
      if (frame_done && counts) ++counters_.frames_sent;
      if (video) counters_.video_bytes_sent += n;
      if (video && frame_done) ++counters_.video_pairs_sent;
    }
    kick_tcp(a);
  });
}

}  // namespace telex::remote
