// SPDX-License-Identifier: MIT
// The strict config loader: TOML (CLI11's reader) or JSON; unknown keys and wrong shapes are
// errors; paths in it are relative to its folder.
#include <algorithm>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "telex/cli/cli.h"
#include "telex/common/rig.h"

namespace telex::cli {
namespace {

// JSON by the extension (.json) or else the first character ('{'); TOML otherwise.
bool is_json(const std::string& file, const std::string& text) {
  const auto first = text.find_first_not_of(" \t\r\n");
  return (file.size() > 5 && file.substr(file.size() - 5) == ".json") ||
         (first != std::string::npos && text[first] == '{');
}

// The folder a config file's relative paths are taken from.
std::filesystem::path folder_of(const std::string& file) {
  return std::filesystem::absolute(file).lexically_normal().parent_path();
}

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
    const std::string file = source_.empty() ? config_file(*app_) : source_;
    const std::string text((std::istreambuf_iterator<char>(input)),
                           std::istreambuf_iterator<char>());
    std::vector<CLI::ConfigItem> items;
    if (is_json(file, text)) {
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
    resolve_paths(file, items);
    values_.clear();
    for (const auto& item : items) {
      std::string v;
      for (const auto& in : item.inputs) v += (v.empty() ? "" : ",") + in;
      values_.emplace_back(item.name, v);
    }
    return items;
  }

  std::vector<std::pair<std::string, std::string>> values() const { return values_; }
  void add_paths(const std::vector<std::string>& keys, const ConfigPath& how) {
    for (const auto& k : keys) paths_[k] = how;
  }
  bool is_path(const std::string& key) const { return paths_.count(key) > 0; }
  // The file a text given without one stands for (parse_config_text); "" = --config's.
  void set_source(std::string file) { source_ = std::move(file); }

 private:
  void resolve_paths(const std::string& file, std::vector<CLI::ConfigItem>& items) const {
    const std::filesystem::path dir = folder_of(file);
    for (auto& item : items)
      if (const auto how = paths_.find(item.name); how != paths_.end())
        for (auto& in : item.inputs) in = how->second(in, dir);
  }

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
  std::map<std::string, ConfigPath> paths_;
  std::string source_;
  mutable std::vector<std::pair<std::string, std::string>> values_;
};

std::shared_ptr<StrictConfig> strict_config_of(const CLI::App& app) {
  return std::dynamic_pointer_cast<StrictConfig>(
      std::const_pointer_cast<CLI::Config>(app.get_config_formatter()));
}

}  // namespace

std::string value_in_config_text(const std::string& file, const std::string& text,
                                 const std::string& key) {
  if (is_json(file, text)) {
    const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
    if (j.is_discarded() || !j.is_object() || !j.contains(key) || !j[key].is_string()) return {};
    return j[key].get<std::string>();
  }
  try {
    std::istringstream toml(text);
    for (const auto& item : CLI::ConfigTOML().from_config(toml))
      if (item.parents.empty() && item.name == key && item.inputs.size() == 1)
        return item.inputs.front();
  } catch (const CLI::Error&) {
  }
  return {};
}

void parse_config_text(CLI::App& app, const std::string& file, const std::string& text) {
  const auto strict = strict_config_of(app);
  if (!strict) throw std::logic_error("parse_config_text: call add_strict_config first");
  strict->set_source(file);
  // Back to --config's file however the parse ends.
  const std::unique_ptr<StrictConfig, void (*)(StrictConfig*)> restore(
      strict.get(), [](StrictConfig* c) { c->set_source({}); });
  std::istringstream in(text);
  app.parse_from_stream(in);
}

std::string path_in(const std::string& value, const std::filesystem::path& dir) {
  if (value.empty() || std::filesystem::path(value).is_absolute()) return value;
  return (dir / value).lexically_normal().string();
}

ConfigPath spec_paths_in(std::map<std::string, int> path_items_by_kind) {
  return [kinds = std::move(path_items_by_kind)](const std::string& value,
                                                 const std::filesystem::path& dir) {
    const auto colon = value.find(':');
    const auto kind = kinds.find(value.substr(0, colon));
    if (colon == std::string::npos || kind == kinds.end()) return value;
    std::string out = value.substr(0, colon + 1);
    std::size_t at = colon + 1;
    for (int i = 0; at <= value.size(); ++i) {
      const std::size_t comma = std::min(value.find(',', at), value.size());
      const std::string item = value.substr(at, comma - at);
      out += (i > 0 ? "," : "") + (i < kind->second ? path_in(item, dir) : item);
      at = comma + 1;
    }
    return out;
  };
}

void config_paths(CLI::App& app, const std::vector<std::string>& keys, const ConfigPath& how) {
  const auto strict = strict_config_of(app);
  if (!strict) throw std::logic_error("config_paths: call add_strict_config first");
  strict->add_paths(keys, how);
}

std::optional<ConfigValue> config_path_before_flags(int argc, const char* const* argv,
                                                    const std::string& key) {
  std::string file;
  for (int i = 1; i < argc; ++i) {
    const std::string_view a = argv[i];
    if (a == "--") break;
    if (a == "--config" && i + 1 < argc) file = argv[++i];
    if (a.starts_with("--config=")) file = std::string(a.substr(9));
  }
  std::ifstream in(file);
  if (file.empty() || !in) return std::nullopt;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string value = value_in_config_text(file, text, key);
  if (value.empty()) return std::nullopt;
  return ConfigValue{path_in(value, folder_of(file)), file};
}

std::string ConfigValue::note(const std::string& key) const {
  return file.empty() ? std::string() : " (key '" + key + "' in " + file + ")";
}

std::optional<ConfigValue> rig_before_flags(int argc, const char* const* argv) {
  if (const auto path = rig_path_in_args(argc, argv)) return ConfigValue{path->string(), ""};
  return config_path_before_flags(argc, argv, "rig");
}

ConfigOrigin config_origin(const CLI::App& app, int argc, const char* const* argv) {
  ConfigOrigin origin;
  origin.file = config_file(app);
  const auto strict = strict_config_of(app);
  if (origin.file.empty() || !strict) return origin;
  for (const auto& [key, value] : strict->values()) {
    // A flag given on the command line wins over the file's value.
    bool given = false;
    for (int i = 1; i < argc && !given; ++i) {
      const std::string_view a = argv[i];
      given = a == "--" + key || a.starts_with("--" + key + "=");
    }
    if (!given) origin.entries.push_back({key, value, strict->is_path(key)});
  }
  return origin;
}

std::string ConfigOrigin::note(std::string_view message) const {
  const auto names_flag = [&](const std::string& key) {
    const std::string flag = "--" + key;
    return message.starts_with(flag) &&
           (message.size() == flag.size() ||
            std::string_view(": ='").find(message[flag.size()]) != std::string_view::npos);
  };
  // An absolute path among the value's items (a spec's too) that the message quotes.
  const auto names_path = [&](const std::string& value) {
    std::size_t at = 0;
    while (at < value.size()) {
      const std::size_t end = std::min(value.find_first_of(":,", at), value.size());
      const std::string_view item = std::string_view(value).substr(at, end - at);
      if (item.size() > 1 && item.front() == '/' && message.find(item) != std::string_view::npos)
        return true;
      at = end + 1;
    }
    return false;
  };
  for (const Entry& e : entries)
    if (names_flag(e.key) || (e.path && names_path(e.value)))
      return " (key '" + e.key + "' in " + file + ")";
  return {};
}

void add_strict_config(CLI::App& app, const std::string& help) {
  app.config_formatter(std::make_shared<StrictConfig>(&app));
  app.set_config("--config", "",
                 help +
                     " [TOML or JSON file; keys = long option names; relative paths in it are "
                     "relative to its folder]");
  app.allow_config_extras(CLI::config_extras_mode::error);
}

std::string config_file(const CLI::App& app) {
  const CLI::Option* opt = app.get_config_ptr();
  if (opt == nullptr || opt->results().empty()) return {};
  return opt->results().back();
}

std::vector<std::pair<std::string, std::string>> config_values(const CLI::App& app) {
  const auto strict = strict_config_of(app);
  return strict ? strict->values() : std::vector<std::pair<std::string, std::string>>{};
}

}  // namespace telex::cli
