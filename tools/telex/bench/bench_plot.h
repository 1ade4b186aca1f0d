// SPDX-License-Identifier: MIT
// Scatter plots of error against run time for `telex bench`, drawn with OpenCV (no Python needed).
#pragma once

#include <cstddef>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace telex::tool {

struct PlotPoint {
  double x = 0.0;
  double y = 0.0;
  std::string label;  // drawn beside Pareto-front and default points
  int group = 0;      // index into PlotSpec::group_names (colour)
  bool is_default = false;
};

struct PlotSpec {
  std::string title;
  std::string x_label;
  std::string y_label;
  bool log_x = true;
  bool log_y = false;
  std::vector<std::string> group_names;
};

// Indices of the points that no other point beats on both axes (lower x and lower y are
// better), sorted by x. Points with a non-finite or (on a log axis) non-positive coordinate are
// never on the front.
std::vector<std::size_t> pareto_front(const std::vector<PlotPoint>& points);

// Draws axes with ticks and labels, a legend, the points coloured by group, the Pareto front as a
// staircase with its points ringed and labelled, and the default point ringed in red. Points that
// cannot be placed (non-finite, non-positive on a log axis) are left out and counted in the
// title. Throws std::invalid_argument when no point can be placed.
// Whether any point can be drawn (finite, positive on a log axis); draw_scatter throws when none.
bool any_placeable(const PlotSpec& spec, const std::vector<PlotPoint>& points);
cv::Mat3b draw_scatter(const PlotSpec& spec, const std::vector<PlotPoint>& points);

}  // namespace telex::tool
