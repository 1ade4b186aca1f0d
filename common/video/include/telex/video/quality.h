// SPDX-License-Identifier: MIT
// Picture quality against the source (tests and the codec benchmark), and a moving stereo scene
// to measure it on.
#pragma once

#include <opencv2/core.hpp>

namespace telex::video {

// PSNR in dB of `decoded` against `source` (same size, 8-bit BGR); 100 when identical.
double psnr_db(const cv::Mat3b& source, const cv::Mat3b& decoded);
// Mean SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5) of the luma of both, in [-1, 1].
double ssim(const cv::Mat3b& source, const cv::Mat3b& decoded);

// A deterministic moving stereo scene, frame `index` of a 30 Hz sequence: a textured backdrop
// with shapes moving across it, the right eye seeing near shapes shifted more than far ones (so
// the eyes differ and a swapped pair shows), and fresh sensor-like noise (sigma `noise`, fixed
// seed per frame) in every frame.
void render_moving_eyes(int index, cv::Size eye_size, double noise, cv::Mat3b& left_bgr,
                        cv::Mat3b& right_bgr);

}  // namespace telex::video
