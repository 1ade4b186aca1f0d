// SPDX-License-Identifier: MIT
// PiMutex: a pthread mutex made with PTHREAD_PRIO_INHERIT.
#include "telex/base/pi_mutex.h"

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

namespace telex {
namespace {

void check(int rc, const char* what) {
  if (rc != 0) throw std::runtime_error(std::string("PiMutex: ") + what + ": " + std::strerror(rc));
}

}  // namespace

PiMutex::PiMutex() {
  pthread_mutexattr_t attr;
  check(pthread_mutexattr_init(&attr), "pthread_mutexattr_init");
  // A system without priority inheritance (none that glibc on Linux builds for) keeps a plain
  // mutex: protocol() says which it got.
  if (pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT) == 0)
    protocol_ = PTHREAD_PRIO_INHERIT;
  const int rc = pthread_mutex_init(&m_, &attr);
  pthread_mutexattr_destroy(&attr);
  check(rc, "pthread_mutex_init");
}

PiMutex::~PiMutex() { pthread_mutex_destroy(&m_); }

void PiMutex::lock() { check(pthread_mutex_lock(&m_), "lock"); }

void PiMutex::unlock() { pthread_mutex_unlock(&m_); }

bool PiMutex::try_lock() {
  const int rc = pthread_mutex_trylock(&m_);
  if (rc == EBUSY) return false;
  check(rc, "try_lock");
  return true;
}

}  // namespace telex
