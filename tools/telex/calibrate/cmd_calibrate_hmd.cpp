// SPDX-License-Identifier: MIT
// `telex calibrate hmd`: the headset's OpenXR STAGE space in the NatNet frame from a CSV of
// moments seen by both (the headset's view pose and the head marker body's), written into a rig
// file as operator.hmd_stage_in_natnet. Registered by cmd_calibrate.cpp.
#include <algorithm>
#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <vector>

#include "calibrate_cli.h"
#include "calibrate_report.h"
#include "command.h"
#include "telex/calib/hmd.h"
#include "telex/common/rig.h"

namespace telex::tool {
namespace {

struct HmdOptions {
  std::string poses, rig, out;
  double min_axis_spread_deg = 15.0;
  double max_rms_mm = 10.0, max_rms_deg = 2.0;
  bool json = false;
};

// Text output lists every pose up to this many, else the worst of them (all are in --json).
constexpr std::size_t kListedPoses = 40;

// operator.head_to_camera (the eye camera in the head body's frame) re-expressed in the headset's
// view frame, which stands for the head body's under --head-source hmd.
RigidTransform camera_in_view(const Rig& rig, const RigidTransform& X_BodyView) {
  const RigidTransform X_BodyCamera{glm::transpose(rig.R_CameraHead), rig.p_HeadCamera};
  return calib::compose(calib::inverse(X_BodyView), X_BodyCamera);
}

nlohmann::json transform_report(const RigidTransform& x) {
  nlohmann::json j = transform_json(x);
  j["rotation_deg"] = rotation_vector_deg(x.rotation);
  return j;
}

void print_json(const std::vector<calib::HmdPoseSample>& poses, const calib::HmdCalibration& c,
                const RigidTransform& X_ViewCamera, const std::string& out) {
  nlohmann::json residuals = nlohmann::json::array();
  for (std::size_t i = 0; i < poses.size(); ++i)
    residuals.push_back({{"line", poses[i].line},
                         {"time_s", poses[i].t_s},
                         {"position_mm", c.position_mm[i]},
                         {"rotation_deg", c.rotation_deg[i]}});
  const glm::dmat3 R_CameraView = glm::transpose(X_ViewCamera.rotation);
  nlohmann::json j{{"poses", poses.size()},

                   {"max_turn_deg", c.max_turn_deg},
                   {"axis_spread_deg", c.axis_spread_deg},
                   {"hmd_stage_in_natnet", transform_report(c.X_NatNetStage)},
                   {"hmd_view_in_head_body", transform_report(c.X_BodyView)},
                   {"head_to_camera_for_hmd",
                    {{"translation_m", vec(X_ViewCamera.translation_m)},
                     {"rotation", transform_json({R_CameraView, glm::dvec3{0.0}})["rotation"]}}},
                   {"rms_position_mm", c.rms_mm},
                   {"rms_rotation_deg", c.rms_deg},
                   {"residuals", residuals},
                   {"rig", out}};
  std::cout << j.dump(2) << "\n";
}

void print_text(const HmdOptions& o, const std::vector<calib::HmdPoseSample>& poses,
                const calib::HmdCalibration& c, const RigidTransform& X_ViewCamera,
                const std::string& out) {
  std::printf("%zu poses from %s: the head turned up to %.1f deg, about axes spread %.1f deg\n",
              poses.size(), o.poses.c_str(), c.max_turn_deg, c.axis_spread_deg);
  const auto line = [](const char* what, const RigidTransform& x, double scale, const char* unit) {
    const auto r = rotation_vector_deg(x.rotation);
    std::printf("%s: translation (%.1f, %.1f, %.1f) %s, rotation vector (%.2f, %.2f, %.2f) deg\n",
                what, x.translation_m.x * scale, x.translation_m.y * scale,
                x.translation_m.z * scale, unit, r[0], r[1], r[2]);
  };
  line("stage in NatNet (operator.hmd_stage_in_natnet)", c.X_NatNetStage, 1e3, "mm");
  line("headset view in the head body (not in the rig)", c.X_BodyView, 1e3, "mm");
  const glm::dvec3 p = X_ViewCamera.translation_m;
  const glm::dmat3 R = glm::transpose(X_ViewCamera.rotation);  // camera from view; glm: [col][row]
  std::printf(
      "  --head-source hmd puts the view frame where the head body's is: operator.head_to_camera "
      "in it would be translation_m (%.4f, %.4f, %.4f), rotation [[%.4f, %.4f, %.4f], [%.4f, "
      "%.4f, %.4f], [%.4f, %.4f, %.4f]]\n",
      p.x, p.y, p.z, R[0][0], R[1][0], R[2][0], R[0][1], R[1][1], R[2][1], R[0][2], R[1][2],
      R[2][2]);
  std::vector<std::size_t> order(poses.size());
  std::iota(order.begin(), order.end(), 0);
  if (poses.size() > kListedPoses) {
    std::partial_sort(
        order.begin(), order.begin() + 10, order.end(),
        [&](std::size_t a, std::size_t b) { return c.position_mm[a] > c.position_mm[b]; });
    order.resize(10);
    std::printf("residuals of the 10 poses farthest off (all %zu with --json):\n", poses.size());
  } else {
    std::printf("residuals per pose:\n");
  }
  for (std::size_t i : order)
    std::printf("  line %d (t %.3f s): %.2f mm, %.3f deg\n", poses[i].line, poses[i].t_s,
                c.position_mm[i], c.rotation_deg[i]);
  std::printf("RMS %.2f mm, %.3f deg\n", c.rms_mm, c.rms_deg);
  std::printf("wrote operator.hmd_stage_in_natnet into %s\n", out.c_str());
}

int run_hmd(const HmdOptions& o) {
  if (o.out.empty() && o.rig.empty()) throw FlagError("give --out RIG (or --rig RIG to update)");
  Rig rig;
  if (!o.rig.empty()) {
    try {
      rig = load_rig(o.rig);
    } catch (const RigError& e) {
      throw FlagError(std::string(e.what()) + " (--rig)");
    }
  }
  const std::string out = o.out.empty() ? o.rig : o.out;
  if (out != o.rig) check_out(out);
  std::vector<calib::HmdPoseSample> poses;
  try {
    poses = calib::load_hmd_poses_csv(o.poses);
  } catch (const calib::PoseCsvError& e) {
    throw FlagError(std::string("--poses: ") + e.what());
  }
  calib::HmdCalibOptions opt;
  opt.min_axis_spread_deg = o.min_axis_spread_deg;
  opt.max_rms_mm = o.max_rms_mm;
  opt.max_rms_deg = o.max_rms_deg;
  const calib::HmdCalibration c = calib::calibrate_hmd(poses, opt);

  nlohmann::json patch;
  patch["operator"]["hmd_stage_in_natnet"] = transform_json(c.X_NatNetStage);
  update_rig_file(out, patch);

  const RigidTransform X_ViewCamera = camera_in_view(rig, c.X_BodyView);
  if (o.json)
    print_json(poses, c, X_ViewCamera, out);
  else
    print_text(o, poses, c, X_ViewCamera, out);
  return 0;
}

}  // namespace

// Adds `hmd` to `telex calibrate`; the returned function runs it when it was parsed and returns
// its exit code, or -1 when it was not.
std::function<int()> add_calibrate_hmd(cli::CommandLine& app) {
  auto ho = std::make_shared<HmdOptions>();
  cli::CommandLine hmd = app.add_subcommand(
      "hmd",
      "the headset's OpenXR STAGE space in the NatNet frame (hand-eye: moments with both the "
      "headset's view pose and the head body's); writes operator.hmd_stage_in_natnet into --out");
  hmd->add_option("--poses", ho->poses,
                  "poses CSV: time_s, the view pose in STAGE (stage_view_x_m..stage_view_qw), "
                  "the head body in NatNet (natnet_head_x_m..natnet_head_qw); docs/RIG.md")
      ->required();
  hmd->add_option("--rig", ho->rig,
                  "rig file to update (its operator.head_to_camera is reported "
                  "in the headset's frame)");
  hmd->add_option("--out", ho->out, "rig file to write (created or updated; default: --rig)");
  hmd->add_option("--min-axis-spread-deg", ho->min_axis_spread_deg,
                  "refuse when the head's turns are about axes spread less than this")
      ->check(cli::Range(1.0, 90.0));
  hmd->add_option("--max-rms-mm", ho->max_rms_mm, "refuse a fit with a larger position RMS")
      ->check(cli::Range(0.1, 1000.0));
  hmd->add_option("--max-rms-deg", ho->max_rms_deg, "refuse a fit with a larger rotation RMS")
      ->check(cli::Range(0.01, 90.0));
  hmd->add_flag("--json", ho->json, "print one JSON object");
  return [=]() -> int {
    if (hmd->parsed()) return guarded("hmd", [&] { return run_hmd(*ho); });
    return -1;
  };
}

}  // namespace telex::tool
