// SPDX-License-Identifier: MIT
// What the link says to a newcomer (issue 50): `localhost` as a --listen address, an address the
// machine lacks named as such, and a station without the key at a keyed remote told the fix
// instead of "is telex-remote running?".
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "daemons.h"
#include "process.h"
#include "telex/proto/auth.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

TEST(LinkWords, TheRemoteListensOnLocalhost) {
  TELEX_REQUIRE_BINARIES("telex-remote");
  const auto dir = scratch_dir("listen_localhost");
  Process remote({built_binary("telex-remote").string(), "--listen",
                  "localhost:" + std::to_string(free_port()), "--source", "synthetic:plane",
                  "--duration", "1", "--no-stats"},
                 dir / "remote.out", dir / "remote.err");
  EXPECT_EQ(remote.wait(30s).value_or(-1), 0) << remote.stderr_text();
}

// 192.0.2.1 is TEST-NET-1 (RFC 5737): no machine has it.
TEST(LinkWords, AnAddressTheMachineLacksIsNamedAsSuch) {
  TELEX_REQUIRE_BINARIES("telex-remote");
  const auto dir = scratch_dir("listen_foreign");
  Process remote({built_binary("telex-remote").string(), "--listen", "192.0.2.1:7300", "--insecure",
                  "--source", "synthetic:plane", "--duration", "1"},
                 dir / "remote.out", dir / "remote.err");
  EXPECT_EQ(remote.wait(30s).value_or(-1), 2) << remote.stderr_text();
  const auto err = remote.stderr_text();
  EXPECT_NE(err.find("this machine has no address 192.0.2.1"), std::string::npos) << err;
  EXPECT_EQ(err.find("another telex-remote"), std::string::npos) << err;
}

// A station without a key at a remote with one reads the remote's clear-text refusal, counts it
// as an authentication failure and stops after three (they do not heal), naming the fix.
TEST(LinkWords, AKeylessStationAtAKeyedRemoteIsToldTheFix) {
  TELEX_REQUIRE_BINARIES("telex-remote", "telex-local");
  const auto dir = scratch_dir("keyless_station");
  const auto key = dir / "telex.key";
  proto::write_new_key_file(key);
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--psk", key.string()});
  Process local(local_args(remote.port, dir,
                           {"--quiet", "--hand", "script:press", "--first-surface-timeout", "30"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(60s);
  ASSERT_TRUE(rc.has_value()) << "the station kept retrying a refusal that cannot heal";
  EXPECT_EQ(*rc, 1);
  const auto err = local.stderr_text();
  EXPECT_NE(err.find("authentication failed"), std::string::npos) << err;
  EXPECT_NE(err.find("--psk"), std::string::npos) << err;
  EXPECT_EQ(err.find("is telex-remote running"), std::string::npos) << err;
  EXPECT_NE(err.find("[error]"), std::string::npos) << "an authentication failure is an error";
}

}  // namespace
}  // namespace telex::test
