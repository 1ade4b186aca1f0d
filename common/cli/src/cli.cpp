// SPDX-License-Identifier: MIT
// telex::cli: parse, usage messages and suggestions, help as JSON, logs on stderr.
#include "telex/cli/cli.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>
#include <iostream>
#include <regex>

#include "telex/common/logging.h"

namespace telex::cli {
namespace {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

std::vector<const CLI::App*> subcommands_of(const CLI::App& app) {
  return app.get_subcommands([](const CLI::App* s) { return !s->get_name().empty(); });
}

// An option name known to `app` or one of its parents (help flags live on the top).
bool known_option(const CLI::App* app, const std::string& name) {
  for (; app != nullptr; app = app->get_parent())
    if (app->get_option_no_throw(name) != nullptr) return true;
  return false;
}

const CLI::App* subcommand_named(const CLI::App& app, const std::string& name) {
  for (const CLI::App* s : subcommands_of(app))
    if (s->check_name(name)) return s;
  return nullptr;
}

std::string trim_number(std::string s) {
  if (s.find('.') == std::string::npos) return s;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// CLI11's texts, in the "<flag>: <what is wrong> (valid: ...)" form.
std::string reword(const CLI::App* app, const std::string& what) {
  std::smatch m;
  static const std::regex range(R"(^(\S+): Value (\S+) not in range (\S+) to (\S+)$)");
  static const std::regex member(R"(^(\S+): (.*) not in \{(.*)\}$)");
  static const std::regex convert(R"(^Could not convert: (\S+) = (.*)$)");
  static const std::regex required(R"(^(-\S+) is required$)");
  if (std::regex_match(what, m, range)) {
    const std::string lo = trim_number(m[3]);
    const std::string valid =
        std::stod(m[4]) > 1e300 ? ">= " + lo : lo + " to " + trim_number(m[4]);
    const std::string value = m[2].str();
    char* end = nullptr;
    std::strtod(value.c_str(), &end);
    const bool number = !value.empty() && end == value.c_str() + value.size();
    return m[1].str() + ": " +
           (number ? value + " is out of range" : "'" + value + "' is not a number") +
           " (valid: " + valid + ")";
  }
  if (std::regex_match(what, m, member))
    return m[1].str() + ": '" + m[2].str() + "' is not a valid value (valid: " + m[3].str() + ")";
  if (std::regex_match(what, m, convert)) {
    const CLI::Option* opt = app->get_option_no_throw(m[1].str());
    const std::string type = opt != nullptr ? opt->get_type_name() : std::string("value");
    return m[1].str() + ": '" + m[2].str() + "' is not a valid " + type;
  }
  if (std::regex_match(what, m, required)) return m[1].str() + ": is required but not given";
  return what;
}

// The first unknown long flag in argv for the subcommand chain it selects, and --help-json.
struct Scan {
  const CLI::App* app = nullptr;  // the deepest subcommand named
  std::string unknown;            // "" = none
  bool unknown_subcommand = false;
  bool help_json = false;
};

Scan scan(const CLI::App& top, int argc, const char* const* argv) {
  Scan s;
  s.app = &top;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--") break;
    if (a == "--help-json") {
      s.help_json = true;
      continue;
    }
    if (a.rfind("--", 0) == 0) {
      const std::string name = a.substr(0, a.find('='));
      if (s.unknown.empty() && !known_option(s.app, name)) s.unknown = name;
      continue;
    }
    if (const CLI::App* sub = subcommand_named(*s.app, a)) {
      s.app = sub;
      continue;
    }
    // A word where only a subcommand can stand (not an option's value, no positionals here).
    const CLI::Option* before = i > 1 ? s.app->get_option_no_throw(argv[i - 1]) : nullptr;
    const bool value = before != nullptr && before->get_expected_max() > 0;
    if (s.unknown.empty() && !value && a.rfind('-', 0) != 0 && !subcommands_of(*s.app).empty() &&
        s.app->get_options([](const CLI::Option* o) { return o->get_positional(); }).empty())
      s.unknown = a, s.unknown_subcommand = true;
  }
  return s;
}

const CLI::App* deepest_parsed(const CLI::App& app) {
  const CLI::App* at = &app;
  for (;;) {
    const auto parsed = at->get_subcommands();
    if (parsed.empty()) return at;
    at = parsed.front();
  }
}

// Before help: what the command line and the config file set shows as each option's default.
void given_as_defaults(CLI::App& app) {
  for (CLI::Option* opt : app.get_options()) {
    if (opt->count() == 0 || opt->get_expected_max() == 0) continue;
    std::string joined;
    for (const auto& r : opt->results()) joined += (joined.empty() ? "" : ",") + r;
    opt->default_str(joined);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) given_as_defaults(*sub);
}

}  // namespace

std::optional<int> load_before_flags(const std::string& program,
                                     const std::function<void()>& load) {
  init_logging(program);
  try {
    load();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kUsageExit;
  }
  return std::nullopt;
}

void prepare(CLI::App& app, std::string program) {
  // Logs go to stderr in the daemons' one format, so stdout carries only a program's output.
  init_logging(program);
  app.name(std::move(program));
  app.option_defaults()->always_capture_default();
  app.add_flag("--help-json")
      ->description("Print every option (names, default, help) as JSON and exit");
}

std::string program_name(const CLI::App& app) {
  std::string name = app.get_name();
  for (const CLI::App* p = app.get_parent(); p != nullptr; p = p->get_parent())
    name = p->get_name() + " " + name;
  return name;
}

CLI::Validator odd_in(int lo, int hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        int v = 0;
        if (!CLI::detail::lexical_cast(text, v)) return "'" + text + "' is not an integer";
        if (v < lo || v > hi || v % 2 == 0)
          return text + " is not odd within " + std::to_string(lo) + " to " + std::to_string(hi) +
                 " (valid: " + std::to_string(lo) + ", " + std::to_string(lo + 2) + ", ..., " +
                 std::to_string(hi) + ")";
        return {};
      },
      "ODD " + std::to_string(lo) + ".." + std::to_string(hi));
}

std::string closest_name(std::string_view typed, const std::vector<std::string>& names) {
  std::string word(typed);
  while (!word.empty() && word.front() == '-') word.erase(word.begin());
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, word.size() / 3) + 1;
  for (const auto& shown : names) {
    std::string_view name = shown;
    while (!name.empty() && name.front() == '-') name.remove_prefix(1);
    // A cut-short name ("--usb" for "--usb-id") counts as one edit away.
    const bool prefix = word.size() >= 3 && name.rfind(word, 0) == 0;
    const std::size_t d = prefix ? 1 : edit_distance(word, name);
    if (d < best_d) best_d = d, best = shown;
  }
  return best;
}

std::string suggest(const CLI::App& app, std::string_view unknown) {
  std::vector<std::string> names;
  for (const CLI::App* a = &app; a != nullptr; a = a->get_parent()) {
    for (const CLI::Option* opt : a->get_options())
      for (const auto& l : opt->get_lnames()) names.push_back("--" + l);
    if (a == &app)
      for (const CLI::App* s : subcommands_of(*a)) names.push_back(s->get_name());
  }
  return closest_name(unknown, names);
}

std::optional<int> parse(CLI::App& app, int argc, const char* const* argv) {
  const Scan s = scan(app, argc, argv);
  if (s.help_json) {
    std::cout << help_json(*s.app).dump(2) << "\n";
    return 0;
  }
  if (!s.unknown.empty()) {
    const std::string near = suggest(*s.app, s.unknown);
    std::cerr << program_name(*s.app) << ": " << s.unknown
              << (s.unknown_subcommand ? ": unknown subcommand" : ": unknown flag")
              << (near.empty() ? "" : " (did you mean " + near + "?)") << "\n(run "
              << program_name(*s.app) << " --help for the options)\n";
    return kUsageExit;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    given_as_defaults(app);
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    given_as_defaults(app);
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    const CLI::App* at = deepest_parsed(app);
    const std::string what = reword(at, e.what());
    std::cerr << program_name(*at) << ": " << what << config_origin(app, argc, argv).note(what)
              << "\n(run " << program_name(*at) << " --help for the options)\n";
    return kUsageExit;
  }
  log_config_values(app);  // a run says what its config file set
  return std::nullopt;
}

nlohmann::json help_json(const CLI::App& app) {
  nlohmann::json j;
  j["program"] = program_name(app);
  j["description"] = app.get_description();
  j["options"] = nlohmann::json::array();
  for (const CLI::Option* opt : app.get_options()) {
    nlohmann::json o;
    o["name"] = opt->get_name();
    std::vector<std::string> names;
    for (const auto& l : opt->get_lnames()) names.push_back("--" + l);
    for (const auto& s : opt->get_snames()) names.push_back("-" + s);
    o["names"] = names;
    o["default"] = opt->get_default_str();
    o["type"] = opt->get_type_name();
    o["flag"] = opt->get_expected_max() == 0;
    o["required"] = opt->get_required();
    o["hidden"] = opt->get_group().empty();
    o["help"] = opt->get_description();
    j["options"].push_back(o);
  }
  j["subcommands"] = nlohmann::json::array();
  for (const CLI::App* s : subcommands_of(app)) j["subcommands"].push_back(help_json(*s));
  return j;
}

void log_config_values(const CLI::App& app) {
  const auto values = config_values(app);
  if (values.empty()) return;
  std::string text;
  for (const auto& [k, v] : values) text += (text.empty() ? "" : ", ") + k + "=" + v;
  spdlog::info("{}: from {}: {}", program_name(app), config_file(app), text);
}

}  // namespace telex::cli
