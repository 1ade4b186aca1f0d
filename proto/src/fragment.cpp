// SPDX-License-Identifier: MIT
// UDP fragmentation and the bounded, newest-frame-wins reassembler.
#include "telex/proto/fragment.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "byte_io.h"

namespace telex::proto {
namespace {

bool older(std::uint32_t a, std::uint32_t b) { return static_cast<std::int32_t>(a - b) < 0; }

std::size_t fragment_count(std::size_t total) {
  return (total + kFragmentChunkBytes - 1) / kFragmentChunkBytes;
}

}  // namespace

std::vector<std::vector<std::uint8_t>> fragment_message(std::span<const std::uint8_t> message,
                                                        std::uint32_t message_id,
                                                        std::uint32_t frame_id) {
  if (message.empty()) throw std::invalid_argument("fragment_message: empty message");
  const std::size_t count = fragment_count(message.size());
  if (count > 0xFFFF || message.size() > 0xFFFFFFFFu)
    throw std::invalid_argument("fragment_message: message needs more than 65535 fragments");
  std::vector<std::vector<std::uint8_t>> out(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t off = i * kFragmentChunkBytes;
    const std::size_t len = std::min(kFragmentChunkBytes, message.size() - off);
    auto& d = out[i];
    d.reserve(kFragmentHeaderSize + len);
    detail::Writer w(d);
    w.u16(kFragmentMagic);
    w.u16(static_cast<std::uint16_t>(i));
    w.u16(static_cast<std::uint16_t>(count));
    w.u16(0);
    w.u32(message_id);
    w.u32(frame_id);
    w.u32(static_cast<std::uint32_t>(message.size()));
    w.bytes(message.subspan(off, len));
  }
  return out;
}

std::optional<FragmentHeader> parse_fragment_header(std::span<const std::uint8_t> datagram) {
  if (datagram.size() <= kFragmentHeaderSize || datagram.size() > kMaxDatagramBytes)
    return std::nullopt;
  detail::Reader r(datagram);
  FragmentHeader h;
  h.magic = r.u16();
  h.index = r.u16();
  h.count = r.u16();
  h.reserved = r.u16();
  h.message_id = r.u32();
  h.frame_id = r.u32();
  h.total_len = r.u32();
  if (!r.ok() || h.magic != kFragmentMagic || h.total_len == 0 || h.count == 0 ||
      h.index >= h.count || fragment_count(h.total_len) != h.count)
    return std::nullopt;
  // Fixed chunking: every fragment but the last is full, so offsets follow from the index.
  const std::size_t off = static_cast<std::size_t>(h.index) * kFragmentChunkBytes;
  const std::size_t expect = std::min(kFragmentChunkBytes, h.total_len - off);
  if (datagram.size() - kFragmentHeaderSize != expect) return std::nullopt;
  return h;
}

Reassembler::Reassembler(ReassemblerLimits limits) : limits_(limits) {}

void Reassembler::note_message_id(std::uint32_t id, std::uint16_t count) {
  const std::uint32_t ahead = id - next_message_id_;      // wraps
  if (have_message_id_ && ahead == 0xFFFF'FFFFu) return;  // another fragment of the last message
  ++counters_.messages_by_fragments[std::min<std::size_t>(count, 8) - 1];
  if (!have_message_id_) {
    have_message_id_ = true;
    next_message_id_ = id + 1;
    return;
  }
  if (ahead < 65536u) {
    counters_.messages_unseen += ahead;
    next_message_id_ = id + 1;
    return;
  }
  if (next_message_id_ - id <= 65536u) return;  // a late message, already counted as lost
  next_message_id_ = id + 1;                    // the sender restarted its sequence
}

bool Reassembler::completed_lately(std::uint32_t id) const {
  const std::size_t n = std::min(completed_count_, kCompletedIds);
  return std::find(completed_ids_.begin(), completed_ids_.begin() + n, id) !=
         completed_ids_.begin() + n;
}

void Reassembler::drop(std::map<std::uint32_t, Partial>::iterator it, std::uint64_t& counter) {
  buffered_bytes_ -= it->second.bytes.size();
  counters_.fragments_missing += it->second.count - it->second.received;
  partial_.erase(it);
  ++counter;
}

bool Reassembler::evict_oldest() {
  if (partial_.empty()) return false;
  auto victim = partial_.begin();
  for (auto it = partial_.begin(); it != partial_.end(); ++it) {
    const Partial& p = it->second;
    const Partial& v = victim->second;
    if (older(p.frame_id, v.frame_id) || (p.frame_id == v.frame_id && p.first_ns < v.first_ns))
      victim = it;
  }
  drop(victim, counters_.dropped_bound);
  return true;
}

void Reassembler::expire(std::uint64_t now_ns) {
  for (auto it = partial_.begin(); it != partial_.end();) {
    if (now_ns >= it->second.first_ns && now_ns - it->second.first_ns > limits_.timeout_ns) {
      auto dead = it++;
      drop(dead, counters_.dropped_timeout);
    } else {
      ++it;
    }
  }
}

std::optional<std::vector<std::uint8_t>> Reassembler::push(std::span<const std::uint8_t> datagram,
                                                           std::uint64_t now_ns) {
  expire(now_ns);
  const auto h = parse_fragment_header(datagram);
  if (!h || h->total_len > limits_.max_message_bytes || h->total_len > limits_.max_buffered_bytes) {
    ++counters_.malformed;
    return std::nullopt;
  }
  if (have_newest_ && older(h->frame_id, newest_completed_frame_)) {
    ++counters_.stale;
    return std::nullopt;
  }
  const auto chunk = datagram.subspan(kFragmentHeaderSize);
  ++counters_.fragments;
  // A message sent twice (a repair, section 4) completes once; the other copy's fragments, and
  // the copy of a one-fragment message, are duplicates, not a new message.
  if (partial_.count(h->message_id) == 0 && completed_lately(h->message_id)) {
    ++counters_.duplicates;
    return std::nullopt;
  }
  note_message_id(h->message_id, h->count);
  std::vector<std::uint8_t> done;
  auto it = partial_.find(h->message_id);
  if (h->count == 1) {
    if (it != partial_.end()) {
      ++counters_.malformed;
      return std::nullopt;
    }
    done.assign(chunk.begin(), chunk.end());
  } else {
    if (it == partial_.end()) {
      while (partial_.size() >= limits_.max_in_flight ||
             buffered_bytes_ + h->total_len > limits_.max_buffered_bytes) {
        if (!evict_oldest()) break;
      }
      Partial p;
      p.frame_id = h->frame_id;
      p.count = h->count;
      p.first_ns = now_ns;
      p.bytes.resize(h->total_len);
      p.have.assign(h->count, false);
      buffered_bytes_ += h->total_len;
      it = partial_.emplace(h->message_id, std::move(p)).first;
    }
    Partial& p = it->second;
    if (p.frame_id != h->frame_id || p.count != h->count || p.bytes.size() != h->total_len) {
      ++counters_.malformed;
      return std::nullopt;
    }
    if (p.have[h->index]) {
      ++counters_.duplicates;
      return std::nullopt;
    }
    p.have[h->index] = true;
    std::memcpy(p.bytes.data() + static_cast<std::size_t>(h->index) * kFragmentChunkBytes,
                chunk.data(), chunk.size());
    if (++p.received < p.count) return std::nullopt;
    done = std::move(p.bytes);
    buffered_bytes_ -= h->total_len;
    partial_.erase(it);
  }
  ++counters_.completed;
  completed_ids_[completed_count_++ % kCompletedIds] = h->message_id;
  if (!have_newest_ || older(newest_completed_frame_, h->frame_id)) {
    have_newest_ = true;
    newest_completed_frame_ = h->frame_id;
    // The newest frame wins: what is still missing of older frames will never be shown.
    for (auto o = partial_.begin(); o != partial_.end();) {
      if (older(o->second.frame_id, newest_completed_frame_)) {
        auto dead = o++;
        drop(dead, counters_.dropped_superseded);
      } else {
        ++o;
      }
    }
  }
  return done;
}

}  // namespace telex::proto
