// SPDX-License-Identifier: MIT
// HOST:PORT as the command lines give it: host:port, a.b.c.d:port, [IPv6]:port.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace telex {

struct Endpoint {
  std::string host;  // without brackets: "::1", "127.0.0.1", "robot.lab"
  std::uint16_t port = 0;
};

// Parses `text` given to `flag` (named in every error). An IPv6 address goes in brackets
// ([::1]:7000); the port is decimal, 1..65535 (0..65535 with allow_port_zero, "any free port").
// Throws std::invalid_argument starting with the flag, saying what is wrong and what is expected.
Endpoint parse_endpoint(std::string_view text, std::string_view flag, bool allow_port_zero = false);

// host:port, with brackets around an IPv6 host: what parse_endpoint reads back.
std::string to_string(const Endpoint& endpoint);

}  // namespace telex
