// SPDX-License-Identifier: MIT
// OpenCV's worker threads, started on purpose by a thread of known scheduling.
#pragma once

namespace telex {

// Starts OpenCV's parallel workers (TBB on Debian) from the calling thread, which they take their
// scheduling from: a new thread inherits its creator's policy. The daemons call it from the
// thread that then starts the others, before any of them is made SCHED_FIFO. Otherwise whichever
// thread first ran a parallel OpenCV call (a synthetic scene's render on the capture thread)
// created them, and they ran the view's and the video's OpenCV work at that thread's real-time
// priority. The depth-to-force path itself makes no parallel OpenCV call. Idempotent.
void start_opencv_workers();

}  // namespace telex
