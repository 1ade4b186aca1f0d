// SPDX-License-Identifier: MIT
// The station's error path, shared by its parts: the fault hook each loop calls at the top of a
// pass, and the first thread error, kept for Station::run to rethrow after everything stopped.
#pragma once

#include <atomic>
#include <exception>
#include <functional>
#include <mutex>
#include <string>

#include "telex/local/station/station_config.h"

namespace telex::local {

class StationFaults {
 public:
  StationFaults(std::atomic<bool>& stop, const std::function<void(StationLoop)>& hook)
      : stop_(stop), hook_(hook) {}

  // The test seam (StationConfig::fault_hook): an exception it throws takes the loop's error path.
  void check(StationLoop loop) const {
    if (hook_) hook_(loop);
  }
  bool hooked() const { return static_cast<bool>(hook_); }

  // A thread's error: logged once, the first one kept (as a StationThreadError naming `thread`),
  // and the station stops.
  void fail(const std::string& thread, std::exception_ptr error);
  std::exception_ptr first_error();

 private:
  std::atomic<bool>& stop_;
  const std::function<void(StationLoop)>& hook_;
  std::mutex mu_;
  std::exception_ptr error_;
};

}  // namespace telex::local
