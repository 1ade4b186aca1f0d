// SPDX-License-Identifier: MIT
#include "telex/common/opencv_workers.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <opencv2/core.hpp>
#include <thread>

namespace telex {

void start_opencv_workers() {
  static std::once_flag once;
  std::call_once(once, [] {
    // Enough stripes for every worker to take one: each blocks until all have begun, so the
    // pool is at full size when this returns (a stripe that waits alone times out after 1 s).
    const int n = std::max(1, cv::getNumThreads());
    std::atomic<int> begun{0};
    parallel_for(
        cv::Range(0, n),
        [&](const cv::Range& r) {
          begun.fetch_add(r.size());
          const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(1);
          while (begun.load() < n && std::chrono::steady_clock::now() < until)
            std::this_thread::yield();
        },
        n);
  });
}

}  // namespace telex
