// SPDX-License-Identifier: MIT
// The body check's cases: generated arms with known elbows, and the inputs that break naive arm
// solvers.
#include "telex/stability/body_check.h"

#include <fmt/format.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

namespace telex {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
constexpr double kElbowTolerance_m = 0.01;     // the 1 cm
constexpr std::int64_t kTick_ns = 10'000'000;  // 100 Hz tracking

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Rotation taking unit `from` to unit `to`.
glm::dquat rotation_between(const glm::dvec3& from, const glm::dvec3& to) {
  const double c = glm::dot(from, to);
  if (c < -1.0 + 1e-12) {
    glm::dvec3 axis = glm::cross(from, glm::dvec3{0.0, 1.0, 0.0});
    if (glm::length(axis) < 1e-9) axis = glm::cross(from, glm::dvec3{1.0, 0.0, 0.0});
    return glm::angleAxis(kPi, glm::normalize(axis));
  }
  const glm::dvec3 axis = glm::cross(from, to);
  const glm::dquat q{1.0 + c, axis.x, axis.y, axis.z};
  return glm::normalize(q);
}

// Shoulders 36 cm apart at 1.45 m, facing -z (Motive: x right, y up, z back).
glm::dvec3 shoulder_of(Side side) { return {side == Side::Right ? 0.18 : -0.18, 1.45, 0.0}; }

BodyInputs inputs_for(Side side, const ArmTruth& t, std::int64_t time_ns) {
  BodyInputs in;
  in.time_ns = time_ns;
  in.head = Pose{{0.0, 1.65, 0.0}, {1.0, 0.0, 0.0, 0.0}};
  const std::size_t i = index_of(side), o = 1 - i;
  in.shoulder[i] = Pose{t.shoulder, {1.0, 0.0, 0.0, 0.0}};
  in.shoulder[o] =
      Pose{shoulder_of(side == Side::Right ? Side::Left : Side::Right), {1.0, 0.0, 0.0, 0.0}};
  in.wrist[i] = t.wrist_pose;
  in.bend[i] = {0.2, 0.4, 0.6, 0.8, 1.0};
  return in;
}

// What every update must give: finite points, segment lengths kept where the wrist is reachable.
struct Tally {
  BodyCaseResult r;
  double worst_length_error_m = 0.0;
  void see(const Body& body, Side side) {
    const ArmState& a = body.state().arms[index_of(side)];
    ++r.updates;
    bool ok = finite(a.shoulder) && finite(a.elbow) && finite(a.wrist);
    for (const auto& finger : a.hand.joints)
      for (const auto& p : finger) ok = ok && finite(p);
    for (const auto& e : body.state().eye) ok = ok && finite(e);
    if (!ok) ++r.nonfinite;
    if (!a.visible) return;
    r.reachable = r.reachable && a.reachable;
    if (a.reachable && !a.held) {
      const double e1 = std::abs(glm::length(a.elbow - a.shoulder) - body.dims().upper_arm_m);
      const double e2 = std::abs(glm::length(a.wrist - a.elbow) - body.dims().forearm_m);
      worst_length_error_m = std::max({worst_length_error_m, e1, e2});
    }
  }
  void elbow_error(double e) { r.elbow_error_m = std::max(r.elbow_error_m.value_or(0.0), e); }
};

struct Generated {
  double azimuth, elevation, flexion, swivel, twist;
};

// Arms across the working space in front of the operator: azimuth -40..100 deg (0 = straight
// out, 90 = forward), elevation -80..60 deg, flexion 15..140 deg, any swivel within the natural
// range (-30..120 deg, elbow down to out).
Generated random_arm(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> az(-40.0, 100.0), el(-80.0, 60.0), fl(15.0, 140.0),
      sw(-30.0, 120.0), tw(-90.0, 90.0);
  return {az(rng) * kDeg, el(rng) * kDeg, fl(rng) * kDeg, sw(rng) * kDeg, tw(rng) * kDeg};
}

enum class Cue { ForearmAxis, Marker, NoisyAxis, Posture };

BodyCaseResult generated_case(const std::string& name, Side side, const Generated& g, Cue cue,
                              std::mt19937_64& rng) {
  BodyDims dims;
  if (cue == Cue::Marker || cue == Cue::Posture) dims.forearm_axis_from_wrist = false;
  Body body(dims);
  const ArmTruth t = arm_forward(dims, side, shoulder_of(side), g.azimuth, g.elevation, g.flexion,
                                 g.swivel, g.twist);
  BodyInputs in = inputs_for(side, t, 0);
  const std::size_t i = index_of(side);
  if (cue == Cue::Marker) {
    // A marker on the elbow's skin, 4 cm out from the joint centre along the swivel direction.
    const glm::dvec3 n = glm::normalize(t.wrist - t.shoulder);
    glm::dvec3 out = t.elbow - t.shoulder;
    out -= n * glm::dot(out, n);
    in.elbow[i] = t.elbow + glm::normalize(out) * 0.04;
  }
  if (cue == Cue::NoisyAxis) {
    // The wrist body's orientation off by 1 degree about a random axis (OptiTrack's rigid-body
    // orientation noise is far below this).
    std::normal_distribution<double> nd;
    const glm::dvec3 axis = glm::normalize(glm::dvec3{nd(rng), nd(rng), nd(rng)});
    in.wrist[i]->q = glm::angleAxis(1.0 * kDeg, axis) * in.wrist[i]->q;
  }
  Tally tally;
  tally.r.name = name;
  body.update(in);
  tally.see(body, side);
  const ArmState& a = body.state().arms[i];
  const char* from = elbow_from_name(a.elbow_from);
  if (cue == Cue::Posture) {
    // Not determined: the rule must give a natural elbow, below the shoulder-wrist line's
    // midpoint height or out to the side, with the lengths kept.
    const glm::dvec3 mid = (t.shoulder + t.wrist) * 0.5;
    const bool natural =
        a.elbow.y <= mid.y + 1e-9 || (side == Side::Right ? a.elbow.x > mid.x : a.elbow.x < mid.x);
    tally.r.criteria =
        "finite; lengths kept within 1e-6 m; elbow (posture rule) below the shoulder-wrist "
        "midpoint or outward of it";
    tally.r.pass = tally.r.nonfinite == 0 && tally.worst_length_error_m < 1e-6 && natural &&
                   a.elbow_from == ElbowFrom::Posture;
    tally.r.note = fmt::format("elbow from {}; truth elbow {:.3f} m away (not determined)", from,
                               glm::length(a.elbow - t.elbow));
    return tally.r;
  }
  tally.elbow_error(glm::length(a.elbow - t.elbow));
  // A straight arm (flexion 0) has its elbow on the shoulder-wrist line, whatever the cue.
  const ElbowFrom want = g.flexion == 0.0     ? ElbowFrom::Straight
                         : cue == Cue::Marker ? ElbowFrom::Marker
                                              : ElbowFrom::ForearmAxis;
  tally.r.criteria =
      fmt::format("finite; lengths kept within 1e-6 m; elbow from {}; elbow error <= {:.0f} mm",
                  elbow_from_name(want), kElbowTolerance_m * 1e3);
  tally.r.pass = tally.r.nonfinite == 0 && tally.worst_length_error_m < 1e-6 &&
                 a.elbow_from == want && *tally.r.elbow_error_m <= kElbowTolerance_m &&
                 tally.r.reachable;
  tally.r.note = fmt::format("elbow from {}; error {:.3g} mm", from, *tally.r.elbow_error_m * 1e3);
  return tally.r;
}

// The wrist swept along a straight path, one update per 10 ms; the elbow's largest step between
// updates must stay small (no flip) and every output finite.
BodyCaseResult sweep_case(const std::string& name, Side side, const glm::dvec3& from,
                          const glm::dvec3& to, int steps, bool use_axis, double max_step_m,
                          const std::string& why) {
  BodyDims dims;
  dims.forearm_axis_from_wrist = use_axis;
  Body body(dims);
  Tally tally;
  tally.r.name = name;
  glm::dvec3 last_elbow{0.0};
  double worst_step = 0.0;
  for (int k = 0; k <= steps; ++k) {
    const double s = static_cast<double>(k) / steps;
    ArmTruth t;
    t.shoulder = shoulder_of(side);
    t.wrist = from + (to - from) * s;
    // The wrist body's forearm axis along shoulder -> wrist (a straight arm's).
    const glm::dvec3 dir = t.wrist - t.shoulder;
    const glm::dvec3 axis = glm::length(dir) > 1e-9 ? glm::normalize(dir) : glm::dvec3{0, -1, 0};
    t.wrist_pose = {t.wrist, rotation_between(dims.forearm_axis_wrist, axis)};
    body.update(inputs_for(side, t, k * kTick_ns));
    tally.see(body, side);
    const glm::dvec3 e = body.state().arms[index_of(side)].elbow;
    if (k > 0) worst_step = std::max(worst_step, glm::length(e - last_elbow));
    last_elbow = e;
  }
  tally.r.criteria = fmt::format(
      "finite; lengths kept where reachable; elbow step <= {:.0f} mm per "
      "update ({})",
      max_step_m * 1e3, why);
  tally.r.pass =
      tally.r.nonfinite == 0 && tally.worst_length_error_m < 1e-6 && worst_step <= max_step_m;
  tally.r.note =
      fmt::format("{} updates; largest elbow step {:.2f} mm", tally.r.updates, worst_step * 1e3);
  return tally.r;
}

}  // namespace

ArmTruth arm_forward(const BodyDims& dims, Side side, const glm::dvec3& shoulder,
                     double azimuth_rad, double elevation_rad, double flexion_rad,
                     double swivel_rad, double twist_rad) {
  const double out_sign = side == Side::Right ? 1.0 : -1.0;
  // Body frame: out (+x for the right arm), up (+y), forward (-z).
  const glm::dvec3 out{out_sign, 0.0, 0.0}, up{0.0, 1.0, 0.0}, forward{0.0, 0.0, -1.0};
  const glm::dvec3 u = glm::normalize(
      (out * std::cos(azimuth_rad) + forward * std::sin(azimuth_rad)) * std::cos(elevation_rad) +
      up * std::sin(elevation_rad));
  ArmTruth t;
  t.shoulder = shoulder;
  t.elbow = shoulder + u * dims.upper_arm_m;
  // The forearm bends by the flexion toward a direction perpendicular to the upper arm, turned
  // by the swivel about it: swivel 0 bends it forward-and-up-ish, as reaching does.
  glm::dvec3 a = forward - u * glm::dot(forward, u);
  if (glm::length(a) < 1e-6) a = up - u * glm::dot(up, u);
  a = glm::normalize(a);
  const glm::dvec3 b = glm::cross(u, a);
  const glm::dvec3 bend_dir = a * std::cos(swivel_rad) + b * std::sin(swivel_rad);
  const glm::dvec3 f = u * std::cos(flexion_rad) + bend_dir * std::sin(flexion_rad);
  t.wrist = t.elbow + f * dims.forearm_m;
  const glm::dquat align = rotation_between(glm::normalize(dims.forearm_axis_wrist), f);
  t.wrist_pose = {t.wrist, glm::angleAxis(twist_rad, f) * align};
  return t;
}

namespace {

// ---- generated arms with known elbows ----------------------------------------------------------

const char* cue_name(Cue cue) {
  return cue == Cue::ForearmAxis ? "forearm-axis"
         : cue == Cue::Marker    ? "elbow-marker"
         : cue == Cue::NoisyAxis ? "forearm-axis-1deg-off"
                                 : "posture-rule";
}

const char* side_name(Side s) { return s == Side::Right ? "right" : "left"; }

// 12 by the forearm axis, 6 by an elbow marker, 4 with the wrist body's orientation 1 deg off, 4
// by the posture rule alone; sides alternate.
std::vector<BodyCaseResult> generated_cases(std::mt19937_64& rng) {
  std::vector<BodyCaseResult> out;
  const std::pair<Cue, int> plan[] = {
      {Cue::ForearmAxis, 12}, {Cue::Marker, 6}, {Cue::NoisyAxis, 4}, {Cue::Posture, 4}};
  for (const auto& [cue, count] : plan) {
    for (int k = 0; k < count; ++k) {
      const Side side = k % 2 == 0 ? Side::Right : Side::Left;
      Generated g = random_arm(rng);
      // The posture rule's cases: arms in the rule's own natural range (elbow hanging).
      if (cue == Cue::Posture) g.swivel = 80.0 * kDeg + 20.0 * kDeg * (k % 2);
      out.push_back(generated_case(
          fmt::format("{}-{}-{:02d}-az{:.0f}-el{:.0f}-flex{:.0f}", cue_name(cue), side_name(side),
                      k, g.azimuth / kDeg, g.elevation / kDeg, g.flexion / kDeg),
          side, g, cue, rng));
    }
  }
  return out;
}

// ---- singular geometry -------------------------------------------------------------------------

const glm::dvec3 kShoulderRight = shoulder_of(Side::Right);

// The right wrist at `target`, its forearm axis along shoulder -> target: unreachable, so the arm
// must point at the wrist with the elbow on the shoulder-wrist segment.
BodyCaseResult beyond_reach_case(const char* name, const glm::dvec3& target) {
  const BodyDims dims;
  const glm::dvec3& sr = kShoulderRight;
  Body body(dims);
  ArmTruth t;
  t.shoulder = sr;
  t.wrist = target;
  t.wrist_pose = {target, rotation_between(dims.forearm_axis_wrist, glm::normalize(target - sr))};
  body.update(inputs_for(Side::Right, t, 0));
  Tally tally;
  tally.r.name = name;
  tally.see(body, Side::Right);
  const ArmState& a = body.state().arms[index_of(Side::Right)];
  const glm::dvec3 n = glm::normalize(target - sr);
  const double off_line = glm::length((a.elbow - sr) - n * glm::dot(a.elbow - sr, n));
  tally.r.criteria =
      "finite; reported unreachable; elbow on the shoulder-wrist line (straight arm)";
  tally.r.pass = tally.r.nonfinite == 0 && !a.reachable && off_line < 1e-9 &&
                 a.elbow_from == ElbowFrom::Straight;
  tally.r.note =
      fmt::format("elbow {:.2g} m off the line; from {}", off_line, elbow_from_name(a.elbow_from));
  return tally.r;
}

// The right wrist `offset` from the shoulder: unreachable, the upper arm keeps its length.
BodyCaseResult wrist_near_shoulder_case(const char* name, const glm::dvec3& offset) {
  const BodyDims dims;
  const glm::dvec3& sr = kShoulderRight;
  Body body(dims);
  ArmTruth t;
  t.shoulder = sr;
  t.wrist = sr + offset;
  t.wrist_pose = {t.wrist, {1.0, 0.0, 0.0, 0.0}};
  body.update(inputs_for(Side::Right, t, 0));
  Tally tally;
  tally.r.name = name;
  tally.see(body, Side::Right);
  const ArmState& a = body.state().arms[index_of(Side::Right)];
  const double e1 = std::abs(glm::length(a.elbow - sr) - dims.upper_arm_m);
  tally.r.criteria = "finite; reported unreachable; upper arm keeps its length";
  tally.r.pass = tally.r.nonfinite == 0 && !a.reachable && a.visible && e1 < 1e-6;
  tally.r.note = fmt::format("upper arm length error {:.2g} m", e1);
  return tally.r;
}

// Targets on the posture rule's axis: the arm swept straight down through the vertical and
// straight up through it, and a circle around the downward vertical, with no forearm axis and
// no marker (the rule alone). A flip would move the elbow by up to 2 r in one update.
std::vector<BodyCaseResult> posture_axis_sweeps() {
  const BodyDims dims;
  const Side R = Side::Right;
  const glm::dvec3& sr = kShoulderRight;
  const double len = 0.5;
  const glm::dvec3 pole = glm::normalize(Body(dims).posture_pull(R, {1.0, 0.0, 0.0})) * len;
  const glm::dvec3 across = glm::normalize(glm::cross(pole, glm::dvec3{0.0, 0.0, 1.0})) * 0.2;
  std::vector<BodyCaseResult> out;
  out.push_back(sweep_case("swivel-axis-sweep-through-pole", R, sr + pole - across,
                           sr + pole + across, 400, false, 0.01,
                           "wrist passes exactly through the posture rule's pole"));
  out.push_back(sweep_case("swivel-axis-sweep-down", R, sr + glm::dvec3{-0.2, -len, -0.05},
                           sr + glm::dvec3{0.2, -len, 0.05}, 400, false, 0.01,
                           "wrist passes straight below the shoulder"));
  out.push_back(sweep_case("swivel-axis-sweep-up", R, sr + glm::dvec3{-0.2, len, 0.05},
                           sr + glm::dvec3{0.2, len, -0.05}, 400, false, 0.01,
                           "wrist passes straight above the shoulder"));
  out.push_back(sweep_case("straight-reach-sweep-with-axis", R, sr + glm::dvec3{0.0, -0.2, -0.3},
                           sr + glm::dvec3{0.0, 0.2, -0.95}, 400, true, 0.02,
                           "wrist moves out of reach along the forearm axis"));
  return out;
}

// The arm fully straight (flexion 0) by the forearm axis; beyond reach, along and off the axes;
// the wrist exactly at the shoulder and 1 um from it; sweeps through the posture rule's axis.
std::vector<BodyCaseResult> singular_cases(std::mt19937_64& rng) {
  const BodyDims dims;
  const double reach = dims.upper_arm_m + dims.forearm_m;
  const glm::dvec3& sr = kShoulderRight;
  std::vector<BodyCaseResult> out;
  out.push_back(generated_case("straight-arm-forward-right", Side::Right, {90 * kDeg, 0, 0, 0, 0},
                               Cue::ForearmAxis, rng));
  out.push_back(
      beyond_reach_case("wrist-beyond-reach-forward", sr + glm::dvec3{0.0, 0.0, -2.0 * reach}));
  out.push_back(
      beyond_reach_case("wrist-beyond-reach-diagonal", sr + glm::dvec3{1.0, 1.0, -1.0} * reach));
  out.push_back(wrist_near_shoulder_case("wrist-at-shoulder", glm::dvec3{0.0}));
  out.push_back(wrist_near_shoulder_case("wrist-1um-from-shoulder", glm::dvec3{1e-6, 0.0, 0.0}));
  for (auto& r : posture_axis_sweeps()) out.push_back(std::move(r));
  return out;
}

// ---- hostile values ----------------------------------------------------------------------------

struct Hostile {
  const char* name;
  std::function<void(BodyInputs&)> spoil;
};

// NaN and Inf in the wrist, the shoulder and the orientation; a zero quaternion; missing bodies.
std::vector<Hostile> hostile_inputs() {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  return {
      {"nan-wrist-position", [nan](BodyInputs& in) { in.wrist[1]->p_m.x = nan; }},
      {"inf-shoulder-position", [inf](BodyInputs& in) { in.shoulder[1]->p_m.y = inf; }},
      {"nan-wrist-orientation", [nan](BodyInputs& in) { in.wrist[1]->q.w = nan; }},
      {"zero-wrist-quaternion",
       [](BodyInputs& in) {
         in.wrist[1]->q = {0.0, 0.0, 0.0, 0.0};
       }},
      {"missing-wrist-body", [](BodyInputs& in) { in.wrist[1].reset(); }},
      {"missing-shoulder-body", [](BodyInputs& in) { in.shoulder[1].reset(); }},
  };
}

// Held while the last valid pose is younger than 200 ms, then hidden; shown again with the next
// valid input.
BodyCaseResult hostile_case(const Hostile& h) {
  const BodyDims dims;
  const Side R = Side::Right;
  Body body(dims);
  const ArmTruth t =
      arm_forward(dims, R, kShoulderRight, 60 * kDeg, -20 * kDeg, 70 * kDeg, 90 * kDeg, 0.0);
  Tally tally;
  tally.r.name = h.name;
  body.update(inputs_for(R, t, 0));
  tally.see(body, R);
  const glm::dvec3 good_elbow = body.state().arms[1].elbow;
  bool held_ok = true, hidden_ok = true;
  double moved = 0.0;
  // Bad inputs for 300 ms at 100 Hz: shown (held) up to 200 ms, hidden after.
  for (int k = 1; k <= 30; ++k) {
    BodyInputs in = inputs_for(R, t, k * kTick_ns);
    h.spoil(in);
    body.update(in);
    tally.see(body, R);
    const ArmState& a = body.state().arms[1];
    if (k <= 20) {
      held_ok = held_ok && a.visible && a.held;
      moved = std::max(moved, glm::length(a.elbow - good_elbow));
    } else {
      hidden_ok = hidden_ok && !a.visible;
    }
  }
  body.update(inputs_for(R, t, 31 * kTick_ns));
  tally.see(body, R);
  const bool back = body.state().arms[1].visible && !body.state().arms[1].held;
  tally.r.criteria =
      "finite; last valid pose held (unchanged) up to 200 ms, hidden after, shown "
      "again with the next valid input";
  tally.r.pass = tally.r.nonfinite == 0 && held_ok && moved == 0.0 && hidden_ok && back;
  tally.r.note = fmt::format("held {}, hidden after 200 ms {}, back {}", held_ok, hidden_ok, back);
  return tally.r;
}

// Far from the origin (a tracking volume whose origin is 10 km away): finite, determined elbows
// still within tolerance.
BodyCaseResult far_origin_case() {
  const Side R = Side::Right;
  BodyDims far_dims;
  Body body(far_dims);
  const glm::dvec3 far_shoulder = kShoulderRight + glm::dvec3{1e4, 0.0, -1e4};
  const ArmTruth t =
      arm_forward(far_dims, R, far_shoulder, 45 * kDeg, 10 * kDeg, 60 * kDeg, 30 * kDeg, 0.3);
  BodyInputs in = inputs_for(R, t, 0);
  in.shoulder[0]->p_m += glm::dvec3{1e4, 0.0, -1e4};
  in.head->p_m += glm::dvec3{1e4, 0.0, -1e4};
  body.update(in);
  Tally tally;
  tally.r.name = "tracking-origin-10km-away";
  tally.see(body, R);
  tally.elbow_error(glm::length(body.state().arms[1].elbow - t.elbow));
  tally.r.criteria = "finite; elbow error <= 10 mm";
  tally.r.pass = tally.r.nonfinite == 0 && *tally.r.elbow_error_m <= kElbowTolerance_m;
  tally.r.note = fmt::format("elbow error {:.3g} mm", *tally.r.elbow_error_m * 1e3);
  return tally.r;
}

std::vector<BodyCaseResult> hostile_cases() {
  std::vector<BodyCaseResult> out;
  for (const auto& h : hostile_inputs()) out.push_back(hostile_case(h));
  out.push_back(far_origin_case());
  return out;
}

}  // namespace

std::vector<BodyCaseResult> run_body_check(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<BodyCaseResult> out = generated_cases(rng);
  for (auto& r : singular_cases(rng)) out.push_back(std::move(r));
  for (auto& r : hostile_cases()) out.push_back(std::move(r));
  return out;
}

}  // namespace telex
