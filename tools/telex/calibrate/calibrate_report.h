// SPDX-License-Identifier: MIT
// What `telex calibrate` reports: rotations in degrees for JSON, and the depth-eye result (the
// depth maps' planes, the JSON object or the printed lines). Internal to tools/telex.
#pragma once

#include <cstddef>
#include <glm/glm.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "telex/calib/calibrate.h"

namespace telex::tool {

// The rotation vector of `r`, in degrees.
std::vector<double> rotation_vector_deg(const glm::dmat3& r);

// A point or vector as a JSON-ready [x, y, z].
std::vector<double> vec(const glm::dvec3& v);

// The depth maps' board planes against the IR pose's plane (medians over the used views), and
// the pose from the planes alone where there is one.
nlohmann::json depth_plane_summary(const calib::DepthEyeCalibration& c);

// What one `telex calibrate depth-eye` run found and wrote.
struct DepthEyeResult {
  const calib::DepthEyeCalibration& c;
  std::size_t views = 0;       // given
  std::size_t views_used = 0;  // the board found in both cameras
  std::vector<std::string> skipped;
  nlohmann::json planes;  // depth_plane_summary, or null without depth maps
  std::string rig;        // the file written
  bool wrote_depth = false;
};

void print_depth_eye_json(const DepthEyeResult& r);
void print_depth_eye_text(const DepthEyeResult& r);

}  // namespace telex::tool
