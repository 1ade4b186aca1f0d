// SPDX-License-Identifier: MIT
// Boost.Asio server: control over TCP, depth tiles and video over UDP (fragmented) or TCP.
#include "telex/remote/server.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <boost/asio.hpp>
#include <deque>
#include <stdexcept>
#include <thread>

#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

namespace telex::remote {

namespace asio = boost::asio;
using tcp = asio::ip::tcp;
using udp = asio::ip::udp;
using Buffer = std::shared_ptr<const std::vector<std::uint8_t>>;
using KeyPtr = std::shared_ptr<const proto::AuthKey>;

std::string_view client_state_name(ClientState state) {
  return state == ClientState::Connected ? "connected" : "waiting";
}

namespace {

// The messages of one frame, sent in order; dropped whole when the queue is over its bound.
struct OutFrame {
  std::uint32_t frame_id = 0;
  std::vector<Buffer> items;
  std::size_t next = 0;
  bool counts_as_frame = true;  // video frames are not counted in frames_sent
};

Buffer make_buffer(std::vector<std::uint8_t> bytes) {
  return std::make_shared<const std::vector<std::uint8_t>>(std::move(bytes));
}

// Drops the oldest frames nobody has started sending so that at most `bound` remain queued.
std::uint64_t trim_queue(std::deque<OutFrame>& q, std::size_t bound) {
  std::uint64_t dropped = 0;
  while (q.size() > bound) {
    auto it = q.begin();
    if (it->next != 0) ++it;  // the frame on the wire finishes
    if (it == q.end()) break;
    q.erase(it);
    ++dropped;
  }
  return dropped;
}

}  // namespace

class RemoteServer::Impl {
 public:
  class Session;

  explicit Impl(ServerConfig config)
      : config_(std::move(config)), acceptor_(io_), udp_(io_), timer_(io_) {
    boost::system::error_code ec;
    const auto address = asio::ip::make_address(config_.host, ec);
    if (ec)
      throw std::invalid_argument(
          fmt::format("--listen host '{}' is not an IP address: {}", config_.host, ec.message()));
    const tcp::endpoint endpoint(address, config_.port);
    acceptor_.open(endpoint.protocol(), ec);
    if (!ec) acceptor_.set_option(tcp::acceptor::reuse_address(true), ec);
    if (!ec) acceptor_.bind(endpoint, ec);
    if (!ec) acceptor_.listen(asio::socket_base::max_listen_connections, ec);
    if (ec)
      // A bad --listen value (port in use, address not ours) is a configuration error: exit 2.
      throw std::invalid_argument(
          fmt::format("cannot listen on {}:{}: {} (is another telex-remote running? pick another "
                      "--listen port)",
                      config_.host, config_.port, ec.message()));
    udp_.open(address.is_v4() ? udp::v4() : udp::v6(), ec);
    if (!ec) udp_.bind(udp::endpoint(address, 0), ec);
    if (!ec) udp_.set_option(asio::socket_base::send_buffer_size(4 << 20), ec);
    if (ec)
      throw std::runtime_error(
          fmt::format("cannot open the UDP socket on {}: {}", config_.host, ec.message()));
  }

  ~Impl() { stop(); }

  void start() {
    if (thread_.joinable()) return;
    do_accept();
    arm_timer();
    udp_receive();
    thread_ = std::thread([this] { io_.run(); });
  }

  void stop() {
    if (!thread_.joinable()) return;
    asio::post(io_, [this] {
      boost::system::error_code ec;
      acceptor_.close(ec);
      timer_.cancel();
      end_session("server stopping");
      udp_.close(ec);
      work_.reset();
    });
    thread_.join();
  }

  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }

  FrameRequest take_request() {
    std::lock_guard lock(mu_);
    FrameRequest r = request_;
    request_.force_key_frame = false;
    return r;
  }

  void request_key_frame() {
    std::lock_guard lock(mu_);
    request_.force_key_frame = true;
  }

  struct Link {
    std::uint32_t session_id = 0;
    std::uint32_t generation = 0;
    bool udp = false;
    KeyPtr key;  // the session key with --psk, else null
  };

  std::optional<Link> link() const {
    std::lock_guard lock(mu_);
    if (!connected_) return std::nullopt;
    return link_;
  }

  proto::Header header(std::uint32_t session_id, std::uint32_t frame_id, std::int64_t capture_ns,
                       bool key, std::uint16_t extra_flags = 0) {
    proto::Header h;
    h.session_id = session_id;
    h.seq = seq_++;
    h.frame_id = frame_id;
    h.capture_ns = static_cast<std::uint64_t>(capture_ns);
    h.flags = static_cast<std::uint16_t>((key ? proto::kFlagKeyFrame : 0) | extra_flags);
    return h;
  }

  // Turns whole messages into what goes on the wire for this link.
  OutFrame pack(const Link& l, std::uint32_t frame_id,
                const std::vector<std::pair<proto::Header, proto::Message>>& msgs) {
    OutFrame f;
    f.frame_id = frame_id;
    for (const auto& [h, m] : msgs) {
      if (l.udp) {
        const auto bytes = proto::encode_sealed(h, m, l.key.get());
        for (auto& d : proto::fragment_message(bytes, message_id_++, frame_id)) {
          // Every datagram carries its own tag, so a forged fragment never reaches the reassembler.
          if (l.key) proto::append_tag(d, *l.key);
          f.items.push_back(make_buffer(std::move(d)));
        }
      } else {
        f.items.push_back(make_buffer(proto::encode_stream_sealed(h, m, l.key.get())));
      }
    }
    return f;
  }

  void publish(const ProcessedFrame& frame) {
    const auto l = link();
    if (!l) return;
    // A frame processed while nobody was connected has no tiles or manifest: a receiver that
    // connected in between waits for the next one (its key frame).
    if (frame.manifest.tile_count == 0) return;
    // A new session, or a frame of another shape or codec, announces the stream first (on TCP).
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
    if (l->generation != announced_generation_ || !(sc == announced_)) {
      announced_generation_ = l->generation;
      announced_ = sc;
      auto buf = make_buffer(proto::encode_stream_sealed(
          header(l->session_id, frame.frame_id, frame.capture_ns, false), sc, l->key.get()));
      asio::post(io_, [this, buf, gen = l->generation] {
        if (active_ && active_generation_ == gen) send_control(buf);
      });
    }
    // An ROI part's messages say so; the rest (or a whole frame) closes the frame and counts it.
    const std::uint16_t part_flag = frame.part == FramePart::RoiPart ? proto::kFlagRoiPart : 0;
    std::vector<std::pair<proto::Header, proto::Message>> msgs;
    msgs.reserve(frame.tiles.size() + 1);
    for (const auto& t : frame.tiles) {
      msgs.emplace_back(
          header(l->session_id, frame.frame_id, frame.capture_ns, frame.key_frame, part_flag),
          proto::tile_message(t, frame.codec));
    }
    msgs.emplace_back(
        header(l->session_id, frame.frame_id, frame.capture_ns, frame.key_frame, part_flag),
        frame.manifest);
    OutFrame f = pack(*l, frame.frame_id, msgs);
    f.counts_as_frame = frame.part != FramePart::RoiPart;
    asio::post(io_, [this, f = std::move(f), gen = l->generation]() mutable {
      if (active_ && active_generation_ == gen) enqueue_frame(std::move(f));
    });
  }

  void publish_video(std::uint32_t frame_id, std::int64_t capture_ns,
                     const std::vector<std::uint8_t>& left, const std::vector<std::uint8_t>& right,
                     int width, int height) {
    const auto l = link();
    if (!l || !video_wanted_) return;
    std::vector<std::pair<proto::Header, proto::Message>> msgs;
    for (std::uint8_t eye : {std::uint8_t{0}, std::uint8_t{1}}) {
      const auto& jpeg = eye == 0 ? left : right;
      if (jpeg.empty()) continue;
      proto::VideoFrame v;
      v.eye = eye;
      v.width = static_cast<std::uint16_t>(width);
      v.height = static_cast<std::uint16_t>(height);
      v.jpeg = jpeg;
      msgs.emplace_back(header(l->session_id, frame_id, capture_ns, false), std::move(v));
    }
    OutFrame f = pack(*l, frame_id, msgs);
    f.counts_as_frame = false;
    asio::post(io_, [this, f = std::move(f), gen = l->generation]() mutable {
      if (active_ && active_generation_ == gen) enqueue_frame(std::move(f));
    });
  }

  ClientState state() const { return connected_ ? ClientState::Connected : ClientState::Waiting; }
  bool video_wanted() const { return video_wanted_; }
  ServerCounters counters_;

 private:
  // ---- everything below runs on the io thread ----
  struct Active {
    tcp::socket socket;
    proto::StreamParser parser;
    KeyPtr session_key;  // after Hello with --psk
    std::array<std::uint8_t, 16384> rx{};
    bool hello_done = false;
    std::chrono::steady_clock::time_point last_rx;
    udp::endpoint udp_peer;
    bool over_udp = false;
    std::deque<Buffer> control;
    std::deque<OutFrame> frames;
    bool tcp_writing = false;
    bool udp_sending = false;
    std::string peer;
    explicit Active(tcp::socket s) : socket(std::move(s)) {}
  };

  void do_accept() {
    acceptor_.async_accept([this](boost::system::error_code ec, tcp::socket socket) {
      if (ec) {
        if (ec != asio::error::operation_aborted && acceptor_.is_open()) do_accept();
        return;
      }
      if (active_) {
        reject(std::move(socket), proto::RejectReason::Busy,
               fmt::format("another operator is connected from {}; try again when it disconnects",
                           active_->peer));
      } else {
        start_session(std::move(socket));
      }
      do_accept();
    });
  }

  void reject(tcp::socket socket, proto::RejectReason reason, std::string text) {
    ++counters_.clients_rejected;
    auto sock = std::make_shared<tcp::socket>(std::move(socket));
    proto::Reject r;
    r.reason = reason;
    r.text = std::move(text);
    // Under the pre-shared key: the station can tell a refusal from a forgery.
    auto buf =
        make_buffer(proto::encode_stream_sealed(header(0, 0, steady_now_ns(), false), r, psk()));
    asio::async_write(*sock, asio::buffer(*buf),
                      [sock, buf](boost::system::error_code, std::size_t) {
                        boost::system::error_code ignore;
                        sock->shutdown(tcp::socket::shutdown_both, ignore);
                        sock->close(ignore);
                      });
  }

  void start_session(tcp::socket socket) {
    active_ = std::make_shared<Active>(std::move(socket));
    ++active_generation_;
    boost::system::error_code ec;
    const auto remote = active_->socket.remote_endpoint(ec);
    active_->peer =
        ec ? std::string("?") : fmt::format("{}:{}", remote.address().to_string(), remote.port());
    active_->socket.set_option(tcp::no_delay(true), ec);
    active_->last_rx = std::chrono::steady_clock::now();
    if (config_.psk) active_->parser.set_key(*config_.psk);
    do_read(active_, active_generation_);
  }

  void end_session(const char* /*why*/) {
    if (!active_) return;
    boost::system::error_code ec;
    active_->socket.shutdown(tcp::socket::shutdown_both, ec);
    active_->socket.close(ec);
    active_.reset();
    std::lock_guard lock(mu_);
    connected_ = false;
    video_wanted_ = false;
  }

  void do_read(std::shared_ptr<Active> a, std::uint32_t gen) {
    a->socket.async_read_some(
        asio::buffer(a->rx), [this, a, gen](boost::system::error_code ec, std::size_t n) {
          if (active_ != a || gen != active_generation_) return;
          if (ec) {
            end_session("connection closed");
            return;
          }
          std::size_t off = 0;
          while (off < n) {
            const std::size_t took =
                a->parser.feed(std::span<const std::uint8_t>(a->rx.data() + off, n - off));
            off += took;
            while (auto r = a->parser.next()) {
              if (!r->ok()) {
                on_bad_message(a, *r);
                if (active_ != a) return;
                continue;
              }
              // Only a message that decoded (and, with --psk, verified) keeps the session alive.
              a->last_rx = std::chrono::steady_clock::now();
              handle(a, *r->envelope);
              if (active_ != a) return;
            }
            if (a->parser.failed()) {
              ++counters_.malformed_in;
              end_session("unparseable stream");
              return;
            }
            if (took == 0) break;
          }
          do_read(a, gen);
        });
  }

  void handle(const std::shared_ptr<Active>& a, const proto::Envelope& env) {
    if (!a->hello_done) {
      const auto* hello = std::get_if<proto::Hello>(&env.message);
      if (hello == nullptr) {
        ++counters_.malformed_in;
        reject_active(proto::RejectReason::BadRequest, "the first message must be Hello");
        return;
      }
      on_hello(a, *hello, env.header.capture_ns);
      return;
    }
    std::visit(
        [&](const auto& m) {
          using T = std::decay_t<decltype(m)>;
          if constexpr (std::is_same_v<T, proto::Heartbeat>) {
            // Only probes (t2 = 0) are answered: an answer to an answer would ping-pong forever.
            if (m.t2_ns != 0) return;
            proto::Heartbeat reply = m;
            reply.t2_ns = static_cast<std::uint64_t>(steady_now_ns());
            reply.t3_ns = static_cast<std::uint64_t>(steady_now_ns());
            send_control(make_buffer(proto::encode_stream_sealed(
                header(session_id_, 0, steady_now_ns(), false), reply, a->session_key.get())));
          } else if constexpr (std::is_same_v<T, proto::RoiRequest>) {
            std::lock_guard lock(mu_);
            request_.rois = m.rects;
          } else if constexpr (std::is_same_v<T, proto::Stats>) {
            for (const auto& [key, value] : m.counters)
              if (key == "key_frame_request" && value != 0) {
                ++counters_.key_frame_requests;
                request_key_frame();
              }
          } else if constexpr (std::is_same_v<T, proto::Bye>) {
            end_session("client said bye");
          } else {
            ++counters_.malformed_in;  // a message only the server sends
          }
        },
        env.message);
  }

  const proto::AuthKey* psk() const { return config_.psk ? &*config_.psk : nullptr; }

  // Counts a rejected message by reason and logs at most once a second. Before Hello an
  // authentication failure refuses the connection with a reason the station can report.
  void on_bad_message(const std::shared_ptr<Active>& a, const proto::Result& r) {
    switch (r.error) {
      case proto::ErrorReason::AuthFailed:
        ++counters_.auth_failed;
        break;
      case proto::ErrorReason::UnexpectedTag:
        ++counters_.unexpected_tag;
        break;
      case proto::ErrorReason::Replayed:
        ++counters_.replayed;
        break;
      default:
        ++counters_.malformed_in;
        break;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now - last_drop_log_ > std::chrono::seconds(1)) {
      last_drop_log_ = now;
      spdlog::warn(
          "dropped a message from {}: {} ({}); totals: auth_failed {} unexpected_tag {} replayed "
          "{} malformed {}",
          a->peer, proto::error_reason_name(r.error), r.detail, counters_.auth_failed.load(),
          counters_.unexpected_tag.load(), counters_.replayed.load(),
          counters_.malformed_in.load());
    }
    if (a->hello_done) return;
    if (r.error == proto::ErrorReason::AuthFailed)
      reject_active(proto::RejectReason::AuthFailed,
                    "authentication failed: the station's Hello does not verify under this "
                    "telex-remote's --psk key (a different key, or the station has none)");
    else if (r.error == proto::ErrorReason::UnexpectedTag)
      reject_active(proto::RejectReason::AuthFailed,
                    "this telex-remote has no --psk key but the station's messages carry "
                    "authentication tags: start both daemons with the same --psk, or neither");
  }

  void udp_receive() {
    udp_.async_receive_from(asio::buffer(udp_rx_), udp_from_,
                            [this](boost::system::error_code ec, std::size_t) {
                              if (ec == asio::error::operation_aborted || !udp_.is_open()) return;
                              if (!ec) ++counters_.udp_ignored;
                              udp_receive();
                            });
  }

  void reject_active(proto::RejectReason reason, std::string text) {
    auto a = active_;
    active_.reset();
    {
      std::lock_guard lock(mu_);
      connected_ = false;
    }
    reject(std::move(a->socket), reason, std::move(text));
  }

  void on_hello(const std::shared_ptr<Active>& a, const proto::Hello& hello,
                std::uint64_t hello_nonce) {
    if (hello.version != proto::kProtocolVersion) {
      reject_active(proto::RejectReason::VersionMismatch,
                    fmt::format("server speaks protocol version {}, client {}",
                                proto::kProtocolVersion, hello.version));
      return;
    }
    proto::Codec codec = config_.codec;
    if (!hello.codecs.empty() &&
        std::find(hello.codecs.begin(), hello.codecs.end(), codec) == hello.codecs.end())
      codec = hello.codecs.front();
    a->over_udp =
        !config_.force_tcp && (hello.capabilities & proto::kCapDepthUdp) && hello.udp_port != 0;
    boost::system::error_code ec;
    if (a->over_udp)
      a->udp_peer = udp::endpoint(a->socket.remote_endpoint(ec).address(), hello.udp_port);
    a->hello_done = true;
    session_id_ = next_session_id_++;
    proto::Header accept_header = header(session_id_, 0, steady_now_ns(), false);
    if (config_.psk) {
      // Both nonces go into the session key: a Hello or a stream recorded in another session
      // verifies under none of this session's keys (docs/PROTOCOL.md section 7).
      accept_header.capture_ns = proto::random_u64();
      a->session_key = std::make_shared<const proto::AuthKey>(proto::derive_session_key(
          *config_.psk, hello_nonce, accept_header.capture_ns, session_id_));
    }
    proto::Accept acc;
    acc.session_id = session_id_;
    acc.codec = codec;
    acc.transport = a->over_udp ? proto::Transport::Udp : proto::Transport::Tcp;
    acc.udp_port = a->over_udp ? udp_.local_endpoint().port() : 0;
    send_control(make_buffer(proto::encode_stream_sealed(accept_header, acc, psk())));
    if (a->session_key) a->parser.set_key(*a->session_key);
    ++counters_.clients_accepted;
    std::lock_guard lock(mu_);
    connected_ = true;
    video_wanted_ = config_.video_available && (hello.capabilities & proto::kCapVideo);
    frame_parts_ = (hello.capabilities & proto::kCapFrameParts) != 0;
    link_ = Link{session_id_, active_generation_, a->over_udp, a->session_key};
    request_ = FrameRequest{};
    request_.force_key_frame = true;  // a new receiver holds nothing
    request_.codec = codec;
    request_.frame_parts = frame_parts_;
  }

  void send_control(Buffer buf) {
    if (!active_) return;
    active_->control.push_back(std::move(buf));
    kick_tcp(active_);
  }

  void enqueue_frame(OutFrame f) {
    auto& a = *active_;
    a.frames.push_back(std::move(f));
    const auto dropped = trim_queue(a.frames, config_.max_queued_frames);
    if (dropped > 0) {
      counters_.frames_dropped += dropped;
      // The receiver misses those tiles: resend everything with the next frame.
      request_key_frame();
    }
    if (a.over_udp)
      kick_udp(active_);
    else
      kick_tcp(active_);
  }

  // Next frame item, advancing the frame queue.
  static Buffer take_frame_item(Active& a, bool& frame_done, bool& counts) {
    while (!a.frames.empty() && a.frames.front().next >= a.frames.front().items.size())
      a.frames.pop_front();
    if (a.frames.empty()) return nullptr;
    auto& f = a.frames.front();
    Buffer b = f.items[f.next++];
    frame_done = f.next == f.items.size();
    counts = f.counts_as_frame;
    if (frame_done) a.frames.pop_front();
    return b;
  }

  void kick_tcp(const std::shared_ptr<Active>& a) {
    if (a->tcp_writing) return;
    Buffer buf;
    bool frame_done = false, counts = false, is_data = false;
    if (!a->control.empty()) {
      buf = a->control.front();
      a->control.pop_front();
    } else if (!a->over_udp) {
      buf = take_frame_item(*a, frame_done, counts);
      is_data = true;
    }
    if (!buf) return;
    a->tcp_writing = true;
    asio::async_write(
        a->socket, asio::buffer(*buf),
        [this, a, buf, frame_done, counts, is_data](boost::system::error_code ec, std::size_t n) {
          a->tcp_writing = false;
          if (active_ != a) return;
          if (ec) {
            end_session("write failed");
            return;
          }
          if (is_data) {
            counters_.bytes_sent += n;
            ++counters_.messages_sent;
            if (frame_done && counts) ++counters_.frames_sent;
          }
          kick_tcp(a);
        });
  }

  void kick_udp(const std::shared_ptr<Active>& a) {
    if (a->udp_sending) return;
    bool frame_done = false, counts = false;
    Buffer buf = take_frame_item(*a, frame_done, counts);
    if (!buf) return;
    a->udp_sending = true;
    udp_.async_send_to(
        asio::buffer(*buf), a->udp_peer,
        [this, a, buf, frame_done, counts](boost::system::error_code ec, std::size_t n) {
          a->udp_sending = false;
          if (active_ != a) return;
          // A refused or failed datagram is lost like any other; key frames repair it.
          if (!ec) {
            counters_.bytes_sent += n;
            ++counters_.datagrams_sent;
            if (frame_done && counts) ++counters_.frames_sent;
          }
          kick_udp(a);
        });
  }

  void arm_timer() {
    timer_.expires_after(std::chrono::milliseconds(100));
    timer_.async_wait([this](boost::system::error_code ec) {
      if (ec) return;
      if (active_ && std::chrono::steady_clock::now() - active_->last_rx > config_.client_timeout) {
        ++counters_.client_timeouts;
        end_session("client silent");
      }
      arm_timer();
    });
  }

  ServerConfig config_;
  asio::io_context io_;
  std::optional<asio::executor_work_guard<asio::io_context::executor_type>> work_{
      asio::make_work_guard(io_)};
  tcp::acceptor acceptor_;
  udp::socket udp_;
  asio::steady_timer timer_;
  std::thread thread_;

  // io thread only
  std::shared_ptr<Active> active_;
  std::uint32_t active_generation_ = 0;
  std::uint32_t session_id_ = 0;
  std::uint32_t next_session_id_ = 1;
  std::chrono::steady_clock::time_point last_drop_log_{};
  std::array<std::uint8_t, 2048> udp_rx_{};
  udp::endpoint udp_from_;

  // processing thread only
  std::uint32_t announced_generation_ = 0;
  proto::StreamConfig announced_;

  // shared
  mutable std::mutex mu_;
  FrameRequest request_;
  bool frame_parts_ = false;  // guarded by mu_
  Link link_;
  std::atomic<bool> connected_{false};
  std::atomic<bool> video_wanted_{false};
  std::atomic<std::uint32_t> seq_{0};
  std::atomic<std::uint32_t> message_id_{0};
};

RemoteServer::RemoteServer(ServerConfig config)
    : impl_(std::make_unique<Impl>(std::move(config))) {}
RemoteServer::~RemoteServer() = default;
void RemoteServer::start() { impl_->start(); }
void RemoteServer::stop() { impl_->stop(); }
std::uint16_t RemoteServer::port() const { return impl_->port(); }
ClientState RemoteServer::state() const { return impl_->state(); }
bool RemoteServer::video_wanted() const { return impl_->video_wanted(); }
const ServerCounters& RemoteServer::counters() const { return impl_->counters_; }
FrameRequest RemoteServer::take_request() { return impl_->take_request(); }
void RemoteServer::publish(const ProcessedFrame& frame) { impl_->publish(frame); }
void RemoteServer::publish_video(std::uint32_t frame_id, std::int64_t capture_ns,
                                 const std::vector<std::uint8_t>& left,
                                 const std::vector<std::uint8_t>& right, int width, int height) {
  impl_->publish_video(frame_id, capture_ns, left, right, width, height);
}

}  // namespace telex::remote
