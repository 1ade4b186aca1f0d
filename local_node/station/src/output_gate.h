// SPDX-License-Identifier: MIT
// The haptic output's gate: with --view openxr the fingers feel forces only while the headset's
// session is FOCUSED (the operator sees the remote and the station has their input); otherwise
// the display is commanded zero force. The view thread opens and closes it; the haptic thread
// reads it twice per tick, before taking the tick's time and before writing the display, and
// outputs force only when it was open both times and did not change between them, so a tick
// whose time falls while the gate is closed never outputs force.
#pragma once

#include <atomic>
#include <cstdint>

namespace telex::local {

class OutputGate {
 public:
  explicit OutputGate(bool open) : epoch_(open ? 0 : 1) {}
  // View thread. An even epoch is open, an odd one closed.
  void open() {
    if (epoch_.load() % 2 == 1) epoch_.fetch_add(1);
  }
  void close() {
    if (epoch_.load() % 2 == 0) epoch_.fetch_add(1);
  }
  // Haptic thread.
  std::uint64_t epoch() const { return epoch_.load(); }
  static bool open_between(std::uint64_t before, std::uint64_t after) {
    return before == after && before % 2 == 0;
  }

 private:
  std::atomic<std::uint64_t> epoch_;
};

}  // namespace telex::local
