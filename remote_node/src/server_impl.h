// SPDX-License-Identifier: MIT
// RemoteServer's insides, shared by its three parts: the acceptor (server.cpp), the operator's
// session (server_session.cpp) and the frame transport (server_transport.cpp).
#pragma once

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <boost/asio.hpp>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "telex/proto/parser.h"
#include "telex/remote/repair_cache.h"
#include "telex/remote/server.h"

namespace telex::remote {

namespace asio = boost::asio;
using tcp = asio::ip::tcp;
using udp = asio::ip::udp;
using Buffer = std::shared_ptr<const std::vector<std::uint8_t>>;
using KeyPtr = std::shared_ptr<const proto::AuthKey>;

inline Buffer make_buffer(std::vector<std::uint8_t> bytes) {
  return std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
}

// The messages of one frame, sent in order; dropped whole when the queue is over its bound.
struct OutFrame {
  std::uint32_t frame_id = 0;
  std::vector<Buffer> items;
  std::size_t next = 0;
  bool counts_as_frame = true;  // video frames are not counted in frames_sent
  // false for resent tiles and for tiles streamed ahead of their part's manifest: not counted
  // against the queue's bound and never dropped (each is a few tiles).
  bool trimmable = true;
};

// The connected operator (Asio's chat_session): its socket, parser and queues. Lives on the io
// thread; the server holds the one current session and drops it when the session ends.
struct Session {
  Session(tcp::socket s, RepairLimiter::Config limits) : socket(std::move(s)), repair(limits) {}
  tcp::socket socket;
  proto::StreamParser parser;
  KeyPtr session_key;  // after Hello with --psk
  std::array<std::uint8_t, 16384> rx{};
  bool hello_done = false;
  std::chrono::steady_clock::time_point last_rx;
  udp::endpoint udp_peer;
  bool over_udp = false;
  std::deque<Buffer> control;  // control messages go before frame data (at most kMaxControlQueue)
  RepairLimiter repair;        // this session's NACK answers: dedup and byte budget
  std::deque<OutFrame> frames;
  bool tcp_writing = false;  // one async_write in flight
  bool udp_sending = false;  // one async_send_to in flight
  std::string peer;

  // The next datagram or message of the queued frames, advancing the queue.
  Buffer next_frame_item(bool& frame_done, bool& counts) {
    while (!frames.empty() && frames.front().next >= frames.front().items.size())
      frames.pop_front();
    if (frames.empty()) return nullptr;
    auto& f = frames.front();
    Buffer b = f.items[f.next++];
    frame_done = f.next == f.items.size();
    counts = f.counts_as_frame;
    if (frame_done) frames.pop_front();
    return b;
  }
};

// Bounds on what a station that does not read can make the remote hold (issue 27).
inline constexpr std::size_t kMaxControlQueue = 64;     // control messages waiting
inline constexpr std::size_t kMaxHeartbeatBacklog = 4;  // a probe is answered only below this
inline constexpr std::size_t kMaxQueuedRepairBytes = 512 * 1024;  // resends waiting to go out

class RemoteServer::Impl {
 public:
  explicit Impl(ServerConfig config);
  ~Impl() { stop(); }
  void start();
  void stop();
  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }
  FrameRequest take_request();
  void publish(const ProcessedFrame& frame);
  void publish_tiles(const ProcessedFrame& part, std::size_t from);
  void publish_video(std::uint32_t frame_id, std::int64_t capture_ns,
                     const std::vector<std::uint8_t>& left, const std::vector<std::uint8_t>& right,
                     int width, int height);
  ClientState state() const { return connected_ ? ClientState::Connected : ClientState::Waiting; }
  bool video_wanted() const { return video_wanted_; }
  ServerCounters counters_;
  std::string scheduling_;  // the io thread's, set by start()

 private:
  // What the processing thread needs to address the current session.
  struct Link {
    std::uint32_t session_id = 0;
    std::uint32_t generation = 0;
    bool udp = false;
    bool repair = false;  // the client announced kCapRepair: its frames' tiles are cached
    KeyPtr key;           // the session key with --psk, else null
  };

  // ---- acceptor (server.cpp), io thread ----
  void do_accept();
  void reject(tcp::socket socket, proto::RejectReason reason, std::string text);
  void start_session(tcp::socket socket);
  void end_session(SessionEnd why);
  void arm_timer();
  const proto::AuthKey* psk() const { return config_.psk ? &*config_.psk : nullptr; }

  // ---- session (server_session.cpp), io thread ----
  void do_read(std::shared_ptr<Session> s, std::uint32_t gen);
  void handle(const std::shared_ptr<Session>& s, const proto::Envelope& env);
  void on_bad_message(const std::shared_ptr<Session>& s, const proto::Result& r);
  void on_hello(const std::shared_ptr<Session>& s, const proto::Hello& hello,
                std::uint64_t hello_nonce);
  void refuse_session(proto::RejectReason reason, std::string text);
  void request_key_frame();
  void on_nack(const proto::TileNack& nack);
  void send_control(Buffer buf);
  std::size_t queued_repair_bytes(const Session& s) const;
  void kick_tcp(const std::shared_ptr<Session>& s);

  // ---- transport (server_transport.cpp) ----
  std::optional<Link> link() const;  // any thread
  proto::Header header(std::uint32_t session_id, std::uint32_t frame_id, std::int64_t capture_ns,
                       bool key, std::uint16_t extra_flags = 0);
  OutFrame pack(const Link& l, std::uint32_t frame_id,
                const std::vector<std::pair<proto::Header, proto::Message>>& msgs);
  // `frame_id` is the fragments' (the messages' headers keep their own).
  // Packs `msgs` on the io thread, so message ids follow the send queue's order (the client's
  // reassembler counts an id that arrives after a later one as lost).
  void post_frame(const Link& l, std::uint32_t frame_id,
                  std::vector<std::pair<proto::Header, proto::Message>> msgs, bool counts_as_frame,
                  bool depth, bool trimmable = true);
  // Sends StreamConfig first when the session or the frame's shape or codec is new.
  void announce(const Link& l, const ProcessedFrame& frame);
  // One message per tile of tiles[from, end), with the part's header flags.
  std::vector<std::pair<proto::Header, proto::Message>> tile_messages(const Link& l,
                                                                      const ProcessedFrame& frame,
                                                                      std::size_t from);
  void enqueue_frame(OutFrame f);  // io thread
  void kick_udp(const std::shared_ptr<Session>& s);
  void udp_receive();

  ServerConfig config_;
  asio::io_context io_;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work_{
      asio::make_work_guard(io_)};
  tcp::acceptor acceptor_;
  udp::socket udp_;
  asio::steady_timer timer_;
  std::thread thread_;

  // io thread only
  std::shared_ptr<Session> active_;
  std::uint32_t active_generation_ = 0;
  std::uint32_t session_id_ = 0;
  std::uint32_t next_session_id_ = 1;
  std::chrono::steady_clock::time_point last_drop_log_{};
  std::array<std::uint8_t, 2048> udp_rx_{};
  udp::endpoint udp_from_;

  // processing thread only
  std::uint32_t announced_generation_ = 0;
  proto::StreamConfig announced_;
  std::uint32_t streamed_generation_ = 0;  // the session the current part's tiles streamed to

  // shared
  std::mutex cache_mu_;
  RepairCache cache_;  // guarded by cache_mu_; filled by publish(), read by on_nack()
  mutable std::mutex mu_;
  FrameRequest request_;
  bool frame_parts_ = false;  // guarded by mu_
  Link link_;
  std::atomic<bool> connected_{false};
  std::atomic<bool> video_wanted_{false};
  std::atomic<std::uint32_t> seq_{0};
  // io thread: the newest depth frame queued; a repair's datagrams carry it in their fragment
  // header, so the client's reassembler (newest frame wins) does not drop them as stale.
  std::uint32_t newest_queued_frame_id_ = 0;
  std::atomic<std::uint32_t> message_id_{0};
};

}  // namespace telex::remote
