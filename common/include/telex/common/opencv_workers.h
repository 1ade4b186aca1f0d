// SPDX-License-Identifier: MIT
// OpenCV's worker threads, started on purpose by a thread of known scheduling, and the one way
// this project hands them work.
#pragma once

#include <opencv2/core/utility.hpp>

#if defined(__SANITIZE_THREAD__)
#define TELEX_TSAN_ANNOTATE 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define TELEX_TSAN_ANNOTATE 1
#endif
#endif
#ifdef TELEX_TSAN_ANNOTATE
#include <sanitizer/tsan_interface.h>
#endif

namespace telex {

// Starts OpenCV's parallel workers (TBB on Debian) from the calling thread, which they take their
// scheduling from: a new thread inherits its creator's policy. The daemons call it from the
// thread that then starts the others, before any of them is made SCHED_FIFO. Otherwise whichever
// thread first ran a parallel OpenCV call (a synthetic scene's render on the capture thread)
// created them, and they ran the view's and the video's OpenCV work at that thread's real-time
// priority. The depth-to-force path itself makes no parallel OpenCV call. Idempotent.
void start_opencv_workers();

// cv::parallel_for_(range, body, nstripes): `body(stripe)` for stripes covering `range`, on
// OpenCV's workers and the calling thread; returns once every stripe has run. Under
// ThreadSanitizer the hand-off is told to it: the workers are Debian's TBB pool, which is not
// instrumented, so TSan cannot see that the stripes finish before the loop returns, and it
// reported the caller's next writes (freeing the body and the buffers the stripes read, reusing
// its stack) as races with the workers' reads. Each stripe acquires what the caller released
// before the loop and releases what it did for the caller to acquire after it; two addresses, so
// that no stripe is ordered after another (a real overlap between stripes is still reported).
template <typename Body>
void parallel_for(const cv::Range& range, const Body& body, double nstripes = -1.0) {
  struct Loop final : cv::ParallelLoopBody {
    explicit Loop(const Body& b) : body(b) {}
    void operator()(const cv::Range& stripe) const override {
#ifdef TELEX_TSAN_ANNOTATE
      __tsan_acquire(const_cast<char*>(&handed_out));
#endif
      body(stripe);
#ifdef TELEX_TSAN_ANNOTATE
      __tsan_release(const_cast<char*>(&handed_back));
#endif
    }
    const Body& body;
    char handed_out = 0, handed_back = 0;  // TSan's sync addresses only
  } loop(body);
#ifdef TELEX_TSAN_ANNOTATE
  __tsan_release(&loop.handed_out);
#endif
  cv::parallel_for_(range, loop, nstripes);
#ifdef TELEX_TSAN_ANNOTATE
  __tsan_acquire(&loop.handed_back);
#endif
}

}  // namespace telex

#undef TELEX_TSAN_ANNOTATE
