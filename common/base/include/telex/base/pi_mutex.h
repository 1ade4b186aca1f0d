// SPDX-License-Identifier: MIT
// A mutex with priority inheritance (POSIX PTHREAD_PRIO_INHERIT), for locks that a real-time
// thread shares with a thread of lower priority: while the low thread holds it, it runs at the
// priority of the highest thread waiting, so a thread of middle priority cannot keep the real-time
// one waiting (priority inversion; the PREEMPT_RT documentation's "priority inheritance"). A
// drop-in Lockable for std::lock_guard and std::unique_lock; with a condition variable use
// std::condition_variable_any.
#pragma once

#include <pthread.h>

namespace telex {

class PiMutex {
 public:
  PiMutex();
  ~PiMutex();
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;

  void lock();
  void unlock();
  bool try_lock();
  // The protocol the mutex was made with (PTHREAD_PRIO_INHERIT where the system supports it).
  int protocol() const { return protocol_; }

 private:
  pthread_mutex_t m_;
  int protocol_ = PTHREAD_PRIO_NONE;
};

}  // namespace telex
