// SPDX-License-Identifier: MIT
// libFuzzer target: arbitrary text as telex-local's --config file, through the daemons' strict
// loader (telex/cli/cli.h: parse_config_text, what parse() does with the file once read) over the
// station's whole option set, and through the read of one key before the flags
// (value_in_config_text, how the daemons find the rig). The loader either takes the text or
// throws CLI::ParseError, a CLI::ConfigError naming the file; the early read never throws.
//
// Input: byte 0 picks the file's name (0 .toml, 1 .json, 2 .conf: JSON then only by its first
// character), then the file's text.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "flags.h"
#include "telex/cli/cli.h"

namespace {

[[noreturn]] void fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "config_fuzz: %s: %s\n", what, detail.c_str());
  std::abort();
}

// Every key a parsed file set is a long option of the program, and the rig the daemons read
// before their flags is the one the flags then get.
void check_taken(const CLI::App& app, const std::string& file, const std::string& text) {
  int rigs = 0;
  std::string rig;
  for (const auto& [key, value] : telex::cli::config_values(app)) {
    if (app.get_option_no_throw("--" + key) == nullptr) fail("key is not an option", key);
    if (key == "rig") {
      ++rigs;
      rig = value;
    }
  }
  const std::string early = telex::cli::value_in_config_text(file, text, "rig");
  if (rigs == 1 && !early.empty() && telex::cli::path_in(early, "/etc/telex") != rig)
    fail("rig read before the flags differs", early + " vs " + rig);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kNames[] = {"/etc/telex/station.toml", "/etc/telex/station.json",
                                       "/etc/telex/station.conf"};
  const std::string file = kNames[data[0] % 3];
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  try {
    (void)telex::cli::value_in_config_text(file, text, "rig");
  } catch (const std::exception& e) {
    fail("value_in_config_text threw", e.what());
  }
  telex::local::StationFlags flags;
  CLI::App app{"telex-local"};
  telex::cli::prepare(app, "telex-local");
  spdlog::default_logger()->set_level(spdlog::level::off);
  telex::local::add_station_options(app, flags);
  try {
    telex::cli::parse_config_text(app, file, text);
  } catch (const CLI::ConfigError& e) {
    if (std::string(e.what()).find(file) == std::string::npos) fail("file not named", e.what());
    return 0;
  } catch (const CLI::ParseError&) {
    return 0;
  } catch (const std::exception& e) {
    fail("not a CLI::ParseError", e.what());
  }
  check_taken(app, file, text);
  return 0;
}
