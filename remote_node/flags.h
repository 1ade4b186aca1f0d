// SPDX-License-Identifier: MIT
// telex-remote's command line: every flag (CLI11), and what the flags' text becomes in the
// daemon's configuration. main.cpp parses with it; the remote tests test it.
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "telex/cli/command_line.h"
#include "telex/cli/link_security.h"
#include "telex/common/rig.h"
#include "telex/remote/daemon.h"
#include "telex/remote/pipeline.h"

namespace CLI {
class App;
}

namespace telex::remote {

// The command line's values: the daemon's configuration and the flags that are not one field of
// it (resolve_remote_flags turns them into it).
struct RemoteFlags {
  DaemonConfig cfg;
  std::optional<Rig> rig;  // --rig, read before the flags
  std::string rig_file;
  std::string listen = "127.0.0.1:7300", transport = "udp", codec = "zip", tile = "80x60",
              size = "640x480", video_size = "0x0", video_bitrate = "4M";
  int client_timeout_ms = 3000;
  std::string register_mode = "none", register_baseline = "0.025,0,0", register_rotation = "0,0,0",
              register_eye;
  std::string registration;  // --registration hardware|rig|none; empty: rig when there are
                             // extrinsics (the rig's, or --register shift|full), else none
  bool fill = false, no_fill = false, no_temporal = false, no_stats = false, no_realtime = false;
  std::string stats_form = "short";  // --stats
  cli::LinkSecurityFlags security;   // --psk, --cert/--key/--ca, --insecure
  // What the --config file set, for the messages of errors after parsing.
  cli::ConfigOrigin config;
};

// telex-remote's whole command line, as main runs it: the rig (--rig) first, then every flag parsed
// and resolved into flags.cfg. Returns the exit code when the program ends here (0 after --help,
// 2 after a usage error, already reported); nothing when it goes on.
std::optional<int> parse_remote_command_line(int argc, char** argv, RemoteFlags& flags);

// --rig FILE (docs/RIG.md), read before the flags so any flag given overrides it. Throws
// std::runtime_error / std::invalid_argument naming the file and the key.
void load_remote_rig(int argc, char** argv, RemoteFlags& flags);

// Every telex-remote option, bound to `flags`, in --help's order; with a rig, its values as the
// registration flags' defaults.
void add_remote_options(CLI::App& app, RemoteFlags& flags);

// After parsing: the flags' text (endpoints, sizes, registration, keys, switches) and the rig into
// flags.cfg, then the whole configuration validated. `app` tells which registration flags were
// given. Throws std::invalid_argument (or the key loader's std::runtime_error) naming the flag.
void resolve_remote_flags(const CLI::App& app, RemoteFlags& flags);

// "none" | "shift" | "full"; throws std::invalid_argument naming the valid values.
RegisterMode parse_register_mode(std::string_view text);

// Builds a RegistrationConfig from the command line's text: mode, eye centre "X,Y,Z" (metres, in
// the depth camera's frame), rotation "RX,RY,RZ" (degrees, applied about x, then y, then z),
// eye intrinsics "FX,FY,CX,CY,W,H" ("" = the source's). Throws std::invalid_argument naming the
// flag and the expected form.
RegistrationConfig parse_registration(std::string_view mode, std::string_view eye_centre_m,
                                      std::string_view rotation_deg, std::string_view eye,
                                      double nominal_depth_m);

// Which registration flags the command line gave (they override the rig).
struct RegistrationFlagsGiven {
  bool mode = false, centre = false, rotation = false, eye = false;
};

// The rig's registration (docs/RIG.md): the right eye's intrinsics (eyes.right), the depth-to-eye
// extrinsics (extrinsics.right_eye_from_depth), the depth's calibrated intrinsics (depth). With
// the extrinsics and no --register, the mode becomes full. Flags given win.
void apply_rig(const Rig& rig, const RegistrationFlagsGiven& given, RegistrationConfig& reg);

// The run's one registration (--registration, `asked`; empty = chosen): hardware, rig or none,
// from the registration stage `reg` already built from the flags and the rig. Sets the source's
// hardware registration and leaves `reg` applying extrinsics only for rig. Throws
// std::invalid_argument naming both sides of a combination that would register twice
// (hardware with extrinsics calibrated in the sensor's own pixels) or that contradicts itself.
struct RegistrationChoice {
  std::string_view asked;        // --registration's text, "" when not given
  bool register_given = false;   // --register shift|full on the command line
  const Rig* rig = nullptr;      // --rig, when given
  std::string_view source_spec;  // --source
};
DepthRegistration choose_registration(const RegistrationChoice& choice, RegistrationConfig& reg,
                                      SourceOptions& source);

// What the rig sets, as the registration flags' defaults in --help (docs/RIG.md: `--help` with
// `--rig` shows the rig's values), and as one line for the start-up log.
void show_rig_defaults(CLI::App& app, const Rig& rig);
std::string describe_rig(const Rig& rig);

}  // namespace telex::remote
