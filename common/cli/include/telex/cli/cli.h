// SPDX-License-Identifier: MIT
// The command-line contract every telex program keeps: usage errors exit 2 with one message naming
// the flag, unknown flags get a suggestion, help shows defaults and units, config files are strict.
#pragma once

#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "telex/cli/command_line.h"

namespace telex::cli {

// Makes `app` one of our programs: `program` prefixes every message ("telex-remote"), option
// defaults are captured for the help, --help-json prints the options as JSON. Call before adding
// options (the defaults apply to options added later).
void prepare(CLI::App& app, std::string program);

// A daemon's first step, before its flags: sets up logging for `program` and runs `load` (reading
// the rig the flags' defaults come from). An exception from it is a usage error: logged, and 2
// returned; nothing when it went well.
std::optional<int> load_before_flags(const std::string& program, const std::function<void()>& load);

// The name that prefixes messages for `app`: its program, or "telex bench" for a subcommand.
std::string program_name(const CLI::App& app);

// Adds an option whose help names its unit: "help [unit]"; the default shows as "=value".
template <class T>
CLI::Option* add(CLI::App& app, const std::string& name, T& value, const std::string& help,
                 std::string_view unit = {}) {
  const std::string text = unit.empty() ? help : help + " [" + std::string(unit) + "]";
  return app.add_option(name, value, text)->capture_default_str();
}

// A validator for odd integers in [lo, hi] (window sides).
CLI::Validator odd_in(int lo, int hi);

// Adds --config FILE read by the strict loader: TOML (CLI11's) or a JSON object, chosen by the
// extension (.json) or else the first character ('{'). Keys are the long option names without
// "--"; an unknown key or a value of the wrong shape is a usage error naming the key and the file.
void add_strict_config(CLI::App& app, const std::string& help);

// A path-valued key's value as a config file gives it, made absolute against `dir`, the file's
// folder: a relative path in a config file is relative to that file, not to the working directory
// (a daemon started by systemd runs in /).
using ConfigPath =
    std::function<std::string(const std::string& value, const std::filesystem::path& dir)>;
// A plain FILE or DIR: "telex.key" -> dir/telex.key; an absolute path and "" stay as they are.
std::string path_in(const std::string& value, const std::filesystem::path& dir);
// A spec KIND:PATH[,PATH][,options] ("sim:forces.csv", "files:L*.png,R*.png,loop"): for each kind
// listed, its number of leading comma-separated items are paths (path_in); other kinds stay.
ConfigPath spec_paths_in(std::map<std::string, int> path_items_by_kind);

// Marks `keys` of the --config file (add_strict_config, before) as paths, read with `how`.
void config_paths(CLI::App& app, const std::vector<std::string>& keys,
                  const ConfigPath& how = path_in);

// Before the flags are parsed (the rig is read first): the value the --config file in argv gives
// `key`, as a path relative to the file's folder, and the file as given. Nothing when argv names
// no config file or it does not set the key; a file that cannot be read or parsed is left for
// parse() to report.
struct ConfigValue {
  std::string value, file;  // file: "" when the value came from the command line
  // " (key 'KEY' in FILE)" for a message about the value when a config file gave it, else "".
  std::string note(const std::string& key) const;
};
std::optional<ConfigValue> config_path_before_flags(int argc, const char* const* argv,
                                                    const std::string& key);

// The rig file both daemons read before their flags (docs/RIG.md): --rig FILE in argv, else the
// config file's `rig` key (relative to its folder). Nothing when neither names one; throws
// telex::RigError for a --rig without a file.
std::optional<ConfigValue> rig_before_flags(int argc, const char* const* argv);

// The value of `key` in a config file's text (`file` names it: .json picks JSON), as the file
// gives it, without the strict checks: "" when it has none or the text does not parse. Never
// throws for any text.
std::string value_in_config_text(const std::string& file, const std::string& text,
                                 const std::string& key);

// What parse() does with a --config file, given its text: `text` read by `app`'s strict loader
// (add_strict_config before) as the file `file` (its name picks the format and is named in the
// errors; its folder resolves relative paths), then applied to the options as CLI11 applies a
// config file (conversions, validators, requirements). Throws CLI::ParseError: a CLI::ConfigError
// naming the key and `file` for an unknown key or a value of the wrong shape, else the option's
// own error for a value it refuses.
void parse_config_text(CLI::App& app, const std::string& file, const std::string& text);

// After parse(): what the config file set that the command line did not give again.
ConfigOrigin config_origin(const CLI::App& app, int argc, const char* const* argv);

// The values a config file set, as (key, value) pairs in file order (empty before parse()); a
// path-valued key's value resolved against the file's folder.
std::vector<std::pair<std::string, std::string>> config_values(const CLI::App& app);

// The config file given, or "" (after parse()).
std::string config_file(const CLI::App& app);

// Parses argv. Returns nothing when the program goes on; else the exit code to return: 0 after
// --help/--help-all/--help-json, 2 after a usage error (its message already on stderr as
// "<program>: <flag>: <what is wrong>", with "did you mean --x?" for an unknown flag). When it goes
// on, the values a config file set are logged (log_config_values).
std::optional<int> parse(CLI::App& app, int argc, const char* const* argv);

// The closest long option or subcommand name of `app` to `unknown` ("" when none is close).
std::string suggest(const CLI::App& app, std::string_view unknown);

// Every option of `app` (and its subcommands, recursively): names, default, help, group.
nlohmann::json help_json(const CLI::App& app);

// Logs (spdlog's default logger) the values a config file set, so a run says what it used.
void log_config_values(const CLI::App& app);

}  // namespace telex::cli
