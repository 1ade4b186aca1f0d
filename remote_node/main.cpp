// SPDX-License-Identifier: MIT
// telex-remote: the robot-head daemon (depth source -> pipeline -> operator over TCP/UDP); a thin
// main around telex::remote::RemoteDaemon, its flags in flags.cpp.
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "flags.h"
#include "telex/base/realtime.h"
#include "telex/remote/daemon.h"

namespace {

using telex::remote::DaemonConfig;
using telex::remote::RemoteDaemon;

// What runs, where it listens and how the link is secured, once the daemon has started.
void log_started(RemoteDaemon& daemon, const DaemonConfig& cfg) {
  spdlog::info("head {}", daemon.head()->name());
  std::string path;
  for (const auto& [name, how] : daemon.scheduling())
    path += (path.empty() ? "" : ", ") + name + " " + how;
  spdlog::info("depth path: {}", path);
  spdlog::info("{} -> listening on {}:{} ({}, {})", daemon.depth_source().describe(),
               cfg.server.host, daemon.port(),
               cfg.server.force_tcp ? "tcp" : "udp if the client offers it",
               cfg.server.tls.enabled() ? cfg.server.tls.describe() + ", datagrams sealed"
                                        : "plain: unauthenticated, unencrypted");
  if (cfg.insecure) spdlog::warn("{}", telex::proto::insecure_warning());
}

}  // namespace

int main(int argc, char** argv) {
  using namespace telex::remote;
  RemoteFlags flags;
  if (const auto rc = parse_remote_command_line(argc, argv, flags)) return *rc;
  const DaemonConfig& cfg = flags.cfg;
  // A start-up error about a value the --config file gave names that file too.
  const auto fail = [&](const std::exception& e, int code) {
    spdlog::error("{}{}", e.what(), flags.config.note(e.what()));
    return code;
  };

  std::unique_ptr<RemoteDaemon> daemon;
  try {
    daemon = std::make_unique<RemoteDaemon>(cfg);  // bad source specs are bad flags
  } catch (const std::invalid_argument& e) {
    return fail(e, 2);
  }
  // Before the daemon's threads start: nothing on the depth path or the servo loop faults a page.
  if (!flags.no_realtime) telex::lock_memory();
  try {
    daemon->start();
  } catch (const std::invalid_argument& e) {
    return fail(e, 2);
  } catch (const std::exception& e) {
    return fail(e, 1);
  }
  log_started(*daemon, cfg);
  spdlog::info("{}", telex::memory_lock_status().description);
  return daemon->run();
}
