// SPDX-License-Identifier: MIT
// TELEX_DEMAND's failure path: one line on stderr, then abort (a core dump and the stack for gdb).
#include "telex/base/demand.h"

#include <cstdio>
#include <cstdlib>

namespace telex::detail {

void demand_failed(const char* condition, const char* file, int line) noexcept {
  std::fprintf(stderr, "%s:%d: TELEX_DEMAND(%s) failed: a caller broke this precondition (a bug)\n",
               file, line, condition);
  std::fflush(stderr);
  std::abort();
}

}  // namespace telex::detail
