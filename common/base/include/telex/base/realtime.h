// SPDX-License-Identifier: MIT
// The real-time practice the PREEMPT_RT documentation teaches ("HOWTO build a simple RT
// application") and ros2_control's realtime_tools apply: lock the process's memory so no page is
// ever faulted in or swapped out under a real-time thread, prefault that thread's stack, keep
// freed heap memory in the process, and optionally pin the thread to one CPU.
#pragma once

#include <pthread.h>

#include <cstddef>
#include <string>

namespace telex {

struct MemoryLock {
  bool locked = false;
  // "memory locked (mlockall)" or why not, e.g. "memory not locked: RLIMIT_MEMLOCK is 8192 kB
  // (raise it with `ulimit -l unlimited` or give the program CAP_IPC_LOCK)".
  std::string description;
};

// mlockall(MCL_CURRENT | MCL_FUTURE) and malloc told never to give freed memory back (so locked
// pages stay locked) nor to map a large block on its own (mmap and munmap take the process's
// mmap lock, which a real-time thread then waits on behind any other). Only where it cannot fail
// later: with CAP_IPC_LOCK or an unlimited RLIMIT_MEMLOCK (with a finite one, MCL_FUTURE would make
// later allocations fail instead). Never in a sanitizer build, whose shadow memory must not be
// locked. Call once, early in main.
MemoryLock lock_memory();
// What the process's lock_memory() did ("memory not locked: lock_memory was not called" before).
MemoryLock memory_lock_status();

// Touches `bytes` of the calling thread's stack so its pages are resident (and, once the memory
// is locked, stay so) before the thread's first deadline.
void prefault_stack(std::size_t bytes = 256 * 1024);

// Pins `thread` to CPU `cpu`; returns "on CPU N" or why not ("CPU 7 refused: Invalid argument").
std::string pin_thread(pthread_t thread, int cpu);

// The CPUs this process may run on, as the kernel says (sched_getaffinity): what --haptic-cpu
// accepts.
int usable_cpu_count();
bool cpu_usable(int cpu);

}  // namespace telex
