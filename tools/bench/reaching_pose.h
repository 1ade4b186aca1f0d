// SPDX-License-Identifier: MIT
// The stereo benchmark's pose, which the body mesh's tests hold it to as well
// (tests/local/body_mesh_test.cpp): both arms reaching toward the camera's view, in the right
// eye's frame (x right, y down, z forward), shoulders above and behind the eyes.
#pragma once

#include <cstddef>

#include "telex/haptics/body.h"

namespace telex::local {

inline BodyState reaching_body() {
  BodyInputs in;
  in.time_ns = 0;
  for (Side s : kSides) {
    const std::size_t i = index_of(s);
    const double x = s == Side::Right ? 0.18 : -0.18;
    // World = the right eye's camera frame here, with up = -y.
    in.shoulder[i] = Pose{{x, 0.25, -0.05}, {1.0, 0.0, 0.0, 0.0}};
    in.wrist[i] = Pose{{x * 0.6, 0.15, 0.45}, {1.0, 0.0, 0.0, 0.0}};
    in.bend[i] = {0.3, 0.2, 0.4, 0.6, 0.7};
  }
  BodyDims dims;
  dims.up_world = {0.0, -1.0, 0.0};
  dims.forearm_axis_from_wrist = false;
  Body body(dims);
  return body.update(in);
}

}  // namespace telex::local
