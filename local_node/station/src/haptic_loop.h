// SPDX-License-Identifier: MIT
// The 1 kHz haptic loop: the tracker's fingertips and the newest surface into the force model,
// its forces to the display, and what it did to the main thread (tick samples, bodies, the head).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <stop_token>
#include <string>

#include "faults.h"
#include "messages.h"
#include "output_gate.h"
#include "telex/base/spsc_ring.h"
#include "telex/base/triple_buffer.h"
#include "telex/haptics/haptic_model.h"
#include "telex/local/displays/haptic_display.h"
#include "telex/local/inputs/tracker.h"
#include "telex/local/station/station_config.h"

namespace telex::local {

class HapticLoop {
 public:
  // Borrows the display and its zero-force guard (released when the loop ends), the surfaces it
  // reads and where it publishes the hand (the surface stage's and the view's).
  // `keep_bodies`: every tracker frame goes to the main thread (for --log-tracking, --record).
  HapticLoop(const StationConfig& cfg, StationFaults& faults, HapticDisplay& display,
             ZeroForceOnExit& display_zero, TripleBuffer<std::shared_ptr<const Surface>>& surfaces,
             TripleBuffer<HandState>& hand_for_surface, TripleBuffer<HandState>& hand_for_view,
             bool keep_bodies);

  // Before the thread starts: the fingertips' source.
  void set_tracker(std::unique_ptr<HandTracker> tracker) { tracker_ = std::move(tracker); }
  HandTracker* tracker() const { return tracker_.get(); }
  // Before the thread starts: a gate the display's forces pass only while open (--view openxr:
  // the headset's focus); none: always open.
  void set_output_gate(const OutputGate* gate) { gate_ = gate; }
  // Ticks whose forces the gate zeroed.
  std::uint64_t ticks_gated() const { return ticks_gated_.load(std::memory_order_relaxed); }
  // Before the thread starts: the link's pulse (ClientStats::alive_ns; 0 while no session). With
  // cfg.link_silence_s > 0 the force is zero while it is older than that or 0 once a session was
  // seen, and so with cfg.tracking_silence_s while the tracker's last frame is older.
  void set_link_pulse(const std::atomic<std::int64_t>* alive_ns) { link_alive_ns_ = alive_ns; }
  // Ticks zeroed for the link's silence and for the tracker's.
  std::uint64_t ticks_link_silent() const {
    return ticks_link_silent_.load(std::memory_order_relaxed);
  }
  std::uint64_t ticks_tracking_silent() const {
    return ticks_tracking_silent_.load(std::memory_order_relaxed);
  }

  // The haptic thread's body: no lock, allocation or log call per tick. On every exit the display
  // is commanded zero force.
  void run(std::stop_token stop);
  // What scheduling the thread got; blocks until it has tried.
  std::string wait_scheduling() const;

  // To the main thread.
  SpscRing<TickSample>& samples() { return samples_; }
  SpscRing<HandState>& bodies() { return bodies_; }
  TripleBuffer<HeadSample>& head_out() { return head_out_; }
  std::uint64_t missed() const { return missed_.load(std::memory_order_relaxed); }
  // The first tick's time (0 before it): a hand script's time zero.
  std::int64_t t0_ns() const { return t0_ns_.load(std::memory_order_acquire); }

 private:
  void ticks(std::stop_token stop);
  // Whether this tick's force must be zero for the link's or the tracker's silence (counted).
  bool silenced(std::int64_t now_ns, const HandState& hand);
  // The hand's fingertips into the model's frame, the model's tick, and its forces back into the
  // newest surface's camera frame. Returns the rotation model -> that camera.
  glm::dmat3 model_tick(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest,
                        const HandState& hand, bool fresh,
                        std::array<FingertipInput, kFingerCount>& in,
                        std::array<FingertipForce, kFingerCount>& out);

  const StationConfig& cfg_;
  StationFaults& faults_;
  HapticDisplay& display_;
  ZeroForceOnExit& display_zero_;
  TripleBuffer<std::shared_ptr<const Surface>>& surfaces_;
  TripleBuffer<HandState>& hand_for_surface_;
  TripleBuffer<HandState>& hand_for_view_;
  const std::int64_t period_ns_;
  // The display channel each finger drives (the rig's, for the haptic hand's side).
  const std::array<int, kFingerCount> channel_;

  std::unique_ptr<HandTracker> tracker_;
  const OutputGate* gate_ = nullptr;
  std::atomic<std::uint64_t> ticks_gated_{0};
  const std::atomic<std::int64_t>* link_alive_ns_ = nullptr;
  bool link_seen_ = false;  // a session's pulse was seen: its end is silence, not a slow start
  std::atomic<std::uint64_t> ticks_link_silent_{0}, ticks_tracking_silent_{0};
  HapticModel model_;
  SpscRing<TickSample> samples_;
  SpscRing<HandState> bodies_;
  TripleBuffer<HeadSample> head_out_;
  std::uint32_t head_samples_ = 0;
  std::string scheduling_;
  std::atomic<bool> scheduling_ready_{false};
  std::atomic<std::uint64_t> missed_{0};
  std::atomic<std::int64_t> t0_ns_{0};
};

}  // namespace telex::local
