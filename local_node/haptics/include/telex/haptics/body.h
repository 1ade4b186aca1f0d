// SPDX-License-Identifier: MIT
// The operator's virtual body: head and eyes, both arms (shoulder, elbow, wrist) and both hands,
// from the tracked rigid bodies and the gloves. The arm is a two-bone chain solved analytically
// (the elbow lies on a circle about the shoulder-wrist line); where the inputs leave the swivel
// about that line open, a natural-posture rule picks it and keeps it continuous. Pure: time comes
// in with the inputs; no allocation per update.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "telex/common/body_dims.h"
#include "telex/haptics/hand_kinematics.h"

namespace telex {

// Where the elbow came from.
enum class ElbowFrom : std::uint8_t {
  Marker,       // an elbow marker: the circle point nearest to it
  ForearmAxis,  // the wrist body's orientation: the circle point nearest to wrist - forearm axis
  Posture,      // neither: the natural-posture rule (not determined by the inputs)
  Straight,     // the wrist at or beyond the arm's reach: the arm points at it, no swivel
};
const char* elbow_from_name(ElbowFrom from);

// The two-bone solve. `posture_dir` is the direction the posture rule pulls the elbow toward
// (down and out, world); `previous_swivel` the last solution's swivel direction, for continuity.
struct ArmSolveInput {
  glm::dvec3 shoulder{0.0};
  glm::dvec3 wrist{0.0};
  std::optional<glm::dvec3> elbow_marker;
  std::optional<glm::dvec3> forearm_axis;  // unit, elbow toward wrist (world)
  glm::dvec3 posture_dir{0.0, -1.0, 0.0};
  std::optional<glm::dvec3> previous_swivel;
  std::optional<glm::dvec3> previous_axis;  // last shoulder-to-wrist direction (wrist at shoulder)
  // The posture rule turns the swivel from the previous one by at most this much (rad).
  double max_swivel_step_rad = 3.14159265358979323846;
};

struct ArmSolution {
  glm::dvec3 elbow{0.0};
  // Unit, perpendicular to the shoulder-wrist axis: where the elbow points from the circle's
  // centre (kept for the next solve's continuity).
  glm::dvec3 swivel{0.0};
  glm::dvec3 axis{0.0, -1.0, 0.0};  // unit shoulder-to-wrist direction used
  bool reachable = true;            // |wrist - shoulder| within [|L1 - L2|, L1 + L2]
  ElbowFrom from = ElbowFrom::Posture;
};

// Finite for any finite input (the caller screens NaN/Inf). With the wrist beyond reach the elbow
// lies on the shoulder-wrist segment at L1/(L1+L2) of it; with the wrist nearer than |L1 - L2| the
// circle of the nearest reachable distance is used.
ArmSolution solve_arm(double upper_arm_m, double forearm_m, const ArmSolveInput& in);

// One update's tracking inputs; a missing body is nullopt. Poses are in the tracking world.
struct BodyInputs {
  std::int64_t time_ns = 0;
  std::optional<Pose> head;
  std::array<std::optional<Pose>, 2> shoulder;     // by Side
  std::array<std::optional<Pose>, 2> wrist;        // the hand (wrist) rigid bodies
  std::array<std::optional<glm::dvec3>, 2> elbow;  // optional elbow markers
  std::array<std::array<double, 5>, 2> bend{};     // glove bends 0..1, thumb first
  // false where the wrist pose's orientation is unknown (a scripted hand): its forearm axis is
  // then not used, whatever BodyDims::forearm_axis_from_wrist says.
  std::array<bool, 2> wrist_orientation{true, true};
};

struct ArmState {
  bool visible = false;  // drawn: valid now, or held
  bool held = false;     // inputs missing or not finite; the last valid pose is shown
  bool reachable = true;
  ElbowFrom elbow_from = ElbowFrom::Posture;
  glm::dvec3 shoulder{0.0}, elbow{0.0}, wrist{0.0};
  Pose wrist_pose;
  HandPoints hand;
  std::int64_t valid_ns = 0;  // time of the inputs shown
};

struct BodyState {
  std::int64_t time_ns = 0;
  bool head_valid = false;
  Pose head;
  std::array<glm::dvec3, 2> eye{};  // by Side, world
  std::array<ArmState, 2> arms{};   // by Side
};

class Body {
 public:
  explicit Body(BodyDims dims = {});  // validates (std::invalid_argument naming the field)
  const BodyState& update(const BodyInputs& in);
  const BodyState& state() const { return state_; }
  const BodyDims& dims() const { return dims_; }

 private:
  void update_arm(Side side, const BodyInputs& in);

 public:
  // The direction the posture rule pulls an elbow toward (world), given the arm's outward
  // direction (zero when unknown: then down only).
  glm::dvec3 posture_pull(Side side, const glm::dvec3& out) const;

 private:
  BodyDims dims_;
  BodyState state_;
  std::array<std::optional<glm::dvec3>, 2> swivel_, axis_;
  std::array<bool, 2> have_valid_{false, false};
};

}  // namespace telex
