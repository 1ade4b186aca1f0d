// SPDX-License-Identifier: MIT
#include "driver_child.h"

#include <dlfcn.h>
#include <execinfo.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <ucontext.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <exception>
#include <sstream>

namespace telex::test {

namespace {

int g_report_fd = -1;

// The C and C++ runtime: a crash in memcpy or in an allocator is charged to its caller.
bool runtime_object(const char* path) {
  if (!path || !*path) return false;
  const char* base = std::strrchr(path, '/');
  base = base ? base + 1 : path;
  for (const char* prefix :
       {"libc.so", "libc-", "libstdc++", "libgcc_s", "libm.so", "libm-", "ld-linux", "libpthread",
        "linux-vdso", "libasan", "libubsan", "libtsan"})
    if (std::strncmp(base, prefix, std::strlen(prefix)) == 0) return true;
  return false;
}

const char* object_of(void* pc) {
  Dl_info info{};
  if (pc && dladdr(pc, &info) && info.dli_fname) return info.dli_fname;
  return nullptr;
}

void write_all(const char* text) {
  std::size_t left = std::strlen(text);
  while (left > 0) {
    const ssize_t n = ::write(g_report_fd, text, left);
    if (n <= 0) return;
    text += n;
    left -= static_cast<std::size_t>(n);
  }
}

void* faulting_pc(void* context) {
  auto* uc = static_cast<ucontext_t*>(context);
#if defined(__x86_64__)
  return reinterpret_cast<void*>(uc->uc_mcontext.gregs[REG_RIP]);
#elif defined(__aarch64__)
  return reinterpret_cast<void*>(uc->uc_mcontext.pc);
#else
  (void)uc;
  return nullptr;
#endif
}

// The child is dying: dladdr and backtrace are not async-signal-safe, but backtrace was warmed
// up before the body ran and nothing else runs in this process's signal path.
void on_crash(int sig, siginfo_t*, void* context) {
  void* pc = faulting_pc(context);
  void* frames[64];
  const int n = backtrace(frames, 64);
  // Walk outwards from the faulting instruction (the frames above it are this handler's).
  int start = n;
  for (int i = 0; i < n; ++i)
    if (frames[i] == pc) {
      start = i;
      break;
    }
  const char* object = object_of(pc);
  if (!object || runtime_object(object)) {
    for (int i = start + 1; i < n; ++i) {
      const char* o = object_of(frames[i]);
      if (o && !runtime_object(o)) {
        object = o;
        break;
      }
    }
  }
  char line[512];
  std::snprintf(line, sizeof line, "crash %d %s\n", sig, object && *object ? object : "unknown");
  write_all(line);
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

class FailureToPipe : public ::testing::EmptyTestEventListener {
  void OnTestPartResult(const ::testing::TestPartResult& r) override {
    if (r.failed()) write_all("failure\n");
  }
};

}  // namespace

std::string ChildRun::describe() const {
  std::ostringstream s;
  switch (end) {
    case ChildEnd::Passed:
      return "passed";
    case ChildEnd::Failed:
      s << "failed";
      if (signal) s << " (then died from signal " << signal << ")";
      return s.str();
    case ChildEnd::CrashedInDriver:
    case ChildEnd::CrashedElsewhere:
      s << "signal " << signal << " (" << strsignal(signal) << ") in " << crash_object;
      return s.str();
  }
  return "?";
}

ChildRun run_in_child(const std::function<void()>& body, const std::string& driver_marker) {
  ChildRun run;
  int fds[2];
  if (::pipe(fds) != 0) {
    ADD_FAILURE() << "pipe failed";
    return run;
  }
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ADD_FAILURE() << "fork failed";
    return run;
  }
  if (pid == 0) {
    ::close(fds[0]);
    g_report_fd = fds[1];
    void* warm[4];
    backtrace(warm, 4);  // loads libgcc's unwinder before any crash
    static char alt_stack[64 * 1024];
    stack_t ss{};
    ss.ss_sp = alt_stack;
    ss.ss_size = sizeof alt_stack;
    sigaltstack(&ss, nullptr);
    struct sigaction sa {};
    sa.sa_sigaction = on_crash;
    sa.sa_flags = SA_SIGINFO | SA_ONSTACK;
    sigemptyset(&sa.sa_mask);
    for (int sig : {SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT}) sigaction(sig, &sa, nullptr);
    ::testing::UnitTest::GetInstance()->listeners().Append(new FailureToPipe);
    // The child must never return into gtest, which would run the rest of the suite in it.
    try {
      body();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "the test body threw: " << e.what();
    } catch (...) {
      ADD_FAILURE() << "the test body threw a non-standard exception";
    }
    std::fflush(nullptr);
    ::_exit(::testing::Test::HasFailure() ? 1 : 0);
  }
  ::close(fds[1]);
  std::string report;
  char buf[512];
  for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) != 0;) {
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    report.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  const bool failed = report.find("failure\n") != std::string::npos;
  if (WIFEXITED(status)) {
    run.end = WEXITSTATUS(status) == 0 && !failed ? ChildEnd::Passed : ChildEnd::Failed;
    return run;
  }
  run.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  const auto at = report.find("crash ");
  if (at != std::string::npos) {
    std::istringstream in(report.substr(at + 6));
    int sig = 0;
    in >> sig >> run.crash_object;
  } else {
    run.crash_object = "unknown (no report: killed, not crashed)";
  }
  if (failed)
    run.end = ChildEnd::Failed;
  else if (!driver_marker.empty() && run.crash_object.find(driver_marker) != std::string::npos)
    run.end = ChildEnd::CrashedInDriver;
  else
    run.end = ChildEnd::CrashedElsewhere;
  return run;
}

void run_driver_test(const std::function<void()>& body) {
  // libOpenNI2.so and the drivers it loads from .../OpenNI2/Drivers/.
  for (int retries = 0;; ++retries) {
    const ChildRun r = run_in_child(body, "OpenNI2");
    ::testing::Test::RecordProperty("driver_crash_retries", retries);
    switch (r.end) {
      case ChildEnd::Passed:
        return;
      case ChildEnd::Failed:
        ADD_FAILURE() << "the test body " << r.describe() << " (its messages are above)";
        return;
      case ChildEnd::CrashedElsewhere:
        ADD_FAILURE() << "the test body crashed outside the driver, not retried: " << r.describe();
        return;
      case ChildEnd::CrashedInDriver:
        break;
    }
    ::testing::Test::RecordProperty("driver_crash_" + std::to_string(retries + 1), r.describe());
    std::printf("[ driver crash ] %s (retry %d of at most %d)\n", r.describe().c_str(), retries + 1,
                kMaxDriverRetries);
    if (retries + 1 > kMaxDriverRetries) {
      ADD_FAILURE() << "the driver crashed " << retries + 1 << " times, more than "
                    << kMaxDriverRetries << " retry allows: " << r.describe();
      return;
    }
  }
}

}  // namespace telex::test
