// SPDX-License-Identifier: MIT
// VideoReceiver: the decode thread, PLIs rate-limited to one per round trip, the last few pairs.
#include "telex/local/video_receiver.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include "telex/base/periodic.h"
#include "telex/video/eye_decoder.h"

namespace telex::local {

struct VideoReceiver::Decoder {
  video::EyeDecoder decoder;
  video::DecodedPair out;
};

VideoReceiver::VideoReceiver(Hooks hooks)
    : hooks_(std::move(hooks)), decoder_(std::make_unique<Decoder>()) {
  thread_ = std::thread([this] { run(); });
  name_thread(thread_.native_handle(), "telex-eyes");
}

VideoReceiver::~VideoReceiver() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_one();
  thread_.join();
}

void VideoReceiver::push(std::vector<std::uint8_t> frame) {
  counters_.received.fetch_add(1, std::memory_order_relaxed);
  {
    std::lock_guard lock(mu_);
    // A decoder behind by kMaxQueued pairs drops the oldest; the gap it leaves asks for an intra.
    if (queue_.size() >= kMaxQueued) {
      queue_.pop_front();
      counters_.queue_dropped.fetch_add(1, std::memory_order_relaxed);
    }
    queue_.push_back(std::move(frame));
  }
  cv_.notify_one();
}

std::shared_ptr<const EyePair> VideoReceiver::pair(std::int64_t want_capture_ns) const {
  std::lock_guard lock(pairs_mu_);
  if (pairs_.empty()) return nullptr;
  if (want_capture_ns == 0) return pairs_.back();
  return *std::min_element(pairs_.begin(), pairs_.end(), [&](const auto& a, const auto& b) {
    return std::llabs(a->capture_ns - want_capture_ns) <
           std::llabs(b->capture_ns - want_capture_ns);
  });
}

void VideoReceiver::run() {
  // Decoding is the view's work: below the depth path, as the stereo view (nice 5).
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 5);
  for (;;) {
    std::vector<std::uint8_t> bytes;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      bytes = std::move(queue_.front());
      queue_.pop_front();
    }
    decode_one(bytes);
  }
}

void VideoReceiver::decode_one(const std::vector<std::uint8_t>& bytes) {
  auto& d = *decoder_;
  const video::DecodeStatus status = d.decoder.decode(bytes, d.out);
  switch (status) {
    case video::DecodeStatus::Ok: {
      counters_.decoded.fetch_add(1, std::memory_order_relaxed);
      if (d.out.header.is_intra) counters_.intra.fetch_add(1, std::memory_order_relaxed);
      last_good_seq_ = d.out.header.encode_seq;
      counters_.eye_width_px.store(d.out.left_bgr.cols, std::memory_order_relaxed);
      counters_.eye_height_px.store(d.out.left_bgr.rows, std::memory_order_relaxed);
      auto p = std::make_shared<EyePair>();
      p->frame_id = d.out.header.frame_id;
      p->capture_ns = d.out.header.capture_ns;
      p->left_bgr = d.out.left_bgr.clone();  // the decoder reuses its images
      p->right_bgr = d.out.right_bgr.clone();
      std::lock_guard lock(pairs_mu_);
      pairs_.push_back(std::move(p));
      if (pairs_.size() > kKeptPairs) pairs_.pop_front();
      return;
    }
    case video::DecodeStatus::MissingReference:
      counters_.damaged.fetch_add(1, std::memory_order_relaxed);
      ask_for_intra(proto::PictureLossReason::MissingReference);
      return;
    case video::DecodeStatus::BadHeader:
    case video::DecodeStatus::DecodeError:
      counters_.decode_errors.fetch_add(1, std::memory_order_relaxed);
      ask_for_intra(proto::PictureLossReason::DecodeError);
      return;
    case video::DecodeStatus::NoPicture:
      // libavcodec holds back pictures without their references: as lost as a damaged one.
      if (d.decoder.needs_intra()) {
        counters_.damaged.fetch_add(1, std::memory_order_relaxed);
        ask_for_intra(proto::PictureLossReason::MissingReference);
      }
      return;
  }
}

void VideoReceiver::ask_for_intra(proto::PictureLossReason reason) {
  // One PLI per round trip: the intra pair it asks for cannot have arrived sooner.
  const std::int64_t now = hooks_.now_ns();
  const std::int64_t wait = std::max(kMinPliIntervalNs, hooks_.rtt_ns ? hooks_.rtt_ns() : 0);
  if (last_pli_ns_ != 0 && now - last_pli_ns_ < wait) {
    counters_.plis_held.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  last_pli_ns_ = now;
  counters_.plis_sent.fetch_add(1, std::memory_order_relaxed);
  if (hooks_.send_pli) hooks_.send_pli(proto::PictureLoss{last_good_seq_, reason});
}

}  // namespace telex::local
