// SPDX-License-Identifier: MIT
// What the encoder and decoder share of libavcodec/libswscale: owners, error text, the log
// capture, and moving one eye into or out of its half of a side-by-side picture.
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavutil/frame.h>
#include <libswscale/swscale.h>
}

namespace telex::video::av {

struct CodecContextFree {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameFree {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketFree {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct BufferUnref {
  void operator()(AVBufferRef* b) const { av_buffer_unref(&b); }
};
struct SwsFree {
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};
using CodecContextPtr = std::unique_ptr<AVCodecContext, CodecContextFree>;
using FramePtr = std::unique_ptr<AVFrame, FrameFree>;
using PacketPtr = std::unique_ptr<AVPacket, PacketFree>;
using BufferPtr = std::unique_ptr<AVBufferRef, BufferUnref>;
using SwsPtr = std::unique_ptr<SwsContext, SwsFree>;

// libav* report why something failed through av_log, not their return codes. From the first
// call on, their log goes to a per-thread record (and to stderr only with TELEX_AV_LOG=1): the
// decoders log every concealed macroblock after a loss, which the statuses already say.
void capture_log();
// The error-level lines logged on this thread since the last call, joined by "; ".
std::string take_log();
std::string error_text(int av_error);

// Converts `eye_bgr` into `frame` (a planar or semi-planar YUV picture) at columns
// [x_px, x_px + eye width): one eye into its half without building the packed BGR picture.
// libswscale reads and writes whole SIMD words past a row's end, so the BGR side goes through
// `padded`, a scratch picture with room to spare.
void eye_into_frame(SwsContext* sws, const cv::Mat3b& eye_bgr, AVFrame* frame, int x_px,
                    cv::Mat3b& padded);
// Converts columns [x_px, x_px + eye_bgr.cols) of `frame` into `eye_bgr` (already sized).
void frame_into_eye(SwsContext* sws, const AVFrame* frame, int x_px, cv::Mat3b& eye_bgr,
                    cv::Mat3b& padded);

// The same for YUV420P pictures through OpenCV's BT.601 limited-range conversion (a third of
// libswscale's time here), by way of `i420`, a contiguous scratch picture.
void eye_into_yuv420p(const cv::Mat3b& eye_bgr, AVFrame* frame, int x_px, cv::Mat& i420);
void yuv420p_into_eye(const AVFrame* frame, int x_px, cv::Mat& i420, cv::Mat3b& eye_bgr);

// Whether an Annex B access unit holds an IDR slice (NAL type 5): decodable alone. x264's
// intra-refresh recovery points are flagged key frames too, but are not.
bool has_idr_slice(std::span<const std::uint8_t> annex_b);

}  // namespace telex::video::av
