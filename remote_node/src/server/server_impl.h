// SPDX-License-Identifier: MIT
// RemoteServer's insides, shared by its three parts: the acceptor (server.cpp), the operator's
// session (server_session.cpp) and the frame transport (server_transport.cpp).
#pragma once

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <boost/asio.hpp>
#include <deque>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "telex/base/pi_mutex.h"
#include "telex/proto/link_stream.h"
#include "telex/proto/parser.h"
#include "telex/proto/seal.h"
#include "telex/remote/operator_clock.h"
#include "telex/remote/repair_cache.h"
#include "telex/remote/send_queue.h"
#include "telex/remote/server.h"

namespace telex::remote {

namespace asio = boost::asio;
using tcp = asio::ip::tcp;
using udp = asio::ip::udp;
using SealerPtr = std::shared_ptr<proto::DatagramSealer>;  // used on the io thread only

inline Buffer make_buffer(std::vector<std::uint8_t> bytes) {
  return std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
}

// The connected operator (Asio's chat_session): its connection (TLS or plain), parser and queues.
// Lives on the io thread; the server holds the one current session and drops it when it ends.
struct Session {
  Session(std::shared_ptr<proto::LinkStream> s, RepairLimiter::Config limits,
          SendQueueLimits queue_limits)
      : link(std::move(s)), repair(limits), queue(queue_limits) {}
  std::shared_ptr<proto::LinkStream> link;
  proto::StreamParser parser;
  // With TLS, after the handshake: datagrams out are sealed under the remote->station key, and
  // datagrams in must open under the station->remote key.
  SealerPtr sealer;
  std::unique_ptr<proto::DatagramOpener> opener;
  std::array<std::uint8_t, 16384> rx{};
  // Until an authenticated Hello the connection is pending (server_pending.cpp), not the session:
  // it waits for its first byte (Idle), runs the TLS handshake (Handshaking), then reads until
  // its Hello (AwaitingHello); only then may it take the operator's slot (Active).
  enum class Stage : std::uint8_t { Idle, Handshaking, AwaitingHello, Active };
  Stage stage = Stage::Idle;
  bool open = true;  // false once closed: its pending handlers bail out
  std::chrono::steady_clock::time_point accepted_at;
  std::string source;             // the peer's address alone, for the per-source cap
  bool first_bytes_seen = false;  // plain server: the first read checks for a TLS ClientHello
  bool hello_done = false;
  std::chrono::steady_clock::time_point last_rx;
  udp::endpoint udp_peer;
  bool over_udp = false;
  std::deque<Buffer> control;  // control messages go before frame data (at most kMaxControlQueue)
  RepairLimiter repair;        // this session's NACK answers: dedup and byte budget
  SendQueue queue;             // depth before video (send_queue.h)
  bool tcp_writing = false;    // one async_write in flight
  bool udp_sending = false;    // one async_send_to in flight
  std::string peer;
  // The station's clock, from the remote's own heartbeat probes (one every kProbeInterval from
  // Accept on): what a HeadCommand's age at arrival is judged on (PROTOCOL.md 2.6).
  OperatorClock clock;
  std::chrono::steady_clock::time_point last_probe{};
  bool clock_logged = false;
};

// Bounds on connections before authentication (issue 49): an idle or half-open crowd can neither
// take the operator's slot nor run the remote out of descriptors. Over a cap the oldest
// connection goes first, idle ones (no byte yet) before those whose handshake runs.
inline constexpr std::size_t kMaxPending = 64;
inline constexpr std::size_t kMaxPendingPerSource = 8;
inline constexpr auto kFirstByteTimeout = std::chrono::seconds(1);      // a TLS client speaks first
inline constexpr auto kPreauthTimeout = std::chrono::seconds(3);        // handshake and Hello done
inline constexpr auto kAcceptBackoff = std::chrono::milliseconds(100);  // after EMFILE and kin

// Bounds on what a station that does not read can make the remote hold (issue 27).
inline constexpr std::size_t kMaxControlQueue = 64;     // control messages waiting
inline constexpr std::size_t kMaxHeartbeatBacklog = 4;  // a probe is answered only below this
// The remote's own probes: the station's clock offset for HeadCommands' ages. Sent only while
// fewer than kMaxHeartbeatBacklog control messages wait (a station that does not read gets none).
inline constexpr std::chrono::milliseconds kProbeInterval{250};
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
  void publish_video(std::uint32_t frame_id, std::int64_t capture_ns, bool is_intra,
                     std::vector<std::uint8_t> encoded_pair);
  ClientState state() const { return connected_ ? ClientState::Connected : ClientState::Waiting; }
  bool video_wanted() const { return video_wanted_; }
  void tell(const std::string& key);  // any thread
  ServerCounters counters_;
  std::string scheduling_;  // the io thread's, set by start()
  ThreadFault fault_{"network (telex-net)"};

 private:
  // What the processing thread needs to address the current session.
  struct Link {
    std::uint32_t session_id = 0;
    std::uint32_t generation = 0;
    bool udp = false;
    bool repair = false;  // the client announced kCapRepair: its frames' tiles are cached
    SealerPtr sealer;     // with TLS: seals this session's datagrams; else null
  };

  // ---- acceptor (server.cpp), io thread ----
  void do_accept();
  void reject(std::shared_ptr<proto::LinkStream> link, proto::RejectReason reason,
              std::string text);
  void on_handshake(const std::shared_ptr<Session>& s, boost::system::error_code ec);
  void end_session(SessionEnd why);
  // Ends `s` whether it is the operator's session or still pending.
  void close_session(const std::shared_ptr<Session>& s, SessionEnd why);
  void arm_timer();
  std::shared_ptr<proto::LinkStream> make_link(tcp::socket socket);

  // ---- pre-authentication (server_pending.cpp), io thread ----
  void admit(tcp::socket socket);
  void on_accept_error(boost::system::error_code ec);
  void make_room(const std::string& source);
  void drop_pending(const std::shared_ptr<Session>& s);
  void sweep_pending(std::chrono::steady_clock::time_point now);
  void close_all_pending();
  // Takes the operator's slot for `s`, whose Hello just authenticated it.
  void promote(const std::shared_ptr<Session>& s);
  // At most one line a second per `last`; how many were held back is said with the next.
  bool log_allowed(std::chrono::steady_clock::time_point& last, std::uint64_t& held);

  // ---- session (server_session.cpp), io thread ----
  void do_read(std::shared_ptr<Session> s);
  void handle(const std::shared_ptr<Session>& s, const proto::Envelope& env);
  void on_bad_message(const std::shared_ptr<Session>& s, const proto::Result& r);
  void on_hello(const std::shared_ptr<Session>& s, const proto::Hello& hello);
  // Ends the session as Refused; the Reject goes over the session's link, or with `plain` in
  // clear text on its socket (a peer that does not speak TLS), or not at all with `send` false.
  void refuse_session(const std::shared_ptr<Session>& s, proto::RejectReason reason,
                      std::string text, bool send = true, bool plain = false);
  void probe(const std::shared_ptr<Session>& s);  // a heartbeat probe, when one is due
  void on_probe_answer(const std::shared_ptr<Session>& s, const proto::Heartbeat& answer);
  void request_key_frame();
  void on_nack(const proto::TileNack& nack);
  void on_video_nack(const proto::VideoNack& nack);
  bool admit_repair(std::size_t& queued, std::uint16_t slot, std::uint32_t id, std::size_t bytes,
                    std::int64_t now_ns, std::atomic<std::uint64_t>& over_queue);
  void send_control(Buffer buf);
  // The standing facts (tell()) as Stats counters to the operator's session; with `eyes_off`
  // also "eyes_off" when it asked for video and there is no --stereo.
  void send_told(bool eyes_off);
  std::size_t queued_repair_bytes(const Session& s) const;
  void kick_tcp(const std::shared_ptr<Session>& s);

  // ---- transport (server_transport.cpp) ----
  std::optional<Link> link() const;  // any thread
  proto::Header header(std::uint32_t session_id, std::uint32_t frame_id, std::int64_t capture_ns,
                       bool key, std::uint16_t extra_flags = 0);
  // Over UDP each message's datagrams go `copies` times, all under one message id (a resent pair
  // twice: the client's reassembler completes it from the fragments of either copy).
  OutFrame pack(const Link& l, std::uint32_t frame_id,
                const std::vector<std::pair<proto::Header, proto::Message>>& msgs, int copies = 1);
  // `frame_id` is the fragments' (the messages' headers keep their own).
  // Packs `msgs` on the io thread, so message ids follow the send queue's order (the client's
  // reassembler counts an id that arrives after a later one as lost).
  void post_frame(const Link& l, std::uint32_t frame_id,
                  std::vector<std::pair<proto::Header, proto::Message>> msgs, bool counts_as_frame,
                  bool depth, bool trimmable = true, int copies = 1);
  // Sends StreamConfig first when the session or the frame's shape or codec is new.
  void announce(const Link& l, const ProcessedFrame& frame);
  // One message per tile of tiles[from, end), with the part's header flags.
  std::vector<std::pair<proto::Header, proto::Message>> tile_messages(const Link& l,
                                                                      const ProcessedFrame& frame,
                                                                      std::size_t from);
  void enqueue_frame(Lane lane, OutFrame f);  // io thread
  void kick_udp(const std::shared_ptr<Session>& s);
  void udp_receive();
  void on_udp_datagram(std::span<const std::uint8_t> d);

  ServerConfig config_;
  asio::io_context io_;
  std::optional<asio::ssl::context> tls_;  // with a key or certificates
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work_{
      asio::make_work_guard(io_)};
  tcp::acceptor acceptor_;
  udp::socket udp_;
  asio::steady_timer timer_;
  asio::steady_timer accept_backoff_;
  std::thread thread_;

  // io thread only
  std::shared_ptr<Session> active_;
  std::uint32_t active_generation_ = 0;
  std::uint32_t session_id_ = 0;
  std::uint32_t next_session_id_ = 1;
  std::vector<std::string> told_;  // tell()'s keys, in order, each once
  std::chrono::steady_clock::time_point last_drop_log_{};
  std::list<std::shared_ptr<Session>> pending_;  // in accept order: the oldest first
  std::chrono::steady_clock::time_point last_auth_log_{}, last_accept_log_{};
  std::uint64_t auth_logs_held_ = 0, accept_logs_held_ = 0;
  std::array<std::uint8_t, 2048> udp_rx_{};
  std::vector<std::uint8_t> udp_plain_;
  udp::endpoint udp_from_;

  // processing thread only
  std::uint32_t announced_generation_ = 0;
  proto::StreamConfig announced_;
  std::uint32_t streamed_generation_ = 0;  // the session the current part's tiles streamed to

  // shared
  PiMutex cache_mu_;   // shared by the video thread with the real-time processing and io threads
  RepairCache cache_;  // guarded by cache_mu_; filled by publish(), read by on_nack()
  VideoRepairCache video_cache_;  // guarded by cache_mu_; publish_video() -> on_video_nack()
  mutable PiMutex mu_;
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
