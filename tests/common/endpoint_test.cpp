// SPDX-License-Identifier: MIT
// parse_endpoint: host:port, IPv4, bracketed IPv6; every error names the flag.
#include "telex/common/endpoint.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace telex {
namespace {

TEST(Endpoint, ParsesNamesIpv4AndBracketedIpv6) {
  const Endpoint a = parse_endpoint("robot.lab:7300", "--connect");
  EXPECT_EQ(a.host, "robot.lab");
  EXPECT_EQ(a.port, 7300);
  const Endpoint b = parse_endpoint("127.0.0.1:1", "--connect");
  EXPECT_EQ(b.host, "127.0.0.1");
  EXPECT_EQ(b.port, 1);
  const Endpoint c = parse_endpoint("[::1]:7000", "--connect");
  EXPECT_EQ(c.host, "::1");
  EXPECT_EQ(c.port, 7000);
  const Endpoint d = parse_endpoint("[fe80::1%eth0]:65535", "--connect");
  EXPECT_EQ(d.host, "fe80::1%eth0");
  EXPECT_EQ(d.port, 65535);
}

TEST(Endpoint, PortZeroOnlyWhenAllowed) {
  EXPECT_EQ(parse_endpoint("0.0.0.0:0", "--listen", true).port, 0);
  EXPECT_THROW(parse_endpoint("0.0.0.0:0", "--forward"), std::invalid_argument);
}

TEST(Endpoint, RoundTripsThroughToString) {
  for (const std::string text : {"host:80", "10.0.0.2:7300", "[::1]:7000"})
    EXPECT_EQ(to_string(parse_endpoint(text, "--x")), text);
}

// Each bad input: the message names the flag and says what is wrong.
TEST(Endpoint, ErrorsNameTheFlagAndTheProblem) {
  const struct {
    const char* text;
    const char* says;
  } cases[] = {
      {"127.0.0.1", "expected HOST:PORT"},
      {"", "expected HOST:PORT"},
      {":7000", "no host"},
      {"[]:7000", "no host"},
      {"host:", "port must be a number 1..65535"},
      {"host:70000", "port must be 1..65535, got '70000'"},
      {"host:123456", "port must be a number"},
      {"host:-1", "port must be a number"},
      {"host:+80", "port must be a number"},
      {"host:80x", "port must be a number"},
      {"::1:7000", "an IPv6 address goes in brackets: [::1]:PORT"},
      {"[::1]7000", "expected HOST:PORT"},
      {"[::1:7000", "expected HOST:PORT"},
  };
  for (const auto& c : cases) {
    try {
      parse_endpoint(c.text, "--connect");
      ADD_FAILURE() << "'" << c.text << "' was accepted";
    } catch (const std::invalid_argument& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind("--connect '", 0), 0u) << what;
      EXPECT_NE(what.find(c.says), std::string::npos) << c.text << ": " << what;
    }
  }
}

}  // namespace
}  // namespace telex
