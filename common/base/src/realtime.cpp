// SPDX-License-Identifier: MIT
#include "telex/base/realtime.h"

#include <malloc.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>

namespace telex {
namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerBuild = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kSanitizerBuild = true;
#else
constexpr bool kSanitizerBuild = false;
#endif
#else
constexpr bool kSanitizerBuild = false;
#endif

std::mutex g_mu;
MemoryLock g_status{false, "memory not locked: lock_memory was not called"};

MemoryLock try_lock_memory() {
  if (kSanitizerBuild) return {false, "memory not locked: sanitizer build"};
  rlimit limit{};
  const bool unlimited =
      ::getrlimit(RLIMIT_MEMLOCK, &limit) == 0 && limit.rlim_cur == RLIM_INFINITY;
  if (!unlimited && ::geteuid() != 0) {
    return {false,
            "memory not locked: RLIMIT_MEMLOCK is " +
                std::to_string(static_cast<unsigned long long>(limit.rlim_cur / 1024)) +
                " kB (raise it with `ulimit -l unlimited` or give the program CAP_IPC_LOCK)"};
  }
  // What is mapped now (the ~230 shared libraries OpenCV, FFmpeg and ROS bring, hundreds of MiB
  // the process mostly never touches) is locked as it is touched, not read in whole: telex-remote's
  // resident set after start fell from 419 to 154 MB (its start-up time did not change
  // measurably at load 4). What is mapped from now on is filled and locked at once, as before.
  if (::mlockall(MCL_CURRENT | MCL_ONFAULT) != 0 || ::mlockall(MCL_FUTURE) != 0) {
    return {false, std::string("memory not locked: mlockall failed: ") + std::strerror(errno)};
  }
  // Freed memory stays in the process: trimming would unmap locked pages that the next
  // allocation then faults in again.
  ::mallopt(M_TRIM_THRESHOLD, -1);
  // And no block gets a mapping of its own: under MCL_FUTURE each such mmap is filled and locked
  // page by page, and each free unmaps it, both holding the process's mmap lock, which has no
  // priority inheritance. The view's and the decoders' frame-sized buffers (over malloc's 128 KiB
  // threshold) then stalled the real-time surface and network threads behind ordinary ones:
  // capture-to-force p99 in contact 23-28 ms with the eyes against 3 ms with this
  // (docs/BENCHMARKS.md, "Depth contact latency with and without the eyes").
  ::mallopt(M_MMAP_MAX, 0);
  return {true, "memory locked (mlockall)"};
}

}  // namespace

MemoryLock lock_memory() {
  MemoryLock result = try_lock_memory();
  const std::lock_guard lock(g_mu);
  g_status = result;
  return result;
}

MemoryLock memory_lock_status() {
  const std::lock_guard lock(g_mu);
  return g_status;
}

void prefault_stack(std::size_t bytes) {
  // A variable-length frame the compiler cannot elide: every page written once.
  auto* p = static_cast<volatile unsigned char*>(__builtin_alloca(bytes));
  const auto page = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
  for (std::size_t i = 0; i < bytes; i += page) p[i] = 0;
  p[bytes - 1] = 0;
}

std::string pin_thread(pthread_t thread, int cpu) {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return "CPU " + std::to_string(cpu) + " refused: out of range";
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  const int rc = ::pthread_setaffinity_np(thread, sizeof(set), &set);
  if (rc == 0) return "on CPU " + std::to_string(cpu);
  return "CPU " + std::to_string(cpu) + " refused: " + std::strerror(rc);
}

int usable_cpu_count() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof(set), &set) != 0) return 1;
  return CPU_COUNT(&set);
}

bool cpu_usable(int cpu) {
  if (cpu < 0 || cpu >= CPU_SETSIZE) return false;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof(set), &set) != 0) return false;
  return CPU_ISSET(cpu, &set);
}

}  // namespace telex
