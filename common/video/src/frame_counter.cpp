// SPDX-License-Identifier: MIT
// The frame counter in an eye's pixels: Manchester-coded cells with a CRC-16 (frame_counter.h).
#include "telex/video/frame_counter.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "telex/base/demand.h"

namespace telex::video {
namespace {

constexpr int kCounterBits = 32;
constexpr int kCrcBits = 16;
constexpr int kBits = kCounterBits + kCrcBits;
constexpr int kBitsPerRow = 8;  // 16 cells: a white and a black one per bit
constexpr int kCols = 2 * kBitsPerRow;
constexpr int kRows = kBits / kBitsPerRow;
// A cell is the image's height / 40 tall and its width / (160 / 3) wide: square in a 4:3 image,
// and where it lands in a picture resized by different factors across and down (a 640x480 eye
// sent at 1280x720), the reader finds it by the same fractions.
constexpr double kRowsPerCell = 40.0;
constexpr double kColsPerCell = 160.0 / 3.0;
constexpr int kMarginCells = 1;

// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of the counter's four bytes, low byte first.
std::uint16_t crc16(std::uint32_t counter) {
  std::uint16_t crc = 0xFFFF;
  for (int byte = 0; byte < 4; ++byte) {
    crc ^= static_cast<std::uint16_t>(((counter >> (8 * byte)) & 0xFFu) << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000u) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021u)
                            : static_cast<std::uint16_t>(crc << 1);
    }
  }
  return crc;
}

std::array<bool, kBits> bits_of(std::uint32_t counter) {
  std::array<bool, kBits> bits{};
  const std::uint16_t crc = crc16(counter);
  for (int i = 0; i < kCounterBits; ++i) bits[i] = (counter >> i) & 1u;
  for (int i = 0; i < kCrcBits; ++i) bits[kCounterBits + i] = (crc >> i) & 1u;
  return bits;
}

double cell_width_px(cv::Size size) { return static_cast<double>(size.width) / kColsPerCell; }
double cell_height_px(cv::Size size) { return static_cast<double>(size.height) / kRowsPerCell; }

bool fits(cv::Size size) {
  return size.height >= kMinFrameCounterHeightPx && cell_width_px(size) >= 2.0;
}

// Cell (col, row) of the grid in an image of `size`, in (fractional) pixels.
cv::Rect2d cell_rect(cv::Size size, int col, int row) {
  const double w = cell_width_px(size), h = cell_height_px(size);
  return {(kMarginCells + col) * w, (kMarginCells + row) * h, w, h};
}

cv::Rect round_rect(const cv::Rect2d& r) {
  const int x0 = static_cast<int>(std::lround(r.x)), y0 = static_cast<int>(std::lround(r.y));
  const int x1 = static_cast<int>(std::lround(r.x + r.width));
  const int y1 = static_cast<int>(std::lround(r.y + r.height));
  return {x0, y0, x1 - x0, y1 - y0};
}

// Mean luma over the middle half of a cell.
double cell_luma(const cv::Mat& image, cv::Size size, int col, int row) {
  const cv::Rect2d cell = cell_rect(size, col, row);
  const cv::Rect2d core(cell.x + cell.width / 4, cell.y + cell.height / 4, cell.width / 2,
                        cell.height / 2);
  cv::Rect r = round_rect(core);
  if (r.width < 1) r.width = 1;
  if (r.height < 1) r.height = 1;
  r &= cv::Rect(0, 0, size.width, size.height);
  const cv::Scalar mean = cv::mean(image(r));
  if (image.channels() == 1) return mean[0];
  return 0.114 * mean[0] + 0.587 * mean[1] + 0.299 * mean[2];  // BGR
}

}  // namespace

cv::Rect frame_counter_rect(cv::Size size) {
  if (!fits(size)) return {};
  const cv::Rect first = round_rect(cell_rect(size, 0, 0));
  const cv::Rect last = round_rect(cell_rect(size, kCols - 1, kRows - 1));
  return first | last;
}

void stamp_frame_counter(cv::Mat& bgr, std::uint32_t counter) {
  TELEX_DEMAND(bgr.type() == CV_8UC3);
  if (!fits(bgr.size())) return;
  const auto bits = bits_of(counter);
  const cv::Scalar white(255, 255, 255), black(0, 0, 0);
  for (int i = 0; i < kBits; ++i) {
    const int row = i / kBitsPerRow, col = 2 * (i % kBitsPerRow);
    bgr(round_rect(cell_rect(bgr.size(), col, row))).setTo(bits[i] ? white : black);
    bgr(round_rect(cell_rect(bgr.size(), col + 1, row))).setTo(bits[i] ? black : white);
  }
}

std::optional<std::uint32_t> read_frame_counter(const cv::Mat& bgr) {
  if (bgr.empty() || bgr.depth() != CV_8U || (bgr.channels() != 1 && bgr.channels() != 3) ||
      !fits(bgr.size()))
    return std::nullopt;
  std::uint32_t counter = 0;
  std::uint16_t crc = 0;
  for (int i = 0; i < kBits; ++i) {
    const int row = i / kBitsPerRow, col = 2 * (i % kBitsPerRow);
    const double contrast =
        cell_luma(bgr, bgr.size(), col, row) - cell_luma(bgr, bgr.size(), col + 1, row);
    if (std::abs(contrast) < kMinCounterContrast) return std::nullopt;  // an erasure
    if (contrast < 0) continue;                                         // a 0
    if (i < kCounterBits)
      counter |= 1u << i;
    else
      crc = static_cast<std::uint16_t>(crc | (1u << (i - kCounterBits)));
  }
  if (crc != crc16(counter)) return std::nullopt;
  return counter;
}

void erase_frame_counter(cv::Mat& bgr) {
  TELEX_DEMAND(bgr.depth() == CV_8U && (bgr.channels() == 1 || bgr.channels() == 3));
  const cv::Rect r = frame_counter_rect(bgr.size());
  if (r.empty()) return;
  // The pattern sits a cell in from the top and left edges: the rows above and below it exist.
  const int above = r.y - 1, below = std::min(r.y + r.height, bgr.rows - 1);
  const int channels = bgr.channels();
  const std::uint8_t* top = bgr.ptr<std::uint8_t>(above);
  const std::uint8_t* bottom = bgr.ptr<std::uint8_t>(below);
  const double span = below - above;
  for (int y = r.y; y < r.y + r.height; ++y) {
    const double t = (y - above) / span;
    std::uint8_t* row = bgr.ptr<std::uint8_t>(y);
    for (int x = r.x * channels; x < (r.x + r.width) * channels; ++x)
      row[x] = static_cast<std::uint8_t>(std::lround((1.0 - t) * top[x] + t * bottom[x]));
  }
}

}  // namespace telex::video
