// SPDX-License-Identifier: MIT
// The station's thread errors: logged, the first kept, the station stopped.
#include "faults.h"

#include <spdlog/spdlog.h>

#include "telex/base/thread_fault.h"

namespace telex::local {

void StationFaults::fail(const std::string& thread, std::exception_ptr error) {
  const std::string what = ThreadFaultReport{thread, error}.what();
  spdlog::error("the {} thread failed: {}; stopping the station with zero force", thread, what);
  {
    std::lock_guard lock(mu_);
    if (!error_) error_ = std::make_exception_ptr(StationThreadError(thread, what));
  }
  stop_.store(true);
}

std::exception_ptr StationFaults::first_error() {
  std::lock_guard lock(mu_);
  return error_;
}

}  // namespace telex::local
