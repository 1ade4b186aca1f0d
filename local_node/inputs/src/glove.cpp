// SPDX-License-Identifier: MIT
// 5DT gloves: report parsing, calibration, and the hidapi / termios readers on their own threads.
#include "telex/local/inputs/glove.h"

#include <fcntl.h>
#include <hidapi.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace telex::local {

std::span<const GloveProduct> glove_products() {
  // vrpn_Analog_5dtUSB.C lists these ids (its vrpn_5DT_DATAGLOVE14_* / DATAGLOVE5_* comments) and
  // the masks that decode them: 0x0001 left, 0x0010 five sensors, 0x0002 / 0x0006 wireless port.
  static constexpr GloveProduct kTable[] = {
      {0x00, GloveModel::Sensors14, false, "wired USB"},
      {0x01, GloveModel::Sensors14, true, "wired USB"},
      {0x02, GloveModel::Sensors14, false, "wireless port A"},
      {0x03, GloveModel::Sensors14, true, "wireless port A"},
      {0x06, GloveModel::Sensors14, false, "wireless port B"},
      {0x07, GloveModel::Sensors14, true, "wireless port B"},
      {0x10, GloveModel::Sensors5Right, false, "wired USB"},
      {0x11, GloveModel::Sensors5Left, true, "wired USB"},
      {0x12, GloveModel::Sensors5Right, false, "wireless port A"},
      {0x13, GloveModel::Sensors5Left, true, "wireless port A"},
      {0x16, GloveModel::Sensors5Right, false, "wireless port B"},
      {0x17, GloveModel::Sensors5Left, true, "wireless port B"},
  };
  return kTable;
}

const GloveProduct* glove_product(std::uint16_t pid) {
  for (const auto& p : glove_products())
    if (p.product_id == pid) return &p;
  return nullptr;
}

std::optional<GloveModel> glove_model_from_product_id(std::uint16_t pid) {
  if (const GloveProduct* p = glove_product(pid)) return p->model;
  return std::nullopt;
}

int sensor_count(GloveModel model) { return model == GloveModel::Sensors14 ? 14 : 5; }

const char* parse_5dt_usb_report(std::span<const std::uint8_t> report, GloveModel model,
                                 GloveRaw& out) {
  if (model == GloveModel::Serial5) return "serial glove model given to the USB report parser";
  if (report.size() < 32) return "5DT USB report shorter than 16 int16 values (32 bytes)";
  auto value = [&](int i) {
    const auto v = static_cast<std::int16_t>((report[2 * i] << 8) | report[2 * i + 1]);
    return static_cast<double>(v) / 4096.0;
  };
  out = GloveRaw{};
  out.sensor_count = sensor_count(model);
  if (model == GloveModel::Sensors14) {
    for (int i = 0; i < 14; ++i) out.sensors[i] = value(i);
  } else {
    for (int i = 0; i < 5; ++i) out.sensors[i] = value(3 * i);
  }
  return nullptr;
}

std::uint8_t serial_5dt_checksum(std::span<const std::uint8_t, 7> data) {
  unsigned sum = 0;
  for (auto b : data) sum += b;
  return static_cast<std::uint8_t>(sum & 0xFF);
}

const char* parse_5dt_serial_info(std::span<const std::uint8_t> reply, Serial5dtInfo& out) {
  if (reply.size() < 32) return "5DT info reply shorter than 32 bytes";
  if (reply[0] != 'B' || reply[1] != 'R') return "5DT info reply does not start with \"BR\"";
  out = Serial5dtInfo{};
  out.version_major = reply[2];
  out.version_minor = reply[3];
  out.right_hand = (reply[4] & 0x01) != 0;
  out.pitch_roll = (reply[5] & 0x10) != 0;
  for (std::size_t i = 16; i < 32 && reply[i] != 0; ++i)
    out.name.push_back(reply[i] >= 32 && reply[i] < 127 ? static_cast<char>(reply[i]) : '?');
  return nullptr;
}

bool Serial5dtParser::push(std::uint8_t byte, GloveRaw& out) {
  if (have_ == 0 && byte != k5dtSerialHeader) {
    ++skipped_;
    return false;
  }
  buf_[have_++] = byte;
  const std::size_t size = wireless_ ? k5dtWirelessReportBytes : k5dtSerialReportBytes;
  if (have_ < size) return false;
  // VRPN's checks: the header, and for the wireless glove the capability byte that ends it.
  if (!wireless_ || buf_[9] == 0x40 || buf_[9] == 0x01) {
    const std::span<const std::uint8_t, 7> data(buf_.data() + 1, 7);
    if (serial_5dt_checksum(data) != buf_[8]) ++checksum_mismatches_;
    out = GloveRaw{};
    out.sensor_count = 5;
    for (int i = 0; i < 5; ++i) out.sensors[i] = buf_[1 + i] / 255.0;
    out.pitch_deg = 180.0 * buf_[6] / 255.0;
    out.roll_deg = 180.0 * buf_[7] / 255.0;
    have_ = 0;
    return true;
  }
  // Out of step: a data byte was taken for a header. Restart at the next 0x80 already read.
  ++bad_reports_;
  const auto end = buf_.begin() + static_cast<std::ptrdiff_t>(size);
  const auto next = std::find(buf_.begin() + 1, end, k5dtSerialHeader);
  skipped_ += static_cast<std::uint64_t>(next - buf_.begin());
  have_ = static_cast<std::size_t>(end - next);
  std::copy(next, end, buf_.begin());
  return false;
}

GloveCalibration GloveCalibration::full_range(int n) {
  GloveCalibration c;
  c.sensor_count = n;
  c.min.fill(0.0);
  c.max.fill(1.0);
  return c;
}

GloveCalibration GloveCalibration::empty(int n) {
  GloveCalibration c;
  c.sensor_count = n;
  c.min.fill(1e9);
  c.max.fill(-1e9);
  return c;
}

void GloveCalibration::observe(const GloveRaw& raw) {
  for (int i = 0; i < std::min(sensor_count, raw.sensor_count); ++i) {
    min[i] = std::min(min[i], raw.sensors[i]);
    max[i] = std::max(max[i], raw.sensors[i]);
  }
}

GloveCalibration GloveCalibration::load(const std::filesystem::path& path, int n) {
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("glove calibration " + path.string() +
                             ": cannot open (leave the path empty for the full sensor range)");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("glove calibration " + path.string() + ": not JSON: " + e.what());
  }
  GloveCalibration c;
  c.sensor_count = n;
  for (const char* key : {"min", "max"}) {
    if (!j.contains(key) || !j[key].is_array() || j[key].size() != static_cast<std::size_t>(n))
      throw std::runtime_error("glove calibration " + path.string() + ": \"" + key +
                               "\" must be an array of " + std::to_string(n) + " numbers");
    for (int i = 0; i < n; ++i) {
      if (!j[key][i].is_number())
        throw std::runtime_error("glove calibration " + path.string() + ": \"" + key + "\"[" +
                                 std::to_string(i) + "] is not a number");
      (std::string(key) == "min" ? c.min : c.max)[i] = j[key][i].get<double>();
    }
  }
  for (int i = 0; i < n; ++i)
    if (!(c.max[i] > c.min[i]))
      throw std::runtime_error("glove calibration " + path.string() + ": sensor " +
                               std::to_string(i) + " has max <= min");
  return c;
}

GloveCalibration GloveCalibration::from_range(const GloveRange& range, int n,
                                              const std::string& where) {
  if (range.min.size() != static_cast<std::size_t>(n) || range.max.size() != range.min.size())
    throw std::runtime_error(where + " holds " + std::to_string(range.min.size()) +
                             " sensors but the glove has " + std::to_string(n) +
                             " (recalibrate it with this glove: telex calibrate glove)");
  GloveCalibration c;
  c.sensor_count = n;
  for (int i = 0; i < n; ++i) {
    c.min[static_cast<std::size_t>(i)] = range.min[static_cast<std::size_t>(i)];
    c.max[static_cast<std::size_t>(i)] = range.max[static_cast<std::size_t>(i)];
    if (!(c.max[static_cast<std::size_t>(i)] > c.min[static_cast<std::size_t>(i)]))
      throw std::runtime_error(where + ": sensor " + std::to_string(i) + " has max <= min");
  }
  return c;
}

void GloveCalibration::save(const std::filesystem::path& path) const {
  nlohmann::json j;
  j["min"] = std::vector<double>(min.begin(), min.begin() + sensor_count);
  j["max"] = std::vector<double>(max.begin(), max.begin() + sensor_count);
  std::ofstream out(path);
  if (!out) throw std::runtime_error("glove calibration " + path.string() + ": cannot write");
  out << j.dump(2) << "\n";
}

namespace {

// One sensor's reading scaled into [0, 1] by its flat and fist values (0 for a dead range).
double normalised(const GloveRaw& raw, const GloveCalibration& cal, int i) {
  const double range = cal.max[i] - cal.min[i];
  if (!(range > 0.0)) return 0.0;
  return std::clamp((raw.sensors[i] - cal.min[i]) / range, 0.0, 1.0);
}

// The 14-sensor glove's knuckle (near) sensor per finger; the next one is the middle joint's.
constexpr int kNearSensor[5] = {0, 3, 6, 9, 12};

}  // namespace

std::array<double, 5> finger_bends(const GloveRaw& raw, const GloveCalibration& cal) {
  const JointBends joints = joint_bends(raw, cal);
  std::array<double, 5> bend{};
  // A 14-sensor glove's finger bend is the mean of its two joints; a 5-sensor glove's is its one.
  for (std::size_t f = 0; f < 5; ++f) bend[f] = 0.5 * (joints[f][0] + joints[f][1]);
  return bend;
}

JointBends joint_bends(const GloveRaw& raw, const GloveCalibration& cal) {
  JointBends out{};
  for (int f = 0; f < 5; ++f) {
    if (raw.sensor_count == 14) {
      const double near = normalised(raw, cal, kNearSensor[f]);
      const double far = normalised(raw, cal, kNearSensor[f] + 1);
      out[static_cast<std::size_t>(f)] = {near, far, far};
    } else {
      const double b = normalised(raw, cal, f);
      out[static_cast<std::size_t>(f)] = {b, b, b};
    }
  }
  return out;
}

GloveDevice::~GloveDevice() = default;

std::optional<ThreadFaultReport> GloveDevice::thread_fault() const {
  auto r = fault_.report();
  if (r) r->thread = "glove (" + name() + ")";
  return r;
}

void GloveDevice::publish(const GloveRaw& raw) {
  GloveSample s;
  s.bend = finger_bends(raw, calibration_);
  s.joints = joint_bends(raw, calibration_);
  s.received_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now().time_since_epoch())
                      .count();
  samples_.publish(s);
  ++reports_;
}

namespace {

GloveCalibration calibration_for(const std::string& path, const std::optional<GloveRange>& range,
                                 int n) {
  if (!path.empty()) return GloveCalibration::load(path, n);
  if (range) return GloveCalibration::from_range(*range, n, "the rig's glove range");
  return GloveCalibration::full_range(n);
}

class Usb5dtGlove final : public GloveDevice {
 public:
  Usb5dtGlove(const std::string& path, const std::string& calibration_path,
              const std::optional<GloveRange>& range) {
    if (hid_init() != 0) throw std::runtime_error("5DT USB glove: hidapi failed to initialise");
    hid_device_info* list = hid_enumerate(k5dtVendorId, 0);
    std::optional<GloveModel> model;
    std::string chosen;
    for (hid_device_info* d = list; d != nullptr; d = d->next) {
      const auto m = glove_model_from_product_id(d->product_id);
      if (!m) continue;
      if (path.empty() || path == d->path) {
        model = m;
        chosen = d->path;
        break;
      }
    }
    hid_free_enumeration(list);
    if (!model) {
      throw std::runtime_error(
          path.empty()
              ? "5DT USB glove: no HID device with vendor 0x5D70 and a glove product id "
                "(0x00-0x03, 0x06, 0x07, 0x10-0x13, 0x16, 0x17) found. Is it plugged in (lsusb | "
                "grep 5d70)? Can your "
                "user read /dev/hidraw* (udev rule, docs/HARDWARE.md)? Or name the glove: "
                "5dt-usb:/dev/hidrawN, or a serial one: 5dt-serial:/dev/ttyUSB0."
              : "5DT USB glove: cannot open " + path +
                    ": no 5DT glove (vendor 0x5D70) at that HID path. Check it exists (ls -l " +
                    path +
                    "), its permissions (udev rule, docs/HARDWARE.md), or omit the path "
                    "to take the first glove found.");
    }
    model_ = *model;
    name_ = "5dt-usb:" + chosen;
    dev_ = hid_open_path(chosen.c_str());
    if (dev_ == nullptr)
      throw std::runtime_error("5DT USB glove: found at " + chosen +
                               " but cannot open it (permissions? see the udev rule in "
                               "docs/HARDWARE.md)");
    calibration_ = calibration_for(calibration_path, range, sensor_count(model_));
    thread_ = std::thread([this] { fault_.run([this] { run(); }); });
  }
  ~Usb5dtGlove() override {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    hid_close(dev_);
  }
  std::string name() const override { return name_; }

 private:
  void run() {
    std::array<std::uint8_t, k5dtUsbReportBytes> buf{};
    GloveRaw raw;
    while (!stop_) {
      const int n = hid_read_timeout(dev_, buf.data(), buf.size(), 100);
      if (n < 0) {
        ++read_errors_;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        continue;
      }
      if (n == 0) continue;
      if (parse_5dt_usb_report(std::span(buf.data(), static_cast<std::size_t>(n)), model_, raw) !=
          nullptr) {
        ++bad_reports_;
        continue;
      }
      publish(raw);
    }
  }
  hid_device* dev_ = nullptr;
  GloveModel model_ = GloveModel::Sensors14;
  std::string name_;
};

class Serial5dtGlove final : public GloveDevice {
 public:
  Serial5dtGlove(const std::string& dev, bool wireless, const std::string& calibration_path,
                 const std::optional<GloveRange>& range)
      : dev_(dev), wireless_(wireless), parser_(wireless) {
    fd_ = ::open(dev.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (fd_ < 0)
      throw std::runtime_error("5DT serial glove: cannot open " + dev + ": " +
                               std::strerror(errno) +
                               ". Check the device path (ls /dev/ttyUSB* /dev/ttyS*), that your "
                               "user is in the dialout group, or use 5dt-usb.");
    termios tio{};
    if (tcgetattr(fd_, &tio) != 0) {
      const std::string why = std::strerror(errno);
      ::close(fd_);
      throw std::runtime_error("5DT serial glove: " + dev + " is not a serial port: " + why);
    }
    // VRPN: 19200 baud for the wired glove, 9600 for the wireless one; 8N1.
    const speed_t baud = wireless ? B9600 : B19200;
    cfmakeraw(&tio);
    cfsetispeed(&tio, baud);
    cfsetospeed(&tio, baud);
    tio.c_cflag &= ~static_cast<tcflag_t>(PARENB | CSTOPB | CSIZE);
    tio.c_cflag |= CS8 | CLOCAL | CREAD;
    tcsetattr(fd_, TCSANOW, &tio);
    try {
      if (!wireless) handshake();  // the wireless glove only sends
    } catch (...) {
      ::close(fd_);
      throw;
    }
    calibration_ = calibration_for(calibration_path, range, 5);
    thread_ = std::thread([this] { fault_.run([this] { run(); }); });
  }
  ~Serial5dtGlove() override {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    ::close(fd_);
  }
  std::string name() const override {
    return "5dt-serial:" + dev_ + (wireless_ ? ",wireless" : "") +
           (info_.name.empty() ? "" : " (" + info_.name + ")");
  }

 private:
  // Reads exactly n bytes or gives up after `timeout_ms`.
  std::size_t read_exactly(std::uint8_t* out, std::size_t n, int timeout_ms) {
    std::size_t got = 0;
    const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
    while (got < n) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
                            until - std::chrono::steady_clock::now())
                            .count();
      if (left <= 0) break;
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, static_cast<int>(left)) <= 0) continue;
      const ssize_t r = ::read(fd_, out + got, n - got);
      if (r > 0) got += static_cast<std::size_t>(r);
    }
    return got;
  }
  void command(char c) {
    tcflush(fd_, TCIFLUSH);
    if (::write(fd_, &c, 1) != 1)
      throw std::runtime_error("5DT serial glove on " + dev_ + ": cannot write the '" +
                               std::string(1, c) + "' command: " + std::strerror(errno));
  }
  // vrpn_Analog_5dt.C's reset(): 'A' answers 'U' (0x55), 'G' answers the 32-byte info, then 'D'
  // starts the stream.
  void handshake() {
    std::array<std::uint8_t, 32> reply{};
    command('A');
    if (read_exactly(reply.data(), 1, 2000) != 1 || reply[0] != 0x55)
      throw std::runtime_error(
          "5DT serial glove on " + dev_ +
          ": no answer to the reset command 'A' within 2 s (expected 0x55). Is the glove "
          "powered and on this port? A wireless 5-W glove needs 5dt-serial:" +
          dev_ + ",wireless.");
    command('G');
    const std::size_t n = read_exactly(reply.data(), reply.size(), 2000);
    if (const char* why = parse_5dt_serial_info(std::span(reply.data(), n), info_))
      throw std::runtime_error("5DT serial glove on " + dev_ + ": bad reply to 'G' (" + why + ", " +
                               std::to_string(n) + " bytes)");
    command('D');
  }
  void run() {
    std::array<std::uint8_t, 256> buf{};
    GloveRaw raw;
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      const ssize_t n = ::read(fd_, buf.data(), buf.size());
      if (n < 0) {
        if (errno != EAGAIN && errno != EINTR) ++read_errors_;
        continue;
      }
      const auto bad_before = parser_.bad_reports();
      for (ssize_t i = 0; i < n; ++i)
        if (parser_.push(buf[static_cast<std::size_t>(i)], raw)) publish(raw);
      bad_reports_ += parser_.bad_reports() - bad_before;
    }
  }
  std::string dev_;
  bool wireless_ = false;
  int fd_ = -1;
  Serial5dtInfo info_;
  Serial5dtParser parser_;
};

}  // namespace

namespace {

struct GloveSpec {
  bool serial = false;
  std::string path;  // the HID path (empty: the first glove) or the serial device
  bool wireless = false;
};

GloveSpec parse_glove_spec(const std::string& spec) {
  if (spec == "5dt-usb") return {};
  if (spec.rfind("5dt-usb:", 0) == 0) return {false, spec.substr(8), false};
  if (spec.rfind("5dt-serial:", 0) == 0 && spec.size() > 11) {
    GloveSpec g{true, spec.substr(11), false};
    if (const auto comma = g.path.find(','); comma != std::string::npos) {
      if (g.path.substr(comma + 1) != "wireless" || comma == 0)
        throw std::invalid_argument("glove spec '" + spec +
                                    "': expected 5dt-serial:DEV or 5dt-serial:DEV,wireless");
      g.wireless = true;
      g.path.resize(comma);
    }
    return g;
  }
  throw std::invalid_argument(
      "glove spec '" + spec +
      "' is not one of 5dt-usb, 5dt-usb:HIDPATH, 5dt-serial:DEV, 5dt-serial:DEV,wireless");
}

}  // namespace

void check_glove_spec(const std::string& spec) { parse_glove_spec(spec); }

std::unique_ptr<GloveDevice> open_glove(const std::string& spec,
                                        const std::string& calibration_path,
                                        const std::optional<GloveRange>& range) {
  const GloveSpec g = parse_glove_spec(spec);
  if (g.serial)
    return std::make_unique<Serial5dtGlove>(g.path, g.wireless, calibration_path, range);
  return std::make_unique<Usb5dtGlove>(g.path, calibration_path, range);
}

}  // namespace telex::local
