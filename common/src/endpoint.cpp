// SPDX-License-Identifier: MIT
// The one HOST:PORT parser of the command lines.
#include "telex/common/endpoint.h"

#include <stdexcept>

namespace telex {
namespace {

std::invalid_argument bad(std::string_view flag, std::string_view text, const std::string& why) {
  return std::invalid_argument(std::string(flag) + " '" + std::string(text) + "': " + why);
}

}  // namespace

Endpoint parse_endpoint(std::string_view text, std::string_view flag, bool allow_port_zero) {
  constexpr const char* kForm = "expected HOST:PORT (an IPv6 address in brackets: [::1]:7000)";
  Endpoint e;
  std::string_view port_text;
  if (!text.empty() && text.front() == '[') {
    const auto close = text.find(']');
    if (close == std::string_view::npos || close + 1 >= text.size() || text[close + 1] != ':')
      throw bad(flag, text, kForm);
    e.host = std::string(text.substr(1, close - 1));
    port_text = text.substr(close + 2);
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string_view::npos) throw bad(flag, text, kForm);
    e.host = std::string(text.substr(0, colon));
    port_text = text.substr(colon + 1);
    if (e.host.find(':') != std::string::npos)
      throw bad(flag, text, "an IPv6 address goes in brackets: [" + e.host + "]:PORT");
  }
  if (e.host.empty()) throw bad(flag, text, std::string("no host; ") + kForm);
  const char* range = allow_port_zero ? "0..65535" : "1..65535";
  if (port_text.empty() || port_text.size() > 5 ||
      port_text.find_first_not_of("0123456789") != std::string_view::npos)
    throw bad(
        flag, text,
        "port must be a number " + std::string(range) + ", got '" + std::string(port_text) + "'");
  const long port = std::stol(std::string(port_text));
  if (port > 65535 || (port == 0 && !allow_port_zero))
    throw bad(flag, text,
              "port must be " + std::string(range) + ", got '" + std::string(port_text) + "'");
  e.port = static_cast<std::uint16_t>(port);
  return e;
}

std::string to_string(const Endpoint& endpoint) {
  const bool v6 = endpoint.host.find(':') != std::string::npos;
  return (v6 ? "[" + endpoint.host + "]" : endpoint.host) + ":" + std::to_string(endpoint.port);
}

}  // namespace telex
