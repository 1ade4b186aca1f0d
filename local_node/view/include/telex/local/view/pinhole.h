// SPDX-License-Identifier: MIT
// Pinhole resampling for the view: the depth camera at an eye's image size, an image or a depth
// seen from another pinhole with the same centre (turned or not). The stereo view and Fig. 7 use
// them.
#pragma once

#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "telex/common/depth_image.h"

namespace telex::local {

// The depth camera `k` at another image size: the same centre and square-pixel scale, the larger
// of the two axes' scales, so the image is filled and the depth's field of view cropped on the
// other axis (a 640x480 depth seen by 1280x720 eyes: scale 2, 120 rows cropped top and bottom).
Intrinsics eye_intrinsics(const Intrinsics& k, cv::Size size);

// `image`, taken with intrinsics `from`, resampled into intrinsics `to` (the same camera centre and
// orientation), `to`'s size; outside `image`: `border`. Nearest keeps depth edges unblended.
cv::Mat resample_pinhole(const cv::Mat& image, const Intrinsics& from, const Intrinsics& to,
                         int interpolation, const cv::Scalar& border = {});
// The same with `to`'s camera turned from `from`'s (same centre): a direction d_To of `to`'s frame
// is R_FromTo d_To in `from`'s. A homography K_from R_FromTo K_to^-1; R_FromTo identity: the
// affine map above, bit for bit.
cv::Mat resample_pinhole(const cv::Mat& image, const Intrinsics& from, const Intrinsics& to,
                         const glm::dmat3& R_FromTo, int interpolation,
                         const cv::Scalar& border = {});
// A depth image (mm, 0: none) taken with `from` seen from `to`, turned as above: each `to` pixel
// takes the nearest `from` pixel along its ray, that pixel's point re-expressed as its z in `to`'s
// frame (the depth the eye's occlusion test needs); outside `from`, behind `to` or beyond 65535
// mm: 0. R_FromTo identity: resample_pinhole with nearest sampling, bit for bit.
cv::Mat1w resample_depth_turned(const cv::Mat1w& depth_mm, const Intrinsics& from,
                                const Intrinsics& to, const glm::dmat3& R_FromTo);

}  // namespace telex::local
