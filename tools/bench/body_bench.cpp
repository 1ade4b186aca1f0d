// SPDX-License-Identifier: MIT
// The virtual body's update (issue 12's goal: at most 20 us per frame): both arms' two-bone solve,
// both hands' forward kinematics and the eyes, on a moving scripted body; and the arm solve alone
// in each of its modes.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "telex/haptics/body.h"

namespace telex {
namespace {

// Arms sweeping through the working space at 100 Hz, fingers curling; every update is new work.
BodyInputs scripted(int k) {
  const double t = k * 0.01;
  BodyInputs in;
  in.time_ns = static_cast<std::int64_t>(k) * 10'000'000;
  in.head = Pose{{0.0, 1.65, 0.0}, glm::angleAxis(0.3 * std::sin(t), glm::dvec3{0.0, 1.0, 0.0})};
  for (Side s : kSides) {
    const std::size_t i = index_of(s);
    const double x = s == Side::Right ? 0.18 : -0.18;
    in.shoulder[i] = Pose{{x, 1.45, 0.0}, {1.0, 0.0, 0.0, 0.0}};
    const glm::dvec3 wrist{x + 0.1 * std::sin(t), 1.2 + 0.15 * std::cos(1.3 * t),
                           -0.35 - 0.1 * std::sin(0.7 * t)};
    in.wrist[i] = Pose{wrist, glm::angleAxis(0.5 * std::sin(t), glm::dvec3{0.0, 0.0, 1.0})};
    for (int f = 0; f < 5; ++f)
      in.bend[i][static_cast<std::size_t>(f)] = 0.5 + 0.5 * std::sin(t + f);
  }
  return in;
}

void BM_BodyUpdate(benchmark::State& state) {
  BodyDims dims;
  dims.forearm_axis_from_wrist = state.range(0) != 0;
  Body body(dims);
  std::vector<BodyInputs> inputs;
  for (int k = 0; k < 1000; ++k) inputs.push_back(scripted(k));
  std::size_t k = 0;
  for (auto _ : state) {
    const BodyState& s = body.update(inputs[k]);
    benchmark::DoNotOptimize(s.arms[0].hand.joints[4][3].x);
    if (++k == inputs.size()) k = 0;
  }
}
// 1: the elbow from the wrist body's forearm axis; 0: the posture rule.
BENCHMARK(BM_BodyUpdate)->Arg(1)->Arg(0);

void BM_ArmSolve(benchmark::State& state) {
  ArmSolveInput in;
  in.shoulder = {0.18, 1.45, 0.0};
  in.wrist = {0.25, 1.2, -0.4};
  in.posture_dir = {0.35, -1.0, 0.5};
  in.previous_swivel = glm::dvec3{1.0, 0.0, 0.0};
  if (state.range(0) == 1) in.forearm_axis = glm::normalize(glm::dvec3{0.1, 0.3, -1.0});
  if (state.range(0) == 2) in.elbow_marker = glm::dvec3{0.3, 1.2, -0.1};
  double x = 0.0;
  for (auto _ : state) {
    in.wrist.x += 1e-9;  // new work each time
    const ArmSolution s = solve_arm(0.3255, 0.2555, in);
    x += s.elbow.x;
  }
  benchmark::DoNotOptimize(x);
}
// 0: posture rule, 1: forearm axis, 2: elbow marker.
BENCHMARK(BM_ArmSolve)->Arg(0)->Arg(1)->Arg(2);

}  // namespace
}  // namespace telex

BENCHMARK_MAIN();
