// SPDX-License-Identifier: MIT
// The remote's network server, pre-authentication part: connections that have not yet passed the
// TLS handshake and sent their Hello. They are not sessions: they wait beside the operator's
// session under a deadline, a cap per source address and overall (the oldest closed first, idle
// ones before those whose handshake runs), and an accept loop that backs off when the process is
// out of descriptors instead of spinning.
#include <algorithm>

#include "server_impl.h"

namespace telex::remote {

void RemoteServer::Impl::admit(tcp::socket socket) {
  boost::system::error_code ec;
  const auto remote = socket.remote_endpoint(ec);
  auto a = std::make_shared<Session>(
      make_link(std::move(socket)), config_.repair_limits,
      SendQueueLimits{config_.max_queued_frames, config_.max_queued_video_frames});
  a->source = ec ? std::string("?") : remote.address().to_string();
  a->peer = ec ? std::string("?") : fmt::format("{}:{}", a->source, remote.port());
  a->accepted_at = std::chrono::steady_clock::now();
  a->link->socket().set_option(tcp::no_delay(true), ec);
  make_room(a->source);
  pending_.push_back(a);
  // The handshake starts at the first byte (a TLS client speaks first): until then the
  // connection is idle, the first to go when room is needed.
  a->link->socket().async_wait(tcp::socket::wait_read, [this, a](boost::system::error_code e) {
    if (!a->open) return;
    if (e) return drop_pending(a);
    a->stage = Session::Stage::Handshaking;
    a->link->async_handshake(asio::ssl::stream_base::server,
                             [this, a](boost::system::error_code h) { on_handshake(a, h); });
  });
}

// EMFILE, ENFILE, ENOBUFS, ENOMEM: the connection stays in the listen backlog and accept would fail
// again at once, spinning the (real-time) network thread. One pending connection is closed to give
// a descriptor back, and accept tries again after kAcceptBackoff.
void RemoteServer::Impl::on_accept_error(boost::system::error_code ec) {
  ++counters_.accept_errors;
  if (ec == asio::error::connection_aborted) return do_accept();  // that connection's own end
  if (log_allowed(last_accept_log_, accept_logs_held_))
    spdlog::warn("cannot accept a connection: {} ({} pending); retrying in {} ms", ec.message(),
                 pending_.size(), kAcceptBackoff.count());
  if (!pending_.empty()) {
    ++counters_.preauth_evicted;
    drop_pending(pending_.front());
  }
  accept_backoff_.expires_after(kAcceptBackoff);
  accept_backoff_.async_wait([this](boost::system::error_code e) {
    if (!e && acceptor_.is_open()) do_accept();
  });
}

// Room for one more pending connection from `source`: over a cap, the oldest idle connection
// (of that source, or of all) is closed, or the oldest of any stage when none is idle.
void RemoteServer::Impl::make_room(const std::string& source) {
  const auto evict = [this](auto&& in_scope) {
    auto it = std::find_if(pending_.begin(), pending_.end(), [&](const auto& p) {
      return in_scope(*p) && p->stage == Session::Stage::Idle;
    });
    if (it == pending_.end())
      it = std::find_if(pending_.begin(), pending_.end(),
                        [&](const auto& p) { return in_scope(*p); });
    if (it == pending_.end()) return;
    ++counters_.preauth_evicted;
    drop_pending(*it);
  };
  const auto same_source = [&](const Session& s) { return s.source == source; };
  if (static_cast<std::size_t>(std::count_if(pending_.begin(), pending_.end(), [&](const auto& p) {
        return same_source(*p);
      })) >= kMaxPendingPerSource)
    evict(same_source);
  if (pending_.size() >= kMaxPending) evict([](const Session&) { return true; });
}

void RemoteServer::Impl::drop_pending(const std::shared_ptr<Session>& a) {
  a->open = false;
  a->link->close();
  pending_.remove(a);
}

void RemoteServer::Impl::sweep_pending(std::chrono::steady_clock::time_point now) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    const auto a = *it++;  // drop_pending erases the element the iterator left
    const auto age = now - a->accepted_at;
    if (age > kPreauthTimeout || (a->stage == Session::Stage::Idle && age > kFirstByteTimeout)) {
      ++counters_.preauth_timeouts;
      drop_pending(a);
    }
  }
}

void RemoteServer::Impl::close_all_pending() {
  while (!pending_.empty()) drop_pending(pending_.front());
}

void RemoteServer::Impl::promote(const std::shared_ptr<Session>& a) {
  pending_.remove(a);
  active_ = a;
  ++active_generation_;
  a->stage = Session::Stage::Active;
  a->last_rx = std::chrono::steady_clock::now();
}

bool RemoteServer::Impl::log_allowed(std::chrono::steady_clock::time_point& last,
                                     std::uint64_t& held) {
  const auto now = std::chrono::steady_clock::now();
  if (now - last < std::chrono::seconds(1)) {
    ++held;
    return false;
  }
  if (held != 0) spdlog::info("({} similar lines in the last second not shown)", held);
  last = now;
  held = 0;
  return true;
}

}  // namespace telex::remote
