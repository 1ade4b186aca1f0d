// SPDX-License-Identifier: MIT
// VideoReceiver: pairs decoded off the caller's thread, a lost pair answered with one PLI per
// round trip, and the picture back after the intra pair the PLI asks for.
#include "telex/local/link/video_receiver.h"

#include <gtest/gtest.h>

#include <chrono>
#include <mutex>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "telex/video/eye_encoder.h"

namespace telex::local {
namespace {

using namespace std::chrono_literals;

// Waits (bounded) for the decode thread to get to a count; the test's outcome never depends on
// how long it took.
template <typename Pred>
bool eventually(Pred p) {
  for (int i = 0; i < 2000 && !p(); ++i) std::this_thread::sleep_for(5ms);
  return p();
}

struct Fixture {
  std::mutex mu;
  std::vector<proto::PictureLoss> plis;
  std::vector<proto::VideoNack> nacks;
  std::atomic<std::int64_t> now_ns{1'000'000'000};
  std::atomic<std::int64_t> offset_ns{0};  // the remote's clock minus ours
  std::atomic<int> client_calls{0};        // the hooks that reach the client (round trip, offset)
  std::unique_ptr<video::EyeEncoder> encoder;
  std::unique_ptr<VideoReceiver> receiver;
  std::uint32_t frame_id = 0;

  explicit Fixture(bool with_nacks = false) {
    video::EncoderConfig c;
    c.eye_width_px = 96;
    c.eye_height_px = 64;
    c.threads = 1;
    encoder = video::EyeEncoder::create(c);
    VideoReceiver::Hooks h;
    h.send_pli = [this](const proto::PictureLoss& p) {
      std::lock_guard lock(mu);
      plis.push_back(p);
    };
    if (with_nacks)
      h.send_nack = [this](const proto::VideoNack& n) {
        std::lock_guard lock(mu);
        nacks.push_back(n);
      };
    h.rtt_ns = [this] {
      ++client_calls;
      return std::int64_t{20'000'000};
    };
    h.now_ns = [this] { return now_ns.load(); };
    h.clock_offset_ns = [this] {
      ++client_calls;
      return offset_ns.load();
    };
    receiver = std::make_unique<VideoReceiver>(std::move(h));
  }
  std::vector<std::uint8_t> next_pair() {
    ++frame_id;
    cv::Mat3b left(64, 96, cv::Vec3b(20, 40, static_cast<std::uint8_t>(frame_id * 3)));
    cv::Mat3b right(64, 96, cv::Vec3b(200, 40, static_cast<std::uint8_t>(frame_id * 3)));
    cv::circle(left, {static_cast<int>(frame_id % 90), 30}, 8, {255, 255, 255}, -1);
    std::vector<std::uint8_t> out;
    EXPECT_EQ(encoder->encode(left, right, frame_id, frame_id * 33'000'000ll, out),
              video::EncodeStatus::Ok);
    return out;
  }
  std::size_t nack_count() {
    std::lock_guard lock(mu);
    return nacks.size();
  }
  std::size_t pli_count() {
    std::lock_guard lock(mu);
    return plis.size();
  }
};

TEST(VideoReceiver, DecodesPairsOfTheRightSizeInOrder) {
  Fixture f;
  EXPECT_EQ(f.receiver->pair(), nullptr);
  for (int i = 0; i < 5; ++i) f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 5; }));
  const auto p = f.receiver->pair();
  ASSERT_NE(p, nullptr);
  EXPECT_EQ(p->frame_id, 5u);
  EXPECT_EQ(p->left_bgr.size(), cv::Size(96, 64));
  EXPECT_EQ(p->right_bgr.size(), cv::Size(96, 64));
  EXPECT_GT(p->right_bgr(5, 5)[0], 150);  // the right eye is the right eye
  EXPECT_LT(p->left_bgr(5, 5)[0], 60);
  EXPECT_EQ(f.receiver->pair(3 * 33'000'000ll)->frame_id, 3u);  // nearest capture among the kept
  EXPECT_EQ(f.pli_count(), 0u);
}

// A view taking the newest pair waits for the next only when it is due within the bound.
TEST(VideoReceiver, AViewWaitsForTheNextPairOnlyWhenItIsDueSoon) {
  constexpr std::int64_t ms = 1'000'000, period = 33 * ms, bound = 12 * ms;
  EXPECT_EQ(late_pair_wait_ns(100 * ms, period, 105 * ms, bound), 0) << "due in 28 ms: no wait";
  EXPECT_EQ(late_pair_wait_ns(100 * ms, period, 120 * ms, bound), 0) << "due in 13 ms: no wait";
  EXPECT_EQ(late_pair_wait_ns(100 * ms, period, 121 * ms, bound), bound + kLatePairSlackNs);
  EXPECT_EQ(late_pair_wait_ns(100 * ms, period, 125 * ms, bound), 8 * ms + kLatePairSlackNs);
  EXPECT_EQ(late_pair_wait_ns(100 * ms, period, 150 * ms, bound), kLatePairSlackNs)
      << "overdue: only the slack";
  EXPECT_EQ(late_pair_wait_ns(0, period, 125 * ms, bound), 0) << "no delivery time";
  EXPECT_EQ(late_pair_wait_ns(100 * ms, 0, 125 * ms, bound), 0) << "no period yet";
}

// wait_newer returns the pair decoded while it waits, and null when none comes in time; the
// period is the median gap of the kept pairs' captures (33 ms in the fixture).
TEST(VideoReceiver, WaitingForANewerPairReturnsItWhenDecodedElseNull) {
  Fixture f;
  EXPECT_EQ(f.receiver->pair_period_ns(), 0);
  for (int i = 0; i < 3; ++i) f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 3; }));
  EXPECT_EQ(f.receiver->pair_period_ns(), 33'000'000);
  EXPECT_EQ(f.receiver->pair()->delivered_ns, f.now_ns.load());
  EXPECT_EQ(f.receiver->wait_newer(3, 20ms), nullptr);
  std::thread pusher([&] {
    std::this_thread::sleep_for(20ms);
    f.receiver->push(f.next_pair());
  });
  const auto newer = f.receiver->wait_newer(3, 10s);
  pusher.join();
  ASSERT_NE(newer, nullptr);
  EXPECT_EQ(newer->frame_id, 4u);
  EXPECT_EQ(f.receiver->wait_newer(3, 0ms)->frame_id, 4u) << "already newer: at once";
}

// The station stops the receiver before its client goes: from then on no hook that reaches the
// client (round trip, clock offset, NACKs, PLIs) is called, later pairs wait undecoded, the last
// pair stays.
TEST(VideoReceiver, StoppedItCallsNoHookAndLaterPairsWaitUndecoded) {
  Fixture f;
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 1; }));
  f.receiver->stop();
  const int calls = f.client_calls.load();
  for (int i = 0; i < 3; ++i) f.receiver->push(f.next_pair());
  std::this_thread::sleep_for(100ms);  // time a running decode thread would take them in
  EXPECT_EQ(f.client_calls.load(), calls);
  EXPECT_EQ(f.receiver->counters().decoded.load(), 1u);
  EXPECT_EQ(f.receiver->counters().received.load(), 4u);
  ASSERT_NE(f.receiver->pair(), nullptr);
  EXPECT_EQ(f.receiver->pair()->frame_id, 1u);
  f.receiver->stop();  // again, as the destructor does
}

// Every pair decoded whole leaves its age at delivery (capture to the view, on the remote's
// clock), and the age the pair before it had reached by then; a damaged pair leaves none.
TEST(VideoReceiver, EveryPairDeliveredLeavesItsAgeAndThePreviousPairsAgeWhenReplaced) {
  Fixture f;
  f.offset_ns = -900'000'000;       // the remote's clock reads 100 ms when ours reads 1 s
  f.receiver->push(f.next_pair());  // captured at 33 ms, delivered at 100 ms
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 1; }));
  f.now_ns += 50'000'000;
  f.receiver->push(f.next_pair());  // captured at 66 ms, delivered at 150 ms
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 2; }));
  (void)f.next_pair();  // lost: the next pair is damaged, not delivered
  f.now_ns += 100'000'000;
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().damaged.load() == 1; }));
  const auto ages = f.receiver->delivery_ages();
  ASSERT_EQ(ages.delivered_ms.size(), 2u);
  EXPECT_NEAR(ages.delivered_ms[0], 67.0, 1e-6);
  EXPECT_NEAR(ages.delivered_ms[1], 84.0, 1e-6);
  ASSERT_EQ(ages.replaced_ms.size(), 1u);
  EXPECT_NEAR(ages.replaced_ms[0], 117.0, 1e-6);  // pair 1 (33 ms) replaced at 150 ms
}

// Pairs 33 ms apart, then none for 200 ms: with NACKs the decode thread wakes by itself and asks
// for the next pair as overdue, once; without (--no-repair) nothing is asked. Then the pair
// comes, only late.
TEST(VideoReceiver, AnOverduePairIsAskedForOnlyWhenNacksCanBeSent) {
  for (const bool with_nacks : {true, false}) {
    Fixture f(with_nacks);
    for (int i = 0; i < 6; ++i) {
      f.receiver->push(f.next_pair());
      ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == i + 1u; }));
      f.now_ns += 33'000'000;
    }
    f.now_ns += 200'000'000;
    if (with_nacks)
      ASSERT_TRUE(eventually([&] { return f.nack_count() == 1; }));
    else
      std::this_thread::sleep_for(100ms);  // time to wake, were it waiting for an overdue pair
    f.receiver->push(f.next_pair());
    ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 7; }));
    EXPECT_EQ(f.receiver->counters().nacks_sent.load(), with_nacks ? 1u : 0u) << with_nacks;
    EXPECT_EQ(f.receiver->counters().asked_overdue.load(), with_nacks ? 1u : 0u);
    EXPECT_EQ(f.nack_count(), with_nacks ? 1u : 0u);
    EXPECT_EQ(f.receiver->counters().repaired.load(), 0u);  // it was only late
  }
}

// The robot head's joints stamped in a pair's header come out with the decoded pair; a pair
// without them (no head reading at its capture) comes out without, and is not counted.
TEST(VideoReceiver, APairKeepsTheHeadPoseItWasCapturedAt) {
  Fixture f;
  const std::array<float, 3> joints{0.3f, -0.1f, 0.0f};
  auto posed = f.next_pair();
  ASSERT_TRUE(video::stamp_head_pose(posed, joints));
  f.receiver->push(std::move(posed));
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 1; }));
  ASSERT_TRUE(f.receiver->pair()->head_joint_rad.has_value());
  EXPECT_EQ(*f.receiver->pair()->head_joint_rad, joints);
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 2; }));
  EXPECT_EQ(f.receiver->pair()->frame_id, 2u);
  EXPECT_FALSE(f.receiver->pair()->head_joint_rad.has_value());
  EXPECT_EQ(f.receiver->counters().with_head_pose.load(), 1u);
}

TEST(VideoReceiver, ALostPairSendsOnePliPerRoundTripAndTheIntraPairRecovers) {
  Fixture f;
  for (int i = 0; i < 3; ++i) f.receiver->push(f.next_pair());
  (void)f.next_pair();  // lost on the way
  f.receiver->push(f.next_pair());
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().damaged.load() == 2; }));
  // Both damaged pairs came within one round trip: one PLI, one held.
  ASSERT_EQ(f.pli_count(), 1u);
  EXPECT_EQ(f.plis[0].last_good_seq, 2u);
  EXPECT_EQ(f.plis[0].reason, proto::PictureLossReason::MissingReference);
  EXPECT_EQ(f.receiver->counters().plis_held.load(), 1u);
  EXPECT_EQ(f.receiver->pair()->frame_id, 3u);  // the damaged pairs are not shown
  // After a round trip the still-missing reference asks again.
  f.now_ns += 150'000'000;
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().damaged.load() == 3; }));
  EXPECT_EQ(f.pli_count(), 2u);
  // The remote answers with an intra pair: whole pairs again.
  f.encoder->request_intra();
  f.receiver->push(f.next_pair());
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 5; }));
  EXPECT_EQ(f.receiver->counters().intra.load(), 2u);  // the first pair and the answer
  EXPECT_EQ(f.receiver->pair()->frame_id, 9u);
  EXPECT_EQ(f.pli_count(), 2u);
}

TEST(VideoReceiver, ALostPairIsAskedForAndTheResendKeepsThePictureWhole) {
  Fixture f(true);
  for (int i = 0; i < 3; ++i) f.receiver->push(f.next_pair());
  const auto lost = f.next_pair();  // encode_seq 3, lost on the way
  f.receiver->push(f.next_pair());
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.nack_count() == 1; }));
  EXPECT_EQ(f.nacks[0], (proto::VideoNack{3, 1}));
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 3; }));
  EXPECT_EQ(f.receiver->counters().held.load(), 2u);  // the pairs behind the gap wait
  f.receiver->push(lost);                             // the remote's resend
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 6; }));
  EXPECT_EQ(f.receiver->pair()->frame_id, 6u);
  EXPECT_EQ(f.receiver->counters().damaged.load(), 0u);
  EXPECT_EQ(f.receiver->counters().repaired.load(), 1u);
  EXPECT_EQ(f.receiver->counters().expected.load(), 6u);
  EXPECT_EQ(f.pli_count(), 0u);
}

TEST(VideoReceiver, AResendThatNeverComesIsGivenUpAndAsksForAnIntraPair) {
  Fixture f(true);
  for (int i = 0; i < 2; ++i) f.receiver->push(f.next_pair());
  (void)f.next_pair();
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.nack_count() >= 1; }));
  ASSERT_TRUE(eventually([&] { return f.receiver->counters().decoded.load() == 2; }));
  f.now_ns += 200'000'000;  // past the gap's deadline
  f.receiver->push(f.next_pair());
  ASSERT_TRUE(eventually([&] { return f.pli_count() == 1; }));
  EXPECT_EQ(f.receiver->counters().given_up.load(), 1u);
  EXPECT_EQ(f.plis[0].last_good_seq, 1u);
}

}  // namespace
}  // namespace telex::local
