// SPDX-License-Identifier: MIT
// Lock-free triple buffer: one writer publishes whole values, one reader always sees the newest.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace telex::local {

// The writer fills write_slot() and calls publish(); the reader calls update() and reads read_slot().
// Neither side ever waits or allocates; slots are reused, so T's storage is recycled on the writer side.
template <typename T>
class TripleBuffer {
 public:
  T& write_slot() { return slots_[write_]; }
  void publish() {
    write_ = static_cast<std::uint8_t>(
        middle_.exchange(static_cast<std::uint8_t>(write_ | kFresh), std::memory_order_acq_rel) &
        kIndex);
  }
  // True when a newer value was published since the last update(); read_slot() then holds it.
  bool update() {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
    read_ = static_cast<std::uint8_t>(middle_.exchange(read_, std::memory_order_acq_rel) & kIndex);
    return true;
  }
  const T& read_slot() const { return slots_[read_]; }
  T& read_slot_mutable() { return slots_[read_]; }

 private:
  static constexpr std::uint8_t kIndex = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;
  std::array<T, 3> slots_{};
  std::atomic<std::uint8_t> middle_{1};
  std::uint8_t write_ = 0;
  std::uint8_t read_ = 2;
};

}  // namespace telex::local
