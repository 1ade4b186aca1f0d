// SPDX-License-Identifier: MIT
// The simulated display (sim_display.h).
#include "sim_display.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <vector>

#include "telex/base/periodic.h"

namespace telex::local {

namespace {

struct SimRecord {
  std::int64_t t_ns = 0;
  std::array<FingerForce, 5> by_finger{};
};

// Keeps what a display would have rendered. With a CSV path, records go through a single-producer
// single-consumer ring (allocated once) to a writer thread, so write() costs a copy and two atomic
// operations; a full ring drops the record and counts it.
class SimDisplay final : public HapticDisplay {
 public:
  SimDisplay(std::string csv_path, std::size_t capacity)
      : path_(std::move(csv_path)), ring_(path_.empty() ? 0 : std::max<std::size_t>(capacity, 2)) {
    if (!path_.empty()) {
      file_ = std::fopen(path_.c_str(), "w");
      if (file_ == nullptr)
        throw std::runtime_error("sim display: cannot write CSV " + path_ + ": " +
                                 std::strerror(errno) + " (check the directory exists)");
      std::fputs("time_ns", file_);
      for (const char* f : {"thumb", "index", "middle", "ring", "little"})
        std::fprintf(file_, ",%s_pressure_N,%s_shear_N,%s_contact", f, f, f);
      std::fputc('\n', file_);
      thread_ = std::thread([this] { fault_.run([this] { drain_loop(); }); });
    }
  }
  ~SimDisplay() override {
    if (file_ != nullptr) {
      stop_ = true;
      thread_.join();
      drain();
      if (std::fclose(file_) != 0) ++counters_.errors;
    }
    spdlog::info(
        "{}: {} writes, {} recorded, {} dropped, max pressure {:.3f} N, max shear {:.3f} N", name(),
        counters_.writes.load(), counters_.sent.load(), counters_.dropped.load(),
        counters_.max_pressure_N.load(), counters_.max_shear_N.load());
  }

  void write(std::int64_t now_ns, std::span<const FingerForce> forces) override {
    ++counters_.writes;
    SimRecord rec;
    rec.t_ns = now_ns;
    for (int i = 0; i < 5; ++i) rec.by_finger[i].finger = i;
    for (const FingerForce& f : forces) {
      if (f.finger < 0 || f.finger > 4) continue;
      rec.by_finger[f.finger] = f;
      if (std::isfinite(f.pressure_N) &&
          f.pressure_N > counters_.max_pressure_N.load(std::memory_order_relaxed))
        counters_.max_pressure_N.store(f.pressure_N, std::memory_order_relaxed);
      if (std::isfinite(f.shear_N) &&
          std::abs(f.shear_N) > counters_.max_shear_N.load(std::memory_order_relaxed))
        counters_.max_shear_N.store(std::abs(f.shear_N), std::memory_order_relaxed);
    }
    if (ring_.empty()) {
      ++counters_.sent;
      return;
    }
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= ring_.size()) {
      ++counters_.dropped;
      return;
    }
    ring_[head % ring_.size()] = rec;
    head_.store(head + 1, std::memory_order_release);
  }

  std::string name() const override { return path_.empty() ? "sim" : "sim:" + path_; }
  DisplayStats stats() const override { return counters_.snapshot(); }
  std::optional<ThreadFaultReport> thread_fault() const override { return fault_.report(); }

 private:
  void drain_loop() {
    while (!stop_) {
      drain();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  void drain() {
    std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t head = head_.load(std::memory_order_acquire);
    for (; tail != head; ++tail) {
      const SimRecord& r = ring_[tail % ring_.size()];
      std::fprintf(file_, "%lld", static_cast<long long>(r.t_ns));
      for (const FingerForce& f : r.by_finger)
        std::fprintf(file_, ",%.6f,%.6f,%d", f.pressure_N, f.shear_N, f.contact ? 1 : 0);
      if (std::fputc('\n', file_) == EOF) ++counters_.errors;
      ++counters_.sent;
      tail_.store(tail + 1, std::memory_order_release);
    }
    std::fflush(file_);
  }

  std::string path_;
  std::vector<SimRecord> ring_;
  std::atomic<std::size_t> head_{0}, tail_{0};
  std::FILE* file_ = nullptr;
  std::atomic<bool> stop_{false};
  ThreadFault fault_{"display writer (sim)"};
  std::thread thread_;
  DisplayCounters counters_;
};

}  // namespace

std::unique_ptr<HapticDisplay> open_sim_display(const std::string& csv_path,
                                                std::size_t ring_capacity) {
  return std::make_unique<SimDisplay>(csv_path, ring_capacity);
}

}  // namespace telex::local
