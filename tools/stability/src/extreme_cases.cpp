// SPDX-License-Identifier: MIT
// Extreme inputs: holes, NaN/Inf, step edges, teleports, time going backwards, random combinations.
#include "support.h"

namespace telex {

using namespace stability_detail;

namespace {

// Common frame of an extreme case: default parameters, a scene, a scripted fingertip.
struct Extreme {
  HapticParams params;
  Driver drv;
  Extreme() : drv(params) {}
};

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

glm::dvec3 on_ray(double u, double v, double z) { return back_project(kExtremeK, u, v, z); }

}  // namespace

std::vector<StabilityCaseResult> extreme_cases(std::uint64_t random_ticks, std::uint64_t seed,
                                               bool with_trace) {
  std::vector<StabilityCaseResult> out;
  const Intrinsics& kin = kExtremeK;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();

  {  // All holes: nothing to touch anywhere.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.0f), kin);
    drv.warm_up(on_ray(160, 120, 0.5));
    bool any_contact = false;
    for (int i = 0; i < 2000; ++i)
      any_contact |= drv.step(on_ray(100 + i % 120, 120, 0.3 + 0.001 * i)).contact;
    out.push_back(finish("all-holes", drv, !any_contact && drv.mon.max_force == 0.0,
                         "never contact, zero force", "fingertip swept through 2 m of holes"));
  }
  {  // One valid pixel: a lone depth value with no neighbours for a normal.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    cv::Mat1f depth(kin.height, kin.width, 0.0f);
    depth(120, 160) = 0.8f;
    drv.publish(depth, kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.82), 500);
    drv.move(on_ray(160, 120, 0.82), on_ray(163, 121, 0.82), 500);
    out.push_back(finish("one-valid-pixel", drv, true, "",
                         "pressed 2 cm into the lone pixel and slid off it"));
  }
  {  // Depth 0 and the largest representable values (and NaN/Inf/negative in the raw map).
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
    out.push_back(finish("depth-0-and-max", drv, true, "",
                         "0, 65.535 m, FLT_MAX, NaN, -Inf pixels; pressed to 70 m and back"));
  }
  {  // 1 m step edge: stroke in contact from the near side over the edge and back.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    cv::Mat1f depth(kin.height, kin.width, 1.5f);
    depth(cv::Rect(0, 0, 160, kin.height)) = 0.5f;
    drv.publish(depth, kin);
    drv.warm_up(on_ray(100, 120, 0.45));
    drv.move(on_ray(100, 120, 0.45), on_ray(100, 120, 0.51), 300);
    drv.move(on_ray(100, 120, 0.51), on_ray(220, 120, 0.51), 500);  // off the edge
    drv.move(on_ray(220, 120, 0.51), on_ray(220, 120, 1.51), 500);  // down onto the far wall
    drv.move(on_ray(220, 120, 1.51), on_ray(100, 120, 1.51), 500);  // into the step's side
    const FingertipForce f = drv.step(on_ray(100, 120, 1.51));
    out.push_back(finish("step-edge-1m", drv, f.p_ModelProxy.z > 1.0,
                         "proxy stays on the far side of the step",
                         "over a 0.5 m / 1.5 m edge both ways while in contact"));
  }
  {  // 89-degree surface: a plane almost edge-on to the camera.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    const double a = 89.0 * M_PI / 180.0;
    const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
    drv.publish(plane_depth(kin, n, glm::dot(n, glm::dvec3(0, 0, 1.0))), kin);
    drv.warm_up(on_ray(160, 120, 0.5));
    drv.move(on_ray(160, 120, 0.5), on_ray(160, 120, 1.2), 1000);
    drv.move(on_ray(160, 120, 1.2), on_ray(100, 150, 1.2), 1000);
    out.push_back(finish("surface-89deg", drv, true, "", "pressed through a plane at 89 degrees"));
  }
  {  // 1 m teleport in one tick, into the surface and back out.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.805), 100);
    FingertipForce f = drv.step(on_ray(160, 120, 1.805));
    bool proxy_outside = f.p_ModelProxy.z < 0.8;
    for (int i = 0; i < 200; ++i)
      proxy_outside &= drv.step(on_ray(200, 60, 1.805)).p_ModelProxy.z < 0.8;
    drv.step(on_ray(160, 120, 0.3));
    f = drv.step(on_ray(160, 120, 0.3));
    out.push_back(finish("teleport-1m", drv, proxy_outside && !f.contact,
                         "proxy never passes the surface; free after the jump back",
                         "1 m jump into the wall, slide, 1.5 m jump out"));
  }
  {  // NaN and Inf from the tracker mid-contact.
    HapticParams p;
    Driver drv(p);
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 200);
    FingertipForce f;
    int ticks_to_zero = -1;
    for (int i = 0; i < 400; ++i) {
      const double bad = i % 2 ? nan : inf;
      f = drv.step({bad, 0.0, bad});
      if (ticks_to_zero < 0 && glm::length(f.force_N) == 0.0) ticks_to_zero = i + 1;
    }
    const int limit = static_cast<int>(std::ceil(p.fade_out_s / kTickS)) + 1;
    out.push_back(finish(
        "tracker-nan-inf", drv,
        f.status == FingertipStatus::TrackingLost && ticks_to_zero > 0 && ticks_to_zero <= limit,
        "force reaches zero within fade_out_s",
        "zero after " + std::to_string(ticks_to_zero) + " ticks"));
  }
  {  // Fingertip outside the image.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    // Leave the image in front of the wall, then go deeper than the wall outside the image.
    drv.move(on_ray(160, 120, 0.7), on_ray(-50, 120, 0.7), 200);
    bool any_contact = false;
    for (int i = 0; i < 1000; ++i)
      any_contact |= drv.step(on_ray(-50.0 - i, 120, 0.7 + 0.0002 * i)).contact;
    out.push_back(finish("outside-image", drv, !any_contact && drv.mon.max_force == 0.0,
                         "never contact, zero force",
                         "left the image in front of the wall, then went 20 cm deeper outside it"));
  }
  {  // Surfaces arriving out of order: older frames must be ignored.
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
    out.push_back(finish("surfaces-out-of-order", drv, !touched_old && c.surfaces_out_of_order > 0,
                         "older frames ignored and counted",
                         std::to_string(c.surfaces_out_of_order) + " late frames ignored"));
  }
  {  // Stale surface: the stream stops; forces must ramp to zero.
    HapticParams p;
    Driver drv(p);
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
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
    out.push_back(finish("stale-surface", drv,
                         t_zero <= p.stale_limit_s + p.fade_out_s + 2 * kTickS &&
                             f.status == FingertipStatus::StaleSurface,
                         "zero force within stale_limit_s + fade_out_s of the last frame",
                         "zero " + fmt_num(t_zero) + " s after the last frame"));
  }
  {  // Timestamps going backwards mid-contact.
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
    for (int i = 0; i < 200; ++i)
      drv.step(on_ray(160, 120, 0.81), true, i % 20 == 0 ? -500 * kTickNs : kTickNs);
    out.push_back(
        finish("time-backwards", drv, drv.model.counters().time_backwards == 10,
               "every backwards step counted",
               std::to_string(drv.model.counters().time_backwards) + " backwards steps of 0.5 s"));
  }
  {  // A 1 s gap between two ticks while in contact (the surface is re-sent during the gap).
    Driver drv{HapticParams{}};
    drv.record = with_trace;
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
    drv.surface = restamp(drv.surface, drv.now_ns + 1'000'000'000, ++drv.frame_id);
    drv.step(on_ray(180, 120, 0.83), true, 1'000'000'000);
    for (int i = 0; i < 100; ++i) drv.step(on_ray(180, 120, 0.83));
    out.push_back(finish("gap-1s", drv, drv.model.counters().long_gaps == 1, "gap counted",
                         "1 s without ticks, fingertip moved 2 cm meanwhile"));
  }
  {  // Random fingertips and surfaces.
    HapticParams p;
    p.startup_ramp_s = 0.2;  // keep most of the run at full gain
    Driver drv(p);
    drv.record = with_trace;
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> step(0.0, 0.002);
    std::vector<cv::Mat1f> scenes;
    scenes.emplace_back(kin.height, kin.width, 0.8f);
    {
      const double a = 60.0 * M_PI / 180.0;
      const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
      scenes.push_back(plane_depth(kin, n, glm::dot(n, glm::dvec3(0, 0, 1.0))));
    }
    {
      cv::Mat1f s(kin.height, kin.width, 1.5f);
      s(cv::Rect(0, 0, 160, kin.height)) = 0.5f;
      scenes.push_back(s);
    }
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
    std::size_t scene = 0;
    drv.republish = false;
    drv.surface = restamp(built[0], 0, ++drv.frame_id);
    glm::dvec3 x(0.0, 0.0, 0.6);
    for (std::uint64_t i = 0; i < random_ticks; ++i) {
      const double r = uni(rng);
      std::int64_t dt = kTickNs;
      if (r < 0.001)
        dt = -static_cast<std::int64_t>(uni(rng) * 5e8);
      else if (r < 0.0015)
        dt = static_cast<std::int64_t>(uni(rng) * 1e9);
      if (uni(rng) < 0.002)
        scene = static_cast<std::size_t>(uni(rng) * built.size()) % built.size();
      if (drv.now_ns + dt - drv.surface->capture_ns >= kFrameNs || uni(rng) < 0.001) {
        // Mostly in order; now and then a late (older) frame id, or a frame that is already stale.
        const bool late = uni(rng) < 0.05;
        const std::int64_t cap = uni(rng) < 0.01 ? drv.now_ns - 400'000'000 : drv.now_ns + dt;
        drv.surface = restamp(built[scene], cap, late ? drv.frame_id - 3 : ++drv.frame_id);
      }
      const double t = uni(rng);
      if (t < 0.005) {
        x = {uni(rng) * 4 - 2, uni(rng) * 3 - 1.5, uni(rng) * 3.5 - 0.5};
      } else {
        x += glm::dvec3(step(rng), step(rng), step(rng));
        x.z = std::clamp(x.z, 0.2, 2.0);
        x.x = std::clamp(x.x, -0.6, 0.6);
        x.y = std::clamp(x.y, -0.45, 0.45);
      }
      glm::dvec3 fed = x;
      bool tracked = true;
      const double q = uni(rng);
      if (q < 0.0005)
        fed.x = nan;
      else if (q < 0.001)
        fed.z = -inf;
      else if (q < 0.0015)
        tracked = false;
      drv.step(fed, tracked, dt);
    }
    const auto& c = drv.model.counters();
    std::ostringstream note;
    note << random_ticks << " ticks over " << built.size() << " surfaces; " << c.time_backwards
         << " backwards, " << c.long_gaps << " gaps, " << c.surfaces_out_of_order
         << " late frames, " << c.nonfinite_inputs << " NaN/Inf inputs, " << c.clamped
         << " clamped";
    out.push_back(
        finish("random-combinations", drv, drv.mon.ticks == random_ticks, "", note.str()));
  }
  return out;
}

}  // namespace telex
