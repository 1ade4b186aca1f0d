// SPDX-License-Identifier: MIT
// The status text at the foot of every view image: wrapped at spaces into as many lines as it
// needs to fit the image's width, on a darkened band, so no view cuts it off.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace telex::local {

// Splits `text` at spaces into lines that each fit `width_px` in FONT_HERSHEY_SIMPLEX at `scale`
// and `thickness`; a single word wider than that gets a line of its own (the caller shrinks the
// scale for it). Pure.
std::vector<std::string> wrap_status(const std::string& text, double scale, int thickness,
                                     int width_px);

// Draws `text` wrapped to the image's width (6 px margins) on a band that darkens what is under
// it, at the bottom of `img`. A word too wide even for a line of its own shrinks the scale.
void draw_status_band(cv::Mat3b& img, const std::string& text, double scale, int thickness);

}  // namespace telex::local
