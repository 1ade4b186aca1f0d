// SPDX-License-Identifier: MIT
// The strict config loader: TOML (CLI11's reader) or JSON; unknown keys and wrong shapes are
// errors.
#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>

#include "telex/cli/cli.h"

namespace telex::cli {
namespace {

// "line L, column C" of the character at 1-based byte offset `byte` (nlohmann's parse_error::byte,
// the last character read; one past the end at a truncated end), both counted from 1.
std::string line_and_column(std::string_view text, std::size_t byte) {
  const std::size_t at = std::min(byte > 0 ? byte - 1 : 0, text.size());
  const std::string_view before = text.substr(0, at);
  const std::size_t line =
      1 + static_cast<std::size_t>(std::count(before.begin(), before.end(), '\n'));
  const std::size_t nl = before.rfind('\n');
  const std::size_t column = at - (nl == std::string_view::npos ? 0 : nl + 1) + 1;
  return "line " + std::to_string(line) + ", column " + std::to_string(column);
}

// What nlohmann says is wrong, without its own prefix and position.
std::string reason_of(const nlohmann::json::parse_error& e) {
  const std::string what = e.what();
  for (const char* start : {"syntax error", "invalid"})
    if (const auto at = what.find(start); at != std::string::npos) return what.substr(at);
  return what;
}

class StrictConfig : public CLI::Config {
 public:
  explicit StrictConfig(const CLI::App* app) : app_(app) {}

  std::string to_config(const CLI::App* app, bool default_also, bool write_description,
                        std::string prefix) const override {
    return CLI::ConfigTOML().to_config(app, default_also, write_description, std::move(prefix));
  }

  std::vector<CLI::ConfigItem> from_config(std::istream& input) const override {
    const std::string file = config_file(*app_);
    const std::string text((std::istreambuf_iterator<char>(input)),
                           std::istreambuf_iterator<char>());
    const auto first = text.find_first_not_of(" \t\r\n");
    const bool json = (file.size() > 5 && file.substr(file.size() - 5) == ".json") ||
                      (first != std::string::npos && text[first] == '{');
    std::vector<CLI::ConfigItem> items;
    if (json) {
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(text);
      } catch (const nlohmann::json::parse_error& e) {
        throw CLI::ConfigError(file + " " + line_and_column(text, e.byte) + ": not valid JSON (" +
                               reason_of(e) + ")");
      }
      if (!j.is_object())
        throw CLI::ConfigError(file + ": not a JSON object (keys = long option names)");
      for (auto it = j.begin(); it != j.end(); ++it)
        items.push_back(json_item(file, it.key(), *it));
    } else {
      std::istringstream toml(text);
      for (auto& item : CLI::ConfigTOML().from_config(toml)) {
        if (item.name == "++" || item.name == "--") continue;  // section markers
        if (!item.parents.empty())
          throw CLI::ConfigError(file + ": section [" + item.parents.front() +
                                 "] is not known (keys are the long option names, at the top)");
        option_for(file, item.name);
        items.push_back(std::move(item));
      }
    }
    values_.clear();
    for (const auto& item : items) {
      std::string v;
      for (const auto& in : item.inputs) v += (v.empty() ? "" : ",") + in;
      values_.emplace_back(item.name, v);
    }
    return items;
  }

  std::vector<std::pair<std::string, std::string>> values() const { return values_; }

 private:
  const CLI::Option* option_for(const std::string& file, const std::string& key) const {
    const CLI::Option* opt = app_->get_option_no_throw("--" + key);
    if (opt == nullptr || opt == app_->get_config_ptr() || key == "help" || key == "help-json") {
      const std::string near = suggest(*app_, key);
      throw CLI::ConfigError(file + ": key '" + key + "' is not an option of " +
                             program_name(*app_) +
                             (near.empty() ? "" : " (did you mean '" + near.substr(2) + "'?)"));
    }
    return opt;
  }

  CLI::ConfigItem json_item(const std::string& file, const std::string& key,
                            const nlohmann::json& v) const {
    const CLI::Option* opt = option_for(file, key);
    const bool flag = opt->get_expected_max() == 0;
    const auto wrong = [&](const std::string& want) {
      return CLI::ConfigError(file + ": key '" + key + "' must be " + want + ", not " + v.dump());
    };
    if (flag && !v.is_boolean()) throw wrong("true or false");
    if (!flag && (v.is_boolean() || v.is_object() || v.is_null()))
      throw wrong("a " + opt->get_type_name());
    if (!flag && v.is_array() && opt->get_expected_max() <= 1) throw wrong("one value, not a list");
    CLI::ConfigItem item;
    item.name = key;
    const auto one = [](const nlohmann::json& x) {
      return x.is_string() ? x.get<std::string>() : x.dump();
    };
    if (v.is_array())
      for (const auto& x : v) item.inputs.push_back(one(x));
    else
      item.inputs.push_back(one(v));
    return item;
  }

  const CLI::App* app_;
  mutable std::vector<std::pair<std::string, std::string>> values_;
};

}  // namespace

void add_strict_config(CLI::App& app, const std::string& help) {
  app.config_formatter(std::make_shared<StrictConfig>(&app));
  app.set_config("--config", "", help + " [TOML or JSON file; keys = long option names]");
  app.allow_config_extras(CLI::config_extras_mode::error);
}

std::string config_file(const CLI::App& app) {
  const CLI::Option* opt = app.get_config_ptr();
  if (opt == nullptr || opt->results().empty()) return {};
  return opt->results().back();
}

std::vector<std::pair<std::string, std::string>> config_values(const CLI::App& app) {
  const auto strict = std::dynamic_pointer_cast<const StrictConfig>(app.get_config_formatter());
  return strict ? strict->values() : std::vector<std::pair<std::string, std::string>>{};
}

}  // namespace telex::cli
