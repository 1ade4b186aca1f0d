// SPDX-License-Identifier: MIT
// The eyes on the station: encoded pairs from the network thread are decoded in order on their
// own thread (never the haptic or network thread). A missing pair holds the ones behind it and is
// asked for again (VideoNack, VideoReorder) until its deadline; a lost reference then sends a
// Picture Loss Indication, at most one per round trip (and 100 ms); the view takes the newest
// whole pair.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "telex/base/pi_mutex.h"
#include "telex/base/thread_fault.h"
#include "telex/local/link/video_reorder.h"
#include "telex/proto/messages.h"

namespace telex::local {

// One decoded pair, as the remote captured it.
struct EyePair {
  std::uint32_t frame_id = 0;
  std::int64_t capture_ns = 0;  // the remote's clock
  // The robot head's joints (yaw, pitch, roll) at capture_ns, when the remote has a head.
  std::optional<std::array<float, 3>> head_joint_rad;
  cv::Mat3b left_bgr, right_bgr;
  std::int64_t delivered_ns = 0;  // when it was decoded whole (the receiver's now_ns)
};

// How long a view about to take the newest pair (delivered at `delivered_ns`, pairs coming every
// `period_ns`) waits for the next one, by the clock of `now_ns`: until the next is due plus
// kLatePairSlackNs when that is at most `max_wait_ns` away, else not at all (0). Unknown
// period or delivery (0): no wait. The slack covers the delivery's jitter (a pair's delivered
// age has a p99 about 8 ms above its median): at 3 ms 5-16 % of the waits ended without the pair
// and showed one two periods old (glass to glass p99 54-71 ms in 6 runs); at 8 ms 1-2 % (42-52 ms).
inline constexpr std::int64_t kLatePairSlackNs = 8'000'000;
std::int64_t late_pair_wait_ns(std::int64_t delivered_ns, std::int64_t period_ns,
                               std::int64_t now_ns, std::int64_t max_wait_ns);

struct VideoReceiverCounters {
  std::atomic<std::uint64_t> received{0};       // EncodedVideo messages taken
  std::atomic<std::uint64_t> queue_dropped{0};  // dropped before decoding: the decoder fell behind
  std::atomic<std::uint64_t> decoded{0};        // pairs decoded whole (shown when asked for)
  std::atomic<std::uint64_t> damaged{0};  // decoded on a missing reference or held back: not shown
  std::atomic<std::uint64_t> decode_errors{0};   // bad header or refused by the codec
  std::atomic<std::uint64_t> intra{0};           // intra pairs decoded
  std::atomic<std::uint64_t> with_head_pose{0};  // of the pairs decoded whole, those with one
  std::atomic<std::uint64_t> plis_sent{0};       //
  std::atomic<std::uint64_t> plis_held{0};       // PLIs not sent: one went out less than an RTT ago
  // Repair (VideoReorder): NACKs sent, missing pairs that came in time, missing pairs given up,
  // pairs that waited behind a gap, copies that came too late or twice.
  std::atomic<std::uint64_t> nacks_sent{0};
  std::atomic<std::uint64_t> repaired{0};
  std::atomic<std::uint64_t> given_up{0};
  std::atomic<std::uint64_t> held{0};
  std::atomic<std::uint64_t> late{0};
  std::atomic<std::uint64_t> expected{0};  // pairs the sequence accounts for: arrived or given up
  std::atomic<std::uint64_t> asked_overdue{0};         // pairs asked for before a later one came
  std::atomic<int> eye_width_px{0}, eye_height_px{0};  // of the newest pair decoded whole
};

class VideoReceiver {
 public:
  struct Hooks {
    std::function<void(const proto::PictureLoss&)> send_pli;  // any thread
    // Unset: nothing is asked again and a gap is given up at once (the remote keeps no pairs).
    std::function<void(const proto::VideoNack&)> send_nack;  // any thread
    std::function<std::int64_t()> rtt_ns;                    // the link's round trip (0: unknown)
    std::function<std::int64_t()> now_ns;                    // monotonic
    // The remote's clock minus now_ns()'s (the heartbeat's offset; unset or 0: unknown), so
    // that a pair's age counts from its capture_ns.
    std::function<std::int64_t()> clock_offset_ns;
  };
  // Capture to delivery of every pair decoded whole, on the remote's clock: `delivered` when it
  // reached the view (the view shows it from then on), `replaced` the age the pair before it had
  // reached at that moment: the oldest that pair was while it was the newest, what a display at
  // any rate showed at worst. Both in ms, in delivery order, at most kMaxAgeSamples.
  struct DeliveryAges {
    std::vector<double> delivered_ms, replaced_ms;
  };
  explicit VideoReceiver(Hooks hooks, VideoReorderConfig reorder = {});
  ~VideoReceiver();  // stop()
  VideoReceiver(const VideoReceiver&) = delete;
  VideoReceiver& operator=(const VideoReceiver&) = delete;

  // Network thread: takes the pair's bytes (never blocks on the decoder); `resent` when the remote
  // sent it again on a VideoNack (kFlagRepair).
  void push(std::vector<std::uint8_t> frame, bool resent = false);
  // Stops and joins the decode thread: after it returns no hook but now_ns (push's arrival stamp)
  // is called, so the client the others reach may go. Pairs pushed later wait undecoded; pair()
  // keeps the last ones. Idempotent.
  void stop();
  // Any thread: the whole pair captured nearest `want_capture_ns` (0: the newest) among the last
  // few decoded, or null before the first.
  std::shared_ptr<const EyePair> pair(std::int64_t want_capture_ns = 0) const;
  // Any thread: the newest pair once one newer than `frame_id` is decoded, waiting at most
  // `timeout` for it (std::chrono's steady clock); null if none came by then.
  std::shared_ptr<const EyePair> wait_newer(std::uint32_t frame_id,
                                            std::chrono::nanoseconds timeout) const;
  // The median capture interval of the last pairs kept (0 before three are).
  std::int64_t pair_period_ns() const;
  const VideoReceiverCounters& counters() const { return counters_; }
  DeliveryAges delivery_ages() const;
  // The decode thread's last-resort catch: empty while it has not failed (the station polls it).
  std::optional<ThreadFaultReport> thread_fault() const { return fault_.report(); }

  // The shortest time between two PLIs, whatever the round trip.
  static constexpr std::int64_t kMinPliIntervalNs = 100'000'000;
  static constexpr std::size_t kMaxAgeSamples = 1 << 20;

 private:
  void run();
  // Decode thread: moves newly pushed pairs into the reorder buffer, sends its NACKs, decodes
  // what it releases.
  struct Arrived {
    std::vector<std::uint8_t> bytes;
    std::int64_t arrival_ns = 0;  // stamped by push(): the decode thread may take it later
    bool resent = false;
  };
  void take_and_decode(std::deque<Arrived>& arrived);
  void decode_one(const std::vector<std::uint8_t>& bytes);
  // Decode thread: the ages of a pair captured at `capture_ns` (remote clock) delivered now.
  void record_delivery(std::int64_t capture_ns);
  void ask_for_intra(proto::PictureLossReason reason);

  Hooks hooks_;
  VideoReceiverCounters counters_;
  ThreadFault fault_{"eyes (telex-eyes)"};
  // Taken by the real-time network thread (push) and the decode thread at nice 5: priority
  // inheritance, so threads between them cannot keep the network thread waiting.
  PiMutex mu_;
  std::condition_variable_any cv_;
  std::deque<Arrived> queue_;  // guarded by mu_
  bool stopping_ = false;      // guarded by mu_
  mutable std::mutex pairs_mu_;
  mutable std::condition_variable pairs_cv_;          // a pair was added to pairs_
  std::deque<std::shared_ptr<const EyePair>> pairs_;  // the last kKeptPairs, oldest first
  DeliveryAges ages_;                                 // guarded by pairs_mu_
  std::int64_t last_capture_ns_ = 0;                  // decode thread: the pair delivered last
  static constexpr std::size_t kKeptPairs = 4;
  static constexpr std::size_t kMaxQueued = 8;
  std::int64_t last_pli_ns_ = 0;     // decode thread
  std::uint32_t last_good_seq_ = 0;  // decode thread
  VideoReorder reorder_;             // decode thread
  struct Decoder;
  std::unique_ptr<Decoder> decoder_;  // decode thread
  std::thread thread_;
};

}  // namespace telex::local
