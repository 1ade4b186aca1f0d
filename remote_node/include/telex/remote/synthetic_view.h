// SPDX-License-Identifier: MIT
// Colour views of a synthetic scene from the operator's left and right eyes (for the stereo
// source).
#pragma once

#include <opencv2/core.hpp>

#include "telex/common/depth_image.h"
#include "telex/common/synthetic.h"

namespace telex::remote {

struct StereoViews {
  cv::Mat3b left_bgr;
  cv::Mat3b right_bgr;
};

// The depth sensor sits at the right eye, so the right view is rendered from the camera origin
// and the left one from -interpupillary_m along x.
inline constexpr double kInterpupillaryM = 0.065;

// Shades one ideal render: a base colour per object id, Lambert term of the true normal against a
// head light, darkened with distance so depth reads in the image. Background (no hit) is black.
cv::Mat3b shade_render(const synth::Rendered& rendered);
// Shades with the scene's materials (synth::Material): procedural textures laid out in the
// scene's texture frame, so both eyes see the same pattern on the same surface; a ceiling light
// and a head light, glossy materials with a highlight. Objects without a material shade as above.
// `p_CameraViewpoint`: where the render's camera sat (render_from's argument).
cv::Mat3b shade_render(const synth::Rendered& rendered, const synth::Scene& scene,
                       const Intrinsics& intrinsics, const glm::dvec3& p_CameraViewpoint);

StereoViews render_stereo_views(const synth::Scene& scene, const Intrinsics& intrinsics,
                                double interpupillary_m = kInterpupillaryM);

}  // namespace telex::remote
