// SPDX-License-Identifier: MIT
// The rig file: JSON -> Rig with every error naming its key path, Rig -> JSON, merge updates.
#include "telex/common/rig.h"

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

namespace telex {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// A JSON value with its key path, for errors that say where. Every object read through it checks
// that it holds only the keys read (`done`).
class Node {
 public:
  Node(const nlohmann::json& j, std::string path, const std::string& origin)
      : j_(j), path_(std::move(path)), origin_(origin) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw RigError("rig " + origin_ + ": " + (path_.empty() ? "top level" : path_) + ": " + what);
  }
  const nlohmann::json& json() const { return j_; }
  const std::string& path() const { return path_; }

  void expect_object() const {
    if (!j_.is_object()) fail("must be an object, got " + type_of(j_));
  }
  bool has(const std::string& key) {
    expect_object();
    seen_.push_back(key);
    return j_.contains(key);
  }
  Node at(const std::string& key) const {
    return Node(j_.at(key), path_.empty() ? key : path_ + "." + key, origin_);
  }
  Node item(std::size_t i) const {
    return Node(j_.at(i), path_ + "[" + std::to_string(i) + "]", origin_);
  }
  // Every key present must have been asked for.
  void done() const {
    for (const auto& [key, value] : j_.items()) {
      bool known = false;
      for (const auto& s : seen_) known = known || s == key;
      if (!known) {
        std::string keys;
        for (const auto& s : seen_) keys += (keys.empty() ? "" : ", ") + s;
        at(key).fail("unknown key (known here: " + keys + ")");
      }
    }
  }

  double number(double lo, double hi) const {
    if (!j_.is_number()) fail("must be a number, got " + type_of(j_));
    const double v = j_.get<double>();
    if (!std::isfinite(v) || v < lo || v > hi) {
      std::ostringstream s;
      s << "must be within [" << lo << ", " << hi << "], got " << v;
      fail(s.str());
    }
    return v;
  }
  int integer(int lo, int hi) const {
    if (!j_.is_number_integer()) fail("must be an integer, got " + type_of(j_));
    const auto v = j_.get<std::int64_t>();
    if (v < lo || v > hi)
      fail("must be within [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
           std::to_string(v));
    return static_cast<int>(v);
  }
  bool boolean() const {
    if (!j_.is_boolean()) fail("must be true or false, got " + type_of(j_));
    return j_.get<bool>();
  }
  std::string string() const {
    if (!j_.is_string()) fail("must be a string, got " + type_of(j_));
    return j_.get<std::string>();
  }
  std::vector<double> numbers(std::size_t n_min, std::size_t n_max, double lo, double hi) const {
    if (!j_.is_array()) fail("must be an array of numbers, got " + type_of(j_));
    if (j_.size() < n_min || j_.size() > n_max)
      fail(n_min == n_max
               ? "must hold " + std::to_string(n_min) + " numbers, got " + std::to_string(j_.size())
               : "must hold " + std::to_string(n_min) + " to " + std::to_string(n_max) +
                     " numbers, got " + std::to_string(j_.size()));
    std::vector<double> v;
    for (std::size_t i = 0; i < j_.size(); ++i) v.push_back(item(i).number(lo, hi));
    return v;
  }
  glm::dvec3 vec3(double lo, double hi) const {
    const auto v = numbers(3, 3, lo, hi);
    return {v[0], v[1], v[2]};
  }
  glm::dvec3 unit3() const {
    const glm::dvec3 v = vec3(-1e6, 1e6);
    const double n = glm::length(v);
    if (!(n > 1e-9)) fail("must be a non-zero direction");
    return v / n;
  }
  // Rows of a rotation matrix; orthonormal with determinant +1 to within 1e-6.
  glm::dmat3 rotation() const {
    if (!j_.is_array() || j_.size() != 3)
      fail("must be a 3x3 rotation matrix as three rows [[r00,r01,r02],[...],[...]]");
    glm::dmat3 r(1.0);
    for (std::size_t i = 0; i < 3; ++i) {
      const auto row = item(i).numbers(3, 3, -1.000001, 1.000001);
      for (std::size_t c = 0; c < 3; ++c)
        r[static_cast<int>(c)][static_cast<int>(i)] = row[c];  // glm is column-major
    }
    const glm::dmat3 e = glm::transpose(r) * r - glm::dmat3(1.0);
    double worst = 0.0;
    for (int c = 0; c < 3; ++c)
      for (int i = 0; i < 3; ++i) worst = std::max(worst, std::abs(e[c][i]));
    if (worst > 1e-6 || glm::determinant(r) < 0.0)
      fail("is not a rotation (R^T R = I and det R = +1 to 1e-6; off by " + std::to_string(worst) +
           ", det " + std::to_string(glm::determinant(r)) + ")");
    return r;
  }

  static std::string type_of(const nlohmann::json& j) {
    if (j.is_null()) return "null";
    if (j.is_boolean()) return "a boolean";
    if (j.is_number()) return "a number";
    if (j.is_string()) return "a string";
    if (j.is_array()) return "an array";
    return "an object";
  }

 private:
  const nlohmann::json& j_;
  std::string path_;
  const std::string& origin_;
  std::vector<std::string> seen_;
};

Intrinsics read_intrinsics(Node& n, bool allow_distortion, std::array<double, 5>* distortion) {
  Intrinsics k;
  if (!n.has("width") || !n.has("height") || !n.has("fx_px") || !n.has("fy_px") ||
      !n.has("cx_px") || !n.has("cy_px"))
    n.fail("needs width, height, fx_px, fy_px, cx_px and cy_px");
  k.width = n.at("width").integer(1, 8192);
  k.height = n.at("height").integer(1, 8192);
  k.fx = n.at("fx_px").number(1.0, 1e5);
  k.fy = n.at("fy_px").number(1.0, 1e5);
  k.cx = n.at("cx_px").number(-k.width, 2.0 * k.width);
  k.cy = n.at("cy_px").number(-k.height, 2.0 * k.height);
  if (allow_distortion && n.has("distortion")) {
    const auto d = n.at("distortion").numbers(4, 5, -100.0, 100.0);
    for (std::size_t i = 0; i < d.size(); ++i) (*distortion)[i] = d[i];
  }
  n.done();
  return k;
}

RigidTransform read_transform(Node& n, double max_translation_m) {
  RigidTransform x;
  if (n.has("rotation")) x.rotation = n.at("rotation").rotation();
  if (n.has("translation_m"))
    x.translation_m = n.at("translation_m").vec3(-max_translation_m, max_translation_m);
  n.done();
  return x;
}

void read_hand(Node& n, HandGeometry& hand) {
  if (n.has("fingers")) {
    const Node fs = n.at("fingers");
    if (!fs.json().is_array() || fs.json().size() != 5)
      fs.fail("must be an array of 5 fingers, thumb first");
    for (std::size_t f = 0; f < 5; ++f) {
      Node fn = fs.item(f);
      FingerGeometry& g = hand.fingers[f];
      if (fn.has("base_m")) g.base_hand_m = fn.at("base_m").vec3(-0.3, 0.3);
      if (fn.has("direction")) g.dir_hand = fn.at("direction").unit3();
      if (fn.has("curl_toward")) g.curl_toward_hand = fn.at("curl_toward").unit3();
      if (fn.has("segments_m")) {
        const auto s = fn.at("segments_m").numbers(3, 3, 0.003, 0.2);
        g.segment_m = {s[0], s[1], s[2]};
      }
      if (fn.has("max_angle_deg")) {
        const auto a = fn.at("max_angle_deg").numbers(3, 3, 0.0, 180.0);
        g.max_angle_rad = {a[0] * kDeg, a[1] * kDeg, a[2] * kDeg};
      }
      fn.done();
    }
  }
  n.done();
}

void read_body(Node& n, BodyDims& b) {
  if (n.has("upper_arm_m")) b.upper_arm_m = n.at("upper_arm_m").number(0.1, 0.6);
  if (n.has("forearm_m")) b.forearm_m = n.at("forearm_m").number(0.1, 0.5);
  if (n.has("ipd_m")) b.ipd_m = n.at("ipd_m").number(0.045, 0.08);
  if (n.has("eyes_in_head_m")) b.p_HeadEyes = n.at("eyes_in_head_m").vec3(-0.3, 0.3);
  if (n.has("forearm_axis_in_wrist")) b.forearm_axis_wrist = n.at("forearm_axis_in_wrist").unit3();
  if (n.has("forearm_axis_from_wrist"))
    b.forearm_axis_from_wrist = n.at("forearm_axis_from_wrist").boolean();
  if (n.has("up")) b.up_world = n.at("up").unit3();
  if (n.has("hands")) {
    Node hands = n.at("hands");
    for (const Side s : kSides) {
      const char* name = s == Side::Left ? "left" : "right";
      if (!hands.has(name)) continue;
      Node h = hands.at(name);
      read_hand(h, b.hands[index_of(s)]);
      b.hands[index_of(s)].left = s == Side::Left;
    }
    hands.done();
  }
  n.done();
}

void read_bodies(Node& n, MarkerBodies& m) {
  const std::pair<const char*, int*> keys[] = {
      {"head", &m.head},
      {"right_hand", &m.right_hand},
      {"right_shoulder", &m.right_shoulder},
      {"left_hand", &m.left_hand},
      {"left_shoulder", &m.left_shoulder},
      {"right_elbow", &m.right_elbow},
      {"left_elbow", &m.left_elbow},
  };
  for (const auto& [key, field] : keys)
    if (n.has(key)) *field = n.at(key).integer(-1, 65535);
  n.done();
  // One body cannot be two parts of the operator.
  for (std::size_t i = 0; i < std::size(keys); ++i)
    for (std::size_t j = i + 1; j < std::size(keys); ++j)
      if (*keys[i].second >= 0 && *keys[i].second == *keys[j].second)
        n.fail(std::string(keys[i].first) + " and " + keys[j].first + " are both body " +
               std::to_string(*keys[i].second));
}

void read_operator(Node& n, Rig& rig) {
  if (n.has("head_to_camera")) {
    Node h = n.at("head_to_camera");
    if (h.has("translation_m")) rig.p_HeadCamera = h.at("translation_m").vec3(-0.5, 0.5);
    if (h.has("rotation")) rig.R_CameraHead = h.at("rotation").rotation();
    h.done();
  }
  if (n.has("bodies")) {
    Node b = n.at("bodies");
    read_bodies(b, rig.bodies);
  }
  if (n.has("hmd_stage_in_natnet")) {
    Node h = n.at("hmd_stage_in_natnet");
    rig.X_NatNetStage = read_transform(h, 20.0);
  }
  if (n.has("body")) {
    Node b = n.at("body");
    read_body(b, rig.body);
  }
  if (n.has("gloves")) {
    Node g = n.at("gloves");
    for (const Side s : kSides) {
      const char* name = s == Side::Left ? "left" : "right";
      if (!g.has(name)) continue;
      Node one = g.at(name);
      GloveRange r;
      if (!one.has("min") || !one.has("max")) one.fail("needs min and max (one per sensor)");
      r.min = one.at("min").numbers(5, 14, -1e6, 1e6);
      r.max = one.at("max").numbers(5, 14, -1e6, 1e6);
      one.done();
      if ((r.min.size() != 5 && r.min.size() != 14) || r.max.size() != r.min.size())
        one.fail("min and max must both hold 5 or 14 numbers (one per sensor), got " +
                 std::to_string(r.min.size()) + " and " + std::to_string(r.max.size()));
      for (std::size_t i = 0; i < r.min.size(); ++i)
        if (!(r.max[i] > r.min[i]))
          one.fail("sensor " + std::to_string(i) + " has max <= min (flat " +
                   std::to_string(r.min[i]) + ", fist " + std::to_string(r.max[i]) + ")");
      rig.glove[index_of(s)] = std::move(r);
    }
    g.done();
  }
  if (n.has("skin_rgb")) {
    const auto c = n.at("skin_rgb").numbers(3, 3, 0, 255);
    for (std::size_t i = 0; i < 3; ++i) rig.skin_rgb[i] = static_cast<int>(std::lround(c[i]));
  }
  if (n.has("display_channels")) {
    Node d = n.at("display_channels");
    for (const Side s : kSides) {
      const char* name = s == Side::Left ? "left" : "right";
      if (!d.has(name)) continue;
      const auto c = d.at(name).numbers(5, 5, 0, 4);
      for (std::size_t f = 0; f < 5; ++f) {
        if (c[f] != std::floor(c[f])) d.at(name).item(f).fail("must be an integer channel");
        rig.display_channel[index_of(s)][f] = static_cast<int>(c[f]);
      }
      for (std::size_t f = 0; f < 5; ++f)
        for (std::size_t g = f + 1; g < 5; ++g)
          if (c[f] == c[g])
            d.at(name).fail("fingers " + std::to_string(f) + " and " + std::to_string(g) +
                            " both drive channel " + std::to_string(static_cast<int>(c[f])));
    }
    d.done();
  }
  n.done();
}

void read_robot_head(Node& n, RobotHead& head) {
  if (n.has("joints")) {
    const Node js = n.at("joints");
    if (!js.json().is_array() || js.json().size() != 3)
      js.fail("must be an array of 3 joints (yaw, pitch, roll)");
    for (std::size_t i = 0; i < 3; ++i) {
      Node jn = js.item(i);
      RobotHeadJoint& j = head.joints[i];
      if (jn.has("name")) j.name = jn.at("name").string();
      if (jn.has("axis")) j.axis = jn.at("axis").unit3();
      if (jn.has("min_deg")) j.min_rad = jn.at("min_deg").number(-180.0, 180.0) * kDeg;
      if (jn.has("max_deg")) j.max_rad = jn.at("max_deg").number(-180.0, 180.0) * kDeg;
      if (jn.has("max_rate_deg_s"))
        j.max_rate_rad_s = jn.at("max_rate_deg_s").number(1.0, kMaxHeadRateDegS) * kDeg;
      if (jn.has("max_accel_deg_s2"))
        j.max_accel_rad_s2 = jn.at("max_accel_deg_s2").number(1.0, kMaxHeadAccelDegS2) * kDeg;
      if (jn.has("servo_id")) j.servo_id = jn.at("servo_id").integer(-1, 252);
      jn.done();
      if (!(j.max_rad > j.min_rad)) jn.fail("max_deg must be above min_deg");
    }
  }
  if (n.has("right_eye_mount")) {
    Node m = n.at("right_eye_mount");
    head.X_LinkRightEye = read_transform(m, 1.0);
  }
  n.done();
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::error_code ec;
    const bool exists = std::filesystem::exists(path, ec);
    throw RigError("rig " + path.string() + ": " +
                   (exists ? "cannot be read (check its permissions)"
                           : "no such file (create one with `telex calibrate ... --out " +
                                 path.string() + "` or from the example in docs/RIG.md)"));
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

nlohmann::json vec_json(const glm::dvec3& v) { return {v.x, v.y, v.z}; }
nlohmann::json rotation_json(const glm::dmat3& r) {
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) rows.push_back({r[0][i], r[1][i], r[2][i]});
  return rows;
}
nlohmann::json intrinsics_json(const Intrinsics& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx_px", k.fx},
          {"fy_px", k.fy},    {"cx_px", k.cx},      {"cy_px", k.cy}};
}

}  // namespace

std::array<RobotHeadJoint, 3> RobotHead::default_joints() {
  // The head base's frame is the right eye camera's at zero angles (x right, y down, z forward):
  // yaw turns about up (-y, positive to the left), pitch about x (positive up), roll about z.
  // Limits of a typical 3-DOF servo head (the paper's head does not publish its own).
  // 1800 deg/s^2 reaches the 180 deg/s in 0.1 s (9 deg of travel): brisk, without the jerk of
  // an unlimited start or stop.
  constexpr double kRate = 180.0 * kDeg, kAccel = 1800.0 * kDeg;
  RobotHeadJoint yaw{"yaw", {0.0, -1.0, 0.0}, -90.0 * kDeg, 90.0 * kDeg, kRate, 1, kAccel};
  RobotHeadJoint pitch{"pitch", {1.0, 0.0, 0.0}, -45.0 * kDeg, 45.0 * kDeg, kRate, 2, kAccel};
  RobotHeadJoint roll{"roll", {0.0, 0.0, 1.0}, -30.0 * kDeg, 30.0 * kDeg, kRate, 3, kAccel};
  return {yaw, pitch, roll};
}

std::optional<double> Rig::baseline_m() const {
  if (!X_RightEyeLeftEye) return std::nullopt;
  return glm::length(X_RightEyeLeftEye->translation_m);
}

Rig parse_rig(std::string_view text, const std::string& origin) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw RigError("rig " + origin + ": not JSON: " + e.what());
  }
  Rig rig;
  Node top(j, "", origin);
  top.expect_object();
  if (top.has("rig_version")) {
    const int v = top.at("rig_version").integer(0, 1000);
    if (v != 1) top.at("rig_version").fail("this build reads version 1, got " + std::to_string(v));
  }
  if (top.has("depth")) {
    Node d = top.at("depth");
    rig.depth = read_intrinsics(d, false, nullptr);
  }
  if (top.has("eyes")) {
    Node eyes = top.at("eyes");
    for (const Side s : kSides) {
      const char* name = s == Side::Left ? "left" : "right";
      if (!eyes.has(name)) continue;
      Node e = eyes.at(name);
      CameraModel m;
      m.k = read_intrinsics(e, true, &m.distortion);
      rig.eye[index_of(s)] = m;
    }
    eyes.done();
  }
  if (top.has("extrinsics")) {
    Node x = top.at("extrinsics");
    if (x.has("right_eye_from_left_eye")) {
      Node t = x.at("right_eye_from_left_eye");
      rig.X_RightEyeLeftEye = read_transform(t, 1.0);
      if (!(glm::length(rig.X_RightEyeLeftEye->translation_m) > 1e-3))
        t.fail("the eyes must be at least 1 mm apart");
    }
    if (x.has("right_eye_from_depth")) {
      Node t = x.at("right_eye_from_depth");
      rig.X_RightEyeDepth = read_transform(t, 1.0);
    }
    if (x.has("depth_pixels")) {
      Node d = x.at("depth_pixels");
      const std::string v = d.string();
      if (v != "ir" && v != "color")
        d.fail(
            "must be \"ir\" (the depth sensor's own pixels) or \"color\" (depth the sensor "
            "registered to its colour camera), got \"" +
            v + "\"");
      rig.depth_pixels = v == "ir" ? DepthPixels::Ir : DepthPixels::Color;
    }
    x.done();
  }
  if (top.has("robot_head")) {
    Node h = top.at("robot_head");
    read_robot_head(h, rig.robot_head);
  }
  if (top.has("operator")) {
    Node o = top.at("operator");
    read_operator(o, rig);
  }
  if (top.has("gravity_grabber")) {
    rig.gravity_grabber = j.at("gravity_grabber");
    if (!rig.gravity_grabber.is_object()) top.at("gravity_grabber").expect_object();
  }
  top.done();
  try {
    rig.body.validate();
  } catch (const std::invalid_argument& e) {
    throw RigError("rig " + origin + ": operator.body: " + e.what());
  }
  return rig;
}

Rig load_rig(const std::filesystem::path& path) {
  Rig rig = parse_rig(read_text(path), path.string());
  rig.path = path;
  return rig;
}

nlohmann::json camera_model_json(const CameraModel& camera) {
  nlohmann::json j = intrinsics_json(camera.k);
  j["distortion"] = camera.distortion;
  return j;
}

nlohmann::json transform_json(const RigidTransform& x) {
  return {{"rotation", rotation_json(x.rotation)}, {"translation_m", vec_json(x.translation_m)}};
}

std::string_view depth_pixels_name(DepthPixels p) { return p == DepthPixels::Ir ? "ir" : "color"; }

nlohmann::json rig_to_json(const Rig& rig) {
  nlohmann::json j;
  j["rig_version"] = 1;
  if (rig.depth) j["depth"] = intrinsics_json(*rig.depth);
  for (const Side s : kSides)
    if (rig.eye[index_of(s)])
      j["eyes"][s == Side::Left ? "left" : "right"] = camera_model_json(*rig.eye[index_of(s)]);
  if (rig.X_RightEyeLeftEye)
    j["extrinsics"]["right_eye_from_left_eye"] = transform_json(*rig.X_RightEyeLeftEye);
  if (rig.X_RightEyeDepth) {
    j["extrinsics"]["right_eye_from_depth"] = transform_json(*rig.X_RightEyeDepth);
    j["extrinsics"]["depth_pixels"] = depth_pixels_name(rig.depth_pixels);
  }
  nlohmann::json joints = nlohmann::json::array();
  for (const RobotHeadJoint& rj : rig.robot_head.joints)
    joints.push_back({{"name", rj.name},
                      {"axis", vec_json(rj.axis)},
                      {"min_deg", rj.min_rad / kDeg},
                      {"max_deg", rj.max_rad / kDeg},
                      {"max_rate_deg_s", rj.max_rate_rad_s / kDeg},
                      {"max_accel_deg_s2", rj.max_accel_rad_s2 / kDeg},
                      {"servo_id", rj.servo_id}});
  j["robot_head"] = {{"joints", joints},
                     {"right_eye_mount", transform_json(rig.robot_head.X_LinkRightEye)}};
  nlohmann::json& op = j["operator"];
  op["head_to_camera"] = {{"translation_m", vec_json(rig.p_HeadCamera)},
                          {"rotation", rotation_json(rig.R_CameraHead)}};
  op["hmd_stage_in_natnet"] = transform_json(rig.X_NatNetStage);
  const MarkerBodies& m = rig.bodies;
  op["bodies"] = {{"head", m.head},
                  {"right_hand", m.right_hand},
                  {"right_shoulder", m.right_shoulder},
                  {"left_hand", m.left_hand},
                  {"left_shoulder", m.left_shoulder},
                  {"right_elbow", m.right_elbow},
                  {"left_elbow", m.left_elbow}};
  const BodyDims& b = rig.body;
  nlohmann::json body = {{"upper_arm_m", b.upper_arm_m},
                         {"forearm_m", b.forearm_m},
                         {"ipd_m", b.ipd_m},
                         {"eyes_in_head_m", vec_json(b.p_HeadEyes)},
                         {"forearm_axis_in_wrist", vec_json(b.forearm_axis_wrist)},
                         {"forearm_axis_from_wrist", b.forearm_axis_from_wrist},
                         {"up", vec_json(b.up_world)}};
  for (const Side s : kSides) {
    nlohmann::json fingers = nlohmann::json::array();
    for (const FingerGeometry& g : b.hands[index_of(s)].fingers)
      fingers.push_back(
          {{"base_m", vec_json(g.base_hand_m)},
           {"direction", vec_json(g.dir_hand)},
           {"curl_toward", vec_json(g.curl_toward_hand)},
           {"segments_m", g.segment_m},
           {"max_angle_deg",
            {g.max_angle_rad[0] / kDeg, g.max_angle_rad[1] / kDeg, g.max_angle_rad[2] / kDeg}}});
    body["hands"][s == Side::Left ? "left" : "right"] = {{"fingers", fingers}};
  }
  op["body"] = body;
  for (const Side s : kSides) {
    const char* name = s == Side::Left ? "left" : "right";
    if (rig.glove[index_of(s)])
      op["gloves"][name] = {{"min", rig.glove[index_of(s)]->min},
                            {"max", rig.glove[index_of(s)]->max}};
    op["display_channels"][name] = rig.display_channel[index_of(s)];
  }
  op["skin_rgb"] = rig.skin_rgb;
  if (!rig.gravity_grabber.is_null()) j["gravity_grabber"] = rig.gravity_grabber;
  return j;
}

void update_rig_file(const std::filesystem::path& path, const nlohmann::json& patch) {
  nlohmann::json j = nlohmann::json::object();
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    const std::string text = read_text(path);
    try {
      j = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
      throw RigError("rig " + path.string() + ": not JSON, not updated: " + e.what());
    }
  } else {
    j["rig_version"] = 1;
  }
  j.merge_patch(patch);
  const std::string text = j.dump(2) + "\n";
  parse_rig(text, path.string() + " (as updated)");  // never write a rig that does not load
  const std::filesystem::path tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw RigError("rig " + path.string() + ": cannot write " + tmp.string());
    out << text;
    out.flush();
    if (!out) throw RigError("rig " + path.string() + ": writing " + tmp.string() + " failed");
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw RigError("rig " + path.string() + ": cannot replace it: " + ec.message());
}

std::optional<std::filesystem::path> rig_path_in_args(int argc, const char* const* argv) {
  std::optional<std::filesystem::path> path;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--") break;
    if (a == "--rig") {
      if (i + 1 >= argc || std::strncmp(argv[i + 1], "--", 2) == 0)
        throw RigError("--rig needs a file (--rig FILE)");
      path = argv[++i];
    } else if (a.starts_with("--rig=")) {
      if (a.size() == 6) throw RigError("--rig needs a file (--rig=FILE)");
      path = std::string(a.substr(6));
    }
  }
  return path;
}

}  // namespace telex
