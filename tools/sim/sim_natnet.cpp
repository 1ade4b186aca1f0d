// SPDX-License-Identifier: MIT
// telex-sim-natnet: a NatNet server that answers connect requests and streams a hand motion.
#include <algorithm>
#include <atomic>
#include <csignal>
#include <filesystem>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include "telex/cli/command_line.h"
#include "telex/sim/natnet_server.h"

namespace {

// --motion: a built-in name or a file; a typo of a name gets the nearest one.
telex::cli::Check motion_check() {
  return telex::cli::Predicate(
      [](std::string& text) -> std::string {
        const std::vector<std::string> builtin{"press", "hold", "head-turns"};
        if (std::find(builtin.begin(), builtin.end(), text) != builtin.end() ||
            std::filesystem::is_regular_file(text))
          return {};
        const std::string near = telex::cli::closest_name(text, builtin);
        return "'" + text + "' is neither a built-in motion nor a file" +
               (near.empty() ? "" : " (did you mean " + near + "?)") +
               " (valid: press, hold, head-turns, or a CSV file)";
      },
      "press|hold|head-turns|FILE");
}

}  // namespace

int main(int argc, char** argv) {
  using namespace telex::local;
  using namespace telex::sim;
  telex::cli::Program program{
      "telex-sim-natnet: NatNet server simulator (answers PING with server info, streams "
      "FRAMEOFDATA with head id 1, right hand id 2, right shoulder id 3)",
      "telex-sim-natnet"};
  const telex::cli::CommandLine& app = program.command_line();
  NatNetServerConfig cfg;
  std::string version = "3.1";
  std::string motion = "press";
  double duration_s = 10.0;
  bool loop = true;
  app.add_option("--natnet-version", version, "NatNet layout to stream: 2.x, 3.x or 4.x")
      ->capture_default_str()
      ->check(telex::cli::Predicate(
          [](std::string& text) -> std::string {
            try {
              natnet::parse_version(text);
              return {};
            } catch (const std::invalid_argument& e) {
              return e.what();
            }
          },
          "MAJOR.MINOR"));
  telex::cli::add(app, "--rate", cfg.rate_hz, "Frames per second", "Hz")
      ->check(telex::cli::Range(1.0, 1000.0));
  telex::cli::add(app, "--duration", duration_s, "Stream this long, then exit (0 = until stopped)",
                  "s")
      ->check(telex::cli::Range(0.0, 86400.0));
  app.add_option("--bind", cfg.bind_address, "address of the command socket")
      ->capture_default_str();
  app.add_option("--command-port", cfg.command_port, "command port (connect requests)")
      ->capture_default_str();
  app.add_flag("--multicast", cfg.multicast,
               "stream to the multicast group instead of to each connected client");
  app.add_option("--group", cfg.multicast_group, "multicast group")->capture_default_str();
  app.add_option("--data-port", cfg.data_port, "multicast data port")->capture_default_str();
  app.add_option("--interface", cfg.multicast_interface, "multicast outbound interface")
      ->capture_default_str();
  app.add_option(
         "--motion", motion,
         "'press' (hand pushes toward the scene and back, 4 s period), 'hold' (with --reach: "
         "the index tip held 2 cm into the surface), 'head-turns' "
         "(press, the head turning as the OpenXR simulator's \"head_path\": \"turns\", "
         "through a fixed stage and headset offset: telex/sim/head_turns.h) or a CSV "
         "file time_s,body_id,x,y,z,qx,qy,qz,qw")
      ->capture_default_str()
      ->check(motion_check());
  app.add_flag("!--no-loop", loop, "play a CSV recording once instead of looping");
  double reach_m = 0.0;
  app.add_option("--reach", reach_m,
                 "with --motion press: the depth (m) in front of the eyes of the surface to press "
                 "into (the desk frames: 0.85, synthetic:plane: 0.8); the index fingertip goes "
                 "from 0.30 m short of it to 0.04 m past it. Default: the fixed 0.25-0.55 m hand "
                 "path")
      ->check(telex::cli::Range(0.35, 5.0));
  if (const auto rc = program.parse(argc, argv)) return *rc;
  if (reach_m > 0.0 && motion != "press" && motion != "hold") {
    std::cerr << "telex-sim-natnet: --reach moves the press motion; it does not apply to --motion "
              << motion << "\n";
    return 2;
  }
  if (motion == "hold" && reach_m <= 0.0) {
    std::cerr << "telex-sim-natnet: --motion hold needs --reach (the surface's depth, m)\n";
    return 2;
  }

  try {
    cfg.version = natnet::parse_version(version);
    NatNetMotion fn = motion == "head-turns" ? natnet_head_turns(cfg.reported_latency_s)
                      : motion == "hold"     ? natnet_hold_toward(reach_m)
                      : motion != "press"    ? load_natnet_csv(motion, loop)
                      : reach_m > 0.0        ? natnet_press_toward(reach_m)
                                             : NatNetMotion(natnet_press_motion);
    // Signals are taken synchronously on this thread (sigtimedwait) rather than in a handler,
    // because stopping the server's io_context is not async-signal-safe.
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
    NatNetServer server(cfg, std::move(fn));
    std::cerr << "telex-sim-natnet: NatNet " << cfg.version.major << "." << cfg.version.minor
              << " on " << cfg.bind_address << ":" << server.command_port() << ", "
              << (cfg.multicast
                      ? "multicast " + cfg.multicast_group + ":" + std::to_string(cfg.data_port)
                      : std::string("unicast"))
              << ", " << cfg.rate_hz << " Hz ";
    // As typed: "12 s", "12.5 s".
    if (duration_s > 0)
      std::cerr << "for " << duration_s << " s\n";
    else
      std::cerr << "until stopped\n";
    std::atomic<bool> done{false};
    std::thread streamer([&] {
      server.run_for(duration_s);
      done = true;
    });
    const timespec tick{0, 50'000'000};
    while (!done) {
      if (sigtimedwait(&stop_signals, nullptr, &tick) > 0) server.stop();
    }
    streamer.join();
    const auto s = server.stats();
    std::cerr << "telex-sim-natnet: sent " << s.frames_sent << " frames to " << s.clients
              << " client(s), " << s.send_errors << " send errors\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "telex-sim-natnet: " << e.what() << "\n";
    return 1;
  }
}
