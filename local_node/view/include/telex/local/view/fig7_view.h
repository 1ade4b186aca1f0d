// SPDX-License-Identifier: MIT
// The paper's Fig. 7 (--view-layout fig7; --view png:DIR writes DIR/fig7.png): the interaction
// view on the left half and, on the right half, the full-frame normal map of the remote scene with
// each fingertip's touch vector drawn on it (god-point, contact normal, force, shear). The view
// computes its own reduced normal map when the haptic path builds normals only in fingertip
// windows, on the view's thread: the haptic path does not pay for the picture.
#pragma once

#include <array>
#include <opencv2/core.hpp>

#include "telex/haptics/haptic_model.h"
#include "telex/local/inputs/tracker.h"

namespace telex::local {

// Full-frame normals for display, the depth's size: the surface's own when they cover the scene
// (at least half of the pixels with depth), else computed from `depth_mm` at 1/`reduce` of its
// size and brought back up (nearest, so edges stay edges). Zero where there is no depth.
cv::Mat3f display_normals(const cv::Mat1w& depth_mm, const Intrinsics& k,
                          const Surface* surface = nullptr, int reduce = 2);

// Each fingertip in contact as drawn on the panel (`k`: the panel's pinhole, camera frame): a
// ring at the god-point, the contact normal (white, 3 cm), the force (yellow, arrow_m_per_N per
// newton) and its shear part (magenta, same scale), with the finger's initial and the force in N.
void draw_touch_vectors(cv::Mat3b& panel, const Intrinsics& k,
                        const std::array<FingertipForce, kFingerCount>& forces,
                        double arrow_m_per_N);

// The layout: `interaction` on the left, the normal map (colorize_normals, resampled to the
// interaction view's pinhole `k_view` from the depth's `k_depth`) with the touch vectors on the
// right; both halves the interaction view's size.
cv::Mat3b fig7_layout(const cv::Mat3b& interaction, const Intrinsics& k_view,
                      const cv::Mat3f& normals, const Intrinsics& k_depth,
                      const std::array<FingertipForce, kFingerCount>& forces, double arrow_m_per_N);

}  // namespace telex::local
