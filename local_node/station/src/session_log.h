// SPDX-License-Identifier: MIT
// What the station writes of a run: --log-forces and --log-tracking CSVs and the --record bag.
#pragma once

#include <cstdint>
#include <fstream>
#include <memory>

#include "messages.h"
#include "telex/local/inputs/hmd_pose_pairer.h"
#include "telex/local/record/recorder.h"
#include "telex/local/station/station_config.h"
#include "telex/local/station/station_summary.h"

namespace telex::local {

class SessionLog {
 public:
  // Opens the files now (a bad path stops the start before anything connects); t_start_ns is the
  // logs' time 0.
  SessionLog(const StationConfig& cfg, std::int64_t t_start_ns);

  SessionRecorder* recorder() const { return recorder_.get(); }
  // Every tracker frame is wanted (for the tracking CSV or the bag).
  bool wants_bodies() const {
    return tracking_csv_.is_open() || recorder_ != nullptr || hmd_csv_.is_open();
  }

  // Main thread: the haptic thread's tick number `tick_index` (1 = the first).
  void add_tick(const TickSample& s, std::uint64_t tick_index);
  void add_bodies(const HandState& state);
  // --record-hmd-poses: the headset's view in STAGE at display time `t_ns`.
  void add_hmd_pose(std::int64_t t_ns, const Pose& X_StageView);
  // Everything written and the bag closed (idempotent).
  void finish();
  void summarize(StationSummary& s) const;

 private:
  void write_forces(const TickSample& s);
  void write_hmd_rows();

  const StationConfig& cfg_;
  const std::int64_t t_start_ns_;
  std::ofstream forces_csv_;
  std::ofstream tracking_csv_;
  std::ofstream hmd_csv_;
  HmdPosePairer hmd_pairer_;
  std::unique_ptr<SessionRecorder> recorder_;  // --record; finished after the threads stop
};

}  // namespace telex::local
