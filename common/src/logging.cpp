// SPDX-License-Identifier: MIT
// spdlog's default logger for the daemons: stderr, the program's name, one pattern.
#include "telex/common/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace telex {

void init_logging(const std::string& program) {
  auto logger = spdlog::stderr_color_mt(program);
  logger->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%n] [%^%l%$] %v");
  spdlog::set_default_logger(std::move(logger));
}

}  // namespace telex
