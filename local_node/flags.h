// SPDX-License-Identifier: MIT
// telex-local's command line: every flag (CLI11), and what the flags' text becomes in the
// station's configuration. main.cpp parses with it; the local tests test it.
#pragma once

#include <optional>
#include <string>

#include "telex/cli/command_line.h"
#include "telex/cli/link_security.h"
#include "telex/local/station/station.h"

namespace CLI {
class App;
}

namespace telex::local {

// The command line's values: the station's configuration and the flags that are not one field of
// it (they are turned into it by the functions below).
struct StationFlags {
  StationConfig cfg;
  std::string rig_file;
  std::string connect = "127.0.0.1:7300";
  std::string transport = "udp";
  std::string glove;
  cli::LinkSecurityFlags security;  // --psk, --cert/--key/--ca, --insecure
  std::string elbow_bodies;
  std::string eye_size;  // --eye-size WxH, into cfg.eye_size
  bool no_realtime = false, no_bilateral = false, json_summary = false, quiet = false;
  bool no_head = false, head_naive = false, no_supervisor = false;
  bool full_frame = false, roi_flag = false, no_fill_here = false;
  int bilateral_radius = 0;  // set from the configuration when the options are added
  bool no_frame_parts = false, no_repair = false;
  // --link-silence-ms and --tracking-silence-ms, into cfg's seconds. 35 ms leaves 15 ms of the
  // 50 ms fault budget (issue 49) for what was already on its way when the link stopped (a TCP
  // backlog still read after the cut) and the display's command; 40 ms missed it by 0.5 ms once.
  double link_silence_ms = 35.0, tracking_silence_ms = 35.0;
  // What the --config file set, for the messages of errors after parsing.
  cli::ConfigOrigin config;
};

// telex-local's command line, as main runs it: the rig (--rig) first, then every flag parsed and
// resolved (resolve_station_flags). Returns the exit code when the program ends here (0 after
// --help, 2 after a usage error, already reported); nothing when it goes on.
std::optional<int> parse_station_command_line(int argc, char** argv, StationFlags& flags);

// --rig FILE (docs/RIG.md), read before the flags so any flag given overrides it. Throws
// std::runtime_error / std::invalid_argument naming the file and the key.
void load_station_rig(int argc, char** argv, StationFlags& flags);

// Every telex-local option, bound to `flags`: one place, so the set stays the same wherever it is
// parsed.
void add_station_options(CLI::App& app, StationFlags& flags);

// After parsing: --connect and --elbow-bodies into the configuration. Throws CLI::ValidationError
// naming the flag.
void resolve_station_flags(StationFlags& flags);

// --eye-size's text: "WxH", each in 16..8192. Throws std::invalid_argument saying what is wrong.
cv::Size parse_eye_size(const std::string& text);

// --psk, --cert/--key/--ca and --insecure: the keys loaded and checked, and a plain link off
// loopback refused without --insecure. Throws std::invalid_argument naming the flag.
void apply_security_flags(StationFlags& flags);

// The switches (--transport, --no-head, --full-frame, ...) into the configuration.
void apply_station_switches(StationFlags& flags);

}  // namespace telex::local
