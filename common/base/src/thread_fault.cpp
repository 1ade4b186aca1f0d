// SPDX-License-Identifier: MIT
// ThreadFault: the first exception a thread let escape, kept for its owner.
#include "telex/base/thread_fault.h"

namespace telex {

std::string ThreadFaultReport::what() const {
  if (!error) return "no exception";
  try {
    std::rethrow_exception(error);
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "unknown exception (not derived from std::exception)";
  }
}

void ThreadFault::set(std::exception_ptr error) noexcept {
  {
    std::lock_guard lock(mu_);
    if (!first_) first_ = std::move(error);
  }
  // Published after the error, so report() sees it once failed() is true.
  count_.fetch_add(1, std::memory_order_acq_rel);
}

std::optional<ThreadFaultReport> ThreadFault::report() const {
  if (!failed()) return std::nullopt;
  std::lock_guard lock(mu_);
  return ThreadFaultReport{thread_, first_};
}

}  // namespace telex
