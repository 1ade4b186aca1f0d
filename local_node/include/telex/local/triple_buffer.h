// SPDX-License-Identifier: MIT
// Lock-free single-producer single-consumer triple buffer: the reader always gets the newest value.
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace telex::local {

// Device threads publish, the haptic thread takes; neither ever waits for the other, which is why
// the haptic loop can poll trackers without a lock.
template <typename T>
class TripleBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "TripleBuffer copies values byte-wise");

 public:
  // Producer side only.
  void publish(const T& value) {
    buf_[back_] = value;
    const std::uint8_t old =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    if (old & kFresh) overwritten_.fetch_add(1, std::memory_order_relaxed);
    back_ = old & kIndex;
  }
  // Consumer side only: true and the newest value when one arrived since the last take.
  bool take(T& out) {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    out = buf_[front_];
    return true;
  }
  // Values replaced before the consumer took them.
  std::uint64_t overwritten() const { return overwritten_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::uint8_t kIndex = 3;
  static constexpr std::uint8_t kFresh = 4;
  T buf_[3]{};
  std::atomic<std::uint8_t> middle_{1};
  std::uint8_t back_ = 0;
  std::uint8_t front_ = 2;
  std::atomic<std::uint64_t> overwritten_{0};
};

}  // namespace telex::local
