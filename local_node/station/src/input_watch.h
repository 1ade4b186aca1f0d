// SPDX-License-Identifier: MIT
// The tracker's device inputs watched for silence on the main thread: an input that delivers
// nothing for 2 s (a NatNet server that is not streaming, a glove switched off) is said as a
// warning naming it and what to check, on each status line while it lasts, and in the summary.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "telex/local/inputs/tracker.h"

namespace telex::local {

class InputWatch {
 public:
  static constexpr std::int64_t kSilentAfterNs = 2'000'000'000;

  // The inputs' frame counts at now_ns (the first call starts the watch). Logs a warning when an
  // input has delivered nothing for kSilentAfterNs, and when one delivers again.
  void update(std::int64_t now_ns, const std::vector<TrackerInput>& inputs);
  // For the status line: " | no NatNet frames from ... for 5 s" per silent input; empty when none.
  std::string status(std::int64_t now_ns) const;
  // For the run's last line: each input silent at the end, and what to check; empty when none.
  std::string summary(std::int64_t now_ns) const;

 private:
  struct Watched {
    TrackerInput input;
    std::int64_t since_ns = 0;  // its last new frame, or the watch's start
    bool silent = false;
  };
  std::vector<Watched> watched_;
};

}  // namespace telex::local
