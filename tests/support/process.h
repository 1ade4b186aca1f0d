// SPDX-License-Identifier: MIT
// Child processes for integration tests: spawn built daemons, signal them, wait with a bound.
#pragma once

#include <netinet/in.h>
#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace telex::test {

class Process {
 public:
  // Starts argv[0] (a path) with stdout and stderr redirected to files. Throws on failure.
  Process(const std::vector<std::string>& argv, const std::filesystem::path& stdout_path,
          const std::filesystem::path& stderr_path);
  ~Process();  // SIGKILLs and reaps a child still running
  Process(Process&& other) noexcept;
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  bool running();
  void signal(int sig);
  // Exit code (128 + signal when killed by one), or nothing when it is still running after timeout.
  std::optional<int> wait(std::chrono::milliseconds timeout);
  std::string stdout_text() const;
  std::string stderr_text() const;

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
  std::filesystem::path out_, err_;
};

// A fresh empty directory under the build tree for one test's files, private to this process and
// this test (<build>/test-scratch/pid-N/<Suite.Test>/<name>); removed at exit when all passed.
std::filesystem::path scratch_dir(const std::string& name);
// A file's path in this test's own folder (the same folder for every call in one test, never
// emptied by this call): for helpers that make several files in one test and read them back.
std::filesystem::path scratch_file(const std::string& name);
// A port nobody listens on right now (bound once with port 0, then released).
std::uint16_t free_port();
std::string read_text(const std::filesystem::path& p);

// A daemon's CSV log (--log-forces, --log-tracking, display CSVs): the header line and each later
// line split at commas (the logs hold no quoted fields). A missing file reads as empty.
struct CsvFile {
  std::string header;
  std::vector<std::vector<std::string>> rows;
};
CsvFile read_csv_file(const std::filesystem::path& p);
// 127.0.0.1:port as a socket address.
sockaddr_in loopback_address(std::uint16_t port);
// A socket of `type` bound to an ephemeral loopback port, which it writes to `port`.
int bound_socket(int type, std::uint16_t& port);
// Hostile-peer helpers: connect to 127.0.0.1:port over TCP, write `bytes`, close (failures are
// ignored: a daemon may reset a hostile peer); or send one UDP datagram there.
void tcp_blurt(std::uint16_t port, const std::vector<std::uint8_t>& bytes);
void udp_blurt(std::uint16_t port, const std::vector<std::uint8_t>& bytes);
// A spoofing sender: from a socket bound to `from_address` (another loopback address, e.g.
// 127.0.0.2), sends each datagram to 127.0.0.1:port. Returns how many were sent; throws when the
// address cannot be bound.
std::size_t udp_send_from(const std::string& from_address, std::uint16_t port,
                          const std::vector<std::vector<std::uint8_t>>& datagrams);
// A built program (test::built_binary) run with `args` to its end (at most 60 s; exit_code -1 if
// it did not end), its output kept in this test's folder.
struct Outcome {
  int exit_code = -1;
  std::string out, err;
};
Outcome run(const std::string& binary, const std::vector<std::string>& args);
// Polls `pred` every 20 ms until it holds or the timeout passes.
bool eventually(std::chrono::milliseconds timeout, const std::function<bool()>& pred);

}  // namespace telex::test
