// SPDX-License-Identifier: MIT
// The daemons as processes for integration tests.
#include "daemons.h"

#include <signal.h>

#include <chrono>

#include "test_support.h"

namespace telex::test {

namespace {
std::vector<std::string> remote_argv(std::uint16_t port, std::vector<std::string> extra) {
  std::vector<std::string> a{built_binary("telex-remote").string(), "--listen",
                             "127.0.0.1:" + std::to_string(port)};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}
}  // namespace

RemoteProcess::RemoteProcess(const std::filesystem::path& dir, std::vector<std::string> extra)
    : port(free_port()),
      proc(remote_argv(port, std::move(extra)), dir / "remote.out", dir / "remote.err") {}

RemoteProcess::~RemoteProcess() {
  proc.signal(SIGINT);
  proc.wait(std::chrono::seconds(5));
}

std::vector<std::string> local_args(std::uint16_t port, const std::filesystem::path& dir,
                                    std::vector<std::string> extra) {
  std::vector<std::string> a{built_binary("telex-local").string(),
                             "--connect",
                             "127.0.0.1:" + std::to_string(port),
                             "--haptics",
                             "sim",
                             "--log-forces",
                             (dir / "forces.csv").string(),
                             "--json-summary",
                             "--no-realtime",
                             "--stale-limit",
                             "1.0"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

nlohmann::json summary_of(const Process& p) {
  const std::string out = p.stdout_text();
  const auto brace = out.rfind('{');
  if (brace == std::string::npos) return {};
  return nlohmann::json::parse(out.substr(brace), nullptr, false);
}

}  // namespace telex::test
