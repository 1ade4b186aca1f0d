// SPDX-License-Identifier: MIT
// The views' status text, wrapped to fit.
#include "telex/local/view/status_band.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace telex::local {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr int kMarginPx = 6;

int text_width(const std::string& s, double scale, int thickness) {
  int base = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &base).width;
}

}  // namespace

std::vector<std::string> wrap_status(const std::string& text, double scale, int thickness,
                                     int width_px) {
  std::vector<std::string> lines;
  std::istringstream words(text);
  std::string word, line;
  while (words >> word) {
    const std::string joined = line.empty() ? word : line + " " + word;
    if (line.empty() || text_width(joined, scale, thickness) <= width_px) {
      line = joined;
      continue;
    }
    lines.push_back(line);
    line = word;
  }
  if (!line.empty()) lines.push_back(line);
  return lines;
}

void draw_status_band(cv::Mat3b& img, const std::string& text, double scale, int thickness) {
  const int width_px = img.cols - 2 * kMarginPx;
  if (text.empty() || width_px <= 0) return;
  std::vector<std::string> lines = wrap_status(text, scale, thickness, width_px);
  int widest = 0;
  for (const auto& l : lines) widest = std::max(widest, text_width(l, scale, thickness));
  if (widest > width_px) {  // one word wider than the image: shrink for it
    scale *= static_cast<double>(width_px) / widest;
    lines = wrap_status(text, scale, thickness, width_px);
  }
  int base = 0;
  const int line_h = cv::getTextSize("Ag", kFont, scale, thickness, &base).height + base + 4;
  const int band_h = std::min(img.rows, static_cast<int>(lines.size()) * line_h + 6);
  const cv::Rect band(0, img.rows - band_h, img.cols, band_h);
  img(band) *= 0.3;
  int y = img.rows - band_h + 3 + line_h - base - 2;
  for (const auto& l : lines) {
    cv::putText(img, l, {kMarginPx, y}, kFont, scale, {255, 255, 255}, thickness, cv::LINE_AA);
    y += line_h;
  }
}

}  // namespace telex::local
