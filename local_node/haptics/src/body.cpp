// SPDX-License-Identifier: MIT
// The operator's virtual body: eyes from the head body, arms by an analytic two-bone solve, hands
// by forward kinematics; missing inputs held for a while, then hidden.
#include "telex/haptics/body.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace telex {
namespace {

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool usable(const Pose& p) {
  const glm::dquat& q = p.q;
  return finite(p.p_m) && std::isfinite(q.w) && std::isfinite(q.x) && std::isfinite(q.y) &&
         std::isfinite(q.z) && glm::length(q) > 0.5;
}

Pose normalized(const Pose& p) { return {p.p_m, glm::normalize(p.q)}; }

// Some unit vector perpendicular to unit `n`.
glm::dvec3 any_perpendicular(const glm::dvec3& n) {
  const glm::dvec3 other =
      std::abs(n.x) < 0.9 ? glm::dvec3{1.0, 0.0, 0.0} : glm::dvec3{0.0, 1.0, 0.0};
  return glm::normalize(glm::cross(n, other));
}

}  // namespace

const char* elbow_from_name(ElbowFrom from) {
  switch (from) {
    case ElbowFrom::Marker:
      return "marker";
    case ElbowFrom::ForearmAxis:
      return "forearm-axis";
    case ElbowFrom::Posture:
      return "posture";
    case ElbowFrom::Straight:
      break;
  }
  return "straight";
}

ArmSolution solve_arm(double upper_arm_m, double forearm_m, const ArmSolveInput& in) {
  const double l1 = upper_arm_m, l2 = forearm_m;
  ArmSolution out;
  const glm::dvec3 v = in.wrist - in.shoulder;
  const double d = glm::length(v);
  // The axis: toward the wrist; with the wrist at the shoulder, the last axis (or straight down).
  glm::dvec3 n{0.0, -1.0, 0.0};
  if (d > 1e-9)
    n = v / d;
  else if (in.previous_axis && glm::length(*in.previous_axis) > 1e-9)
    n = glm::normalize(*in.previous_axis);
  else if (glm::length(in.posture_dir) > 1e-9)
    n = glm::normalize(in.posture_dir);
  out.axis = n;
  const auto perp = [&n](const glm::dvec3& x) { return x - n * glm::dot(x, n); };
  const double d_min = std::abs(l1 - l2), d_max = l1 + l2;
  const double tol = 1e-9 * d_max;
  out.reachable = d >= d_min - tol && d <= d_max + tol;

  // The previous swivel, if it still has a component off the axis.
  std::optional<glm::dvec3> previous;
  if (in.previous_swivel) {
    const glm::dvec3 p = perp(*in.previous_swivel);
    if (glm::length(p) > 1e-9) previous = glm::normalize(p);
  }

  if (d >= d_max) {
    // Out of reach (or exactly at it): the arm points at the wrist; segments share the stretch.
    out.elbow = in.shoulder + n * (d * l1 / d_max);
    out.swivel = previous ? *previous : any_perpendicular(n);
    out.from = ElbowFrom::Straight;
    return out;
  }
  // The elbow circle: centre on the axis at a from the shoulder, radius r.
  const double dc = std::max(d, d_min + 1e-6 * d_max);
  const double a = (l1 * l1 - l2 * l2 + dc * dc) / (2.0 * dc);
  const double r = std::sqrt(std::max(0.0, l1 * l1 - a * a));
  const glm::dvec3 centre = in.shoulder + n * a;

  std::optional<glm::dvec3> u;
  if (in.elbow_marker) {
    const glm::dvec3 p = perp(*in.elbow_marker - centre);
    if (glm::length(p) > 1e-6) {
      u = glm::normalize(p);
      out.from = ElbowFrom::Marker;
    }
  }
  if (!u && in.forearm_axis) {
    // The elbow the wrist body's forearm axis points back to; the circle point nearest to it.
    const glm::dvec3 p = perp(in.wrist - *in.forearm_axis * l2 - centre);
    if (glm::length(p) > 1e-6) {
      u = glm::normalize(p);
      out.from = ElbowFrom::ForearmAxis;
    }
  }
  if (!u) {
    // Natural posture: the elbow hangs down, out and back. Near the rule's pole (the axis along
    // that direction) its projection swings round; at the pole it is undefined and the previous
    // swivel stays. The swivel turns toward the rule's at most max_swivel_step_rad per solve.
    out.from = ElbowFrom::Posture;
    const glm::dvec3 want =
        glm::length(in.posture_dir) > 1e-9 ? glm::normalize(in.posture_dir) : glm::dvec3{0.0};
    const glm::dvec3 pd = perp(want);
    const double m = glm::length(pd);
    glm::dvec3 target = m > 1e-6 ? pd / m : previous ? *previous : any_perpendicular(n);
    if (previous) {
      const double cos_a = std::clamp(glm::dot(*previous, target), -1.0, 1.0);
      const double angle = std::acos(cos_a);
      const double step = std::max(0.0, in.max_swivel_step_rad);
      if (angle > step) {
        // Turn the previous swivel about the axis, the shorter way (counter-clockwise when the
        // rule points exactly opposite).
        const double sign = glm::dot(glm::cross(*previous, target), n) < 0.0 ? -1.0 : 1.0;
        target = glm::normalize(glm::angleAxis(sign * step, n) * *previous);
      }
    }
    u = target;
  }
  out.swivel = *u;
  out.elbow = centre + *u * r;
  return out;
}

Body::Body(BodyDims dims) : dims_(std::move(dims)) { dims_.validate(); }

const BodyState& Body::update(const BodyInputs& in) {
  state_.time_ns = in.time_ns;
  state_.head_valid = in.head && usable(*in.head);
  if (state_.head_valid) {
    state_.head = normalized(*in.head);
    const glm::dvec3 half{dims_.ipd_m / 2.0, 0.0, 0.0};
    state_.eye[index_of(Side::Left)] = state_.head.p_m + state_.head.q * (dims_.p_HeadEyes - half);
    state_.eye[index_of(Side::Right)] = state_.head.p_m + state_.head.q * (dims_.p_HeadEyes + half);
  }
  for (Side s : kSides) update_arm(s, in);
  return state_;
}

glm::dvec3 Body::posture_pull(Side side, const glm::dvec3& out) const {
  const glm::dvec3 up = glm::normalize(dims_.up_world);
  glm::dvec3 pull = -up + out * dims_.elbow_out_weight;
  // Back: the operator's right, crossed with up (Motive: x right, y up -> z back).
  const glm::dvec3 right = side == Side::Right ? out : -out;
  const glm::dvec3 back = glm::cross(right, up);
  if (glm::length(back) > 1e-9) pull += glm::normalize(back) * dims_.elbow_back_weight;
  return pull;
}

void Body::update_arm(Side side, const BodyInputs& in) {
  const std::size_t i = index_of(side), other = 1 - i;
  ArmState& arm = state_.arms[i];
  const bool valid =
      in.shoulder[i] && in.wrist[i] && usable(*in.shoulder[i]) && usable(*in.wrist[i]);
  if (!valid) {
    // Hold the last valid pose for hold_s (a clock that stepped back counts as no time), then hide.
    const double age_s = static_cast<double>(in.time_ns - arm.valid_ns) * 1e-9;
    arm.held = have_valid_[i] && age_s <= dims_.hold_s;
    arm.visible = arm.held;
    return;
  }
  const glm::dvec3 shoulder = in.shoulder[i]->p_m;
  const Pose wrist = normalized(*in.wrist[i]);

  // Out: away from the other shoulder when it is tracked, else along the head's x.
  glm::dvec3 out{0.0};
  if (in.shoulder[other] && usable(*in.shoulder[other]) &&
      glm::length(shoulder - in.shoulder[other]->p_m) > 1e-3)
    out = glm::normalize(shoulder - in.shoulder[other]->p_m);
  else if (state_.head_valid)
    out = state_.head.q * glm::dvec3{side == Side::Right ? 1.0 : -1.0, 0.0, 0.0};
  ArmSolveInput s;
  s.shoulder = shoulder;
  s.wrist = wrist.p_m;
  if (in.elbow[i] && finite(*in.elbow[i])) s.elbow_marker = *in.elbow[i];
  if (dims_.forearm_axis_from_wrist && in.wrist_orientation[i])
    s.forearm_axis = glm::normalize(wrist.q * dims_.forearm_axis_wrist);
  s.posture_dir = posture_pull(side, out);
  s.previous_swivel = swivel_[i];
  s.previous_axis = axis_[i];
  if (have_valid_[i]) {
    const double dt_s = std::max(0.0, static_cast<double>(in.time_ns - arm.valid_ns) * 1e-9);
    s.max_swivel_step_rad = std::min(3.14159265358979323846, dims_.swivel_rate_rad_s * dt_s);
  }
  const ArmSolution sol = solve_arm(dims_.upper_arm_m, dims_.forearm_m, s);
  swivel_[i] = sol.swivel;
  axis_[i] = sol.axis;

  arm.visible = true;
  arm.held = false;
  arm.reachable = sol.reachable;
  arm.elbow_from = sol.from;
  arm.shoulder = shoulder;
  arm.elbow = sol.elbow;
  arm.wrist = wrist.p_m;
  arm.wrist_pose = wrist;
  arm.hand = hand_forward(dims_.hands[i], wrist, in.bend[i]);
  arm.valid_ns = in.time_ns;
  have_valid_[i] = true;
}

}  // namespace telex
