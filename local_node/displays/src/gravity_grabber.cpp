// SPDX-License-Identifier: MIT
// Gravity Grabber motor mapping, HID report encoding, and the hidapi display with a writer thread.
#include "telex/local/displays/gravity_grabber.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <hidapi.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>
#include <utility>

#include "telex/base/demand.h"
#include "telex/base/periodic.h"
#include "telex/base/triple_buffer.h"

namespace telex::local {

GravityGrabberConfig GravityGrabberConfig::load(const std::filesystem::path& path) {
  const std::string where = "Gravity Grabber config " + path.string();
  std::ifstream in(path);
  if (!in) throw std::runtime_error(where + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(where + ": not JSON: " + e.what());
  }
  return from_json(j, where);
}

GravityGrabberConfig GravityGrabberConfig::from_json(const nlohmann::json& j,
                                                     const std::string& where) {
  if (!j.is_object()) throw std::runtime_error(where + ": expected a JSON object");
  GravityGrabberConfig c;
  auto number = [&](const nlohmann::json& o, const std::string& key, double lo, double hi,
                    double& v) {
    if (!o.contains(key)) return;
    if (!o[key].is_number() || o[key].get<double>() < lo || o[key].get<double>() > hi)
      throw std::runtime_error(where + ": \"" + key + "\" must be a number in [" +
                               std::to_string(lo) + ", " + std::to_string(hi) + "]");
    v = o[key].get<double>();
  };
  for (const auto& [key, value] : j.items()) {
    if (key != "max_pressure_N" && key != "max_shear_N" && key != "max_command" &&
        key != "report_id" && key != "fingers")
      throw std::runtime_error(where + ": unknown key \"" + key + "\"");
  }
  number(j, "max_pressure_N", 1e-3, 100.0, c.max_pressure_N);
  number(j, "max_shear_N", 1e-3, 100.0, c.max_shear_N);
  number(j, "max_command", 0.0, 1.0, c.max_command);
  double report_id = c.report_id;
  number(j, "report_id", 0, 255, report_id);
  c.report_id = static_cast<std::uint8_t>(report_id);
  if (j.contains("fingers")) {
    if (!j["fingers"].is_array())
      throw std::runtime_error(where + ": \"fingers\" must be an array of objects");
    for (const auto& f : j["fingers"]) {
      if (!f.is_object() || !f.contains("finger") || !f["finger"].is_number_integer() ||
          f["finger"].get<int>() < 0 || f["finger"].get<int>() > 4)
        throw std::runtime_error(where + ": each \"fingers\" entry needs \"finger\": 0..4");
      auto& g = c.fingers[f["finger"].get<int>()];
      for (const auto& [key, value] : f.items())
        if (key != "finger" && key != "enabled" && key != "gain_pressure" && key != "gain_shear" &&
            key != "motor_a_sign" && key != "motor_b_sign" && key != "dead_zone")
          throw std::runtime_error(where + ": unknown finger key \"" + key + "\"");
      if (f.contains("enabled")) {
        if (!f["enabled"].is_boolean())
          throw std::runtime_error(where + ": \"enabled\" must be true or false");
        g.enabled = f["enabled"].get<bool>();
      }
      number(f, "gain_pressure", 0.0, 10.0, g.gain_pressure);
      number(f, "gain_shear", 0.0, 10.0, g.gain_shear);
      number(f, "dead_zone", 0.0, 0.5, g.dead_zone);
      for (const char* key : {"motor_a_sign", "motor_b_sign"}) {
        if (!f.contains(key)) continue;
        if (!f[key].is_number_integer() || std::abs(f[key].get<int>()) != 1)
          throw std::runtime_error(where + ": \"" + key + "\" must be 1 or -1");
        (std::string(key) == "motor_a_sign" ? g.motor_a_sign : g.motor_b_sign) = f[key].get<int>();
      }
    }
  }
  return c;
}

std::array<double, 10> gravity_grabber_motors(std::span<const FingerForce> forces,
                                              const GravityGrabberConfig& cfg) {
  std::array<double, 10> m{};
  for (const FingerForce& f : forces) {
    if (f.finger < 0 || f.finger > 4 || !f.contact) continue;
    const GravityGrabberFinger& g = cfg.fingers[f.finger];
    if (!g.enabled) continue;
    // NaN forces (a bug upstream) must not reach a motor.
    const double p_N = std::isfinite(f.pressure_N) ? f.pressure_N : 0.0;
    const double s_N = std::isfinite(f.shear_N) ? f.shear_N : 0.0;
    const double p = g.gain_pressure * std::clamp(p_N / cfg.max_pressure_N, 0.0, 1.0);
    const double s = g.gain_shear * std::clamp(s_N / cfg.max_shear_N, -1.0, 1.0);
    double a = s + p, b = s - p;
    const double peak = std::max(std::abs(a), std::abs(b));
    if (peak > cfg.max_command && peak > 0.0) {
      a *= cfg.max_command / peak;
      b *= cfg.max_command / peak;
    }
    // Dead-zone compensation: a non-zero command starts where the motor starts turning.
    auto comp = [&](double c) {
      if (c == 0.0) return 0.0;
      return std::copysign(g.dead_zone + (1.0 - g.dead_zone) * std::abs(c), c);
    };
    m[2 * f.finger] = g.motor_a_sign * comp(a);
    m[2 * f.finger + 1] = g.motor_b_sign * comp(b);
  }
  return m;
}

std::array<std::uint8_t, kGravityGrabberReportBytes> gravity_grabber_report(
    std::span<const FingerForce> forces, const GravityGrabberConfig& cfg, std::uint8_t sequence) {
  std::array<std::uint8_t, kGravityGrabberReportBytes> r{};
  r[0] = cfg.report_id;
  r[1] = sequence;
  std::uint8_t flags = 0;
  for (const FingerForce& f : forces)
    if (f.contact && f.finger >= 0 && f.finger <= 4 && cfg.fingers[f.finger].enabled)
      flags |= static_cast<std::uint8_t>(1u << (f.finger + 1));
  if (flags != 0) flags |= 1;  // bit 0: motors enabled
  r[2] = flags;
  const auto m = gravity_grabber_motors(forces, cfg);
  for (int i = 0; i < 10; ++i) {
    const auto v = static_cast<std::int16_t>(std::lround(std::clamp(m[i], -1.0, 1.0) * 32767.0));
    const auto u = static_cast<std::uint16_t>(v);
    r[3 + 2 * i] = static_cast<std::uint8_t>(u & 0xFF);
    r[4 + 2 * i] = static_cast<std::uint8_t>(u >> 8);
  }
  unsigned sum = 0;
  for (int i = 1; i <= 22; ++i) sum += r[i];
  r[23] = static_cast<std::uint8_t>(sum & 0xFF);
  return r;
}

HidTarget parse_hid_target(std::string_view text) {
  const auto bad = [&] {
    return std::invalid_argument(fmt::format(
        "Gravity Grabber device '{}': expected a hidraw path (/dev/hidraw3) or the controller's "
        "USB ids VID:PID[:SERIAL] in hex (e.g. 16c0:05df)",
        text));
  };
  HidTarget t;
  if (text.empty()) throw bad();
  if (text.front() == '/') {
    t.path = std::string(text);
    return t;
  }
  const auto hex16 = [&](std::string_view s, std::uint16_t& v) {
    if (s.empty() || s.size() > 4) return false;
    const auto r = std::from_chars(s.data(), s.data() + s.size(), v, 16);
    return r.ec == std::errc{} && r.ptr == s.data() + s.size();
  };
  const auto c1 = text.find(':');
  if (c1 == std::string_view::npos) throw bad();
  const auto c2 = text.find(':', c1 + 1);
  const std::string_view pid =
      text.substr(c1 + 1, c2 == std::string_view::npos ? std::string_view::npos : c2 - c1 - 1);
  if (!hex16(text.substr(0, c1), t.vendor_id) || !hex16(pid, t.product_id)) throw bad();
  if (c2 != std::string_view::npos) {
    t.serial = std::string(text.substr(c2 + 1));
    if (t.serial.empty()) throw bad();
  }
  return t;
}

std::optional<std::string> choose_hid_device(const HidTarget& target,
                                             std::span<const HidCandidate> candidates) {
  for (const auto& c : candidates) {
    if (!target.by_ids()) {
      if (c.path == target.path) return c.path;
      continue;
    }
    if (c.vendor_id == target.vendor_id && c.product_id == target.product_id &&
        (target.serial.empty() || c.serial == target.serial))
      return c.path;
  }
  return std::nullopt;
}

HidReportWriter::~HidReportWriter() = default;

const GravityGrabberReport& GravityGrabberKeepAlive::fresh(std::int64_t now_ns,
                                                           const GravityGrabberReport& report) {
  last_ = report;
  written_ns_ = sent_ns_ = now_ns;
  holding_ = true;
  return last_;
}

const GravityGrabberReport* GravityGrabberKeepAlive::idle(std::int64_t now_ns) {
  if (!holding_ || now_ns - sent_ns_ < timing_.keepalive_period_ns) return nullptr;
  sent_ns_ = now_ns;
  if (now_ns - written_ns_ < timing_.hold_ns) return &last_;
  // The haptic thread stopped writing: release the belts rather than keep a stale force alive.
  holding_ = false;
  last_ = gravity_grabber_report({}, config_, static_cast<std::uint8_t>(last_[1] + 1));
  return &last_;
}

namespace {

// Resolves a VID:PID target to the hidraw path hidapi reports for it; a path target stays as is.
std::string resolve(const HidTarget& t) {
  if (!t.by_ids()) return t.path;
  const auto found = enumerate_hid();
  if (const auto path = choose_hid_device(t, found)) return *path;
  std::string seen;
  for (const auto& c : found)
    seen += fmt::format("{}{:04x}:{:04x} {} ({})", seen.empty() ? "" : ", ", c.vendor_id,
                        c.product_id, c.path, c.product.empty() ? "no name" : c.product);
  throw std::runtime_error(fmt::format(
      "Gravity Grabber: no HID device {:04x}:{:04x}{}{} among the {} hidapi enumerates ({}). Is "
      "the controller plugged in (lsusb -d {:04x}:{:04x}), may your user read it (udev rule in "
      "docs/HARDWARE.md), or run without hardware with --haptics sim or udp:HOST:PORT.",
      t.vendor_id, t.product_id, t.serial.empty() ? "" : " with serial ", t.serial, found.size(),
      seen.empty() ? "none" : seen, t.vendor_id, t.product_id));
}

std::string cannot_open(const std::string& path) {
  return "Gravity Grabber: cannot open HID device " + path +
         ". Check that it exists (ls -l /dev/hidraw*; the device's hidraw node appears when it is "
         "plugged in), that your user may write it (udev rule in docs/HARDWARE.md), or run "
         "without hardware with --haptics sim or udp:HOST:PORT.";
}

struct Report {
  GravityGrabberReport bytes;
};

// hidapi's handle on the device (hidraw backend: a write() of the report on the node).
class HidapiWriter final : public HidReportWriter {
 public:
  explicit HidapiWriter(std::string path) : path_(std::move(path)) {
    dev_ = hid_open_path(path_.c_str());
    if (dev_ == nullptr) throw std::runtime_error(cannot_open(path_));
  }
  ~HidapiWriter() override { hid_close(dev_); }
  int write(std::span<const std::uint8_t> report) override {
    return hid_write(dev_, report.data(), report.size());
  }
  std::string name() const override { return path_; }

 private:
  std::string path_;
  hid_device* dev_ = nullptr;
};

class GravityGrabberDisplay final : public HapticDisplay {
 public:
  GravityGrabberDisplay(std::unique_ptr<HidReportWriter> writer, const GravityGrabberConfig& cfg,
                        GravityGrabberTiming timing)
      : cfg_(cfg), writer_(std::move(writer)), keepalive_(cfg, timing) {
    thread_ = std::thread([this] { fault_.run([this] { run(); }); });
  }
  ~GravityGrabberDisplay() override {
    // Release the belts before closing: a stuck pressure command would keep squeezing.
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    const auto off = gravity_grabber_report({}, cfg_, ++seq_);
    writer_->write(off);
  }
  void write(std::int64_t, std::span<const FingerForce> forces) override {
    ++writes_;
    for (const auto& f : forces) {
      update_max(max_p_, f.pressure_N);
      update_max(max_s_, std::abs(f.shear_N));
    }
    pending_.publish(Report{gravity_grabber_report(forces, cfg_, ++seq_)});
  }
  std::string name() const override { return "gravity-grabber:" + writer_->name(); }
  DisplayStats stats() const override {
    DisplayStats s;
    s.writes = writes_;
    s.sent = sent_;
    s.dropped = pending_.overwritten();
    s.errors = errors_;
    s.max_pressure_N = max_p_;
    s.max_shear_N = max_s_;
    return s;
  }
  std::optional<ThreadFaultReport> thread_fault() const override { return fault_.report(); }

 private:
  static void update_max(std::atomic<double>& m, double v) {
    if (std::isfinite(v) && v > m.load(std::memory_order_relaxed))
      m.store(v, std::memory_order_relaxed);
  }
  void send(const GravityGrabberReport& r) {
    if (writer_->write(r) < 0)
      ++errors_;
    else
      ++sent_;
  }
  void run() {
    Report r;
    while (!stop_) {
      if (pending_.take(r)) {
        send(keepalive_.fresh(monotonic_ns(), r.bytes));
      } else if (const GravityGrabberReport* again = keepalive_.idle(monotonic_ns())) {
        send(*again);
      } else {
        std::this_thread::sleep_for(std::chrono::microseconds(250));
      }
    }
  }
  GravityGrabberConfig cfg_;
  std::unique_ptr<HidReportWriter> writer_;
  GravityGrabberKeepAlive keepalive_;  // writer thread only
  std::uint8_t seq_ = 0;               // haptic thread only
  TripleBuffer<Report> pending_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> writes_{0}, sent_{0}, errors_{0};
  std::atomic<double> max_p_{0.0}, max_s_{0.0};
  ThreadFault fault_{"display writer (gravity-grabber)"};
  std::thread thread_;
};

GravityGrabberConfig load_config(const std::string& config_path, const nlohmann::json& rig_config) {
  return !config_path.empty() ? GravityGrabberConfig::load(config_path)
         : rig_config.is_object()
             ? GravityGrabberConfig::from_json(rig_config, "rig gravity_grabber")
             : GravityGrabberConfig{};
}

HidTarget checked_target(const std::string& target) {
  if (target.empty())
    throw std::invalid_argument(
        "display spec 'gravity-grabber:' needs the HID path or the controller's USB ids, e.g. "
        "gravity-grabber:/dev/hidraw3 or gravity-grabber:16c0:05df");
  return parse_hid_target(target);
}

}  // namespace

std::unique_ptr<HapticDisplay> open_gravity_grabber(const std::string& target,
                                                    const std::string& config_path,
                                                    const nlohmann::json& rig_config) {
  const HidTarget t = checked_target(target);
  const GravityGrabberConfig cfg = load_config(config_path, rig_config);
  if (hid_init() != 0) throw std::runtime_error("Gravity Grabber: hidapi failed to initialise");
  return make_gravity_grabber_display(std::make_unique<HidapiWriter>(resolve(t)), cfg);
}

std::unique_ptr<HapticDisplay> make_gravity_grabber_display(std::unique_ptr<HidReportWriter> writer,
                                                            const GravityGrabberConfig& config,
                                                            GravityGrabberTiming timing) {
  TELEX_DEMAND(writer != nullptr);
  return std::make_unique<GravityGrabberDisplay>(std::move(writer), config, timing);
}

GravityGrabberZero open_gravity_grabber_zero(const std::string& target,
                                             const std::string& config_path,
                                             const nlohmann::json& rig_config) {
  const HidTarget t = checked_target(target);
  GravityGrabberZero z;
  z.report = gravity_grabber_report({}, load_config(config_path, rig_config), 0);
  if (hid_init() != 0) throw std::runtime_error("Gravity Grabber: hidapi failed to initialise");
  z.path = resolve(t);
  // The hidraw backend's hid_write is a write() of the report on the node: the supervisor does
  // the same on its own descriptor, with no library call after the fork.
  z.fd = ::open(z.path.c_str(), O_WRONLY | O_CLOEXEC);
  if (z.fd < 0) throw std::runtime_error(cannot_open(z.path));
  return z;
}

}  // namespace telex::local
