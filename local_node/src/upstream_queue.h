// SPDX-License-Identifier: MIT
// The station's messages to the remote waiting for the link (SurfaceClient's network thread):
// bounded, and a head command replaces one still waiting. The front is the message being written
// while a write is in flight (async_write reads its buffer until the handler runs and pops it),
// so it is never dropped or replaced.
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

  // Queues `bytes`; `writing`: the front is in flight. Returns how many waiting messages were
  // dropped for it: a head command replaces any head command still waiting (the remote wants the
  // operator's newest pose, not a backlog of old ones), and past kMaxQueued the oldest waiting
  // message goes, so a stuck link cannot grow memory.
  std::size_t push(std::vector<std::uint8_t> bytes, bool head, bool writing) {
    const std::size_t before = q_.size();
    const auto waiting = q_.begin() + (writing && !q_.empty() ? 1 : 0);
    if (head)
      q_.erase(std::remove_if(waiting, q_.end(), [](const Outgoing& o) { return o.head; }),
               q_.end());
    std::size_t dropped = before - q_.size();
    q_.push_back({std::move(bytes), head});
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
    bool head = false;  // a head command: only the newest waiting one is worth sending
  };
  std::deque<Outgoing> q_;
};

}  // namespace telex::local
