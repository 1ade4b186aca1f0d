// SPDX-License-Identifier: MIT
// VideoReceiver: the decode thread, gaps NACKed and held (VideoReorder), PLIs rate-limited to one
// per round trip, the last few pairs.
#include "telex/local/link/video_receiver.h"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>

#include "telex/base/periodic.h"
#include "telex/video/eye_decoder.h"
#include "telex/video/frame_header.h"

namespace telex::local {

struct VideoReceiver::Decoder {
  video::EyeDecoder decoder;
  video::DecodedPair out;
};

namespace {

// Without a way to ask again, waiting for a missing pair only delays the ones behind it, and an
// overdue pair is not asked for.
VideoReorderConfig reorder_config(const VideoReceiver::Hooks& hooks, VideoReorderConfig cfg) {
  if (!hooks.send_nack) {
    cfg.hold_min_ns = cfg.hold_max_ns = 0;
    cfg.ask_overdue = false;
  }
  return cfg;
}

}  // namespace

VideoReceiver::VideoReceiver(Hooks hooks, VideoReorderConfig reorder)
    : hooks_(std::move(hooks)),
      reorder_(reorder_config(hooks_, reorder)),
      decoder_(std::make_unique<Decoder>()) {
  thread_ = std::thread([this] { fault_.run([this] { run(); }); });
  name_thread(thread_.native_handle(), "telex-eyes");
}

VideoReceiver::~VideoReceiver() { stop(); }

void VideoReceiver::stop() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
}

void VideoReceiver::push(std::vector<std::uint8_t> frame, bool resent) {
  counters_.received.fetch_add(1, std::memory_order_relaxed);
  const std::int64_t arrival_ns = hooks_.now_ns();
  {
    std::lock_guard lock(mu_);
    // A decoder behind by kMaxQueued pairs drops the oldest; the gap it leaves asks for an intra.
    if (queue_.size() >= kMaxQueued) {
      queue_.pop_front();
      counters_.queue_dropped.fetch_add(1, std::memory_order_relaxed);
    }
    queue_.push_back(Arrived{std::move(frame), arrival_ns, resent});
  }
  cv_.notify_one();
}

std::int64_t late_pair_wait_ns(std::int64_t delivered_ns, std::int64_t period_ns,
                               std::int64_t now_ns, std::int64_t max_wait_ns) {
  if (delivered_ns == 0 || period_ns <= 0) return 0;
  const std::int64_t due_in = delivered_ns + period_ns - now_ns;
  if (due_in > max_wait_ns) return 0;  // the newest is young enough: the next is far
  return std::max<std::int64_t>(due_in, 0) + kLatePairSlackNs;
}

std::shared_ptr<const EyePair> VideoReceiver::wait_newer(std::uint32_t frame_id,
                                                         std::chrono::nanoseconds timeout) const {
  std::unique_lock lock(pairs_mu_);
  const bool came = pairs_cv_.wait_for(
      lock, timeout, [&] { return !pairs_.empty() && pairs_.back()->frame_id != frame_id; });
  return came ? pairs_.back() : nullptr;
}

std::int64_t VideoReceiver::pair_period_ns() const {
  std::vector<std::int64_t> gaps;
  {
    std::lock_guard lock(pairs_mu_);
    for (std::size_t i = 1; i < pairs_.size(); ++i)
      gaps.push_back(pairs_[i]->capture_ns - pairs_[i - 1]->capture_ns);
  }
  if (gaps.size() < 2) return 0;
  const auto mid = gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2);
  std::nth_element(gaps.begin(), mid, gaps.end());
  return std::max<std::int64_t>(*mid, 0);
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
  std::deque<Arrived> arrived;
  for (;;) {
    {
      std::unique_lock lock(mu_);
      const std::int64_t rtt = hooks_.rtt_ns ? hooks_.rtt_ns() : 0;
      const std::int64_t wake_ns = reorder_.next_wake_ns(rtt);
      const auto ready = [this] { return stopping_ || !queue_.empty(); };
      if (wake_ns == 0) {
        cv_.wait(lock, ready);
      } else {
        const std::int64_t wait_ns = std::max<std::int64_t>(wake_ns - hooks_.now_ns(), 0);
        cv_.wait_for(lock, std::chrono::nanoseconds(wait_ns), ready);
      }
      if (stopping_) return;
      arrived.swap(queue_);
    }
    take_and_decode(arrived);
    arrived.clear();
  }
}

void VideoReceiver::take_and_decode(std::deque<Arrived>& arrived) {
  const std::int64_t now = hooks_.now_ns();
  const std::int64_t rtt = hooks_.rtt_ns ? hooks_.rtt_ns() : 0;
  std::vector<std::vector<std::uint8_t>> ready;
  std::vector<proto::VideoNack> nacks;
  // One pair at a time, as they came: what is in order is released before the next is taken.
  for (auto& a : arrived) {
    const video::ParsedFrame parsed = video::parse_frame(a.bytes);
    if (parsed.status != video::HeaderStatus::Ok) {
      ready.push_back(std::move(a.bytes));  // the decoder counts it as an error
      continue;
    }
    reorder_.push(parsed.header.encode_seq, std::move(a.bytes), a.arrival_ns, a.resent);
    reorder_.poll(now, rtt, ready, nacks);
  }
  reorder_.poll(now, rtt, ready, nacks);  // deadlines and retries, with or without new pairs
  const VideoReorderCounters& rc = reorder_.counters();
  counters_.repaired.store(rc.repaired, std::memory_order_relaxed);
  counters_.given_up.store(rc.given_up, std::memory_order_relaxed);
  counters_.held.store(rc.held, std::memory_order_relaxed);
  counters_.late.store(rc.late, std::memory_order_relaxed);
  counters_.expected.store(rc.in_order + rc.held + rc.given_up, std::memory_order_relaxed);
  counters_.asked_overdue.store(rc.asked_overdue, std::memory_order_relaxed);
  for (const auto& n : nacks) {
    counters_.nacks_sent.fetch_add(1, std::memory_order_relaxed);
    if (hooks_.send_nack) hooks_.send_nack(n);
  }
  for (const auto& bytes : ready) decode_one(bytes);
}

void VideoReceiver::decode_one(const std::vector<std::uint8_t>& bytes) {
  auto& d = *decoder_;
  const video::DecodeStatus status = d.decoder.decode(bytes, d.out);
  switch (status) {
    case video::DecodeStatus::Ok: {
      last_good_seq_ = d.out.header.encode_seq;
      auto p = std::make_shared<EyePair>();
      p->frame_id = d.out.header.frame_id;
      p->capture_ns = d.out.header.capture_ns;
      p->head_joint_rad = d.out.header.head_joint_rad;
      p->left_bgr = d.out.left_bgr.clone();  // the decoder reuses its images
      p->right_bgr = d.out.right_bgr.clone();
      p->delivered_ns = hooks_.now_ns();
      const std::int64_t capture_ns = p->capture_ns;
      const bool posed = p->head_joint_rad.has_value();
      {
        std::lock_guard lock(pairs_mu_);
        pairs_.push_back(std::move(p));
        if (pairs_.size() > kKeptPairs) pairs_.pop_front();
      }
      record_delivery(capture_ns);
      // Counted once the pair and its age can be had: a reader that sees `decoded` reach N (an
      // acquire load) finds the N-th pair in pair() and its age in delivery_ages(). Counting
      // first let a test take pair() while it was still null (a SEGV in CI).
      if (d.out.header.is_intra) counters_.intra.fetch_add(1, std::memory_order_relaxed);
      if (posed) counters_.with_head_pose.fetch_add(1, std::memory_order_relaxed);
      counters_.eye_width_px.store(d.out.left_bgr.cols, std::memory_order_relaxed);
      counters_.eye_height_px.store(d.out.left_bgr.rows, std::memory_order_relaxed);
      counters_.decoded.fetch_add(1, std::memory_order_release);
      pairs_cv_.notify_all();
      return;
    }
    case video::DecodeStatus::MissingReference:
      // As above: asked (or held) before it is counted.
      ask_for_intra(proto::PictureLossReason::MissingReference);
      counters_.damaged.fetch_add(1, std::memory_order_release);
      return;
    case video::DecodeStatus::BadHeader:
    case video::DecodeStatus::DecodeError:
      ask_for_intra(proto::PictureLossReason::DecodeError);
      counters_.decode_errors.fetch_add(1, std::memory_order_release);
      return;
    case video::DecodeStatus::NoPicture:
      // libavcodec holds back pictures without their references: as lost as a damaged one.
      if (d.decoder.needs_intra()) {
        ask_for_intra(proto::PictureLossReason::MissingReference);
        counters_.damaged.fetch_add(1, std::memory_order_release);
      }
      return;
  }
}

void VideoReceiver::record_delivery(std::int64_t capture_ns) {
  const std::int64_t now_remote_ns =
      hooks_.now_ns() + (hooks_.clock_offset_ns ? hooks_.clock_offset_ns() : 0);
  const std::int64_t previous_ns = last_capture_ns_;
  last_capture_ns_ = capture_ns;
  std::lock_guard lock(pairs_mu_);
  if (ages_.delivered_ms.size() >= kMaxAgeSamples) return;
  ages_.delivered_ms.push_back(static_cast<double>(now_remote_ns - capture_ns) / 1e6);
  if (previous_ns != 0)
    ages_.replaced_ms.push_back(static_cast<double>(now_remote_ns - previous_ns) / 1e6);
}

VideoReceiver::DeliveryAges VideoReceiver::delivery_ages() const {
  std::lock_guard lock(pairs_mu_);
  return ages_;
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
