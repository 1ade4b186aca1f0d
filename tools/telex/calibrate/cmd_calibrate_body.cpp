// SPDX-License-Identifier: MIT
// `telex calibrate body|glove`: the operator's arm segment lengths from a T-pose (a tracking CSV or
// live NatNet) and a glove's per-sensor flat-hand and fist values (two CSVs or a live glove),
// written into a rig file. Registered by cmd_calibrate.cpp.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "calibrate_cli.h"
#include "command.h"
#include "telex/calib/operator.h"
#include "telex/common/rig.h"
#include "telex/local/inputs/glove.h"
#include "telex/local/inputs/natnet_client.h"

namespace telex::tool {
namespace {

namespace fs = std::filesystem;
using calib::ArmBodies;
using calib::ArmCalibration;
using calib::TrackingFrame;

// SERVER[,multicast|,unicast][,local=IP][,cmd=PORT][,data=PORT]: the station's natnet: spec.
local::NatNetClientConfig natnet_config(const std::string& spec) {
  local::NatNetClientConfig c;
  c.app_name = "telex calibrate";
  try {
    return local::parse_natnet_spec(spec, "--natnet '" + spec + "'", c);
  } catch (const std::invalid_argument& e) {
    throw FlagError(e.what());
  }
}

// ---- body --------------------------------------------------------------------------------------

struct BodyOptions {
  std::string tracking, natnet, rig, out;
  double seconds = 3.0, settle_s = 2.0;
  // -2 = not given (the rig's or the built-in id); -1 = none.
  int right_shoulder = -2, right_wrist = -2, right_elbow = -2;
  int left_shoulder = -2, left_wrist = -2, left_elbow = -2;
  double max_spread_mm = 10.0;
  int min_samples = 30;
  bool json = false;
};

std::vector<TrackingFrame> record_natnet(const BodyOptions& o, const std::vector<int>& ids) {
  local::NatNetClientConfig cfg = natnet_config(o.natnet);
  if (ids.size() > static_cast<std::size_t>(local::NatNetSample::kMaxBodies))
    throw FlagError(fmt::format("{} bodies asked for; NatNet publishes at most {}", ids.size(),
                                local::NatNetSample::kMaxBodies));
  cfg.body_ids.assign(ids.begin(), ids.end());
  local::NatNetClient client(cfg);
  std::fprintf(stderr,
               "telex calibrate body: stand in a T-pose (arms straight out to the sides, palms "
               "down); recording %.1f s in %.1f s\n",
               o.seconds, o.settle_s);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(o.settle_s));
  const auto end =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.seconds));
  bool announced = false;
  std::vector<TrackingFrame> frames;
  local::NatNetSample s;
  while (Clock::now() < end) {
    if (client.latest(s) && Clock::now() >= start) {
      if (!announced) {
        std::fprintf(stderr, "telex calibrate body: recording, hold still\n");
        announced = true;
      }
      TrackingFrame f;
      f.t_s = s.timestamp_s;
      for (const auto& b : s.bodies)
        if (b.valid) f.p_World_m[b.id] = b.pose.p_m;
      frames.push_back(std::move(f));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  if (frames.empty()) {
    const local::NatNetClientStats st = client.stats();
    throw std::runtime_error(fmt::format(
        "no frames from the NatNet server {} in {:.1f} s ({} datagrams, {} parse errors{}{}): is "
        "Motive streaming, to this interface (try unicast)?",
        cfg.server_ip, o.settle_s + o.seconds, st.datagrams, st.parse_errors,
        client.last_error().empty() ? "" : "; last: ", client.last_error()));
  }
  std::fprintf(stderr, "telex calibrate body: %zu frames\n", frames.size());
  return frames;
}

int pick(int flag, int from_rig) { return flag == -2 ? from_rig : flag; }

int run_body(const BodyOptions& o) {
  if (o.tracking.empty() == o.natnet.empty())
    throw FlagError("give exactly one of --tracking FILE and --natnet SERVER");
  if (o.out.empty() && o.rig.empty()) throw FlagError("give --out RIG (or --rig RIG to update)");
  Rig rig;
  if (!o.rig.empty()) {
    try {
      rig = load_rig(o.rig);
    } catch (const RigError& e) {
      throw FlagError(e.what());
    }
  }
  const std::string out = o.out.empty() ? o.rig : o.out;
  if (out != o.rig) check_out(out);
  struct Side {
    const char* name;
    ArmBodies bodies;
  };
  const MarkerBodies& m = rig.bodies;
  std::vector<Side> sides;
  const ArmBodies right{pick(o.right_shoulder, m.right_shoulder), pick(o.right_wrist, m.right_hand),
                        pick(o.right_elbow, m.right_elbow), -1};
  const ArmBodies left{pick(o.left_shoulder, m.left_shoulder), pick(o.left_wrist, m.left_hand),
                       pick(o.left_elbow, m.left_elbow), -1};
  if (right.shoulder >= 0 && right.wrist >= 0) sides.push_back({"right", right});
  if (left.shoulder >= 0 && left.wrist >= 0) sides.push_back({"left", left});
  if (sides.empty())
    throw FlagError(
        "no arm has both a shoulder and a wrist body: set operator.bodies in --rig or give "
        "--right-shoulder and --right-wrist (or the left ones)");
  if (sides.size() == 2) {
    sides[0].bodies.other_shoulder = left.shoulder;
    sides[1].bodies.other_shoulder = right.shoulder;
  }
  std::vector<int> ids;
  for (const Side& s : sides)
    for (int id : {s.bodies.shoulder, s.bodies.wrist, s.bodies.elbow})
      if (id >= 0 && std::find(ids.begin(), ids.end(), id) == ids.end()) ids.push_back(id);

  const std::vector<TrackingFrame> frames =
      o.tracking.empty() ? record_natnet(o, ids) : calib::load_tracking_csv(o.tracking);
  calib::BodyCalibOptions opt;
  opt.max_spread_m = o.max_spread_mm * 1e-3;
  opt.min_samples = o.min_samples;
  std::vector<ArmCalibration> arms;
  for (const Side& s : sides) arms.push_back(calib::calibrate_arm(frames, s.bodies, s.name, opt));

  // Both arms measured: their mean (a person's arms differ by millimetres; BodyDims has one).
  double upper = 0, fore = 0, spread = 0;
  int samples = 0, from_elbow = 0;
  for (const auto& a : arms) {
    upper += a.upper_arm_m / static_cast<double>(arms.size());
    fore += a.forearm_m / static_cast<double>(arms.size());
    spread = std::max(spread, a.spread_m);
    samples += a.samples;
    from_elbow += a.from_elbow ? 1 : 0;
  }
  const char* from = from_elbow == static_cast<int>(arms.size()) ? "elbow markers"
                     : from_elbow == 0                           ? "ratio"
                                                                 : "elbow markers and ratio";
  nlohmann::json patch;
  patch["operator"]["body"] = {{"upper_arm_m", upper}, {"forearm_m", fore}};
  update_rig_file(out, patch);

  if (o.json) {
    nlohmann::json j{{"upper_arm_m", upper},
                     {"forearm_m", fore},
                     {"samples", samples},
                     {"spread_m", spread},
                     {"from", from},
                     {"frames", frames.size()},
                     {"rig", out}};
    for (const auto& a : arms)
      j["sides"][a.side] = {
          {"upper_arm_m", a.upper_arm_m}, {"forearm_m", a.forearm_m},
          {"reach_m", a.reach_m},         {"spread_m", a.spread_m},
          {"samples", a.samples},         {"from", a.from_elbow ? "elbow markers" : "ratio"}};
    std::cout << j.dump(2) << "\n";
  } else {
    for (const auto& a : arms)
      std::printf(
          "%-5s arm: shoulder to wrist %.1f mm (spread %.1f mm over %d samples): upper arm %.1f "
          "mm, forearm %.1f mm (%s)\n",
          a.side.c_str(), a.reach_m * 1e3, a.spread_m * 1e3, a.samples, a.upper_arm_m * 1e3,
          a.forearm_m * 1e3, a.from_elbow ? "elbow marker" : "Drillis & Contini ratio");
    std::printf("wrote operator.body.upper_arm_m = %.4f, forearm_m = %.4f into %s\n", upper, fore,
                out.c_str());
  }
  return 0;
}

// ---- glove -------------------------------------------------------------------------------------

struct GloveOptions {
  std::string flat, fist, glove, side, out;
  int sensors = 0;
  double seconds = 3.0, settle_s = 2.0;
  double min_range_pct = 5.0;
  bool json = false;
};

// The device hands out bends, not raw values: opened with the full range 0..1 (no calibration
// file, no rig range), a bend is the parsed sensor value clamped to 0..1, which is the parsed
// range of both 5DT formats. A 14-sensor glove's near and far knuckle sensors are the MCP and PIP
// bends; its abduction sensors are not published (they are unused) and stay 0 here.
calib::GloveCapture record_phase(local::GloveDevice& glove, int sensors, const char* prompt,
                                 const GloveOptions& o) {
  std::fprintf(stderr, "telex calibrate glove: %s; recording %.1f s in %.1f s\n", prompt, o.seconds,
               o.settle_s);
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                        std::chrono::duration<double>(o.settle_s));
  const auto end =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.seconds));
  calib::GloveCapture c;
  c.sensor_count = sensors;
  local::GloveSample s;
  while (Clock::now() < end) {
    if (glove.latest(s) && Clock::now() >= start) {
      std::array<double, 14> row{};
      for (int f = 0; f < 5; ++f) {
        const auto& j = s.joints[static_cast<std::size_t>(f)];
        if (sensors == 5) {
          row[static_cast<std::size_t>(f)] = j[0];
        } else {
          row[static_cast<std::size_t>(3 * f)] = j[0];
          row[static_cast<std::size_t>(3 * f + 1)] = j[1];
        }
      }
      c.rows.push_back(row);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  std::fprintf(stderr, "telex calibrate glove: %zu reports\n", c.rows.size());
  return c;
}

int run_glove(const GloveOptions& o) {
  const bool files = !o.flat.empty() || !o.fist.empty();
  if (files == !o.glove.empty())
    throw FlagError("give either --flat FILE and --fist FILE, or --glove SPEC");
  if (files && (o.flat.empty() || o.fist.empty()))
    throw FlagError("give both --flat FILE (hand held flat) and --fist FILE (a fist)");
  if (!o.glove.empty() && o.sensors != 5 && o.sensors != 14)
    throw FlagError("--glove needs --sensors 5 or 14 (the glove's model)");
  check_out(o.out);
  calib::GloveCapture flat, fist;
  std::string input;
  if (files) {
    flat = calib::load_glove_csv(o.flat);
    fist = calib::load_glove_csv(o.fist);
    input = o.flat + ", " + o.fist;
  } else {
    std::unique_ptr<local::GloveDevice> glove;
    try {
      glove = local::open_glove(o.glove, "", std::nullopt);
    } catch (const std::invalid_argument& e) {
      throw FlagError(e.what());
    }
    input = glove->name();
    flat = record_phase(*glove, o.sensors, "hold the hand flat (fingers straight and together)", o);
    fist = record_phase(*glove, o.sensors, "make a fist (thumb over the fingers)", o);
  }
  calib::GloveCalibOptions opt;
  opt.min_range_fraction = o.min_range_pct / 100.0;
  const calib::GloveCalibResult r = calib::calibrate_glove(flat, fist, opt);

  nlohmann::json patch;
  patch["operator"]["gloves"][o.side] = {{"min", r.range.min}, {"max", r.range.max}};
  update_rig_file(o.out, patch);

  const int n = flat.sensor_count;
  if (o.json) {
    nlohmann::json j{{"side", o.side},
                     {"sensors", n},
                     {"min", r.range.min},
                     {"max", r.range.max},
                     {"flat_reports", flat.rows.size()},
                     {"fist_reports", fist.rows.size()},
                     {"full_range_sensors", r.full_range_sensors},
                     {"rig", o.out}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("%d sensors from %s (%zu flat, %zu fist reports)\n", n, input.c_str(),
                flat.rows.size(), fist.rows.size());
    for (int i = 0; i < n; ++i) {
      const bool full = std::find(r.full_range_sensors.begin(), r.full_range_sensors.end(), i) !=
                        r.full_range_sensors.end();
      std::printf("  %2d %-26s min %.4f max %.4f%s\n", i, calib::glove_sensor_name(n, i).c_str(),
                  r.range.min[static_cast<std::size_t>(i)],
                  r.range.max[static_cast<std::size_t>(i)],
                  full ? "  (unused, did not move: full range)" : "");
    }
    std::printf("wrote operator.gloves.%s into %s\n", o.side.c_str(), o.out.c_str());
  }
  return 0;
}

}  // namespace

// Adds `body` and `glove` to `telex calibrate`; the returned function runs whichever was parsed
// and returns its exit code, or -1 when neither was.
std::function<int()> add_calibrate_operator(cli::CommandLine& app) {
  auto bo = std::make_shared<BodyOptions>();
  cli::CommandLine body = app.add_subcommand(
      "body",
      "the operator's upper arm and forearm lengths from a few seconds of T-pose (a tracking "
      "CSV or live NatNet); writes operator.body.upper_arm_m and forearm_m into --out");
  body->add_option("--tracking", bo->tracking,
                   "tracking CSV: telex-local --log-tracking, or a NatNet recording");
  body->add_option("--natnet", bo->natnet,
                   "live Motive server: SERVER[,unicast][,local=IP][,cmd=PORT][,data=PORT]");
  body->add_option("--seconds", bo->seconds, "live: how long to record")
      ->check(cli::Range(0.5, 60.0));
  body->add_option("--settle-s", bo->settle_s, "live: time to take the pose before recording")
      ->check(cli::Range(0.0, 30.0));
  body->add_option("--rig", bo->rig, "rig file whose operator.bodies name the marker bodies");
  body->add_option("--out", bo->out, "rig file to write (created or updated; default: --rig)");
  for (auto [flag, id] :
       {std::pair{"--right-shoulder", &bo->right_shoulder},
        std::pair{"--right-wrist", &bo->right_wrist}, std::pair{"--right-elbow", &bo->right_elbow},
        std::pair{"--left-shoulder", &bo->left_shoulder},
        std::pair{"--left-wrist", &bo->left_wrist}, std::pair{"--left-elbow", &bo->left_elbow}})
    body->add_option(flag, *id, "rigid body id, overriding the rig's (-1: not tracked)")
        ->check(cli::Range(-1, 1 << 30));
  body->add_option("--max-spread-mm", bo->max_spread_mm,
                   "reject when the shoulder-to-wrist distance spreads more (10th-90th percentile)")
      ->check(cli::Range(0.1, 200.0));
  body->add_option("--min-samples", bo->min_samples, "fewest frames with every body valid")
      ->check(cli::Range(3, 1000000));
  body->add_flag("--json", bo->json, "print one JSON object");

  auto go = std::make_shared<GloveOptions>();
  cli::CommandLine glove = app.add_subcommand(
      "glove",
      "a data glove's per-sensor range: the flat hand's values (min) and the fist's (max); "
      "writes operator.gloves.SIDE into --out");
  glove->add_option("--flat", go->flat,
                    "raw-glove CSV taken with the hand flat: time_s, then one value per sensor");
  glove->add_option("--fist", go->fist, "raw-glove CSV taken with the hand in a fist");
  glove->add_option("--glove", go->glove,
                    "live glove: 5dt-usb[:HIDPATH] | 5dt-serial:DEV[,wireless] (prompts on "
                    "stderr)");
  glove->add_option("--sensors", go->sensors, "live: the glove's sensor count (5 or 14)")
      ->check(cli::IsMember({5, 14}));
  glove->add_option("--side", go->side, "which hand")
      ->required()
      ->check(cli::IsMember({"right", "left"}));
  glove->add_option("--out", go->out, "rig file to write (created or updated)")->required();
  glove->add_option("--seconds", go->seconds, "live: how long each phase records")
      ->check(cli::Range(0.5, 60.0));
  glove->add_option("--settle-s", go->settle_s, "live: time to take each pose before recording")
      ->check(cli::Range(0.0, 30.0));
  glove
      ->add_option("--min-range-pct", go->min_range_pct,
                   "a sensor must move at least this percentage of full scale")
      ->check(cli::Range(0.1, 90.0));
  glove->add_flag("--json", go->json, "print one JSON object");

  return [=]() -> int {
    if (body->parsed()) return guarded("body", [&] { return run_body(*bo); });
    if (glove->parsed()) return guarded("glove", [&] { return run_glove(*go); });
    return -1;
  };
}

}  // namespace telex::tool
