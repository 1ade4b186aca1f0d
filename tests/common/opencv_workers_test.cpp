// SPDX-License-Identifier: MIT
// OpenCV's workers take the scheduling of the thread that started them: start_opencv_workers()
// from an ordinary thread keeps them ordinary when a SCHED_FIFO thread later runs parallel work.
#include "telex/common/opencv_workers.h"

#include <gtest/gtest.h>
#include <sched.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <opencv2/core.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "telex/base/periodic.h"

namespace telex {
namespace {

// Threads of this process the kernel holds at SCHED_FIFO (/proc/self/task/*/sched's policy).
int fifo_threads() {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream in(e.path() / "stat");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto close = text.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream fields(text.substr(close + 2));
    std::vector<std::string> f{std::istream_iterator<std::string>(fields), {}};
    if (f.size() >= 39 && std::stoi(f[41 - 3]) == SCHED_FIFO) ++n;
  }
  return n;
}

// The child: this test run again in a fresh process (OpenCV's pool not made yet) with
// TELEX_OPENCV_WORKERS_CHILD set. With "start" it starts the workers on its main thread first;
// then parallel work runs from a SCHED_FIFO thread, which prints how many SCHED_FIFO threads the
// process has.
void run_as_child(const std::string& mode) {
  if (mode == "start") start_opencv_workers();
  std::string result;
  std::thread rt([&] {
    if (try_realtime(10).rfind("SCHED_FIFO", 0) != 0) {
      result = "refused";
      return;
    }
    std::atomic<int> sum{0};
    for (int i = 0; i < 50; ++i)
      cv::parallel_for_(cv::Range(0, 64), [&](const cv::Range& r) {
        volatile double x = 0;
        for (int k = 0; k < 20000; ++k) x = x + k * 1e-9;
        sum += r.size();
      });
    result = std::to_string(fifo_threads());
  });
  rt.join();
  std::printf("fifo-threads=%s\n", result.c_str());
}

// Runs the child; returns its count, -2 when SCHED_FIFO was refused, -1 when it printed none.
int child_fifo_threads(bool start_first) {
  const std::string cmd = std::string("TELEX_OPENCV_WORKERS_CHILD=") +
                          (start_first ? "start" : "none") + " /proc/" +
                          std::to_string(::getpid()) + "/exe --gtest_filter=OpenCvWorkers.* 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return -1;
  std::string out;
  char buf[512];
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  ::pclose(p);
  const auto at = out.find("fifo-threads=");
  if (at == std::string::npos) return -1;
  const std::string v = out.substr(at + 13, out.find('\n', at) - at - 13);
  return v == "refused" ? -2 : std::stoi(v);
}

TEST(OpenCvWorkers, StartedFromAnOrdinaryThreadTheyStayOrdinaryUnderARealtimeCaller) {
  if (const char* mode = std::getenv("TELEX_OPENCV_WORKERS_CHILD")) return run_as_child(mode);
  if (cv::getNumThreads() < 2) GTEST_SKIP() << "OpenCV runs serially here: no workers to check";
  const int without = child_fifo_threads(false);
  if (without == -2) GTEST_SKIP() << "this machine refuses SCHED_FIFO";
  // The control: a realtime thread that makes the pool passes its policy to its workers.
  EXPECT_GT(without, 1) << "the control did not show the inheritance: the check cannot fail";
  // Started first from the ordinary main thread: only the realtime thread itself.
  EXPECT_EQ(child_fifo_threads(true), 1);
}

// The stripes' writes are the caller's to read and free once parallel_for returns. Under TSan
// (build-tsan's common_tests) this is the hand-off Debian's uninstrumented TBB pool hides: with
// cv::parallel_for_ itself TSan reported the caller's free of `rows` as a race with the workers'
// writes, as it did for the synthetic renderer in RemoteDaemon.* (docs/VERIFICATION.md, TSan).
TEST(ParallelFor, EveryRowOnceAndTheCallerOwnsTheResultAfterIt) {
  start_opencv_workers();
  for (int round = 0; round < 20; ++round) {
    auto rows = std::make_unique<std::vector<int>>(480, 0);
    parallel_for(cv::Range(0, 480), [&](const cv::Range& r) {
      for (int v = r.start; v < r.end; ++v) (*rows)[static_cast<std::size_t>(v)] += v + 1;
    });
    for (int v = 0; v < 480; ++v) ASSERT_EQ((*rows)[static_cast<std::size_t>(v)], v + 1) << v;
    rows.reset();
  }
}

}  // namespace
}  // namespace telex
