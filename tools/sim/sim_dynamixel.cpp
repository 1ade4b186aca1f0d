// SPDX-License-Identifier: MIT
// telex-sim-dynamixel: emulated DYNAMIXEL X-series servos on a pseudo-terminal, for --head
// dynamixel.
#include <algorithm>
#include <csignal>
#include <ctime>
#include <iostream>
#include <sstream>

#include "telex/cli/command_line.h"
#include "telex/sim/dynamixel_servos.h"

int main(int argc, char** argv) {
  telex::cli::Program program{
      "telex-sim-dynamixel: DYNAMIXEL Protocol 2.0 servos (X series, position mode) on a "
      "pseudo-terminal; prints the device to give telex-remote --head dynamixel:DEV",
      "telex-sim-dynamixel"};
  const telex::cli::CommandLine& app = program.command_line();
  std::string ids_text = "1,2,3";
  double duration_s = 0.0;
  int mode = telex::dynamixel::xseries::kPositionMode;
  app.add_option("--ids", ids_text, "servo ids, comma-separated")->capture_default_str();
  app.add_option("--operating-mode", mode,
                 "the servos' Operating Mode at start (3 position; 4 extended position, which "
                 "telex-remote refuses)")
      ->capture_default_str()
      ->check(telex::cli::Range(0, 16));
  telex::cli::add(app, "--duration", duration_s, "Run this long (0 = until SIGINT/SIGTERM)", "s")
      ->check(telex::cli::Range(0.0, 86400.0));
  if (const auto rc = program.parse(argc, argv)) return *rc;

  try {
    std::vector<std::uint8_t> ids;
    std::stringstream in(ids_text);
    std::string item;
    while (std::getline(in, item, ',')) {
      std::size_t used = 0;
      int id = -1;
      try {
        id = std::stoi(item, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != item.size() || id < 0 || id > 252)
        throw std::invalid_argument("--ids '" + ids_text + "': '" + item + "' is not an id 0..252");
      // One bus cannot hold two servos of one id: both would answer every instruction.
      if (std::find(ids.begin(), ids.end(), id) != ids.end())
        throw std::invalid_argument("--ids '" + ids_text + "': id " + std::to_string(id) +
                                    " is given twice");
      ids.push_back(static_cast<std::uint8_t>(id));
    }
    if (ids.empty()) throw std::invalid_argument("--ids is empty");
    // Signals are taken synchronously on this thread, as in telex-sim-natnet.
    sigset_t stop_signals;
    sigemptyset(&stop_signals);
    sigaddset(&stop_signals, SIGINT);
    sigaddset(&stop_signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
    telex::sim::DynamixelPtyServer server(ids);
    for (const std::uint8_t id : ids)
      server.bus().set_operating_mode(id, static_cast<std::uint8_t>(mode));
    std::cout << "telex-sim-dynamixel: servos " << ids_text << " on " << server.device()
              << "\n  telex-remote --head dynamixel:" << server.device() << ",ids=" << ids_text
              << std::endl;
    const timespec tick{0, 100'000'000};
    for (int ticks = 0; duration_s <= 0 || ticks < duration_s * 10; ++ticks)
      if (sigtimedwait(&stop_signals, nullptr, &tick) > 0) break;
    const auto c = server.bus().counters();
    std::cerr << "telex-sim-dynamixel: " << c.instructions << " instructions, " << c.answers
              << " answers, " << c.crc_errors << " CRC errors, " << c.malformed << " malformed, "
              << c.goals_refused << " goals beyond the position limits refused\n";
    // What a driver programmed: the limits and the profile each servo ended with.
    namespace xs = telex::dynamixel::xseries;
    for (const std::uint8_t id : ids) {
      const auto& bus = server.bus();
      std::cerr << "  servo " << int{id} << ": position limits "
                << bus.register_value(id, xs::kMinPositionLimit, 4) << ".."
                << bus.register_value(id, xs::kMaxPositionLimit, 4) << ", profile velocity "
                << bus.register_value(id, xs::kProfileVelocity, 4) << ", acceleration "
                << bus.register_value(id, xs::kProfileAcceleration, 4) << ", torque "
                << (bus.torque_enabled(id) ? "on" : "off") << "\n";
    }
    return 0;
  } catch (const std::invalid_argument& e) {
    std::cerr << "telex-sim-dynamixel: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "telex-sim-dynamixel: " << e.what() << "\n";
    return 1;
  }
}
