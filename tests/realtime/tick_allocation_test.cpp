// SPDX-License-Identifier: MIT
// The haptic tick allocates nothing: this binary replaces malloc and operator new with counting
// versions (a malloc hook, as realtime_tools' tests do it) and runs the station's HapticLoop on its
// own thread against a scripted fingertip pressing and sliding on a synthetic plane while new
// surfaces arrive. After a warm-up every allocation that thread makes is counted; there must be
// none. Kept in its own binary so the hook touches no other test.
#include <gtest/gtest.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <cstdlib>
#include <deque>
#include <new>
#include <thread>

#include "haptic_loop.h"
#include "telex/base/periodic.h"
#include "telex/base/realtime.h"
#include "telex/common/synthetic.h"
#include "telex/local/displays/display_registry.h"
#include "telex/local/displays/display_supervisor.h"
#include "telex/local/inputs/hand_script.h"
#include "telex/local/link/surface_builder.h"

namespace {

std::atomic<bool> g_counting{false};
std::atomic<pthread_t> g_watched{};
std::atomic<std::uint64_t> g_allocations{0};

inline void count_allocation() {
  if (g_counting.load(std::memory_order_relaxed) &&
      pthread_equal(pthread_self(), g_watched.load(std::memory_order_relaxed)))
    g_allocations.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

#ifndef TELEX_SANITIZER_BUILD
// glibc's own entry points stay reachable under these names; C code (and libstdc++'s operator new)
// calls malloc through the PLT, which this executable's definitions take over.
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t n) {
  count_allocation();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) {
  count_allocation();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) {
  count_allocation();
  return __libc_realloc(p, n);
}
void* aligned_alloc(std::size_t alignment, std::size_t n) {
  count_allocation();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) {
  count_allocation();
  *out = __libc_memalign(alignment, n);
  return *out ? 0 : ENOMEM;
}
}
constexpr bool kHooked = true;
#else
constexpr bool kHooked = false;
#endif

namespace telex::local {
namespace {

std::shared_ptr<const Surface> plane_surface(std::uint32_t frame_id) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  synth::Scene scene;
  scene.add_plane({0, 0, 1}, 0.6);
  synth::SensorModel sensor;
  sensor.seed = frame_id;
  AssembledFrame frame;
  frame.depth_mm = synth::render(scene, k, sensor, frame_id).depth.depth_mm;
  frame.intrinsics = k;
  frame.frame_id = frame_id;
  frame.capture_ns = monotonic_ns();
  SurfaceOptions options;
  options.roi = false;
  return build_surface(frame, options, {});
}

// The index fingertip 5 mm into the plane at 0.6 m, sliding 40 mm sideways and back every 2 s:
// contact, friction and slip on every tick.
HandScript pressing_stroke() {
  return HandScript::parse(
      "time_s finger x_m y_m z_m\n"
      "0 1 -0.02 0 0.605\n"
      "1 1 0.02 0 0.605\n"
      "2 1 -0.02 0 0.605\n",
      "pressing stroke");
}

TEST(TickAllocation, TheHapticTickAllocatesNothingAfterWarmUp) {
  if (!kHooked) GTEST_SKIP() << "sanitizer build: its allocator cannot be replaced by the hook";
  StationConfig cfg;
  cfg.realtime = false;
  cfg.rate_hz = 1000.0;
  // The display supervisor's heartbeat, beaten every tick; a zeroing by the supervisor while
  // counting (below) takes the loop's restart from zero too.
  StationHeartbeat heartbeat;
  cfg.supervisor_heartbeat = &heartbeat;
  std::atomic<bool> stop_flag{false};
  const std::function<void(StationLoop)> no_hook;
  StationFaults faults(stop_flag, no_hook);
  auto display = make_display("sim", cfg.display);
  ZeroForceOnExit zero(*display);
  TripleBuffer<std::shared_ptr<const Surface>> surfaces;
  TripleBuffer<HandState> hand_for_surface, hand_for_view;
  HapticLoop loop(cfg, faults, *display, zero, surfaces, hand_for_surface, hand_for_view, false);
  loop.set_tracker(std::make_unique<ScriptTracker>(pressing_stroke(), "script", true));

  // As the surface stage does: retired snapshots stay alive here, so their last release never
  // happens on the haptic thread.
  std::deque<std::shared_ptr<const Surface>> retired;
  std::uint32_t frame_id = 0;
  auto publish = [&] {
    auto s = plane_surface(++frame_id);
    surfaces.publish(s);
    retired.push_back(std::move(s));
    if (retired.size() > 8) retired.pop_front();
  };
  publish();

  std::jthread haptic([&](std::stop_token st) { loop.run(st); });
  g_watched.store(haptic.native_handle());
  std::uint64_t ticks = 0, counted_ticks = 0, contact_ticks = 0;
  std::uint32_t surfaces_while_counting = 0;
  TickSample sample;
  // Warm-up: 300 ticks (first contact, the first surfaces); then 1500 counted ticks with a new
  // surface every 30 ticks.
  while (counted_ticks < 1500) {
    bool any = false;
    while (loop.samples().pop(sample)) {
      any = true;
      ++ticks;
      if (g_counting.load()) {
        ++counted_ticks;
        if (sample.forces[1].contact) ++contact_ticks;
      }
      if (ticks % 30 == 0) {
        publish();
        if (g_counting.load()) ++surfaces_while_counting;
      }
      if (ticks == 300) g_counting.store(true);
      if (ticks == 900) heartbeat.zeroed.fetch_add(1);
    }
    if (!any) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  g_counting.store(false);
  haptic.request_stop();
  haptic.join();
  EXPECT_EQ(g_allocations.load(), 0u) << "allocations on the haptic thread after warm-up";
  EXPECT_NE(heartbeat.beat_ns.load(), 0) << "the loop never beat";
  EXPECT_EQ(heartbeat.limit_ns.load(), 0) << "the loop ended without disarming the heartbeat";
  EXPECT_GE(surfaces_while_counting, 40u);
  EXPECT_GT(contact_ticks, counted_ticks / 2) << "the fingertip must be in contact";
}

// The hook itself counts: an allocation made on the watched thread is seen.
TEST(TickAllocation, TheHookCountsAnAllocationOnTheWatchedThread) {
  if (!kHooked) GTEST_SKIP() << "sanitizer build: its allocator cannot be replaced by the hook";
  g_allocations.store(0);
  std::atomic<bool> go{false};
  std::jthread t([&] {
    while (!go.load()) std::this_thread::yield();
    auto* p = new std::string(100, 'x');
    delete p;
    void* q = std::malloc(64);
    std::free(q);
  });
  g_watched.store(t.native_handle());
  g_counting.store(true);
  go.store(true);
  t.join();
  g_counting.store(false);
  EXPECT_GE(g_allocations.load(), 2u);
}

TEST(Realtime, HapticCpuOutsideTheMachineIsRefusedByPin) {
  EXPECT_NE(pin_thread(pthread_self(), 100000).find("refused"), std::string::npos);
  EXPECT_FALSE(cpu_usable(-1));
  // cpu_usable agrees with the process's affinity count, and pinning to a usable CPU works.
  int usable = 0, first = -1;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu)
    if (cpu_usable(cpu)) {
      ++usable;
      if (first < 0) first = cpu;
    }
  EXPECT_EQ(usable, usable_cpu_count());
  ASSERT_GE(first, 0);
  std::thread t([&] {
    EXPECT_EQ(pin_thread(pthread_self(), first), "on CPU " + std::to_string(first));
    EXPECT_EQ(sched_getcpu(), first);
  });
  t.join();
}

TEST(Realtime, LockMemoryReportsWhatItDid) {
  const MemoryLock m = lock_memory();
  EXPECT_FALSE(m.description.empty());
  EXPECT_EQ(memory_lock_status().locked, m.locked);
  if (m.locked)
    EXPECT_EQ(m.description, "memory locked (mlockall)");
  else
    EXPECT_NE(m.description.find("not locked"), std::string::npos);
}

// With the memory locked, a frame-sized block comes from the heap, never from a mapping of its
// own (whose mmap and munmap would take the mmap lock a real-time thread then waits on).
TEST(Realtime, LockedMemoryMapsNoBlockOfItsOwn) {
  const MemoryLock m = lock_memory();
  if (!m.locked) GTEST_SKIP() << "the memory could not be locked here: " << m.description;
  const std::size_t mapped_before = ::mallinfo2().hblks;
  void* volatile block = std::malloc(8u << 20);  // 1280x720 BGR is 2.7 MiB; malloc maps >128 KiB
  ASSERT_NE(block, nullptr);
  EXPECT_EQ(::mallinfo2().hblks, mapped_before);
  std::free(block);
}

}  // namespace
}  // namespace telex::local
