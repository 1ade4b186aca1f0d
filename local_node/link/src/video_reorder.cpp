// SPDX-License-Identifier: MIT
// VideoReorder: pairs in encode_seq order, gaps NACKed within their deadline, then given up.
#include "telex/local/link/video_reorder.h"

#include <algorithm>

namespace telex::local {
namespace {

// Farther ahead than this is not a gap but a new sequence (a restarted encoder) ...
constexpr std::uint32_t kSeqWindow = 1024;
// ... and so is farther behind than this: a resend is at most the remote's 16 cached pairs old.
constexpr std::uint32_t kLateWindow = 64;

}  // namespace

std::int64_t VideoReorder::hold_ns(std::int64_t rtt_ns) const {
  return std::clamp<std::int64_t>(3 * std::max<std::int64_t>(rtt_ns, 0) + 10'000'000,
                                  std::min(cfg_.hold_min_ns, cfg_.hold_max_ns), cfg_.hold_max_ns);
}

std::int64_t VideoReorder::retry_ns(std::int64_t rtt_ns) const {
  return std::max<std::int64_t>(cfg_.retry_min_ns,
                                2 * std::max<std::int64_t>(rtt_ns, 0) + 2'000'000);
}

void VideoReorder::push(std::uint32_t seq, std::vector<std::uint8_t> frame, std::int64_t now_ns,
                        bool resent) {
  if (!started_) {
    started_ = true;
    next_seq_ = seq;
  }
  const std::uint32_t ahead = seq - next_seq_;  // serial arithmetic (RFC 1982)
  const std::uint32_t behind = next_seq_ - seq;
  if (ahead >= 0x8000'0000u && behind <= kLateWindow) {
    ++counters_.late;  // released or given up already
    return;
  }
  if (ahead >= kSeqWindow) {
    ++counters_.restarts;
    held_.clear();
    missing_.clear();
    next_seq_ = seq;
    have_newest_ = false;
    interval_count_ = 0;
  }
  if (held_.count(seq) != 0) {
    ++counters_.late;  // a second copy (a resend that crossed the original)
    return;
  }
  const auto was_missing = missing_.find(seq);
  if (was_missing != missing_.end()) {
    // Asked for as overdue and come before any later pair: a repair if it is the remote's copy,
    // else the pair itself, only late.
    if (!was_missing->second.overdue || resent) ++counters_.repaired;
    missing_.erase(was_missing);
  }
  if (seq == next_seq_)
    ++counters_.in_order;
  else
    ++counters_.held;
  // Every pair between the released ones and this one that is not here is missing from now on;
  // one asked for as overdue is now known to be a gap (its retries count from that NACK).
  for (std::uint32_t s = next_seq_; s != seq; ++s) {
    if (held_.count(s) != 0) continue;
    auto [it, added] = missing_.emplace(s, Missing{now_ns, 0, 0, false});
    if (!added && it->second.overdue) {
      it->second.overdue = false;  // a gap now: asked for again up to max_nacks times
      it->second.seen_ns = now_ns;
      it->second.nacks = 0;
    }
  }
  held_.emplace(seq, std::move(frame));
  note_arrival(seq, now_ns, resent);
}

void VideoReorder::note_arrival(std::uint32_t seq, std::int64_t now_ns, bool resent) {
  std::int64_t arrival_ns = now_ns;
  if (have_newest_) {
    const std::uint32_t ahead = seq - newest_seq_;
    if (ahead == 0 || ahead >= 0x8000'0000u) return;  // not newer: a repair or a late copy
    if (resent) {
      // A copy came when it was asked for, not on the pairs' schedule: the next pair is still
      // due an interval after this one was, not an interval after the copy.
      if (const std::int64_t interval = usual_interval_ns(); interval > 0)
        arrival_ns =
            std::min(now_ns, newest_arrival_ns_ + static_cast<std::int64_t>(ahead) * interval);
    } else if (ahead <= kIntervals) {
      // Pairs lost in between (many, as a stream starts with large pairs) still tell the
      // interval: the time since the newest, per pair.
      intervals_ns_[interval_count_ % kIntervals] =
          (now_ns - newest_arrival_ns_) / static_cast<std::int64_t>(ahead);
      ++interval_count_;
    }
  }
  have_newest_ = true;
  newest_seq_ = seq;
  newest_arrival_ns_ = arrival_ns;
  overdue_asked_ = false;
}

std::int64_t VideoReorder::usual_interval_ns() const {
  if (interval_count_ < kMinIntervals) return 0;
  const std::size_t n = std::min(interval_count_, kIntervals);
  std::array<std::int64_t, kIntervals> sorted = intervals_ns_;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.begin() + n);
  return std::max<std::int64_t>(sorted[n / 2], 0);
}

std::int64_t VideoReorder::overdue_ns() const {
  if (!cfg_.ask_overdue || interval_count_ < kMinIntervals) return 0;
  const std::int64_t interval = usual_interval_ns();
  return interval + std::max(interval / 2, cfg_.overdue_slack_min_ns);
}

void VideoReorder::ask_overdue(std::int64_t now_ns) {
  const std::int64_t overdue = overdue_ns();
  if (overdue == 0 || overdue_asked_ || now_ns - newest_arrival_ns_ < overdue) return;
  overdue_asked_ = true;
  const std::uint32_t next = newest_seq_ + 1;
  if (held_.count(next) != 0 || missing_.count(next) != 0) return;
  missing_.emplace(next, Missing{now_ns, 0, 0, true});
  ++counters_.asked_overdue;
}

void VideoReorder::release_in_order(std::vector<std::vector<std::uint8_t>>& ready) {
  for (auto it = held_.find(next_seq_); it != held_.end(); it = held_.find(next_seq_)) {
    ready.push_back(std::move(it->second));
    held_.erase(it);
    ++next_seq_;
  }
}

void VideoReorder::give_up_head(std::vector<std::vector<std::uint8_t>>& ready) {
  // Skip to the oldest pair held (the one nearest next_seq_ in serial order).
  auto oldest = held_.begin();
  for (auto it = held_.begin(); it != held_.end(); ++it)
    if (it->first - next_seq_ < oldest->first - next_seq_) oldest = it;
  for (std::uint32_t s = next_seq_; s != oldest->first; ++s) {
    missing_.erase(s);
    ++counters_.given_up;
  }
  next_seq_ = oldest->first;
  release_in_order(ready);
}

void VideoReorder::poll(std::int64_t now_ns, std::int64_t rtt_ns,
                        std::vector<std::vector<std::uint8_t>>& ready,
                        std::vector<proto::VideoNack>& nacks) {
  release_in_order(ready);
  while (!held_.empty()) {
    const auto head = missing_.find(next_seq_);
    const bool due = head == missing_.end() || now_ns - head->second.seen_ns >= hold_ns(rtt_ns);
    if (!due && held_.size() <= cfg_.max_held) break;
    give_up_head(ready);
  }
  ask_overdue(now_ns);
  // The NACKs due now, consecutive seqs joined into one request of at most kMaxVideoNackPairs.
  // An overdue pair is asked for again like a gap (its copy may be lost too), and again up to
  // max_nacks times once a later pair shows the gap.
  const std::int64_t retry = retry_ns(rtt_ns);
  std::vector<std::uint32_t> due;
  for (auto& [seq, m] : missing_) {
    if (m.nacks >= cfg_.max_nacks) continue;
    if (m.last_nack_ns != 0 && now_ns - m.last_nack_ns < retry) continue;
    m.last_nack_ns = now_ns;
    ++m.nacks;
    due.push_back(seq);
  }
  std::sort(due.begin(), due.end(),
            [this](std::uint32_t a, std::uint32_t b) { return a - next_seq_ < b - next_seq_; });
  const std::size_t first_new = nacks.size();
  for (std::uint32_t seq : due) {
    if (nacks.size() > first_new && nacks.back().first_seq + nacks.back().count == seq &&
        nacks.back().count < proto::kMaxVideoNackPairs) {
      ++nacks.back().count;
      continue;
    }
    nacks.push_back(proto::VideoNack{seq, 1});
    ++counters_.nacks;
  }
}

std::int64_t VideoReorder::next_wake_ns(std::int64_t rtt_ns) const {
  std::int64_t wake = 0;
  const auto consider = [&wake](std::int64_t t) { wake = wake == 0 ? t : std::min(wake, t); };
  const auto head = missing_.find(next_seq_);
  if (head != missing_.end() && !held_.empty()) consider(head->second.seen_ns + hold_ns(rtt_ns));
  for (const auto& [seq, m] : missing_)
    if (m.nacks < cfg_.max_nacks) consider(m.last_nack_ns + retry_ns(rtt_ns));
  if (const std::int64_t overdue = overdue_ns(); overdue != 0 && !overdue_asked_)
    consider(newest_arrival_ns_ + overdue);
  return wake;
}

}  // namespace telex::local
