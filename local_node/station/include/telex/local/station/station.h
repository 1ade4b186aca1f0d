// SPDX-License-Identifier: MIT
// The operator station: network client, surface thread, 1 kHz haptic thread, logging, status and
// operator view, wired together. telex-local is a thin main around it.
#pragma once

#include "telex/local/station/station_config.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

class Station {
 public:
  explicit Station(StationConfig config);
  ~Station();
  // Runs until duration_s elapses or request_stop() (e.g. from a signal handler thread).
  // Throws std::runtime_error / std::invalid_argument for start-up problems (bad device, file),
  // and StationThreadError for the first thread that stopped on an exception (its own threads,
  // the network client's, the tracker's and gloves', the display's writer, the recorder's), after
  // stopping them all. On every exit, normal or not, the display's last command is zero force on
  // every finger.
  StationSummary run();
  void request_stop() { stop_.store(true); }

 private:
  class Run;  // one run's parts (src/station/), their threads and wiring (station.cpp)
  StationConfig cfg_;
  std::atomic<bool> stop_{false};
};

// Sets what the rig file holds (docs/RIG.md): marker body ids, the head-to-camera offset, both
// hands' geometry and gloves, the body, the eyes and the baseline, the display channels and the
// Gravity Grabber settings. Called before the flags are parsed, so flags override it.
void apply_rig(const Rig& rig, StationConfig& cfg);

}  // namespace telex::local
