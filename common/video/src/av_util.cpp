// SPDX-License-Identifier: MIT
// libavcodec/libswscale helpers shared by the eyes' encoder and decoder.
#include "av_util.h"

#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <opencv2/imgproc.hpp>

extern "C" {
#include <libavutil/error.h>
#include <libavutil/log.h>
#include <libavutil/pixdesc.h>
}

namespace telex::video::av {

namespace {
thread_local std::string t_log;

void log_callback(void* avcl, int level, const char* fmt, va_list args) {
  if (level > AV_LOG_ERROR) return;
  static const bool to_stderr = [] {
    const char* v = std::getenv("TELEX_AV_LOG");
    return v != nullptr && v[0] == '1';
  }();
  char line[512];
  int print_prefix = 1;
  av_log_format_line(avcl, level, fmt, args, line, sizeof(line), &print_prefix);
  std::string text(line);
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  if (to_stderr) std::fprintf(stderr, "libav: %s\n", text.c_str());
  // Bounded: a decoder after a loss logs a line per damaged macroblock row.
  if (t_log.size() > 2000) return;
  if (!t_log.empty()) t_log += "; ";
  t_log += text;
}

// Offset in bytes of column x_px in `plane` of `desc`'s pixel format.
std::ptrdiff_t column_offset(const AVPixFmtDescriptor* desc, int plane, int x_px) {
  const int x = plane == 0 || plane == 3 ? x_px : x_px >> desc->log2_chroma_w;
  for (int c = 0; c < desc->nb_components; ++c)
    if (desc->comp[c].plane == plane) return static_cast<std::ptrdiff_t>(x) * desc->comp[c].step;
  return 0;
}

void offset_planes(const AVFrame* frame, int x_px, std::uint8_t* planes[4], int strides[4]) {
  const auto* desc = av_pix_fmt_desc_get(static_cast<AVPixelFormat>(frame->format));
  for (int p = 0; p < 4; ++p) {
    planes[p] = frame->data[p] ? frame->data[p] + column_offset(desc, p, x_px) : nullptr;
    strides[p] = frame->linesize[p];
  }
}
}  // namespace

void capture_log() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_callback(log_callback); });
}

std::string take_log() {
  std::string out;
  out.swap(t_log);
  return out.empty() ? "nothing logged" : out;
}

std::string error_text(int av_error) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(av_error, buf, sizeof(buf));
  return buf;
}

namespace {
// A BGR scratch picture of at least w x h with 64 bytes of slack per row and one spare row.
cv::Mat3b padded_view(cv::Mat3b& padded, int w, int h) {
  const int cols = w + 64 / 3 + 1;
  if (padded.cols < cols || padded.rows < h + 1) padded.create(h + 1, cols);
  return padded(cv::Rect(0, 0, w, h));
}
}  // namespace

void eye_into_frame(SwsContext* sws, const cv::Mat3b& eye_bgr, AVFrame* frame, int x_px,
                    cv::Mat3b& padded) {
  cv::Mat3b src_view = padded_view(padded, eye_bgr.cols, eye_bgr.rows);
  eye_bgr.copyTo(src_view);
  std::uint8_t* dst[4];
  int dst_strides[4];
  offset_planes(frame, x_px, dst, dst_strides);
  const std::uint8_t* src[4] = {src_view.data, nullptr, nullptr, nullptr};
  const int src_strides[4] = {static_cast<int>(src_view.step[0]), 0, 0, 0};
  sws_scale(sws, src, src_strides, 0, eye_bgr.rows, dst, dst_strides);
}

void frame_into_eye(SwsContext* sws, const AVFrame* frame, int x_px, cv::Mat3b& eye_bgr,
                    cv::Mat3b& padded) {
  std::uint8_t* src[4];
  int src_strides[4];
  offset_planes(frame, x_px, src, src_strides);
  cv::Mat3b dst_view = padded_view(padded, eye_bgr.cols, eye_bgr.rows);
  std::uint8_t* dst[4] = {dst_view.data, nullptr, nullptr, nullptr};
  const int dst_strides[4] = {static_cast<int>(dst_view.step[0]), 0, 0, 0};
  sws_scale(sws, src, src_strides, 0, frame->height, dst, dst_strides);
  dst_view.copyTo(eye_bgr);
}

namespace {
// Copies between a contiguous I420 picture (Y, then U, then V) and columns [x_px, x_px + w) of
// a YUV420P frame.
template <bool kToFrame>
void copy_i420(std::uint8_t* i420, int w, int h, const AVFrame* frame, int x_px) {
  const int widths[3] = {w, w / 2, w / 2}, heights[3] = {h, h / 2, h / 2};
  const int xs[3] = {x_px, x_px / 2, x_px / 2};
  for (int p = 0; p < 3; ++p) {
    for (int y = 0; y < heights[p]; ++y) {
      std::uint8_t* row =
          frame->data[p] + static_cast<std::ptrdiff_t>(y) * frame->linesize[p] + xs[p];
      if constexpr (kToFrame)
        std::memcpy(row, i420, static_cast<std::size_t>(widths[p]));
      else
        std::memcpy(i420, row, static_cast<std::size_t>(widths[p]));
      i420 += widths[p];
    }
  }
}
}  // namespace

void eye_into_yuv420p(const cv::Mat3b& eye_bgr, AVFrame* frame, int x_px, cv::Mat& i420) {
  cv::cvtColor(eye_bgr, i420, cv::COLOR_BGR2YUV_I420);
  copy_i420<true>(i420.data, eye_bgr.cols, eye_bgr.rows, frame, x_px);
}

void yuv420p_into_eye(const AVFrame* frame, int x_px, cv::Mat& i420, cv::Mat3b& eye_bgr) {
  i420.create(eye_bgr.rows * 3 / 2, eye_bgr.cols, CV_8UC1);
  copy_i420<false>(i420.data, eye_bgr.cols, eye_bgr.rows, frame, x_px);
  cv::cvtColor(i420, eye_bgr, cv::COLOR_YUV2BGR_I420);
}

bool has_idr_slice(std::span<const std::uint8_t> annex_b) {
  // Start codes are 00 00 01 (a leading 00 makes the 4-byte form); the NAL type is the low 5
  // bits of the byte after.
  for (std::size_t i = 0; i + 3 < annex_b.size(); ++i) {
    if (annex_b[i] == 0 && annex_b[i + 1] == 0 && annex_b[i + 2] == 1) {
      if ((annex_b[i + 3] & 0x1f) == 5) return true;
      i += 2;
    }
  }
  return false;
}

}  // namespace telex::video::av
