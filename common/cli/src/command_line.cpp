// SPDX-License-Identifier: MIT
// The CLI11 face (command_line.h): each call is the CLI11 call of the same name, compiled once
// here.
#include "telex/cli/command_line.h"

#include <CLI/CLI.hpp>
#include <cmath>
#include <utility>

#include "telex/cli/cli.h"

namespace telex::cli {

Check::Check(CLI::Validator validator)
    : validator_(std::make_shared<const CLI::Validator>(std::move(validator))) {}

Check Range(int lo, int hi) { return Check(CLI::Range(lo, hi)); }
Check Range(double lo, double hi) { return Check(CLI::Range(lo, hi)); }
Check Range(std::uint64_t lo, std::uint64_t hi) { return Check(CLI::Range(lo, hi)); }
Check IsMember(std::initializer_list<const char*> values) { return Check(CLI::IsMember(values)); }
Check IsMember(std::vector<std::string> values) { return Check(CLI::IsMember(std::move(values))); }
Check IsMember(std::initializer_list<int> values) { return Check(CLI::IsMember(values)); }
Check Predicate(std::function<std::string(std::string&)> check, const std::string& description) {
  return Check(CLI::Validator(std::move(check), description));
}
Check ExistingFile() { return Check(CLI::ExistingFile); }
// Not CLI::PositiveNumber: that is a range from DBL_MIN, whose message prints the bound as 0
// ("valid: >= 0") although 0 is refused.
Check PositiveNumber() {
  return Check(CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(text, v))
          return "'" + text + "' is not a number (valid: > 0)";
        return v > 0.0 && std::isfinite(v) ? std::string() : text + " is out of range (valid: > 0)";
      },
      "POSITIVE"));
}

const Flag& Flag::check(const Check& check) const {
  option_->check(check.validator());
  return *this;
}
const Flag& Flag::required() const {
  option_->required();
  return *this;
}
const Flag& Flag::capture_default_str() const {
  option_->capture_default_str();
  return *this;
}
const Flag& Flag::default_str(std::string text) const {
  option_->default_str(std::move(text));
  return *this;
}
const Flag& Flag::delimiter(char separator) const {
  option_->delimiter(separator);
  return *this;
}
const Flag& Flag::expected(int count) const {
  option_->expected(count);
  return *this;
}
const Flag& Flag::each(std::function<void(const std::string&)> on_value) const {
  option_->each(std::move(on_value));
  return *this;
}

#define TELEX_CLI_ADD_OPTION(T)                                                                    \
  Flag CommandLine::add_option(const std::string& name, T& value, const std::string& help) const { \
    return Flag(app_->add_option(name, value, help));                                              \
  }
TELEX_CLI_ADD_OPTION(int)
TELEX_CLI_ADD_OPTION(unsigned)
TELEX_CLI_ADD_OPTION(long)
TELEX_CLI_ADD_OPTION(unsigned long)
TELEX_CLI_ADD_OPTION(float)
TELEX_CLI_ADD_OPTION(double)
TELEX_CLI_ADD_OPTION(std::string)
TELEX_CLI_ADD_OPTION(std::vector<std::string>)
TELEX_CLI_ADD_OPTION(std::vector<double>)
TELEX_CLI_ADD_OPTION(std::vector<int>)
TELEX_CLI_ADD_OPTION(std::optional<double>)
#undef TELEX_CLI_ADD_OPTION

Flag CommandLine::add_option_function(const std::string& name,
                                      std::function<void(const std::string&)> on_value,
                                      const std::string& help) const {
  return Flag(app_->add_option_function<std::string>(name, std::move(on_value), help));
}

Flag CommandLine::add_flag(const std::string& name, bool& value, const std::string& help) const {
  return Flag(app_->add_flag(name, value, help));
}

CommandLine CommandLine::add_subcommand(const std::string& name,
                                        const std::string& description) const {
  return CommandLine(*app_->add_subcommand(name, description));
}

void CommandLine::require_subcommand(int count) const { app_->require_subcommand(count); }

bool CommandLine::parsed() const { return app_->parsed(); }

std::string CommandLine::get_name() const { return app_->get_name(); }

CLI::App* CommandLine::get_parent() const { return app_->get_parent(); }

Program::Program(const std::string& description, const std::string& program)
    : app_(std::make_unique<CLI::App>(description)), cmd_(*app_) {
  prepare(*app_, program);
}

Program::~Program() = default;

std::optional<int> Program::parse(int argc, const char* const* argv) {
  return cli::parse(*app_, argc, argv);
}

void throw_validation_error(const std::string& flag, const std::string& what) {
  throw CLI::ValidationError(flag, what);
}

}  // namespace telex::cli
