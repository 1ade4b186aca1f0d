// SPDX-License-Identifier: MIT
// What the station's threads hand each other: the haptic thread's tick samples (to the main
// thread's log and statistics) and the operator's head samples (to the head sender).
#pragma once

#include <array>
#include <cstdint>
#include <glm/mat3x3.hpp>

#include "telex/haptics/haptic_model.h"
#include "telex/local/inputs/tracker.h"

namespace telex::local {

// What the haptic thread reports per tick; trivially copyable so the ring never allocates.
struct TickSample {
  std::int64_t t_ns = 0;
  std::int64_t deadline_ns = 0;  // the timer's deadline this tick waited for
  std::int64_t period_ns = 0;
  std::uint64_t surface_frame = 0;
  std::int64_t surface_capture_ns = 0;  // remote clock; 0 = no surface yet
  std::array<FingertipForce, kFingerCount> forces{};
  std::array<bool, kFingerCount> tracked{};
  std::array<glm::dvec3, kFingerCount> p_CameraFingertip{};
  std::array<glm::dvec3, kFingerCount> axis_Camera{};
};

// The operator's head: one per tracker frame that held the head body, numbered, stamped when the
// tracker delivered it.
struct HeadSample {
  std::int64_t time_ns = 0;
  std::uint32_t id = 0;
  glm::dmat3 R_BaseCamera{1.0};
};

inline constexpr const char* kFingerNames[kFingerCount] = {"thumb", "index", "middle", "ring",
                                                           "little"};

}  // namespace telex::local
