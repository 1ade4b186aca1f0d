// SPDX-License-Identifier: MIT
// telex-local: the operator-station daemon (thin main around telex::local::Station).
#include <signal.h>
#include <spdlog/spdlog.h>

#include <iostream>
#include <thread>

#include "flags.h"
#include "telex/base/realtime.h"
#include "telex/local/displays/display_supervisor.h"
#include "telex/local/station/station.h"

namespace {

using telex::local::DisplaySupervisor;
using telex::local::kSupervisorLostLine;
using telex::local::Station;
using telex::local::StationConfig;
using telex::local::StationSummary;

// Runs the station until --duration, a signal or a fault; logs its summary (and prints it as
// JSON on stdout with --json-summary). Exit code 1 when the recording failed, or when the display
// supervisor was lost: then the station stops at once with zero force, since nothing would
// command zero force on the display if it died next.
int run_station(const StationConfig& cfg, bool json_summary, DisplaySupervisor& supervisor) {
  // Signals go to one waiting thread, never interrupting the haptic loop.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGCHLD);  // the supervisor (the station's only child) ended or was stopped
  sigaddset(&set, SIGUSR1);  // our own wake-up for the signal thread when the run ends
  pthread_sigmask(SIG_BLOCK, &set, nullptr);

  Station station(cfg);
  std::string supervisor_lost;
  std::thread signals([&] {
    // A SIGCHLD before the mask above was discarded: ask once first.
    supervisor_lost = supervisor.lost();
    while (supervisor_lost.empty()) {
      int sig = 0;
      if (sigwait(&set, &sig) != 0 || sig == SIGUSR1) return;
      if (sig != SIGCHLD) break;  // SIGINT, SIGTERM
      supervisor_lost = supervisor.lost();
    }
    station.request_stop();
  });
  const auto join_signals = [&] {
    pthread_kill(signals.native_handle(), SIGUSR1);
    signals.join();
  };
  StationSummary s;
  try {
    s = station.run();
  } catch (...) {
    join_signals();
    throw;
  }
  join_signals();  // wakes the signal thread if the run ended by itself
  spdlog::info("{}", s.done_text());
  if (!s.record_file.empty()) spdlog::info("{}", s.record_text());
  if (json_summary) std::cout << s.to_json().dump() << std::endl;
  if (!supervisor_lost.empty()) {
    spdlog::error(
        "{}: {}; stopped the station with zero force on {}, as nothing would command zero force "
        "there if the station died now. Start telex-local again (--no-supervisor runs without "
        "a supervisor)",
        kSupervisorLostLine, supervisor_lost, cfg.haptics_spec);
    return 1;
  }
  return s.record_error.empty() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace telex::local;
  StationFlags flags;
  if (const auto rc = parse_station_command_line(argc, argv, flags)) return *rc;
  // A start-up error about a value the --config file gave names that file too.
  const auto fail = [&](const std::exception& e, int code) {
    spdlog::error("{}{}", e.what(), flags.config.note(e.what()));
    return code;
  };
  try {
    apply_security_flags(flags);
  } catch (const std::exception& e) {
    return fail(e, 2);
  }
  StationConfig& cfg = flags.cfg;
  if (cfg.insecure) spdlog::warn("{}", telex::proto::insecure_warning());
  // Forked before any thread starts: the supervisor is a copy of this one thread.
  DisplaySupervisor supervisor;
  if (!flags.no_supervisor) {
    try {
      supervisor = start_display_supervisor(zero_channel_for(cfg.haptics_spec, cfg.display),
                                            {.realtime = !flags.no_realtime});
    } catch (const std::exception& e) {
      return fail(e, dynamic_cast<const std::invalid_argument*>(&e) != nullptr ? 2 : 1);
    }
    cfg.supervisor_heartbeat = supervisor.heartbeat();
  }
  apply_station_switches(flags);
  // After the fork (a child does not inherit the lock) and before any thread starts.
  if (!flags.no_realtime) telex::lock_memory();
  try {
    return run_station(cfg, flags.json_summary, supervisor);
  } catch (const std::invalid_argument& e) {
    return fail(e, 2);
  } catch (const std::exception& e) {
    return fail(e, 1);
  }
}
