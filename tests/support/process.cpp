// SPDX-License-Identifier: MIT
// Child processes for integration tests.
#include "process.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "test_support.h"

extern char** environ;

namespace telex::test {

Process::Process(const std::vector<std::string>& argv, const std::filesystem::path& stdout_path,
                 const std::filesystem::path& stderr_path)
    : out_(stdout_path), err_(stderr_path) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  const int rc = posix_spawn(&pid_, args[0], &fa, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
}

Process::Process(Process&& o) noexcept
    : pid_(o.pid_), status_(o.status_), out_(std::move(o.out_)), err_(std::move(o.err_)) {
  o.pid_ = -1;
}

Process::~Process() {
  if (pid_ > 0 && !status_) {
    ::kill(pid_, SIGKILL);
    int st = 0;
    waitpid(pid_, &st, 0);
  }
}

bool Process::running() { return !wait(std::chrono::milliseconds(0)).has_value(); }

void Process::signal(int sig) {
  if (pid_ > 0 && !status_) ::kill(pid_, sig);
}

std::optional<int> Process::wait(std::chrono::milliseconds timeout) {
  if (status_) return status_;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    int st = 0;
    const pid_t r = waitpid(pid_, &st, WNOHANG);
    if (r == pid_) {
      status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
      return status_;
    }
    if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

std::string Process::stdout_text() const { return read_text(out_); }
std::string Process::stderr_text() const { return read_text(err_); }

namespace {
// This process's scratch root: ctest runs every test as its own process, several at once, so a
// folder shared by name between two tests (or two runs of one) would let one delete or read the
// other's files.
const std::filesystem::path& process_scratch_root() {
  static const std::filesystem::path root = std::filesystem::path(TELEX_BINARY_DIR) /
                                            "test-scratch" / ("pid-" + std::to_string(getpid()));
  return root;
}

// Removes this process's scratch root when every test in it passed (a failure keeps its files).
class ScratchCleanup : public ::testing::Environment {
 public:
  void TearDown() override {
    if (!::testing::UnitTest::GetInstance()->Passed()) return;
    std::error_code ec;
    std::filesystem::remove_all(process_scratch_root(), ec);
  }
};
[[maybe_unused]] const auto* const kScratchCleanup =
    ::testing::AddGlobalTestEnvironment(new ScratchCleanup);

// Per process and per test: <build>/test-scratch/pid-N/<Suite.Test>.
std::filesystem::path test_scratch_root() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string test = info != nullptr
                         ? std::string(info->test_suite_name()) + "." + std::string(info->name())
                         : std::string("outside-a-test");
  std::replace(test.begin(), test.end(), '/', '_');  // parameterised tests: Suite/Test/0
  return process_scratch_root() / test;
}
}  // namespace

std::filesystem::path scratch_file(const std::string& name) {
  const auto p = test_scratch_root() / "files" / name;
  std::filesystem::create_directories(p.parent_path());
  return p;
}

std::filesystem::path scratch_dir(const std::string& name) {
  const auto p = test_scratch_root() / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

std::uint16_t free_port() {
  // A port free for both TCP and UDP: the daemons use the same number for both.
  for (int attempt = 0; attempt < 50; ++attempt) {
    const int t = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t len = sizeof a;
    bind(t, reinterpret_cast<sockaddr*>(&a), sizeof a);
    getsockname(t, reinterpret_cast<sockaddr*>(&a), &len);
    const int u = socket(AF_INET, SOCK_DGRAM, 0);
    const bool udp_ok = bind(u, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(u);
    close(t);
    if (udp_ok) return ntohs(a.sin_port);
  }
  throw std::runtime_error("no free port found");
}

sockaddr_in loopback_address(std::uint16_t port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  return a;
}

int bound_socket(int type, std::uint16_t& port) {
  const int fd = socket(AF_INET, type, 0);
  sockaddr_in a = loopback_address(0);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  port = ntohs(a.sin_port);
  return fd;
}

void tcp_blurt(std::uint16_t port, const std::vector<std::uint8_t>& bytes) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  const sockaddr_in a = loopback_address(port);
  if (connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0)
    (void)!send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
  close(fd);
}

void udp_blurt(std::uint16_t port, const std::vector<std::uint8_t>& bytes) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  const sockaddr_in a = loopback_address(port);
  sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&a), sizeof a);
  close(fd);
}

std::size_t udp_send_from(const std::string& from_address, std::uint16_t port,
                          const std::vector<std::vector<std::uint8_t>>& datagrams) {
  const int fd = socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in from{};
  from.sin_family = AF_INET;
  if (fd < 0 || inet_pton(AF_INET, from_address.c_str(), &from.sin_addr) != 1 ||
      bind(fd, reinterpret_cast<const sockaddr*>(&from), sizeof from) != 0) {
    const std::string why = std::strerror(errno);
    if (fd >= 0) close(fd);
    throw std::runtime_error("cannot bind a UDP socket to " + from_address + ": " + why);
  }
  const sockaddr_in to = loopback_address(port);
  std::size_t sent = 0;
  for (const auto& d : datagrams)
    if (sendto(fd, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to) ==
        static_cast<ssize_t>(d.size()))
      ++sent;
  close(fd);
  return sent;
}

std::string read_text(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

bool eventually(std::chrono::milliseconds timeout, const std::function<bool()>& pred) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return pred();
}

CsvFile read_csv_file(const std::filesystem::path& p) {
  CsvFile csv;
  std::istringstream in(read_text(p));
  std::getline(in, csv.header);
  for (std::string line; std::getline(in, line);) {
    auto& f = csv.rows.emplace_back();
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
  }
  return csv;
}

Outcome run(const std::string& binary, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {built_binary(binary).string()};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, scratch_file("out.txt"), scratch_file("err.txt"));
  const auto rc = p.wait(std::chrono::seconds(60));
  return {rc.value_or(-1), p.stdout_text(), p.stderr_text()};
}

}  // namespace telex::test
