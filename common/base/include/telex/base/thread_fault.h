// SPDX-License-Identifier: MIT
// The last-resort catch of a thread: what escaped it is kept for the thread's owner to poll.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

namespace telex {

// Which thread stopped and what it threw, for the owner's log and exit message.
struct ThreadFaultReport {
  std::string thread;  // e.g. "tracking (telex-natnet)"
  std::exception_ptr error;
  std::string what() const;  // the exception's what(), or "unknown exception"
};

// A thread body run through run() never lets an exception reach std::terminate: the first one is
// kept, every one is counted, and the thread's function returns. The owner polls failed() (one
// atomic load, fine on any thread) and report() (locks; off the real-time path) and stops what
// depends on the thread. Nothing here logs: the owner logs once, with its own prefix.
class ThreadFault {
 public:
  explicit ThreadFault(std::string thread) : thread_(std::move(thread)) {}
  ThreadFault(const ThreadFault&) = delete;
  ThreadFault& operator=(const ThreadFault&) = delete;

  template <typename Body>
  bool run(Body&& body) noexcept {
    try {
      std::forward<Body>(body)();
      return true;
    } catch (...) {
      set(std::current_exception());
      return false;
    }
  }
  void set(std::exception_ptr error) noexcept;
  bool failed() const noexcept { return count_.load(std::memory_order_acquire) != 0; }
  std::uint64_t count() const noexcept { return count_.load(std::memory_order_acquire); }
  std::optional<ThreadFaultReport> report() const;  // empty while the thread has not failed
  const std::string& thread() const { return thread_; }

 private:
  const std::string thread_;
  std::atomic<std::uint64_t> count_{0};
  mutable std::mutex mu_;
  std::exception_ptr first_;
};

}  // namespace telex
