// SPDX-License-Identifier: MIT
// Scripted fingertip trajectories: built-in gestures, a text format, and the tracker that plays
// them.
#include "telex/local/inputs/hand_script.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <glm/gtc/quaternion.hpp>
#include <sstream>
#include <stdexcept>

#include "telex/haptics/hand_kinematics.h"
#include "telex/haptics/haptic_surface.h"

namespace telex::local {

namespace {

constexpr int kIndex = 1;

// Appends a key reached from the previous one at a constant speed.
void move_to(std::vector<ScriptKey>& k, const glm::dvec3& p, double speed_mps) {
  const double d = glm::length(p - k.back().p_CameraFingertip);
  k.push_back({k.back().t_s + d / speed_mps, p});
}
void hold(std::vector<ScriptKey>& k, double dt_s) {
  k.push_back({k.back().t_s + dt_s, k.back().p_CameraFingertip});
}

std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() &&
           (line[i] == ' ' || line[i] == '\t' || line[i] == ',' || line[i] == '\r'))
      ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != ',' &&
           line[j] != '\r')
      ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

bool to_double(std::string_view s, double& v) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  return r.ec == std::errc{} && r.ptr == s.data() + s.size() && std::isfinite(v);
}

}  // namespace

std::vector<std::string> HandScript::builtin_names() { return {"press", "stroke", "tap"}; }

HandScript HandScript::builtin(std::string_view name, double surface_depth_m) {
  if (!(surface_depth_m > 0.0) || !std::isfinite(surface_depth_m))
    throw std::invalid_argument("script '" + std::string(name) +
                                "': surface depth must be a positive number of metres");
  const double d = surface_depth_m;
  const glm::dvec3 away{0.0, 0.0, d - 0.3};
  HandScript s;
  auto& k = s.keys_[kIndex];
  k.push_back({0.0, away});
  if (name == "press") {
    move_to(k, {0.0, 0.0, d + 0.010}, 0.1);
    hold(k, 1.0);
    move_to(k, away, 0.1);
  } else if (name == "stroke") {
    move_to(k, {0.0, 0.0, d + 0.005}, 0.1);
    hold(k, 0.2);
    move_to(k, {0.100, 0.0, d + 0.005}, 0.05);
    move_to(k, {0.0, 0.0, d + 0.005}, 0.05);
    hold(k, 0.2);
    move_to(k, away, 0.1);
  } else if (name == "tap") {
    const glm::dvec3 hover{0.0, 0.0, d - 0.020};
    move_to(k, hover, 0.1);
    for (int i = 0; i < 3; ++i) {
      hold(k, 0.3);
      k.push_back({k.back().t_s + 0.1, {0.0, 0.0, d + 0.005}});
      k.push_back({k.back().t_s + 0.1, hover});
    }
    hold(k, 0.3);
    move_to(k, away, 0.1);
  } else {
    throw std::invalid_argument("unknown built-in script '" + std::string(name) +
                                "' (valid: press, stroke, tap, or a script file path)");
  }
  s.duration_s_ = k.back().t_s;
  s.planned_depth_m_ = d;
  return s;
}

HandScript HandScript::parse(std::string_view text, const std::string& source) {
  HandScript s;
  bool header = false;
  int line_no = 0;
  std::size_t pos = 0;
  auto fail = [&](const std::string& why) {
    throw std::runtime_error(source + " line " + std::to_string(line_no) + ": " + why);
  };
  while (pos <= text.size()) {
    const std::size_t nl = std::min(text.find('\n', pos), text.size());
    std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    ++line_no;
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    const auto f = split_fields(line);
    if (f.empty()) continue;
    if (!header) {
      const std::vector<std::string_view> want{"time_s", "finger", "x_m", "y_m", "z_m"};
      if (f != want) fail("expected the header 'time_s finger x_m y_m z_m'");
      header = true;
      continue;
    }
    if (f.size() != 5)
      fail("expected 5 fields (time_s finger x_m y_m z_m), got " + std::to_string(f.size()));
    double t = 0, x = 0, y = 0, z = 0, finger_d = 0;
    if (!to_double(f[0], t) || t < 0) fail("time_s '" + std::string(f[0]) + "' is not a time >= 0");
    if (!to_double(f[1], finger_d) || finger_d != std::floor(finger_d) || finger_d < 0 ||
        finger_d > 4)
      fail("finger '" + std::string(f[1]) + "' is not 0..4 (thumb..little)");
    if (!to_double(f[2], x) || !to_double(f[3], y) || !to_double(f[4], z))
      fail("x_m, y_m, z_m must be finite numbers");
    auto& k = s.keys_[static_cast<int>(finger_d)];
    if (!k.empty() && t < k.back().t_s) fail("time goes backwards for this finger");
    k.push_back({t, {x, y, z}});
    s.duration_s_ = std::max(s.duration_s_, t);
  }
  if (!header) fail("no header line 'time_s finger x_m y_m z_m'");
  if (std::all_of(s.keys_.begin(), s.keys_.end(), [](const auto& k) { return k.empty(); }))
    fail("no keys after the header");
  return s;
}

HandScript HandScript::load(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw std::runtime_error("hand script " + path.string() +
                             ": cannot open (built-in scripts: press, stroke, tap)");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse(ss.str(), path.string());
}

glm::dvec3 HandScript::position(int finger, double t_s) const {
  const auto& k = keys_[finger];
  if (k.empty()) return glm::dvec3{0.0};
  if (t_s <= k.front().t_s) return k.front().p_CameraFingertip;
  if (t_s >= k.back().t_s) return k.back().p_CameraFingertip;
  const auto it = std::upper_bound(k.begin(), k.end(), t_s,
                                   [](double t, const ScriptKey& key) { return t < key.t_s; });
  const ScriptKey& b = *it;
  const ScriptKey& a = *std::prev(it);
  const double span = b.t_s - a.t_s;
  const double u = span > 0.0 ? (t_s - a.t_s) / span : 1.0;
  return a.p_CameraFingertip + (b.p_CameraFingertip - a.p_CameraFingertip) * u;
}

void HandScript::sample(double t_s, HandState& out) const {
  constexpr double kH = 1e-3;
  out.skeleton_valid = false;
  out.shoulder_valid = false;
  for (int i = 0; i < kFingerCount; ++i) {
    Fingertip& tip = out.tips[i];
    tip.finger = i;
    tip.valid = has_finger(i);
    // The finger points right and into the scene (a right hand reaching across): a stroke along
    // +x then has a component along the finger that a one-shear-direction display can render.
    tip.axis_Camera = glm::normalize(glm::dvec3{1.0, 0.0, 1.0});
    if (!tip.valid) {
      tip.v_CameraFingertip = glm::dvec3{0.0};
      continue;
    }
    tip.p_CameraFingertip = position(i, t_s);
    // Backward difference, forward at the very start where there is no past.
    const double t0 = t_s - kH >= 0.0 ? t_s - kH : t_s;
    tip.v_CameraFingertip = (position(i, t0 + kH) - position(i, t0)) / kH;
  }
  pose_hand(out);
}

// A scripted body for the view: a pointing right hand (the default hand geometry) whose leading
// finger (the first scripted one) is straight along the finger axis with its tip exactly at the
// script's position, the back of the hand up, the other fingers curled. Only the scripted
// fingertips are haptic fingertips; the skeleton is drawn.
void HandScript::pose_hand(HandState& out) {
  int lead = -1;
  for (int i = 0; i < kFingerCount && lead < 0; ++i)
    if (out.tips[static_cast<std::size_t>(i)].valid) lead = i;
  if (lead < 0) return;
  const Fingertip& tip = out.tips[static_cast<std::size_t>(lead)];
  const glm::dvec3 x = glm::normalize(tip.axis_Camera);
  const glm::dvec3 up{0.0, -1.0, 0.0};  // the camera's y points down
  glm::dvec3 y = up - x * glm::dot(up, x);
  y = glm::length(y) > 1e-9 ? glm::normalize(y) : glm::dvec3{0.0, 0.0, -1.0};
  const glm::dquat q = glm::quat_cast(glm::dmat3(x, y, glm::cross(x, y)));
  std::array<double, 5> bend{0.5, 0.8, 0.8, 0.8, 0.8};
  bend[static_cast<std::size_t>(lead)] = 0.0;
  static const HandGeometry kHand;
  const HandPoints hp = hand_forward(kHand, Pose{glm::dvec3{0.0}, q}, bend);
  const glm::dvec3 offset = tip.p_CameraFingertip - hp.joints[static_cast<std::size_t>(lead)][3];
  for (std::size_t f = 0; f < kFingerCount; ++f)
    for (std::size_t j = 0; j < 4; ++j) out.joints_camera[f][j] = hp.joints[f][j] + offset;
  out.wrist_camera = hp.wrist + offset;
  out.skeleton_valid = true;
}

ScriptTracker::ScriptTracker(HandScript script, std::string name, bool repeat)
    : script_(std::move(script)), name_(std::move(name)), repeat_(repeat) {}

bool ScriptTracker::poll(std::int64_t now_ns, HandState& out) {
  ++stats_.polls;
  if (!started_) {
    started_ = true;
    start_ns_ = now_ns;
  } else if (now_ns <= last_ns_ || finished_) {
    return false;
  }
  const double dt_s = now_ns > start_ns_ ? static_cast<double>(now_ns - last_ns_) * 1e-9 : 0.0;
  last_ns_ = now_ns;
  double t_s = static_cast<double>(now_ns - start_ns_) * 1e-9;
  if (repeat_ && script_.duration_s() > 0.0) {
    t_s = std::fmod(t_s, script_.duration_s());
  } else if (t_s >= script_.duration_s()) {
    t_s = script_.duration_s();
    finished_ = true;
  }
  script_.sample(t_s, out);
  if (script_.planned_surface_depth_m()) aim(dt_s, out);
  out.time_ns = out.motion_ns = now_ns;
  ++stats_.updates;
  ++stats_.frames_in;
  return true;
}

void ScriptTracker::aim(double dt_s, HandState& out) {
  const auto lead = std::find_if(out.tips.begin(), out.tips.end(),
                                 [](const Fingertip& tip) { return tip.valid; });
  if (lead == out.tips.end()) return;
  const glm::dvec3 p = lead->p_CameraFingertip + glm::dvec3(0.0, 0.0, offset_m_);
  double rate_mps = 0.0;
  if (surface_ != nullptr && p.z > 0.0 && dt_s > 0.0) {
    const Intrinsics& k = surface_->intrinsics;
    const std::optional<double> z =
        depth_at(*surface_, k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy);
    // Where the gesture would meet the surface under it as planned. Toward a deeper surface
    // always (the scene moved away); back toward a nearer one only from in front of it, so a
    // press is never chased by what it presses.
    const double want_m = z ? *z - *script_.planned_surface_depth_m() : offset_m_;
    if (z && (want_m > offset_m_ || p.z < *z)) {
      const double step_m = kFollowSpeedMps * dt_s;
      const double move_m = std::clamp(want_m - offset_m_, -step_m, step_m);
      offset_m_ += move_m;
      rate_mps = move_m / dt_s;
    }
  }
  const glm::dvec3 shift{0.0, 0.0, offset_m_};
  for (auto& tip : out.tips) {
    if (!tip.valid) continue;
    tip.p_CameraFingertip += shift;
    tip.v_CameraFingertip.z += rate_mps;
  }
  for (auto& finger : out.joints_camera)
    for (auto& joint : finger) joint += shift;
  out.wrist_camera += shift;
}

}  // namespace telex::local
