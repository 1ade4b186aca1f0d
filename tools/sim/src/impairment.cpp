// SPDX-License-Identifier: MIT
// Deterministic network impairment scheduler (the pure part of telex-sim-impair).
#include "telex/sim/impairment.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace telex::sim {

namespace {

void check_probability(double p, const char* name) {
  if (!(p >= 0.0 && p <= 1.0))
    throw std::invalid_argument(std::string("impairment: ") + name + " must be in [0, 1], got " +
                                std::to_string(p));
}

void check_ms(double v, const char* name) {
  if (!(v >= 0.0 && v <= 60'000.0))
    throw std::invalid_argument(std::string("impairment: ") + name +
                                " must be in [0, 60000] ms, got " + std::to_string(v));
}

std::int64_t ms_to_ns(double ms) { return static_cast<std::int64_t>(std::llround(ms * 1e6)); }

}  // namespace

void validate(const ImpairmentConfig& c) {
  check_probability(c.loss, "loss");
  check_probability(c.reorder, "reorder");
  check_probability(c.duplicate, "duplicate");
  check_probability(c.corrupt, "corrupt");
  check_ms(c.delay_ms, "delay_ms");
  check_ms(c.jitter_ms, "jitter_ms");
  check_ms(c.reorder_hold_ms, "reorder_hold_ms");
  check_ms(c.rate_queue_ms, "rate_queue_ms");
  if (!(c.rate_limit_mbit >= 0.0 && c.rate_limit_mbit <= 100'000.0))
    throw std::invalid_argument("impairment: rate_limit_mbit must be in [0, 100000], got " +
                                std::to_string(c.rate_limit_mbit));
  if (!(c.rate_limit_from_s >= 0.0 && c.rate_limit_from_s <= 1e7))
    throw std::invalid_argument("impairment: rate_limit_from_s must be in [0, 1e7], got " +
                                std::to_string(c.rate_limit_from_s));
  if (!(c.rate_limit_until_s == 0.0 ||
        (c.rate_limit_until_s > c.rate_limit_from_s && c.rate_limit_until_s <= 1e7)))
    throw std::invalid_argument(
        "impairment: rate_limit_until_s must be 0 or in (rate_limit_from_s, 1e7], got " +
        std::to_string(c.rate_limit_until_s));
  if (!(c.rate_burst_bytes >= 1.0 && c.rate_burst_bytes <= 1e9))
    throw std::invalid_argument("impairment: rate_burst_bytes must be in [1, 1e9], got " +
                                std::to_string(c.rate_burst_bytes));
}

Impairment::Impairment(const ImpairmentConfig& config) : config_(config) {
  validate(config_);
  // splitmix64 seeding, so seeds 1, 2, 3 give unrelated streams.
  state_ = config_.seed * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull;
}

// splitmix64: tiny, fast and identical on every platform (std distributions are not).
std::uint64_t Impairment::next_u64() {
  std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

double Impairment::next_unit() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }

// Tokens accrue at the rate up to the burst; a datagram takes its size in tokens, going into debt
// when there are too few, and leaves when the debt before it is repaid. The debt is the queue.
std::int64_t Impairment::shape(std::size_t bytes, std::int64_t now_ns) {
  const double rate_bytes_per_ns = config_.rate_limit_mbit * 1e6 / 8.0 / 1e9;
  if (!bucket_started_) {
    bucket_started_ = true;
    tokens_bytes_ = config_.rate_burst_bytes;
    tokens_at_ns_ = now_ns;
  }
  if (now_ns > tokens_at_ns_) {
    tokens_bytes_ = std::min(config_.rate_burst_bytes,
                             tokens_bytes_ + rate_bytes_per_ns * double(now_ns - tokens_at_ns_));
    tokens_at_ns_ = now_ns;
  }
  const double debt_after = static_cast<double>(bytes) - tokens_bytes_;
  const double queue_limit_bytes = rate_bytes_per_ns * config_.rate_queue_ms * 1e6;
  if (debt_after > queue_limit_bytes) return -1;
  tokens_bytes_ -= static_cast<double>(bytes);
  if (debt_after <= 0.0) return now_ns;
  ++counters_.rate_queued;
  return now_ns + static_cast<std::int64_t>(std::ceil(debt_after / rate_bytes_per_ns));
}

bool Impairment::rate_limited(std::int64_t now_ns) const {
  if (config_.rate_limit_mbit <= 0.0) return false;
  const double t_s = static_cast<double>(now_ns - first_ns_) * 1e-9;
  return t_s >= config_.rate_limit_from_s &&
         (config_.rate_limit_until_s == 0.0 || t_s < config_.rate_limit_until_s);
}

std::vector<Delivery> Impairment::process(std::span<const std::uint8_t> datagram,
                                          std::int64_t now_ns) {
  if (first_ns_ < 0) first_ns_ = now_ns;
  ++counters_.received;
  counters_.bytes_in += datagram.size();
  // Draw every variate for every datagram, so one setting does not shift the others' streams.
  const double u_loss = next_unit();
  const double u_jitter = next_unit();
  const double u_reorder = next_unit();
  const double u_dup = next_unit();
  const double u_corrupt = next_unit();
  const std::uint64_t bit_pick = next_u64();

  std::vector<Delivery> out;
  // The bottleneck comes first: a datagram takes its slot, then the wire may lose it.
  std::int64_t leave_ns = now_ns;
  if (rate_limited(now_ns)) {
    leave_ns = shape(datagram.size(), now_ns);
    if (leave_ns < 0) {
      ++counters_.rate_dropped;
      return out;
    }
  }
  if (u_loss < config_.loss) {
    ++counters_.dropped;
    return out;
  }
  const double delay_ms =
      std::max(0.0, config_.delay_ms + (2.0 * u_jitter - 1.0) * config_.jitter_ms);
  std::int64_t at_ns = leave_ns + ms_to_ns(delay_ms);
  if (u_reorder < config_.reorder) {
    ++counters_.reordered;
    at_ns += ms_to_ns(config_.reorder_hold_ms);
  } else {
    at_ns = std::max(at_ns, last_in_order_ns_);
    last_in_order_ns_ = at_ns;
  }
  Delivery d{at_ns, std::vector<std::uint8_t>(datagram.begin(), datagram.end())};
  if (u_corrupt < config_.corrupt && !d.bytes.empty()) {
    ++counters_.corrupted;
    const std::size_t bit = static_cast<std::size_t>(bit_pick % (d.bytes.size() * 8));
    d.bytes[bit / 8] ^= static_cast<std::uint8_t>(1u << (bit % 8));
  }
  out.push_back(std::move(d));
  if (u_dup < config_.duplicate) {
    ++counters_.duplicated;
    out.push_back(out.front());
  }
  counters_.delivered += out.size();
  counters_.bytes_out += out.size() * datagram.size();
  return out;
}

std::string to_string(const ImpairmentCounters& c) {
  return "received=" + std::to_string(c.received) + " dropped=" + std::to_string(c.dropped) +
         " delivered=" + std::to_string(c.delivered) + " reordered=" + std::to_string(c.reordered) +
         " duplicated=" + std::to_string(c.duplicated) +
         " corrupted=" + std::to_string(c.corrupted) + " bytes_in=" + std::to_string(c.bytes_in) +
         " rate_dropped=" + std::to_string(c.rate_dropped) +
         " bytes_out=" + std::to_string(c.bytes_out);
}

}  // namespace telex::sim
