// SPDX-License-Identifier: MIT
// EyeDecoder: H.264 side-by-side pictures and MJPEG pairs back to two BGR eyes, with loss
// detection from the header's encode_seq.
#include "telex/video/eye_decoder.h"

#include <optional>
#include <utility>
#include <vector>

#include "av_util.h"
#include "telex/base/byte_cursor.h"

namespace telex::video {

std::string_view decode_status_name(DecodeStatus status) {
  switch (status) {
    case DecodeStatus::Ok:
      return "ok";
    case DecodeStatus::BadHeader:
      return "bad header";
    case DecodeStatus::DecodeError:
      return "decode error";
    case DecodeStatus::MissingReference:
      return "missing reference";
    case DecodeStatus::NoPicture:
      return "no picture";
  }
  return "unknown";
}

struct EyeDecoder::Impl {
  av::CodecContextPtr h264, mjpeg;
  av::FramePtr frame{av_frame_alloc()};
  av::PacketPtr packet{av_packet_alloc()};
  SwsContext* sws = nullptr;         // sws_getCachedContext's: freed in the destructor
  std::vector<std::uint8_t> padded;  // libavcodec reads up to 64 bytes past a packet's end
  std::optional<std::uint32_t> last_seq;
  int eye_width_px = 0, eye_height_px = 0;
  cv::Mat3b scratch_left, scratch_right;
  cv::Mat i420;
  cv::Mat3b padded_bgr;

  ~Impl() { sws_freeContext(sws); }

  static av::CodecContextPtr open(AVCodecID id) {
    const AVCodec* codec = avcodec_find_decoder(id);
    if (codec == nullptr) return nullptr;
    av::CodecContextPtr ctx(avcodec_alloc_context3(codec));
    // Slice threads add no delay (frame threads hold pictures back).
    ctx->thread_type = FF_THREAD_SLICE;
    ctx->thread_count = id == AV_CODEC_ID_H264 ? 2 : 1;
    ctx->flags |= AV_CODEC_FLAG_LOW_DELAY;
    if (avcodec_open2(ctx.get(), codec, nullptr) < 0) return nullptr;
    return ctx;
  }

  // Sends `bytes` as one packet and takes one picture of exactly w x h pixels into `frame`.
  DecodeStatus decode_picture(AVCodecContext* ctx, std::span<const std::uint8_t> bytes, int w,
                              int h) {
    // Bounds what a lying bitstream can make the decoder allocate (with room for the decoder's
    // own alignment of the width and the coded height's macroblock rows).
    ctx->max_pixels = static_cast<std::int64_t>(w + 128) * (h + 32);
    padded.assign(bytes.begin(), bytes.end());
    padded.resize(bytes.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
    packet->data = padded.data();
    packet->size = static_cast<int>(bytes.size());
    const int sent = avcodec_send_packet(ctx, packet.get());
    packet->data = nullptr;
    packet->size = 0;
    if (sent < 0) return DecodeStatus::DecodeError;
    const int got = avcodec_receive_frame(ctx, frame.get());
    if (got == AVERROR(EAGAIN)) return DecodeStatus::NoPicture;
    if (got < 0 || frame->width != w || frame->height != h) return DecodeStatus::DecodeError;
    return DecodeStatus::Ok;
  }

  void to_eye(int x_px, cv::Mat3b& eye) {
    eye.create(eye_height_px, eye_width_px);
    if (frame->format == AV_PIX_FMT_YUV420P) {
      av::yuv420p_into_eye(frame.get(), x_px, i420, eye);
      return;
    }
    sws = sws_getCachedContext(
        sws, eye_width_px, eye_height_px, static_cast<AVPixelFormat>(frame->format), eye_width_px,
        eye_height_px, AV_PIX_FMT_BGR24, SWS_FAST_BILINEAR, nullptr, nullptr, nullptr);
    av::frame_into_eye(sws, frame.get(), x_px, eye, padded_bgr);
  }
};

EyeDecoder::EyeDecoder() : impl_(std::make_unique<Impl>()), needs_intra_(true) {
  av::capture_log();
}
EyeDecoder::~EyeDecoder() = default;

DecodeStatus EyeDecoder::decode(std::span<const std::uint8_t> bytes, DecodedPair& out) {
  const ParsedFrame parsed = parse_frame(bytes);
  last_header_status_ = parsed.status;
  if (parsed.status != HeaderStatus::Ok) {
    ++counters_.bad_header;
    return DecodeStatus::BadHeader;
  }
  const EncodedFrameHeader& h = parsed.header;
  Impl& im = *impl_;
  if (h.eye_width_px != im.eye_width_px || h.eye_height_px != im.eye_height_px) {
    // A new geometry is a new stream: the old references are useless.
    im.h264.reset();
    im.eye_width_px = h.eye_width_px;
    im.eye_height_px = h.eye_height_px;
    needs_intra_ = true;
  }
  if (im.last_seq && h.encode_seq != *im.last_seq + 1) {
    ++counters_.gaps;
    needs_intra_ = true;
  }
  im.last_seq = h.encode_seq;
  DecodeStatus status =
      h.codec == VideoCodec::H264 ? decode_h264(parsed, out) : decode_mjpeg(parsed, out);
  (void)av::take_log();  // the status says it; keep the per-thread record from growing
  if (status == DecodeStatus::DecodeError) {
    ++counters_.decode_errors;
    if (h.codec == VideoCodec::H264) needs_intra_ = true;
    return status;
  }
  if (status != DecodeStatus::Ok) return status;
  out.header = h;
  ++counters_.pairs;
  if (needs_intra_) {
    ++counters_.missing_reference;
    return DecodeStatus::MissingReference;
  }
  return DecodeStatus::Ok;
}

DecodeStatus EyeDecoder::decode_h264(const ParsedFrame& parsed, DecodedPair& out) {
  Impl& im = *impl_;
  if (!im.h264) im.h264 = Impl::open(AV_CODEC_ID_H264);
  if (!im.h264) return DecodeStatus::DecodeError;
  const DecodeStatus status =
      im.decode_picture(im.h264.get(), parsed.payload, 2 * im.eye_width_px, im.eye_height_px);
  if (status != DecodeStatus::Ok) return status;
  const bool damaged =
      (im.frame->flags & AV_FRAME_FLAG_CORRUPT) != 0 || im.frame->decode_error_flags != 0;
  if (parsed.header.is_intra && !damaged) needs_intra_ = false;
  if (damaged) needs_intra_ = true;
  im.to_eye(0, out.left_bgr);
  im.to_eye(im.eye_width_px, out.right_bgr);
  av_frame_unref(im.frame.get());
  return DecodeStatus::Ok;
}

DecodeStatus EyeDecoder::decode_mjpeg(const ParsedFrame& parsed, DecodedPair& out) {
  Impl& im = *impl_;
  ByteReader r(parsed.payload);
  const std::uint32_t left_bytes = r.u32();
  if (!r.ok() || left_bytes == 0 || left_bytes >= r.remaining()) return DecodeStatus::DecodeError;
  const auto left = r.bytes(left_bytes);
  const auto right = r.bytes(r.remaining());
  if (!im.mjpeg) im.mjpeg = Impl::open(AV_CODEC_ID_MJPEG);
  if (!im.mjpeg) return DecodeStatus::DecodeError;
  // Both eyes decode into scratch first, so a failure leaves `out` as it was.
  for (auto [jpeg, eye] :
       {std::pair{left, &im.scratch_left}, std::pair{right, &im.scratch_right}}) {
    if (im.decode_picture(im.mjpeg.get(), jpeg, im.eye_width_px, im.eye_height_px) !=
        DecodeStatus::Ok)
      return DecodeStatus::DecodeError;
    im.to_eye(0, *eye);
    av_frame_unref(im.frame.get());
  }
  std::swap(out.left_bgr, im.scratch_left);
  std::swap(out.right_bgr, im.scratch_right);
  // MJPEG pairs reference nothing: a loss before one needs no intra request.
  needs_intra_ = false;
  return DecodeStatus::Ok;
}

}  // namespace telex::video
