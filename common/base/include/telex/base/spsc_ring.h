// SPDX-License-Identifier: MIT
// Bounded single-producer single-consumer ring: the haptic thread pushes without locks or
// allocation.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace telex {

template <typename T>
class SpscRing {
 public:
  explicit SpscRing(std::size_t capacity) : buf_(capacity + 1) {}

  // Producer side. Returns false (and counts a drop) when full: the producer never waits.
  bool push(const T& v) {
    const std::size_t h = head_.load(std::memory_order_relaxed);
    const std::size_t next = (h + 1) % buf_.size();
    if (next == tail_.load(std::memory_order_acquire)) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    buf_[h] = v;
    head_.store(next, std::memory_order_release);
    return true;
  }

  // Consumer side.
  bool pop(T& out) {
    const std::size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return false;
    out = buf_[t];
    tail_.store((t + 1) % buf_.size(), std::memory_order_release);
    return true;
  }

  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }
  std::size_t capacity() const { return buf_.size() - 1; }

 private:
  std::vector<T> buf_;
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
  std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace telex
