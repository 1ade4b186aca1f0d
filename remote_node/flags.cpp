// SPDX-License-Identifier: MIT
// telex-remote's registration flags: text -> RegistrationConfig.
#include "flags.h"

#include <fmt/format.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace telex::remote {

RegisterMode parse_register_mode(std::string_view text) {
  if (text == "none") return RegisterMode::None;
  if (text == "shift") return RegisterMode::Shift;
  if (text == "full") return RegisterMode::Full;
  throw std::invalid_argument("registration mode '" + std::string(text) +
                              "' is not one of none, shift, full");
}

namespace {

std::vector<double> parse_numbers(std::string_view text, std::size_t count, const char* flag,
                                  const char* form) {
  std::vector<double> out;
  std::string item;
  const std::string all(text);
  std::size_t start = 0;
  while (start <= all.size()) {
    const std::size_t comma = std::min(all.find(',', start), all.size());
    item = all.substr(start, comma - start);
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || !std::isfinite(v))
      throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
    out.push_back(v);
    start = comma + 1;
  }
  if (out.size() != count)
    throw std::invalid_argument(std::string(flag) + " '" + all + "' is not " + form);
  return out;
}

}  // namespace

RegistrationConfig parse_registration(std::string_view mode, std::string_view eye_centre_m,
                                      std::string_view rotation_deg, std::string_view eye,
                                      double nominal_depth_m) {
  RegistrationConfig c;
  c.mode = parse_register_mode(mode);
  const auto centre = parse_numbers(eye_centre_m, 3, "--register-baseline", "X,Y,Z in metres");
  const auto rot = parse_numbers(rotation_deg, 3, "--register-rotation", "RX,RY,RZ in degrees");
  const double k = std::numbers::pi / 180.0;
  const glm::dmat3 rx(1, 0, 0, 0, std::cos(rot[0] * k), std::sin(rot[0] * k), 0,
                      -std::sin(rot[0] * k), std::cos(rot[0] * k));
  const glm::dmat3 ry(std::cos(rot[1] * k), 0, -std::sin(rot[1] * k), 0, 1, 0, std::sin(rot[1] * k),
                      0, std::cos(rot[1] * k));
  const glm::dmat3 rz(std::cos(rot[2] * k), std::sin(rot[2] * k), 0, -std::sin(rot[2] * k),
                      std::cos(rot[2] * k), 0, 0, 0, 1);
  // The eye's axes, seen from the depth camera, are the depth camera's turned by R; a depth-frame
  // point p is at R^T (p - C) in the eye's frame.
  const glm::dmat3 r = rz * ry * rx;
  const glm::dvec3 c_m(centre[0], centre[1], centre[2]);
  c.X_EyeDepth.rotation = glm::transpose(r);
  c.X_EyeDepth.translation_m = -(glm::transpose(r) * c_m);
  if (!eye.empty()) {
    const auto e = parse_numbers(eye, 6, "--register-eye", "FX,FY,CX,CY,W,H in pixels");
    if (!(e[0] > 0 && e[1] > 0 && e[4] >= 1 && e[5] >= 1 && e[4] <= 8192 && e[5] <= 8192 &&
          e[4] == std::floor(e[4]) && e[5] == std::floor(e[5])))
      throw std::invalid_argument("--register-eye '" + std::string(eye) +
                                  "': FX, FY must be > 0 and W, H whole numbers 1..8192");
    c.eye = Intrinsics{e[0], e[1], e[2], e[3], static_cast<int>(e[4]), static_cast<int>(e[5])};
  }
  if (!(nominal_depth_m > 0) || !std::isfinite(nominal_depth_m))
    throw std::invalid_argument("--register-nominal must be > 0 m");
  c.nominal_depth_m = nominal_depth_m;
  return c;
}

void apply_rig(const Rig& rig, const RegistrationFlagsGiven& given, RegistrationConfig& reg) {
  if (rig.depth) reg.depth = rig.depth;
  if (rig.eye[index_of(Side::Right)] && !given.eye) reg.eye = rig.eye[index_of(Side::Right)]->k;
  if (rig.X_RightEyeDepth) {
    if (!given.centre) reg.X_EyeDepth.translation_m = rig.X_RightEyeDepth->translation_m;
    if (!given.rotation) reg.X_EyeDepth.rotation = rig.X_RightEyeDepth->rotation;
    if (!given.mode) reg.mode = RegisterMode::Full;
  }
}

namespace {

// The eye centre X,Y,Z in the depth camera's frame (the inverse of parse_registration's).
std::string eye_centre_text(const RigidTransform& X_EyeDepth) {
  const glm::dvec3 c = -(glm::transpose(X_EyeDepth.rotation) * X_EyeDepth.translation_m);
  return fmt::format("{:.4f},{:.4f},{:.4f}", c.x, c.y, c.z);
}

std::string intrinsics_text(const Intrinsics& k) {
  return fmt::format("{:.2f},{:.2f},{:.2f},{:.2f},{},{}", k.fx, k.fy, k.cx, k.cy, k.width,
                     k.height);
}

}  // namespace

void show_rig_defaults(CLI::App& app, const Rig& rig) {
  const auto set = [&](const char* flag, const std::string& text) {
    if (CLI::Option* opt = app.get_option_no_throw(flag)) opt->default_str(text + " (rig)");
  };
  if (rig.eye[index_of(Side::Right)]) set("--register-eye", intrinsics_text(rig.eye[1]->k));
  if (rig.X_RightEyeDepth) {
    set("--register", "full");
    set("--register-baseline", eye_centre_text(*rig.X_RightEyeDepth));
    set("--register-rotation", "the rig's extrinsics.right_eye_from_depth");
  }
}

std::string describe_rig(const Rig& rig) {
  std::string text = "rig " + rig.path.string() + ":";
  if (rig.depth) text += " depth " + intrinsics_text(*rig.depth) + ";";
  if (rig.eye[index_of(Side::Right)])
    text += " right eye " + intrinsics_text(rig.eye[index_of(Side::Right)]->k) + ";";
  if (rig.X_RightEyeDepth)
    text += " eye centre in depth frame " + eye_centre_text(*rig.X_RightEyeDepth) + " m;";
  text += " robot head joints and limits";
  return text;
}

}  // namespace telex::remote
