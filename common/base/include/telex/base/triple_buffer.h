// SPDX-License-Identifier: MIT
// Lock-free single-producer single-consumer triple buffer: the reader always gets the newest value.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace telex {

// Device and surface threads publish, the haptic thread takes; neither ever waits for the other,
// which is why the haptic loop reads trackers and surfaces without a lock. Two styles:
// copy in/out (publish(value) / take(out)) for small values, and in-place (write_slot() + publish()
// / update() + read_slot()) for large ones whose storage is recycled on the writer side.
template <typename T>
class TripleBuffer {
 public:
  // ---- producer side only ----
  T& write_slot() { return buf_[back_]; }
  void publish() {
    const std::uint8_t old =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    if (old & kFresh) overwritten_.fetch_add(1, std::memory_order_relaxed);
    back_ = old & kIndex;
  }
  void publish(const T& value) {
    buf_[back_] = value;
    publish();
  }

  // ---- consumer side only ----
  // True when a newer value was published since the last update(); read_slot() then holds it.
  bool update() {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndex;
    return true;
  }
  const T& read_slot() const { return buf_[front_]; }
  // True and the newest value when one arrived since the last take.
  bool take(T& out) {
    if (!update()) return false;
    out = buf_[front_];
    return true;
  }

  // Values replaced before the consumer took them.
  std::uint64_t overwritten() const { return overwritten_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::uint8_t kIndex = 3;
  static constexpr std::uint8_t kFresh = 4;
  std::array<T, 3> buf_{};
  std::atomic<std::uint8_t> middle_{1};
  std::uint8_t back_ = 0;
  std::uint8_t front_ = 2;
  std::atomic<std::uint64_t> overwritten_{0};
};

}  // namespace telex
