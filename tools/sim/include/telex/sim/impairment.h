// SPDX-License-Identifier: MIT
// Deterministic network impairment (a rate limit, loss, delay, jitter, reorder, duplicate,
// corrupt) for datagrams.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace telex::sim {

// Probabilities are per datagram in [0, 1]; times in milliseconds. validate() names a bad field.
struct ImpairmentConfig {
  double loss = 0.0;
  double delay_ms = 0.0;
  double jitter_ms = 0.0;  // uniform in [-jitter, +jitter] around delay, never below zero
  double reorder = 0.0;  // held back by reorder_hold_ms on top of its delay, so later ones pass it
  double reorder_hold_ms = 10.0;
  double duplicate = 0.0;  // a second copy delivered right after the first
  double corrupt = 0.0;    // one random bit of one random byte flipped (what netem does)
  std::uint64_t seed = 1;
  // A bottleneck before the rest (0 = none): a token bucket of rate_limit_mbit (10^6 bit/s)
  // holding at most rate_burst_bytes, in front of a FIFO queue that holds at most rate_queue_ms
  // of the rate; a datagram that would wait longer is dropped (rate_dropped). The sending side of
  // tc's tbf with its "latency".
  double rate_limit_mbit = 0.0;
  double rate_burst_bytes = 15'000.0;  // ten 1500-byte datagrams pass at once
  double rate_queue_ms = 100.0;
  // When the limit holds, in seconds from the first datagram: [from, until) (until 0 = for ever),
  // so that one run shows a sender finding a bottleneck and the bottleneck going away.
  double rate_limit_from_s = 0.0;
  double rate_limit_until_s = 0.0;
};

// Throws std::invalid_argument naming the first field out of range.
void validate(const ImpairmentConfig& config);

struct ImpairmentCounters {
  std::uint64_t received = 0;
  std::uint64_t dropped = 0;     // lost
  std::uint64_t delivered = 0;   // copies scheduled, duplicates included
  std::uint64_t reordered = 0;   // held back
  std::uint64_t duplicated = 0;  // extra copies
  std::uint64_t corrupted = 0;   // datagrams with a flipped bit
  std::uint64_t bytes_in = 0;
  std::uint64_t rate_dropped = 0;  // dropped by the rate limit's full queue
  std::uint64_t rate_queued = 0;   // waited for tokens (delayed by the rate limit)
  std::uint64_t bytes_out = 0;     // bytes of the copies scheduled, duplicates included
};

struct Delivery {
  std::int64_t deliver_at_ns = 0;
  std::vector<std::uint8_t> bytes;
};

// One direction of a link. Pure apart from its seeded generator: the same config, datagrams and
// times give the same deliveries. Datagrams that are not held back keep their arrival order even
// under jitter (a queue never lets a later packet overtake an earlier one unless told to reorder),
// so reordering is only what `reorder` asks for.
class Impairment {
 public:
  explicit Impairment(const ImpairmentConfig& config);

  // The copies of `datagram` to send and when; empty when it is lost.
  std::vector<Delivery> process(std::span<const std::uint8_t> datagram, std::int64_t now_ns);

  const ImpairmentCounters& counters() const { return counters_; }
  const ImpairmentConfig& config() const { return config_; }

 private:
  std::uint64_t next_u64();
  double next_unit();  // [0, 1)
  // When the rate limit lets a datagram of `bytes` leave, or -1 when its queue is full.
  std::int64_t shape(std::size_t bytes, std::int64_t now_ns);
  ImpairmentConfig config_;
  ImpairmentCounters counters_;
  std::uint64_t state_;
  std::int64_t last_in_order_ns_ = 0;
  std::int64_t first_ns_ = -1;  // the first datagram's arrival
  bool rate_limited(std::int64_t now_ns) const;
  // The token bucket: tokens at tokens_at_ns_; negative while datagrams queue for them.
  bool bucket_started_ = false;
  double tokens_bytes_ = 0.0;
  std::int64_t tokens_at_ns_ = 0;
};

// "received=... dropped=..." for logs and summaries.
std::string to_string(const ImpairmentCounters& c);

}  // namespace telex::sim
