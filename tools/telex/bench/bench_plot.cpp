// SPDX-License-Identifier: MIT
// OpenCV scatter plots with log axes, Pareto front and legend for `telex bench`.
#include "bench_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace telex::tool {
namespace {

constexpr int kWidth = 1000, kHeight = 640;
constexpr int kLeft = 90, kRight = 230, kTop = 50, kBottom = 70;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

bool placeable(const PlotPoint& p, bool log_x, bool log_y) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) return false;
  if (log_x && p.x <= 0.0) return false;
  if (log_y && p.y <= 0.0) return false;
  return true;
}

// Colour-blind-safe palette (Okabe-Ito), BGR.
cv::Scalar group_colour(int g) {
  static const cv::Scalar kPalette[] = {{178, 114, 0},  {0, 159, 230},   {115, 158, 0},
                                        {66, 228, 240}, {167, 121, 204}, {233, 180, 86},
                                        {0, 94, 213},   {120, 120, 120}, {40, 40, 40}};
  constexpr int n = static_cast<int>(sizeof(kPalette) / sizeof(kPalette[0]));
  return kPalette[((g % n) + n) % n];
}

std::string format_tick(double v) {
  char buf[32];
  const double a = std::abs(v);
  if (a == 0.0)
    std::snprintf(buf, sizeof buf, "0");
  else if (a >= 1e7 || a < 1e-3)
    std::snprintf(buf, sizeof buf, "%.0e", v);
  else if (a >= 100)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else
    std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

struct Axis {
  double lo, hi;  // in axis units (log10 when log)
  bool log;
  double to_unit(double v) const { return log ? std::log10(v) : v; }
  double frac(double v) const { return (to_unit(v) - lo) / (hi - lo); }

  // Tick values in data units: 1-2-5 per decade on a log axis, a 1-2-5 step on a linear one.
  std::vector<double> ticks() const {
    std::vector<double> out;
    if (log) {
      const bool fine = hi - lo < 2.5;
      for (int e = static_cast<int>(std::floor(lo)); e <= static_cast<int>(std::ceil(hi)); ++e)
        for (double m : {1.0, 2.0, 5.0}) {
          if (!fine && m != 1.0) continue;
          const double v = m * std::pow(10.0, e);
          const double u = std::log10(v);
          if (u >= lo - 1e-9 && u <= hi + 1e-9) out.push_back(v);
        }
    } else {
      const double raw = (hi - lo) / 6.0;
      const double p = std::pow(10.0, std::floor(std::log10(raw)));
      double step = p;
      for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * p >= raw) {
          step = m * p;
          break;
        }
      for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step)
        out.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
    }
    return out;
  }
};

Axis make_axis(double min_v, double max_v, bool log) {
  double lo = log ? std::log10(min_v) : min_v;
  double hi = log ? std::log10(max_v) : max_v;
  if (hi - lo < 1e-9) {
    const double pad = log ? 0.3 : std::max(1e-3, std::abs(lo) * 0.2);
    lo -= pad;
    hi += pad;
  } else {
    const double pad = (hi - lo) * 0.08;
    lo -= pad;
    hi += pad;
  }
  // A linear error axis starts at zero when the data is close to it, so ratios read correctly.
  if (!log && min_v >= 0.0 && lo < 0.0) lo = 0.0;
  return {lo, hi, log};
}

void put_text(cv::Mat3b& img, const std::string& s, cv::Point org, double scale,
              const cv::Scalar& colour, int thickness = 1) {
  cv::putText(img, s, org, kFont, scale, colour, thickness, cv::LINE_AA);
}

}  // namespace

std::vector<std::size_t> pareto_front(const std::vector<PlotPoint>& points) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (std::isfinite(points[i].x) && std::isfinite(points[i].y)) idx.push_back(i);
  std::sort(idx.begin(), idx.end(), [&](std::size_t a, std::size_t b) {
    return points[a].x != points[b].x ? points[a].x < points[b].x : points[a].y < points[b].y;
  });
  std::vector<std::size_t> front;
  double best_y = std::numeric_limits<double>::infinity();
  for (std::size_t i : idx)
    if (points[i].y < best_y) {
      front.push_back(i);
      best_y = points[i].y;
    }
  return front;
}

bool any_placeable(const PlotSpec& spec, const std::vector<PlotPoint>& points) {
  return std::any_of(points.begin(), points.end(),
                     [&](const PlotPoint& p) { return placeable(p, spec.log_x, spec.log_y); });
}

cv::Mat3b draw_scatter(const PlotSpec& spec, const std::vector<PlotPoint>& points) {
  std::vector<PlotPoint> placed;
  for (const auto& p : points)
    if (placeable(p, spec.log_x, spec.log_y)) placed.push_back(p);
  if (placed.empty())
    throw std::invalid_argument("plot '" + spec.title + "': no point with finite coordinates");
  const std::size_t left_out = points.size() - placed.size();

  auto [min_x, max_x] =
      std::minmax_element(placed.begin(), placed.end(), [](auto& a, auto& b) { return a.x < b.x; });
  auto [min_y, max_y] =
      std::minmax_element(placed.begin(), placed.end(), [](auto& a, auto& b) { return a.y < b.y; });
  const Axis ax = make_axis(min_x->x, max_x->x, spec.log_x);
  const Axis ay = make_axis(min_y->y, max_y->y, spec.log_y);

  cv::Mat3b img(kHeight, kWidth, cv::Vec3b(255, 255, 255));
  const int pw = kWidth - kLeft - kRight, ph = kHeight - kTop - kBottom;
  auto px = [&](double x) { return kLeft + static_cast<int>(std::lround(ax.frac(x) * pw)); };
  auto py = [&](double y) { return kTop + ph - static_cast<int>(std::lround(ay.frac(y) * ph)); };
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225), grey(90, 90, 90);

  // Grid and ticks.
  for (double t : ax.ticks()) {
    const int x = px(t);
    cv::line(img, {x, kTop}, {x, kTop + ph}, grid, 1);
    cv::line(img, {x, kTop + ph}, {x, kTop + ph + 6}, black, 1);
    const std::string s = format_tick(t);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, kFont, 0.45, 1, &base);
    put_text(img, s, {x - sz.width / 2, kTop + ph + 22}, 0.45, black);
  }
  for (double t : ay.ticks()) {
    const int y = py(t);
    cv::line(img, {kLeft, y}, {kLeft + pw, y}, grid, 1);
    cv::line(img, {kLeft - 6, y}, {kLeft, y}, black, 1);
    const std::string s = format_tick(t);
    int base = 0;
    const cv::Size sz = cv::getTextSize(s, kFont, 0.45, 1, &base);
    put_text(img, s, {kLeft - 10 - sz.width, y + sz.height / 2}, 0.45, black);
  }
  cv::rectangle(img, cv::Rect(kLeft, kTop, pw, ph), black, 1);

  // Labels and title.
  {
    int base = 0;
    const cv::Size sz = cv::getTextSize(spec.x_label, kFont, 0.55, 1, &base);
    put_text(img, spec.x_label, {kLeft + pw / 2 - sz.width / 2, kHeight - 20}, 0.55, black);
    const cv::Size ys = cv::getTextSize(spec.y_label, kFont, 0.55, 1, &base);
    cv::Mat3b label(ys.height + base + 6, ys.width + 6, cv::Vec3b(255, 255, 255));
    put_text(label, spec.y_label, {3, ys.height + 2}, 0.55, black);
    cv::Mat3b rotated;
    cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, kTop + ph / 2 - rotated.rows / 2);
    const int h = std::min(rotated.rows, kHeight - y0);
    rotated.rowRange(0, h).copyTo(img(cv::Rect(8, y0, rotated.cols, h)));
    std::string title = spec.title;
    if (left_out > 0) title += " (" + std::to_string(left_out) + " points not placeable)";
    put_text(img, title, {kLeft, 30}, 0.65, black, 1);
  }

  // Pareto staircase under the points.
  const std::vector<std::size_t> front = pareto_front(placed);
  for (std::size_t k = 0; k + 1 < front.size(); ++k) {
    const auto& a = placed[front[k]];
    const auto& b = placed[front[k + 1]];
    cv::line(img, {px(a.x), py(a.y)}, {px(b.x), py(a.y)}, grey, 1, cv::LINE_AA);
    cv::line(img, {px(b.x), py(a.y)}, {px(b.x), py(b.y)}, grey, 1, cv::LINE_AA);
  }

  for (const auto& p : placed)
    cv::circle(img, {px(p.x), py(p.y)}, 5, group_colour(p.group), cv::FILLED, cv::LINE_AA);
  for (std::size_t i : front) {
    const auto& p = placed[i];
    cv::circle(img, {px(p.x), py(p.y)}, 8, black, 1, cv::LINE_AA);
    put_text(img, p.label, {px(p.x) + 9, py(p.y) - 7}, 0.38, grey);
  }
  for (const auto& p : placed)
    if (p.is_default) {
      cv::circle(img, {px(p.x), py(p.y)}, 11, cv::Scalar(0, 0, 220), 2, cv::LINE_AA);
      put_text(img, "default", {px(p.x) + 12, py(p.y) + 16}, 0.45, cv::Scalar(0, 0, 200));
    }

  // Legend.
  int ly = kTop + 12;
  const int lx = kLeft + pw + 20;
  for (std::size_t g = 0; g < spec.group_names.size(); ++g) {
    cv::circle(img, {lx + 6, ly - 4}, 5, group_colour(static_cast<int>(g)), cv::FILLED,
               cv::LINE_AA);
    put_text(img, spec.group_names[g], {lx + 18, ly}, 0.45, black);
    ly += 22;
  }
  ly += 8;
  cv::line(img, {lx, ly - 4}, {lx + 12, ly - 4}, grey, 1);
  cv::circle(img, {lx + 6, ly - 4}, 8, black, 1, cv::LINE_AA);
  put_text(img, "Pareto front", {lx + 18, ly}, 0.45, black);
  ly += 24;
  cv::circle(img, {lx + 6, ly - 4}, 9, cv::Scalar(0, 0, 220), 2, cv::LINE_AA);
  put_text(img, "default config", {lx + 18, ly}, 0.45, black);
  ly += 22;
  put_text(img, "lower-left is better", {lx, ly + 10}, 0.4, grey);
  return img;
}

}  // namespace telex::tool
