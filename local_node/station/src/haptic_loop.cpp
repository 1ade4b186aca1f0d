// SPDX-License-Identifier: MIT
// The haptic loop: tracker + newest surface -> force model -> display, at the station's rate.
#include "haptic_loop.h"

#include <chrono>
#include <cmath>
#include <thread>

#include "telex/base/periodic.h"
#include "telex/base/realtime.h"
#include "telex/local/displays/display_supervisor.h"

namespace telex::local {
namespace {

bool all_finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

HapticLoop::HapticLoop(const StationConfig& cfg, StationFaults& faults, HapticDisplay& display,
                       ZeroForceOnExit& display_zero,
                       TripleBuffer<std::shared_ptr<const Surface>>& surfaces,
                       TripleBuffer<HandState>& hand_for_surface,
                       TripleBuffer<HandState>& hand_for_view, bool keep_bodies)
    : cfg_(cfg),
      faults_(faults),
      display_(display),
      display_zero_(display_zero),
      surfaces_(surfaces),
      hand_for_surface_(hand_for_surface),
      hand_for_view_(hand_for_view),
      period_ns_(static_cast<std::int64_t>(std::llround(1e9 / cfg.rate_hz))),
      channel_(cfg.display_channel[index_of(cfg.tracker.use_left_hand ? Side::Left : Side::Right)]),
      model_(cfg.haptic, kFingerCount),
      samples_(1 << 14),
      bodies_(keep_bodies ? 1024 : 1) {}

void HapticLoop::run(std::stop_token stop) {
  scheduling_ = try_realtime(cfg_.realtime ? kHapticPriority : 0);
  if (cfg_.haptic_cpu >= 0) scheduling_ += ", " + pin_thread(pthread_self(), cfg_.haptic_cpu);
  // The stack's pages resident before the first deadline (locked too when main locked memory).
  prefault_stack();
  scheduling_ready_.store(true);
  try {
    ticks(stop);
  } catch (...) {
    faults_.fail("haptic (telex-haptic)", std::current_exception());
  }
  // Release the device: zero force on every finger (the guard does it again after the join).
  display_zero_.release();
  // Stopped in order: the silence that follows is not a hang.
  if (cfg_.supervisor_heartbeat) cfg_.supervisor_heartbeat->disarm();
}

std::string HapticLoop::wait_scheduling() const {
  while (!scheduling_ready_.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return scheduling_;
}

void HapticLoop::ticks(std::stop_token stop) {
  PeriodicTimer timer(period_ns_);
  std::shared_ptr<const Surface> newest;
  HandState hand{};
  std::array<FingertipInput, kFingerCount> in{};
  std::array<FingertipForce, kFingerCount> out{};
  std::array<FingerForce, kFingerCount> shown{};
  TickSample sample{};
  std::int64_t prev = 0;
  const std::int64_t tracking_stale_ns = static_cast<std::int64_t>(cfg_.haptic.stale_limit_s * 1e9);
  std::uint64_t gate_before = 0;
  bool was_silent = false;
  // The display supervisor's heartbeat is written here, on the thread that commands the force:
  // its silence is exactly what leaves a force held on the display (SIGSTOP or Ctrl-Z stop every
  // thread; a hung or starved tick stops this one), where a thread of its own would beat on
  // through a hung tick. A beat is one relaxed atomic store to the page mapped before this
  // thread started: no system call, lock or allocation.
  StationHeartbeat* const heartbeat = cfg_.supervisor_heartbeat;
  std::uint64_t zeroings = 0;
  if (heartbeat) {
    zeroings = heartbeat->zeroings();
    heartbeat->arm(period_ns_);
  }
  while (!stop.stop_requested()) {
    if (gate_) gate_before = gate_->epoch();
    const std::int64_t now = timer.wait_next();
    if (heartbeat) heartbeat->beat(now);
    faults_.check(StationLoop::Haptic);
    // The supervisor zeroed the display while this thread was silent: start again from zero
    // (the rate limit and the start-up ramp) rather than jump back to the force last sent.
    if (heartbeat && heartbeat->zeroings() != zeroings) {
      zeroings = heartbeat->zeroings();
      model_.restart_output();
    }
    if (prev == 0) t0_ns_.store(now, std::memory_order_release);
    surfaces_.take(newest);
    tracker_->see_surface(newest.get());  // a scripted hand aims at what it will be felt against
    if (tracker_->poll(now, hand)) {
      hand_for_surface_.publish(hand);
      hand_for_view_.publish(hand);
      // A new sample only from a new tracker frame that held the head: a glove's update or a
      // frame without the head body repeats the last one, which then ages (PROTOCOL.md 2.6).
      if (hand.head_valid && hand.bodies_fresh)
        head_out_.publish({hand.time_ns, ++head_samples_, hand.R_BaseCamera});
      if (hand.bodies_fresh && hand.body_count > 0) bodies_.push(hand);
    }
    const bool fresh = now - hand.time_ns <= tracking_stale_ns;
    // A silent link or tracker zeroes the force at once; when both speak again the force starts
    // from zero through the rate limit, never jumps back (a silence long enough for the surface
    // or the tracking to go stale has faded the gain too: the start-up ramp follows).
    const bool silent = silenced(now, hand);
    if (was_silent && !silent) model_.resume_output();
    was_silent = silent;
    const glm::dmat3 from_model = model_tick(now, newest, hand, fresh, in, out);
    if (silent)  // what the display is told, the logs and the recording say
      for (auto& f : out) {
        f.force_N = f.tangential_force_N = glm::dvec3(0.0);
        f.normal_force_N = f.shear_along_axis_N = f.gain = 0.0;
      }
    for (int i = 0; i < kFingerCount; ++i) {
      const auto& f = out[static_cast<std::size_t>(i)];
      shown[static_cast<std::size_t>(i)] = {channel_[static_cast<std::size_t>(i)], f.normal_force_N,
                                            f.shear_along_axis_N, f.contact};
    }
    if (gate_ && !OutputGate::open_between(gate_before, gate_->epoch())) {
      for (auto& f : shown) f = {f.finger, 0.0, 0.0, false};
      ticks_gated_.fetch_add(1, std::memory_order_relaxed);
    }
    display_.write(now, shown);
    // A zero that came between the check above and this write (the station stopped in between)
    // may have gone out before it: zero again now; the next tick starts from zero.
    if (heartbeat && heartbeat->zeroings() != zeroings) {
      for (auto& f : shown) f = {f.finger, 0.0, 0.0, false};
      display_.write(now, shown);
    }
    sample.t_ns = now;
    sample.deadline_ns = timer.deadline_ns();
    sample.period_ns = prev ? now - prev : period_ns_;
    prev = now;
    sample.surface_frame = newest ? newest->frame_id : 0;
    sample.surface_capture_ns = newest ? newest->capture_ns : 0;
    sample.forces = out;
    for (int i = 0; i < kFingerCount; ++i) {
      sample.tracked[static_cast<std::size_t>(i)] = in[static_cast<std::size_t>(i)].tracked;
      sample.p_CameraFingertip[static_cast<std::size_t>(i)] =
          from_model * in[static_cast<std::size_t>(i)].p_ModelFingertip;
      sample.axis_Camera[static_cast<std::size_t>(i)] =
          from_model * in[static_cast<std::size_t>(i)].axis_Model;
    }
    samples_.push(sample);
    missed_.store(timer.missed(), std::memory_order_relaxed);
  }
}

bool HapticLoop::silenced(std::int64_t now_ns, const HandState& hand) {
  bool silent = false;
  if (link_alive_ns_ && cfg_.link_silence_s > 0.0) {
    const std::int64_t alive = link_alive_ns_->load(std::memory_order_relaxed);
    link_seen_ = link_seen_ || alive != 0;
    const auto limit = static_cast<std::int64_t>(cfg_.link_silence_s * 1e9);
    if (link_seen_ && (alive == 0 || now_ns - alive > limit)) {
      ticks_link_silent_.fetch_add(1, std::memory_order_relaxed);
      silent = true;
    }
  }
  // A tracker that has delivered and then stopped (time_ns is its last frame's poll time; a
  // scripted hand's is every tick's).
  if (cfg_.tracking_silence_s > 0.0 && hand.time_ns != 0 &&
      now_ns - hand.time_ns > static_cast<std::int64_t>(cfg_.tracking_silence_s * 1e9)) {
    ticks_tracking_silent_.fetch_add(1, std::memory_order_relaxed);
    silent = true;
  }
  return silent;
}

glm::dmat3 HapticLoop::model_tick(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest,
                                  const HandState& hand, bool fresh,
                                  std::array<FingertipInput, kFingerCount>& in,
                                  std::array<FingertipForce, kFingerCount>& out) {
  // The model's frame: the head base's when the surface carries the head's pose at capture
  // (the robot head lags the operator's; each surface is placed by its own pose), else the
  // camera's. The fingertips go there from the camera of the operator's head; a hand without a
  // head (scripted) is taken to be in the newest surface's camera.
  const bool in_base = cfg_.head_captured_pose && hand.head_valid && newest && newest->head_valid;
  const glm::dmat3 to_model =
      in_base ? hand.R_BaseCamera : (newest ? newest->R_ModelCamera : glm::dmat3(1.0));
  for (int i = 0; i < kFingerCount; ++i) {
    const auto& tip = hand.tips[static_cast<std::size_t>(i)];
    // The tracker's poses are checked; a fingertip that still is not finite is not touched,
    // and its value never reaches the model's state.
    if (!all_finite(tip.p_CameraFingertip) || !all_finite(tip.axis_Camera)) {
      in[static_cast<std::size_t>(i)] = {glm::dvec3(0.0), glm::dvec3(0.0, 0.0, 1.0), false};
      continue;
    }
    in[static_cast<std::size_t>(i)] = {to_model * tip.p_CameraFingertip, to_model * tip.axis_Camera,
                                       tip.valid && fresh};
  }
  model_.tick(now_ns, newest, in, out);
  // Logs, recording and view take the tick re-expressed in the newest surface's camera.
  const glm::dmat3 from_model = newest ? glm::transpose(newest->R_ModelCamera) : glm::dmat3(1.0);
  if (newest && newest->R_ModelCamera != glm::dmat3(1.0)) reexpress(from_model, out);
  return from_model;
}

}  // namespace telex::local
