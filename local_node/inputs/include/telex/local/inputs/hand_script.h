// SPDX-License-Identifier: MIT
// Scripted fingertip trajectories (built-in press/stroke/tap or a text file) and their tracker.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "telex/local/inputs/tracker.h"

namespace telex::local {

struct ScriptKey {
  double t_s = 0;
  glm::dvec3 p_CameraFingertip{0.0};
};

// Piecewise-linear fingertip paths in the camera frame; pure (time comes in as an argument).
class HandScript {
 public:
  // "press": the index tip moves along the optical axis toward the image centre from 0.3 m in
  //   front of the surface at 0.1 m/s, reaches 10 mm beyond it, holds 1 s and returns.
  // "stroke": press to 5 mm, slide 100 mm toward +x and back at 50 mm/s, return.
  // "tap": approach to 20 mm in front, three taps to 5 mm beyond (0.1 s in, 0.1 s out, 0.3 s
  //   apart), return.
  // Throws std::invalid_argument naming the valid names, or a surface depth that is not positive.
  static HandScript builtin(std::string_view name, double surface_depth_m);
  static std::vector<std::string> builtin_names();

  // Text format (docs/HARDWARE.md): '#' comments and blank lines ignored; a header line
  // "time_s finger x_m y_m z_m"; then one key per line, whitespace or comma separated, finger
  // 0..4, time non-decreasing per finger. Throws std::runtime_error "SOURCE line N: ...".
  static HandScript parse(std::string_view text, const std::string& source_name);
  static HandScript load(const std::filesystem::path& path);

  double duration_s() const { return duration_s_; }
  // The surface depth a built-in script was planned for; nothing for a file (its positions are
  // where the file puts them).
  std::optional<double> planned_surface_depth_m() const { return planned_depth_m_; }
  bool has_finger(int finger) const { return !keys_[finger].empty(); }
  glm::dvec3 position(int finger, double t_s) const;  // clamped to the finger's first/last key
  // Tips at t: positions, velocities by a 1 ms backward finite difference, axis (1,0,1)/sqrt2 (the
  // finger points right and into the scene), valid for scripted fingers only. Sets out.time_ns only
  // via caller.
  void sample(double t_s, HandState& out) const;
  // The skeleton of a pointing right hand around the first scripted fingertip (sample() calls it).
  static void pose_hand(HandState& out);

 private:
  std::array<std::vector<ScriptKey>, kFingerCount> keys_{};
  double duration_s_ = 0;
  std::optional<double> planned_depth_m_;
};

// Runs a script on the caller's clock from its first poll. Once (returns false after the final
// state has been delivered, so the daemon sees the tracker stop and releases forces) or repeated.
// A built-in script aims at the surface it is shown (see_surface): the whole gesture slides along
// the optical axis (at most kFollowSpeedMps) so that it meets the surface under its fingertip as
// planned, so a press planned against the first frame's centre still reaches a scene that moved,
// or whose centre lay elsewhere. It slides toward a deeper surface always, toward a nearer one only
// while the fingertip is in front of it: a press is never chased by what it presses.
class ScriptTracker final : public HandTracker {
 public:
  static constexpr double kFollowSpeedMps = 0.2;

  ScriptTracker(HandScript script, std::string name, bool repeat);
  bool poll(std::int64_t now_ns, HandState& out) override;
  void see_surface(const Surface* newest) override { surface_ = newest; }
  // How far (m, along +z) the gesture has slid from where it was planned.
  double aim_offset_m() const { return offset_m_; }
  std::string name() const override { return name_; }
  TrackerStats stats() const override { return stats_.snapshot(); }
  bool finished() const { return finished_; }

 private:
  HandScript script_;
  std::string name_;
  bool repeat_;
  bool started_ = false;
  bool finished_ = false;
  std::int64_t start_ns_ = 0;
  std::int64_t last_ns_ = 0;
  TrackerCounters stats_;
  // Aiming (built-in scripts only).
  void aim(double dt_s, HandState& out);
  const Surface* surface_ = nullptr;
  double offset_m_ = 0.0;
};

}  // namespace telex::local
