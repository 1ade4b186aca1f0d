// SPDX-License-Identifier: MIT
// The station's messages to the remote waiting for the link (SurfaceClient's network thread):
// bounded, and a head command or a liveness probe replaces one of its kind still waiting. The front
// is the message being written while a write is in flight (async_write reads its buffer until the
// handler runs and pops it), so it is never dropped or replaced.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

namespace telex::local {

class UpstreamQueue {
 public:
  static constexpr std::size_t kMaxQueued = 64;
  // What a message is to the queue: kept until written, or one of a kind only the newest of
  // which is worth sending.
  enum class Kind : std::uint8_t { Kept, Head, Probe };

  // Queues `bytes`; `writing`: the front is in flight. Returns how many waiting messages were
  // dropped for it: a head command replaces any head command still waiting (the remote wants the
  // operator's newest pose, not a backlog of old ones), a probe any probe still waiting (not
  // counted: a newer probe asks the same), and past kMaxQueued the oldest waiting message goes,
  // so a stuck link cannot grow memory.
  std::size_t push(std::vector<std::uint8_t> bytes, Kind kind, bool writing) {
    const std::size_t before = q_.size();
    const auto waiting = q_.begin() + (writing && !q_.empty() ? 1 : 0);
    if (kind != Kind::Kept)
      q_.erase(
          std::remove_if(waiting, q_.end(), [kind](const Outgoing& o) { return o.kind == kind; }),
          q_.end());
    std::size_t dropped = kind == Kind::Head ? before - q_.size() : 0;
    q_.push_back({std::move(bytes), kind});
    if (q_.size() > kMaxQueued) {
      q_.erase(q_.begin() + (writing ? 1 : 0));
      ++dropped;
    }
    return dropped;
  }
  bool empty() const { return q_.empty(); }
  std::size_t size() const { return q_.size(); }
  const std::vector<std::uint8_t>& front() const { return q_.front().bytes; }
  void pop_front() { q_.pop_front(); }
  void clear() { q_.clear(); }

 private:
  struct Outgoing {
    std::vector<std::uint8_t> bytes;
    Kind kind = Kind::Kept;
  };
  std::deque<Outgoing> q_;
};

}  // namespace telex::local
