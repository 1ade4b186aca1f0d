// SPDX-License-Identifier: MIT
// H.264 pairs through libavcodec: libx264 tuned for zero latency with intra refresh, or a
// hardware encoder (VA-API, NVENC) chosen by name.
#include <atomic>
#include <cmath>
#include <deque>

#include "av_util.h"
#include "encoders.h"

extern "C" {
#include <libavutil/hwcontext.h>
#include <libavutil/opt.h>
}

namespace telex::video::detail {

namespace {

struct PendingPair {
  std::int64_t pts = 0;
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;
};

std::string failure(const EncoderConfig& config, const std::string& what, int av_error) {
  return "video encoder '" + config.encoder + "' " + what + ": " + av::error_text(av_error) +
         " (libavcodec: " + av::take_log() + ")";
}

class H264Encoder final : public EyeEncoder {
 public:
  explicit H264Encoder(const EncoderConfig& config)
      : EyeEncoder(config, VideoCodec::H264), bitrate_bps_(config.bitrate_bps) {
    av::capture_log();
    (void)av::take_log();
    const AVCodec* codec = avcodec_find_encoder_by_name(config.encoder.c_str());
    if (codec == nullptr)
      throw VideoError("video encoder '" + config.encoder +
                       "' is not in this libavcodec build (" LIBAVCODEC_IDENT
                       "); software H.264 is 'libx264'");
    const bool vaapi = config.encoder == "h264_vaapi";
    if (vaapi) open_vaapi_device();
    ctx_.reset(avcodec_alloc_context3(codec));
    set_rate(config.bitrate_bps);
    AVCodecContext* c = ctx_.get();
    c->width = 2 * config.eye_width_px;
    c->height = config.eye_height_px;
    c->time_base = av_d2q(1.0 / config.frame_rate_hz, 1'000'000);
    c->framerate = av_d2q(config.frame_rate_hz, 1'000'000);
    c->max_b_frames = 0;  // a B-frame waits for the frame after it: latency
    c->gop_size = config.intra_refresh_frames;
    c->thread_count = config.threads;
    c->pix_fmt = vaapi ? AV_PIX_FMT_VAAPI : AV_PIX_FMT_YUV420P;
    if (vaapi) c->hw_frames_ctx = av_buffer_ref(hw_frames_.get());
    AVDictionary* opts = encoder_options(config);
    const int err = avcodec_open2(c, codec, &opts);
    av_dict_free(&opts);
    if (err < 0) throw VideoError(failure(config, "could not open", err));
    alloc_frames(vaapi ? AV_PIX_FMT_NV12 : AV_PIX_FMT_YUV420P);
  }

  EncodeStatus encode(const cv::Mat3b& left_bgr, const cv::Mat3b& right_bgr, std::uint32_t frame_id,
                      std::int64_t capture_ns, std::vector<std::uint8_t>& out) override {
    const cv::Size eye(config_.eye_width_px, config_.eye_height_px);
    if (left_bgr.size() != eye || right_bgr.size() != eye) return fail(EncodeStatus::BadInput);
    if (av_frame_make_writable(sw_frame_.get()) < 0) return fail(EncodeStatus::EncoderError);
    if (hw_frames_) {
      av::eye_into_frame(sws_.get(), left_bgr, sw_frame_.get(), 0, padded_bgr_);
      av::eye_into_frame(sws_.get(), right_bgr, sw_frame_.get(), config_.eye_width_px, padded_bgr_);
    } else {
      av::eye_into_yuv420p(left_bgr, sw_frame_.get(), 0, i420_);
      av::eye_into_yuv420p(right_bgr, sw_frame_.get(), config_.eye_width_px, i420_);
    }
    AVFrame* frame = sw_frame_.get();
    if (hw_frames_) {
      av_frame_unref(hw_frame_.get());
      if (av_hwframe_get_buffer(hw_frames_.get(), hw_frame_.get(), 0) < 0 ||
          av_hwframe_transfer_data(hw_frame_.get(), sw_frame_.get(), 0) < 0)
        return fail(EncodeStatus::EncoderError);
      frame = hw_frame_.get();
    }
    apply_requests(frame);
    frame->pts = next_pts_++;
    pending_.push_back({frame->pts, frame_id, capture_ns});
    if (pending_.size() > 64) pending_.pop_front();  // a pipeline never holds this many
    if (avcodec_send_frame(ctx_.get(), frame) < 0) return fail(EncodeStatus::EncoderError);
    const int err = avcodec_receive_packet(ctx_.get(), packet_.get());
    if (err == AVERROR(EAGAIN)) return EncodeStatus::Buffered;
    if (err < 0) return fail(EncodeStatus::EncoderError);
    // A delaying (hardware) encoder returns an earlier picture: its own id and time go out.
    PendingPair pair{packet_->pts, frame_id, capture_ns};
    while (!pending_.empty() && pending_.front().pts <= packet_->pts) {
      if (pending_.front().pts == packet_->pts) pair = pending_.front();
      pending_.pop_front();
    }
    const std::span<const std::uint8_t> au(packet_->data, static_cast<std::size_t>(packet_->size));
    out.assign(kHeaderBytes, 0);
    out.insert(out.end(), au.begin(), au.end());
    const bool is_intra = av::has_idr_slice(au);
    av_packet_unref(packet_.get());  // `au` dangles from here
    finish_pair(pair.frame_id, pair.capture_ns, is_intra, out);
    return EncodeStatus::Ok;
  }

  void set_bitrate(std::int64_t bitrate_bps) override {
    bitrate_bps_.store(std::clamp<std::int64_t>(bitrate_bps, 10'000, 1'000'000'000));
  }
  void request_intra() override { intra_requested_.store(true); }

 private:
  void open_vaapi_device() {
    AVBufferRef* device = nullptr;
    int err = av_hwdevice_ctx_create(&device, AV_HWDEVICE_TYPE_VAAPI, config_.vaapi_device.c_str(),
                                     nullptr, 0);
    if (err < 0)
      throw VideoError(failure(config_, "has no VA-API device at " + config_.vaapi_device, err));
    hw_device_.reset(device);
    hw_frames_.reset(av_hwframe_ctx_alloc(hw_device_.get()));
    auto* frames = reinterpret_cast<AVHWFramesContext*>(hw_frames_->data);
    frames->format = AV_PIX_FMT_VAAPI;
    frames->sw_format = AV_PIX_FMT_NV12;
    frames->width = 2 * config_.eye_width_px;
    frames->height = config_.eye_height_px;
    frames->initial_pool_size = 4;
    err = av_hwframe_ctx_init(hw_frames_.get());
    if (err < 0) throw VideoError(failure(config_, "could not make VA-API surfaces", err));
  }

  // Zero latency: no look-ahead, no B-frames, one picture in and its bytes out. Intra refresh:
  // a column of intra blocks sweeps the picture every intra_refresh_frames, so no frame is a
  // key frame several times the size of the others (a burst the link would queue). forced-idr:
  // a PLI gets an IDR, decodable alone, at once.
  static AVDictionary* encoder_options(const EncoderConfig& config) {
    AVDictionary* opts = nullptr;
    if (config.encoder == "libx264") {
      av_dict_set(&opts, "preset", config.preset.c_str(), 0);
      av_dict_set(&opts, "tune", "zerolatency", 0);
      av_dict_set(&opts, "intra-refresh", "1", 0);
      av_dict_set(&opts, "forced-idr", "1", 0);
      // ultrafast turns the deblocking filter off; on it costs ~1 ms a pair and buys the SSIM
      // goal at 4 Mbit/s (docs/BENCHMARKS.md "The eyes' codec").
      av_dict_set(&opts, "x264-params", "deblock=1,0,0", 0);
    } else if (config.encoder == "h264_nvenc") {
      av_dict_set(&opts, "preset", "p1", 0);
      av_dict_set(&opts, "tune", "ull", 0);
      av_dict_set(&opts, "zerolatency", "1", 0);
      av_dict_set(&opts, "rc", "cbr", 0);
      av_dict_set(&opts, "intra-refresh", "1", 0);
      av_dict_set(&opts, "forced-idr", "1", 0);
    } else {  // h264_vaapi: no intra refresh in libavcodec 5.1; periodic IDR every gop_size
      av_dict_set(&opts, "rc_mode", "CBR", 0);
    }
    return opts;
  }

  void alloc_frames(AVPixelFormat sw_format) {
    sw_frame_.reset(av_frame_alloc());
    sw_frame_->format = sw_format;
    sw_frame_->width = ctx_->width;
    sw_frame_->height = ctx_->height;
    if (const int err = av_frame_get_buffer(sw_frame_.get(), 0); err < 0)
      throw VideoError(failure(config_, "could not allocate a picture", err));
    hw_frame_.reset(av_frame_alloc());
    packet_.reset(av_packet_alloc());
    sws_.reset(sws_getContext(config_.eye_width_px, config_.eye_height_px, AV_PIX_FMT_BGR24,
                              config_.eye_width_px, config_.eye_height_px, sw_format,
                              SWS_FAST_BILINEAR, nullptr, nullptr, nullptr));
    if (!sws_ || !hw_frame_ || !packet_)
      throw VideoError("video encoder '" + config_.encoder + "': out of memory");
  }

  // Rate: a capped bit rate with a VBV of two frames, so no pair is much larger than its share
  // of the link (a large one would wait in the send queue).
  void set_rate(std::int64_t bitrate_bps) {
    ctx_->bit_rate = bitrate_bps;
    ctx_->rc_max_rate = bitrate_bps;
    ctx_->rc_buffer_size =
        static_cast<int>(std::min<double>(2.0 * bitrate_bps / config_.frame_rate_hz, 1e9));
  }

  void apply_requests(AVFrame* frame) {
    // libx264 reconfigures itself when it sees the context's rates change.
    const std::int64_t bitrate_bps = bitrate_bps_.load();
    if (bitrate_bps != ctx_->bit_rate) set_rate(bitrate_bps);
    frame->pict_type = AV_PICTURE_TYPE_NONE;
    if (intra_requested_.exchange(false)) {
      frame->pict_type = AV_PICTURE_TYPE_I;
      ++counters_.intra_requests;
    }
  }

  std::atomic<std::int64_t> bitrate_bps_;
  std::atomic<bool> intra_requested_{false};
  av::BufferPtr hw_device_, hw_frames_;
  av::CodecContextPtr ctx_;
  av::FramePtr sw_frame_, hw_frame_;
  av::PacketPtr packet_;
  av::SwsPtr sws_;  // NV12 for VA-API; YUV420P goes through i420_
  cv::Mat i420_;
  cv::Mat3b padded_bgr_;
  std::int64_t next_pts_ = 0;
  std::deque<PendingPair> pending_;
};

}  // namespace

std::unique_ptr<EyeEncoder> make_h264_encoder(const EncoderConfig& config) {
  return std::make_unique<H264Encoder>(config);
}

}  // namespace telex::video::detail
