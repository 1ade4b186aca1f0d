// SPDX-License-Identifier: MIT
// A single-slot mailbox where the newest value wins: a slow consumer never blocks the producer.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>

namespace telex {

// Producer calls put() and never waits on the consumer; an unconsumed value is replaced and
// counted as dropped. Consumer calls take() with a timeout.
template <typename T>
class LatestSlot {
 public:
  void put(T value) {
    {
      std::lock_guard lock(mu_);
      if (value_) ++dropped_;
      value_ = std::move(value);
      ++put_count_;
    }
    cv_.notify_one();
  }

  template <typename Rep, typename Period>
  std::optional<T> take(std::chrono::duration<Rep, Period> timeout) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, timeout, [&] { return value_.has_value() || closed_; });
    std::optional<T> out;
    out.swap(value_);
    return out;
  }

  void close() {
    {
      std::lock_guard lock(mu_);
      closed_ = true;
    }
    cv_.notify_all();
  }

  // True while a value waits to be taken (a consumer may cut long work short for it).
  bool has_value() const {
    std::lock_guard lock(mu_);
    return value_.has_value();
  }

  std::uint64_t dropped() const {
    std::lock_guard lock(mu_);
    return dropped_;
  }
  std::uint64_t put_count() const {
    std::lock_guard lock(mu_);
    return put_count_;
  }

 private:
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::optional<T> value_;
  bool closed_ = false;
  std::uint64_t dropped_ = 0;
  std::uint64_t put_count_ = 0;
};

}  // namespace telex
