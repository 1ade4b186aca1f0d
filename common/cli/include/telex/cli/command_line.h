// SPDX-License-Identifier: MIT
// A thin face of CLI11 for code that only declares flags: CLI11 (header-only in Debian, 5-8 s of
// compile in every file that includes it) stays in the cli library's own files; the `telex` tool's
// sub-commands declare their flags through this header. Every call forwards to the CLI11 call of
// the same name, so options, help text and usage errors are CLI11's own.
#pragma once

#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace CLI {
class App;
class Option;
class Validator;
}  // namespace CLI

namespace telex::cli {

inline constexpr int kUsageExit = 2;

// What a --config file set, for the messages after parsing (a key file that cannot be read, a
// log that cannot be opened): one that names an option the file set, by its flag or by the path
// the file gave it, gets " (key 'K' in FILE)".
struct ConfigOrigin {
  struct Entry {
    std::string key, value;  // the value as used: a path relative to the file's folder resolved
    bool path = false;
  };
  std::string file;  // as given to --config; empty when none was
  std::vector<Entry> entries;
  // " (key 'psk' in cfg/remote.toml)" when `message` starts with "--psk" or holds the absolute
  // path that key was given; empty otherwise.
  std::string note(std::string_view message) const;
};

// A CLI11 validator, made by the functions below.
class Check {
 public:
  explicit Check(CLI::Validator validator);
  const CLI::Validator& validator() const { return *validator_; }

 private:
  std::shared_ptr<const CLI::Validator> validator_;
};

// CLI::Range(lo, hi): its text names the type ("INT in [1 - 9]", "FLOAT in [...]").
Check Range(int lo, int hi);
Check Range(double lo, double hi);
Check Range(std::uint64_t lo, std::uint64_t hi);
// CLI::IsMember over these values.
Check IsMember(std::initializer_list<const char*> values);
Check IsMember(std::vector<std::string> values);
Check IsMember(std::initializer_list<int> values);
// CLI::Validator(check, description): `check` returns "" for a good value, else what is wrong.
Check Predicate(std::function<std::string(std::string&)> check, const std::string& description);
// The name among `names` closest to `typed` (a typo or a cut-short name), "" when none is close;
// leading dashes are ignored on both sides. cli::suggest's rule, for a flag's values.
std::string closest_name(std::string_view typed, const std::vector<std::string>& names);

// CLI::ExistingFile.
Check ExistingFile();
// A number > 0 ("--flag: 0 is out of range (valid: > 0)" otherwise).
Check PositiveNumber();

// One option (CLI::Option*); `->` chains as on CLI11's pointer.
class Flag {
 public:
  explicit Flag(CLI::Option* option) : option_(option) {}
  // A handle, as CLI11's pointer: const does not make the option const.
  const Flag* operator->() const { return this; }
  CLI::Option* option() const { return option_; }

  const Flag& check(const Check& check) const;
  const Flag& required() const;
  const Flag& capture_default_str() const;
  const Flag& default_str(std::string text) const;
  const Flag& delimiter(char separator) const;
  const Flag& expected(int count) const;
  const Flag& each(std::function<void(const std::string&)> on_value) const;

 private:
  CLI::Option* option_;
};

// A program's or sub-command's command line (CLI::App&, not owned).
class CommandLine {
 public:
  explicit CommandLine(CLI::App& app) : app_(&app) {}
  // A handle, as CLI11's pointer: const does not make the command line const.
  const CommandLine* operator->() const { return this; }
  CLI::App& app() const { return *app_; }

  Flag add_option(const std::string& name, int& value, const std::string& help) const;
  Flag add_option(const std::string& name, unsigned& value, const std::string& help) const;
  Flag add_option(const std::string& name, long& value, const std::string& help) const;
  Flag add_option(const std::string& name, unsigned long& value, const std::string& help) const;
  Flag add_option(const std::string& name, float& value, const std::string& help) const;
  Flag add_option(const std::string& name, double& value, const std::string& help) const;
  Flag add_option(const std::string& name, std::string& value, const std::string& help) const;
  Flag add_option(const std::string& name, std::vector<std::string>& value,
                  const std::string& help) const;
  Flag add_option(const std::string& name, std::vector<double>& value,
                  const std::string& help) const;
  Flag add_option(const std::string& name, std::vector<int>& value, const std::string& help) const;
  Flag add_option(const std::string& name, std::optional<double>& value,
                  const std::string& help) const;
  // CLI::App::add_option_function<std::string>.
  Flag add_option_function(const std::string& name,
                           std::function<void(const std::string&)> on_value,
                           const std::string& help) const;
  Flag add_flag(const std::string& name, bool& value, const std::string& help) const;

  CommandLine add_subcommand(const std::string& name, const std::string& description) const;
  void require_subcommand(int count) const;
  bool parsed() const;
  std::string get_name() const;
  // The enclosing command line (the program of a sub-command); nullptr at the top.
  CLI::App* get_parent() const;

 private:
  CLI::App* app_;
};

// A program's command line (a CLI::App made one of ours by cli::prepare), owned here.
class Program {
 public:
  Program(const std::string& description, const std::string& program);
  ~Program();
  Program(const Program&) = delete;
  Program& operator=(const Program&) = delete;
  CommandLine& command_line() { return cmd_; }
  // cli::parse: nothing when the program goes on, else its exit code (0 after --help, 2 after a
  // usage error, already reported).
  std::optional<int> parse(int argc, const char* const* argv);

 private:
  std::unique_ptr<CLI::App> app_;
  CommandLine cmd_;
};

// Throws CLI11's usage error for `flag` (exit 2 with "<program>: <flag>: <what>" from parse()).
[[noreturn]] void throw_validation_error(const std::string& flag, const std::string& what);

// cli::help_json (cli.h): every option of `app` and its sub-commands, as JSON.
nlohmann::json help_json(const CLI::App& app);

// cli::add (cli.h) on a CommandLine: "help [unit]", the default shown.
template <class T>
Flag add(const CommandLine& cmd, const std::string& name, T& value, const std::string& help,
         std::string_view unit = {}) {
  const std::string text = unit.empty() ? help : help + " [" + std::string(unit) + "]";
  return cmd.add_option(name, value, text)->capture_default_str();
}

}  // namespace telex::cli
