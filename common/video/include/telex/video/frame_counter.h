// SPDX-License-Identifier: MIT
// A frame counter drawn in an eye's pixels and read back after the codec: glass-to-glass latency
// on loopback (the synthetic eyes stamp their frame id; the station reads which frame it shows).
//
// The pattern: 48 bits (the 32-bit counter, then its CRC-16/CCITT-FALSE) in a 16 x 6 grid of
// square cells in the top-left corner, one cell in from the edges. Each bit is a pair of cells,
// white-black for 1 and black-white for 0 (Manchester), so every bit carries its own threshold:
// the read needs neither a global level nor a white balance, and a pair whose two cells differ by
// less than kMinCounterContrast is an erasure. A read is accepted only when all 48 pairs are
// clear and the CRC matches, so a damaged or absent pattern gives nullopt rather than a wrong
// number (a random pattern passes with odds 2^-16 at most, after its 48 contrast tests).
//
// A cell is the image's height / 40 tall and its width / (160 / 3) wide (12 px square at 640x480;
// 24 x 18 px at 1280x720, the pattern 384 x 108 px), in floating point, and read at each cell's
// centre over half its size: a picture resized by any factors across and down (by half: 6 px
// cells at 320x240; a 640x480 eye sent at 1280x720) reads the same, and H.264 at 2-4 Mbit/s
// smears the cells' edges, not their centres.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>

namespace telex::video {

// Images with fewer rows (or under 107 columns) carry no counter: the cells would be under 2 px.
inline constexpr int kMinFrameCounterHeightPx = 80;
// Least luma difference (0-255) between a bit's two cells for the bit to count as read.
inline constexpr double kMinCounterContrast = 48.0;

// The pattern's extent in an image of `size`: what stamp_frame_counter overwrites (empty when the
// image is too small for it).
cv::Rect frame_counter_rect(cv::Size size);

// Draws `counter` into `bgr` (8-bit, 3 channels) in place. An image under
// kMinFrameCounterHeightPx rows, or too narrow for the pattern, is left as it is.
void stamp_frame_counter(cv::Mat& bgr, std::uint32_t counter);

// The counter stamped in `bgr` (8-bit, 1 or 3 channels, any scale of the stamped image), or
// nullopt when there is none, or it is too damaged to be sure of.
std::optional<std::uint32_t> read_frame_counter(const cv::Mat& bgr);

// Paints over the pattern's extent in `bgr` (8-bit, 1 or 3 channels, as stamped: not rescaled)
// with what surrounds it: each column of the rectangle runs linearly from the pixel just above it
// to the one just below. The view does this to the picture it shows, after reading the counter:
// the counter stays measurable and the operator never sees it.
void erase_frame_counter(cv::Mat& bgr);

}  // namespace telex::video
