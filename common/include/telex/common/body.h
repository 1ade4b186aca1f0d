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

#include "telex/common/hand_kinematics.h"

namespace telex {

enum class Side : std::uint8_t { Left = 0, Right = 1 };
inline constexpr std::array<Side, 2> kSides{Side::Left, Side::Right};
inline std::size_t index_of(Side s) { return static_cast<std::size_t>(s); }

// The operator's body. The default is an adult of 1.75 m stature with the segment proportions of
// Drillis & Contini (1966) as tabulated in Winter, "Biomechanics and Motor Control of Human
// Movement" (4th ed., table 4.1): upper arm 0.186 H = 0.326 m, forearm 0.146 H = 0.256 m; the hand
// is HandGeometry's default; the interpupillary distance 64 mm (Dodgson 2004: adult mean 63 mm)
// with the eyes 8 cm in front of the head body, as the station's camera offset assumes.
struct BodyDims {
  double upper_arm_m = 0.186 * 1.75;  // shoulder centre to elbow centre
  double forearm_m = 0.146 * 1.75;    // elbow centre to wrist centre
  // The eyes' midpoint in the head rigid body's frame (Motive's: x right, y up, z backward).
  glm::dvec3 p_HeadEyes{0.0, 0.0, -0.08};
  double ipd_m = 0.064;
  // The forearm axis (elbow toward wrist) in the wrist rigid body's frame: with the body on the
  // back of the wrist, along the fingers' straight direction.
  glm::dvec3 forearm_axis_wrist{1.0, 0.0, 0.0};
  // false when the wrist body sits on the hand (which flexes at the wrist): its orientation then
  // says nothing of the forearm, and without an elbow marker the posture rule picks the elbow.
  bool forearm_axis_from_wrist = true;
  // World up (Motive: +y). The posture rule pulls the elbow down, out and back; its one
  // undetermined direction (the pole) is the arm pointing that way, down and behind the body,
  // outside a teleoperator's working space in front.
  glm::dvec3 up_world{0.0, 1.0, 0.0};
  double elbow_out_weight = 0.35;  // how far "out" pulls the elbow against "down"
  double elbow_back_weight = 0.5;  // how far "back" pulls it
  // The posture rule's swivel turns at most this fast (rad/s): near the pole, where the rule's
  // direction swings round, the elbow turns at a natural pace instead of flipping.
  double swivel_rate_rad_s = 3.0;
  // An arm whose inputs are missing or not finite keeps its last pose this long, then is hidden.
  double hold_s = 0.2;
  std::array<HandGeometry, 2> hands{left_hand(), HandGeometry{}};  // by Side

  static HandGeometry left_hand() {
    HandGeometry h;
    h.left = true;
    return h;
  }
  // Throws std::invalid_argument naming the field when a length or time is not finite and
  // positive or a direction is zero.
  void validate() const;
};

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
