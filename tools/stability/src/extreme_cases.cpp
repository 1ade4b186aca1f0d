// SPDX-License-Identifier: MIT
// Extreme inputs: holes, NaN/Inf, step edges, teleports, time going backwards, random combinations.
#include "support.h"

namespace telex {

using namespace stability_detail;

namespace {

StabilityCaseResult finish(const char* name, Driver& drv, bool extra_ok,
                           const std::string& extra_criteria, const std::string& note) {
  StabilityCaseResult r = make_result(name, "extreme");
  drv.mon.fill(r);
  r.pass = drv.mon.base_ok(drv.model.params()) && extra_ok;
  r.criteria = base_criteria(drv.model.params()) +
               (extra_criteria.empty() ? std::string() : "; " + extra_criteria);
  r.note = note;
  r.trace = std::move(drv.trace);
  return r;
}

const Intrinsics kExtremeK = kinect_v1_intrinsics(320, 240);
const double kNan = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

glm::dvec3 on_ray(double u, double v, double z) { return back_project(kExtremeK, u, v, z); }

// A flat wall 0.8 m away over the whole image.
cv::Mat1f wall_0p8m() { return cv::Mat1f(kExtremeK.height, kExtremeK.width, 0.8f); }

// Depth 0.5 m left of column 160 and 1.5 m right of it: a 1 m step edge.
cv::Mat1f step_edge_1m() {
  cv::Mat1f depth(kExtremeK.height, kExtremeK.width, 1.5f);
  depth(cv::Rect(0, 0, 160, kExtremeK.height)) = 0.5f;
  return depth;
}

// A plane through (0, 0, 1 m) turned `angle_deg` about the camera's y axis.
cv::Mat1f tilted_plane(double angle_deg) {
  const double a = angle_deg * M_PI / 180.0;
  const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
  return plane_depth(kExtremeK, n, glm::dot(n, glm::dvec3(0, 0, 1.0)));
}

// ---- degenerate depth maps ---------------------------------------------------------------------

StabilityCaseResult all_holes(bool with_trace) {  // nothing to touch anywhere
  const Intrinsics& kin = kExtremeK;
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(cv::Mat1f(kin.height, kin.width, 0.0f), kin);
  drv.warm_up(on_ray(160, 120, 0.5));
  bool any_contact = false;
  for (int i = 0; i < 2000; ++i)
    any_contact |= drv.step(on_ray(100 + i % 120, 120, 0.3 + 0.001 * i)).contact;
  return finish("all-holes", drv, !any_contact && drv.mon.max_force == 0.0,
                "never contact, zero force", "fingertip swept through 2 m of holes");
}

// A lone depth value with no neighbours for a normal.
StabilityCaseResult one_valid_pixel(bool with_trace) {
  const Intrinsics& kin = kExtremeK;
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  cv::Mat1f depth(kin.height, kin.width, 0.0f);
  depth(120, 160) = 0.8f;
  drv.publish(depth, kin);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.82), 500);
  drv.move(on_ray(160, 120, 0.82), on_ray(163, 121, 0.82), 500);
  return finish("one-valid-pixel", drv, true, "",
                "pressed 2 cm into the lone pixel and slid off it");
}

// Depth 0 and the largest representable values (and NaN/Inf/negative in the raw map).
StabilityCaseResult depth_zero_and_max(bool with_trace) {
  const Intrinsics& kin = kExtremeK;
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  cv::Mat1f depth(kin.height, kin.width, 65.535f);  // uint16 max in mm
  for (int v = 0; v < kin.height; ++v)
    for (int u = 0; u < kin.width; ++u) {
      const int c = (u + 3 * v) % 6;
      if (c == 0) depth(v, u) = 0.0f;
      if (c == 1) depth(v, u) = std::numeric_limits<float>::max();
      if (c == 2) depth(v, u) = std::numeric_limits<float>::quiet_NaN();
      if (c == 3) depth(v, u) = -std::numeric_limits<float>::infinity();
    }
  drv.publish(depth, kin);
  drv.warm_up(on_ray(160, 120, 1.0));
  drv.move(on_ray(160, 120, 1.0), on_ray(170, 125, 70.0), 1000);
  drv.move(on_ray(170, 125, 70.0), on_ray(150, 110, 0.5), 1000);
  return finish("depth-0-and-max", drv, true, "",
                "0, 65.535 m, FLT_MAX, NaN, -Inf pixels; pressed to 70 m and back");
}

std::vector<StabilityCaseResult> degenerate_depth_cases(bool with_trace) {
  std::vector<StabilityCaseResult> out;
  out.push_back(all_holes(with_trace));
  out.push_back(one_valid_pixel(with_trace));
  out.push_back(depth_zero_and_max(with_trace));
  return out;
}

// ---- hard geometry -----------------------------------------------------------------------------

// Stroke in contact from the near side over the edge and back.
StabilityCaseResult step_edge(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(step_edge_1m(), kExtremeK);
  drv.warm_up(on_ray(100, 120, 0.45));
  drv.move(on_ray(100, 120, 0.45), on_ray(100, 120, 0.51), 300);
  drv.move(on_ray(100, 120, 0.51), on_ray(220, 120, 0.51), 500);  // off the edge
  drv.move(on_ray(220, 120, 0.51), on_ray(220, 120, 1.51), 500);  // down onto the far wall
  drv.move(on_ray(220, 120, 1.51), on_ray(100, 120, 1.51), 500);  // into the step's side
  const FingertipForce f = drv.step(on_ray(100, 120, 1.51));
  return finish("step-edge-1m", drv, f.p_ModelProxy.z > 1.0,
                "proxy stays on the far side of the step",
                "over a 0.5 m / 1.5 m edge both ways while in contact");
}

// A plane almost edge-on to the camera.
StabilityCaseResult surface_89deg(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(tilted_plane(89.0), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.5));
  drv.move(on_ray(160, 120, 0.5), on_ray(160, 120, 1.2), 1000);
  drv.move(on_ray(160, 120, 1.2), on_ray(100, 150, 1.2), 1000);
  return finish("surface-89deg", drv, true, "", "pressed through a plane at 89 degrees");
}

std::vector<StabilityCaseResult> geometry_cases(bool with_trace) {
  std::vector<StabilityCaseResult> out;
  out.push_back(step_edge(with_trace));
  out.push_back(surface_89deg(with_trace));
  return out;
}

// ---- bad fingertip input -----------------------------------------------------------------------

// 1 m teleport in one tick, into the surface and back out.
StabilityCaseResult teleport(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.805), 100);
  FingertipForce f = drv.step(on_ray(160, 120, 1.805));
  bool proxy_outside = f.p_ModelProxy.z < 0.8;
  for (int i = 0; i < 200; ++i)
    proxy_outside &= drv.step(on_ray(200, 60, 1.805)).p_ModelProxy.z < 0.8;
  drv.step(on_ray(160, 120, 0.3));
  f = drv.step(on_ray(160, 120, 0.3));
  return finish("teleport-1m", drv, proxy_outside && !f.contact,
                "proxy never passes the surface; free after the jump back",
                "1 m jump into the wall, slide, 1.5 m jump out");
}

// NaN and Inf from the tracker mid-contact.
StabilityCaseResult tracker_nan_inf(bool with_trace) {
  HapticParams p;
  Driver drv(p);
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 200);
  FingertipForce f;
  int ticks_to_zero = -1;
  for (int i = 0; i < 400; ++i) {
    const double bad = i % 2 ? kNan : kInf;
    f = drv.step({bad, 0.0, bad});
    if (ticks_to_zero < 0 && glm::length(f.force_N) == 0.0) ticks_to_zero = i + 1;
  }
  const int limit = static_cast<int>(std::ceil(p.fade_out_s / kTickS)) + 1;
  return finish(
      "tracker-nan-inf", drv,
      f.status == FingertipStatus::TrackingLost && ticks_to_zero > 0 && ticks_to_zero <= limit,
      "force reaches zero within fade_out_s",
      "zero after " + std::to_string(ticks_to_zero) + " ticks");
}

StabilityCaseResult outside_image(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  // Leave the image in front of the wall, then go deeper than the wall outside the image.
  drv.move(on_ray(160, 120, 0.7), on_ray(-50, 120, 0.7), 200);
  bool any_contact = false;
  for (int i = 0; i < 1000; ++i)
    any_contact |= drv.step(on_ray(-50.0 - i, 120, 0.7 + 0.0002 * i)).contact;
  return finish("outside-image", drv, !any_contact && drv.mon.max_force == 0.0,
                "never contact, zero force",
                "left the image in front of the wall, then went 20 cm deeper outside it");
}

std::vector<StabilityCaseResult> fingertip_cases(bool with_trace) {
  std::vector<StabilityCaseResult> out;
  out.push_back(teleport(with_trace));
  out.push_back(tracker_nan_inf(with_trace));
  out.push_back(outside_image(with_trace));
  return out;
}

// ---- bad timing --------------------------------------------------------------------------------

// Surfaces arriving out of order: older frames must be ignored.
StabilityCaseResult surfaces_out_of_order(bool with_trace) {
  const Intrinsics& kin = kExtremeK;
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.republish = false;
  const cv::Mat1f near(kin.height, kin.width, 0.6f), far(kin.height, kin.width, 0.8f);
  drv.surface = snapshot(far, kin, 0, 100);
  drv.warm_up(on_ray(160, 120, 0.5));
  std::uint64_t id = 100;
  bool touched_old = false;
  for (int i = 0; i < 1000; ++i) {
    if (i % 33 == 0) {
      ++id;
      drv.surface = snapshot(far, kin, drv.now_ns, id);
    } else if (i % 33 == 10) {
      drv.surface = snapshot(near, kin, drv.now_ns, id - 50);  // a late, older frame
    }
    touched_old |= drv.step(on_ray(160, 120, 0.7)).contact;
  }
  const auto& c = drv.model.counters();
  return finish("surfaces-out-of-order", drv, !touched_old && c.surfaces_out_of_order > 0,
                "older frames ignored and counted",
                std::to_string(c.surfaces_out_of_order) + " late frames ignored");
}

// The stream stops; forces must ramp to zero.
StabilityCaseResult stale_surface(bool with_trace) {
  HapticParams p;
  Driver drv(p);
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
  drv.republish = false;
  const std::int64_t stop_ns = drv.surface->capture_ns;
  FingertipForce f;
  std::int64_t zero_at = -1;
  for (int i = 0; i < 600; ++i) {
    f = drv.step(on_ray(160, 120, 0.81));
    if (zero_at < 0 && glm::length(f.force_N) == 0.0) zero_at = drv.now_ns;
  }
  const double t_zero = zero_at < 0 ? 1e9 : (zero_at - stop_ns) * 1e-9;
  return finish("stale-surface", drv,
                t_zero <= p.stale_limit_s + p.fade_out_s + 2 * kTickS &&
                    f.status == FingertipStatus::StaleSurface,
                "zero force within stale_limit_s + fade_out_s of the last frame",
                "zero " + fmt_num(t_zero) + " s after the last frame");
}

// Timestamps going backwards mid-contact.
StabilityCaseResult time_backwards(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
  for (int i = 0; i < 200; ++i)
    drv.step(on_ray(160, 120, 0.81), true, i % 20 == 0 ? -500 * kTickNs : kTickNs);
  return finish("time-backwards", drv, drv.model.counters().time_backwards == 10,
                "every backwards step counted",
                std::to_string(drv.model.counters().time_backwards) + " backwards steps of 0.5 s");
}

// A 1 s gap between two ticks while in contact (the surface is re-sent during the gap).
StabilityCaseResult gap_1s(bool with_trace) {
  Driver drv{HapticParams{}};
  drv.record = with_trace;
  drv.publish(wall_0p8m(), kExtremeK);
  drv.warm_up(on_ray(160, 120, 0.7));
  drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
  drv.surface = restamp(drv.surface, drv.now_ns + 1'000'000'000, ++drv.frame_id);
  drv.step(on_ray(180, 120, 0.83), true, 1'000'000'000);
  for (int i = 0; i < 100; ++i) drv.step(on_ray(180, 120, 0.83));
  return finish("gap-1s", drv, drv.model.counters().long_gaps == 1, "gap counted",
                "1 s without ticks, fingertip moved 2 cm meanwhile");
}

std::vector<StabilityCaseResult> timing_cases(bool with_trace) {
  std::vector<StabilityCaseResult> out;
  out.push_back(surfaces_out_of_order(with_trace));
  out.push_back(stale_surface(with_trace));
  out.push_back(time_backwards(with_trace));
  out.push_back(gap_1s(with_trace));
  return out;
}

// ---- random combinations -----------------------------------------------------------------------

// The scenes the random walk switches between: wall, 60-degree plane, step, sphere, 30 % holes,
// one pixel, all holes.
std::vector<std::shared_ptr<const Surface>> random_scenes() {
  const Intrinsics& kin = kExtremeK;
  std::vector<cv::Mat1f> scenes;
  scenes.push_back(wall_0p8m());
  scenes.push_back(tilted_plane(60.0));
  scenes.push_back(step_edge_1m());
  scenes.push_back(sphere_depth(kin, {0.0, 0.0, 0.7}, 0.15, 1.2));
  {
    cv::Mat1f s(kin.height, kin.width, 0.9f);
    cv::RNG r(3);
    cv::Mat1f holes(s.size());
    r.fill(holes, cv::RNG::UNIFORM, 0.0, 1.0);
    s.setTo(0.0f, holes < 0.3);
    scenes.push_back(s);
  }
  {
    cv::Mat1f s(kin.height, kin.width, 0.0f);
    s(120, 160) = 0.8f;
    scenes.push_back(s);
  }
  scenes.emplace_back(kin.height, kin.width, 0.0f);
  std::vector<std::shared_ptr<const Surface>> built;
  for (const auto& s : scenes) built.push_back(snapshot(s, kin, 0, 1));
  return built;
}

// One random walk; every draw from `rng` in a fixed order so a seed replays the same run.
struct RandomWalk {
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> uni{0.0, 1.0};
  std::normal_distribution<double> step{0.0, 0.002};
  std::vector<std::shared_ptr<const Surface>> built = random_scenes();
  std::size_t scene = 0;
  glm::dvec3 x{0.0, 0.0, 0.6};

  explicit RandomWalk(std::uint64_t seed) : rng(seed) {}

  // Mostly one tick; now and then time going backwards or a long gap.
  std::int64_t next_dt_ns() {
    const double r = uni(rng);
    std::int64_t dt = kTickNs;
    if (r < 0.001)
      dt = -static_cast<std::int64_t>(uni(rng) * 5e8);
    else if (r < 0.0015)
      dt = static_cast<std::int64_t>(uni(rng) * 1e9);
    return dt;
  }

  void maybe_new_frame(Driver& drv, std::int64_t dt) {
    if (uni(rng) < 0.002) scene = static_cast<std::size_t>(uni(rng) * built.size()) % built.size();
    if (drv.now_ns + dt - drv.surface->capture_ns >= kFrameNs || uni(rng) < 0.001) {
      // Mostly in order; now and then a late (older) frame id, or a frame that is already stale.
      const bool late = uni(rng) < 0.05;
      const std::int64_t cap = uni(rng) < 0.01 ? drv.now_ns - 400'000'000 : drv.now_ns + dt;
      drv.surface = restamp(built[scene], cap, late ? drv.frame_id - 3 : ++drv.frame_id);
    }
  }

  // A small random step, kept in front of the camera; now and then a jump anywhere.
  void move_fingertip() {
    const double t = uni(rng);
    if (t < 0.005) {
      x = {uni(rng) * 4 - 2, uni(rng) * 3 - 1.5, uni(rng) * 3.5 - 0.5};
    } else {
      x += glm::dvec3(step(rng), step(rng), step(rng));
      x.z = std::clamp(x.z, 0.2, 2.0);
      x.x = std::clamp(x.x, -0.6, 0.6);
      x.y = std::clamp(x.y, -0.45, 0.45);
    }
  }

  // The fingertip as the tracker reports it: now and then NaN, -Inf or not tracked.
  void feed(Driver& drv, std::int64_t dt) {
    glm::dvec3 fed = x;
    bool tracked = true;
    const double q = uni(rng);
    if (q < 0.0005)
      fed.x = kNan;
    else if (q < 0.001)
      fed.z = -kInf;
    else if (q < 0.0015)
      tracked = false;
    drv.step(fed, tracked, dt);
  }
};

StabilityCaseResult random_combinations(std::uint64_t random_ticks, std::uint64_t seed,
                                        bool with_trace) {
  HapticParams p;
  p.startup_ramp_s = 0.2;  // keep most of the run at full gain
  Driver drv(p);
  drv.record = with_trace;
  RandomWalk walk(seed);
  drv.republish = false;
  drv.surface = restamp(walk.built[0], 0, ++drv.frame_id);
  for (std::uint64_t i = 0; i < random_ticks; ++i) {
    const std::int64_t dt = walk.next_dt_ns();
    walk.maybe_new_frame(drv, dt);
    walk.move_fingertip();
    walk.feed(drv, dt);
  }
  const auto& c = drv.model.counters();
  std::ostringstream note;
  note << random_ticks << " ticks over " << walk.built.size() << " surfaces; " << c.time_backwards
       << " backwards, " << c.long_gaps << " gaps, " << c.surfaces_out_of_order << " late frames, "
       << c.nonfinite_inputs << " NaN/Inf inputs, " << c.clamped << " clamped";
  return finish("random-combinations", drv, drv.mon.ticks == random_ticks, "", note.str());
}

void append(std::vector<StabilityCaseResult>& out, std::vector<StabilityCaseResult> group) {
  for (auto& r : group) out.push_back(std::move(r));
}

}  // namespace

std::vector<StabilityCaseResult> extreme_cases(std::uint64_t random_ticks, std::uint64_t seed,
                                               bool with_trace) {
  std::vector<StabilityCaseResult> out = degenerate_depth_cases(with_trace);
  append(out, geometry_cases(with_trace));
  append(out, fingertip_cases(with_trace));
  append(out, timing_cases(with_trace));
  out.push_back(random_combinations(random_ticks, seed, with_trace));
  return out;
}

}  // namespace telex
