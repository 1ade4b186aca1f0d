// SPDX-License-Identifier: MIT
// spdlog's default logger for the daemons: stderr, the program's name, one pattern.
#include "telex/common/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace telex {

void init_logging(const std::string& program) {
  // Not registered by name: a second call (the cli library's prepare() makes one) replaces the
  // first.
  auto logger = std::make_shared<spdlog::logger>(
      program, std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
  logger->set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%n] [%^%l%$] %v");
  spdlog::set_default_logger(std::move(logger));
}

}  // namespace telex
