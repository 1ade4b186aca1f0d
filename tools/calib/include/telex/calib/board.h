// SPDX-License-Identifier: MIT
// The calibration chessboard: its spec ("9x6", square size), its corners in the board's frame, and
// corner detection with sub-pixel refinement in one image, in the board's own corner order.
#pragma once

#include <opencv2/core.hpp>
#include <string_view>
#include <vector>

namespace telex::calib {

// A chessboard of cols x rows INNER corners (OpenCV's patternSize, ROS's --size: "9x6" is a board
// of 10 x 7 squares). The board's frame: origin at the first inner corner, x along a row of
// corners, y along a column, z into the board (away from a camera that sees its printed face).
// Square (a, b), a in [0, cols], b in [0, rows], spans x in [(a-1) s, a s], y in [(b-1) s, b s]
// and is black when a + b is even, so the square diagonally outside corner 0 is black.
struct BoardSpec {
  int cols = 9;
  int rows = 6;
  double square_m = 0.03;

  cv::Size pattern_size() const { return {cols, rows}; }
  int corner_count() const { return cols * rows; }
  // cols + rows odd: the colours fix the board's orientation, so corner 0 is the same physical
  // corner in every image. Otherwise a half turn looks the same and the order is chosen from the
  // image (corner 0 nearer the top left), which holds for cameras side by side.
  bool orientation_unique() const { return (cols + rows) % 2 == 1; }
};

// Parses "CxR" (inner corners, e.g. "9x6") and the square size in millimetres. Throws
// std::invalid_argument naming what is wrong: not CxR, fewer than 3 corners a side, more than 100,
// a square board (cols == rows: a quarter turn looks the same), a square not in (0, 1000] mm.
BoardSpec parse_board(std::string_view cxr, double square_mm);

// The inner corners in the board's frame (z = 0), row by row: corner (i, j) = (j s, i s, 0) at
// index i * cols + j. Metres.
std::vector<cv::Point3f> board_points(const BoardSpec& board);

struct CornerDetection {
  bool found = false;
  // In board_points order (canonical: see BoardSpec), pixel coordinates with (0, 0) the centre of
  // the top-left pixel.
  std::vector<cv::Point2f> corners_px;
};

// Finds the board in an 8-bit grey image with OpenCV's classic detector, or when that fails with
// the sector-based one (findChessboardCornersSB); refines the corners with cornerSubPix over a
// window of 0.8 corner spacings and orders them canonically. Never throws on image content;
// throws std::invalid_argument when `gray` is not CV_8UC1. A board of another size than `board`
// in the image is slow to reject (the classic detector: seconds).
CornerDetection detect_corners(const cv::Mat& gray, const BoardSpec& board);

// Puts detected corners in the board's canonical order (used by detect_corners; exposed for tests):
// a mirrored order is unmirrored (the printed face keeps the image's handedness), and a half turn
// is undone by the colour of the square outside corner 0 (or, when the colours cannot tell, so
// that corner 0 is the one nearer the image's top left).
void canonical_corner_order(const cv::Mat& gray, const BoardSpec& board,
                            std::vector<cv::Point2f>& corners_px);

}  // namespace telex::calib
