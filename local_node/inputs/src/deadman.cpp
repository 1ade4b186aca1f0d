// SPDX-License-Identifier: MIT
// --deadman: the spec, evdev's input_event records and HID reports to a pressed state, and the
// two devices (a Linux event device through its ioctls, a HID device through hidapi).
#include "telex/local/inputs/deadman.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <hidapi.h>
#include <linux/input.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "telex/base/byte_cursor.h"
#include "telex/local/displays/hid.h"

namespace telex::local {

static_assert(sizeof(input_event) == kInputEventBytes,
              "input_event is 24 bytes on the 64-bit Linux this reads");

namespace {

struct NamedKey {
  const char* name;
  std::uint16_t code;
};
// Keys a dead-man is likely to be: a keyboard's big keys, a foot pedal's (they send a configured
// key, often a letter or a mouse button), a joystick's trigger.
constexpr NamedKey kKeys[] = {
    {"KEY_SPACE", KEY_SPACE},
    {"KEY_ENTER", KEY_ENTER},
    {"KEY_LEFTCTRL", KEY_LEFTCTRL},
    {"KEY_RIGHTCTRL", KEY_RIGHTCTRL},
    {"KEY_LEFTSHIFT", KEY_LEFTSHIFT},
    {"KEY_RIGHTSHIFT", KEY_RIGHTSHIFT},
    {"KEY_LEFTALT", KEY_LEFTALT},
    {"KEY_RIGHTALT", KEY_RIGHTALT},
    {"KEY_A", KEY_A},
    {"KEY_B", KEY_B},
    {"KEY_C", KEY_C},
    {"KEY_D", KEY_D},
    {"KEY_E", KEY_E},
    {"KEY_F", KEY_F},
    {"KEY_G", KEY_G},
    {"KEY_H", KEY_H},
    {"KEY_I", KEY_I},
    {"KEY_J", KEY_J},
    {"KEY_K", KEY_K},
    {"KEY_L", KEY_L},
    {"KEY_M", KEY_M},
    {"KEY_N", KEY_N},
    {"KEY_O", KEY_O},
    {"KEY_P", KEY_P},
    {"KEY_Q", KEY_Q},
    {"KEY_R", KEY_R},
    {"KEY_S", KEY_S},
    {"KEY_T", KEY_T},
    {"KEY_U", KEY_U},
    {"KEY_V", KEY_V},
    {"KEY_W", KEY_W},
    {"KEY_X", KEY_X},
    {"KEY_Y", KEY_Y},
    {"KEY_Z", KEY_Z},
    {"KEY_F1", KEY_F1},
    {"KEY_F2", KEY_F2},
    {"KEY_F3", KEY_F3},
    {"KEY_F4", KEY_F4},
    {"KEY_F5", KEY_F5},
    {"KEY_F6", KEY_F6},
    {"KEY_F7", KEY_F7},
    {"KEY_F8", KEY_F8},
    {"KEY_F9", KEY_F9},
    {"KEY_F10", KEY_F10},
    {"KEY_F11", KEY_F11},
    {"KEY_F12", KEY_F12},
    {"BTN_LEFT", BTN_LEFT},
    {"BTN_RIGHT", BTN_RIGHT},
    {"BTN_MIDDLE", BTN_MIDDLE},
    {"BTN_0", BTN_0},
    {"BTN_1", BTN_1},
    {"BTN_2", BTN_2},
    {"BTN_TRIGGER", BTN_TRIGGER},
    {"BTN_THUMB", BTN_THUMB},
};

template <typename T>
bool parse_number(std::string_view s, T& v, int base = 10) {
  if (s.empty()) return false;
  if (base == 0) {
    base = 10;
    if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
      s.remove_prefix(2);
      base = 16;
    }
  }
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v, base);
  return r.ec == std::errc{} && r.ptr == s.data() + s.size();
}

std::vector<std::string_view> split(std::string_view text, char sep) {
  std::vector<std::string_view> out;
  while (true) {
    const auto at = text.find(sep);
    out.push_back(text.substr(0, at));
    if (at == std::string_view::npos) return out;
    text.remove_prefix(at + 1);
  }
}

}  // namespace

std::optional<std::uint16_t> evdev_key_code(std::string_view name) {
  for (const NamedKey& k : kKeys)
    if (name == k.name) return k.code;
  std::uint16_t code = 0;
  if (parse_number(name, code, 0) && code > 0 && code <= KEY_MAX) return code;
  return std::nullopt;
}

DeadmanSpec parse_deadman_spec(std::string_view text) {
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument(
        fmt::format("--deadman '{}': {} (valid: {})", text, why, kDeadmanSpecForms));
  };
  DeadmanSpec s;
  const auto colon = text.find(':');
  if (colon == std::string_view::npos) throw bad("no device: expected evdev:PATH or hid:VID:PID");
  const std::string_view kind = text.substr(0, colon);
  const std::vector<std::string_view> parts = split(text.substr(colon + 1), ',');
  if (kind == "evdev") {
    s.kind = DeadmanSpec::Kind::Evdev;
    s.path = std::string(parts[0]);
    if (s.path.empty() || s.path.front() != '/')
      throw bad("evdev needs the device's path, e.g. evdev:/dev/input/event3");
    bool key_given = false;
    for (std::size_t i = 1; i < parts.size(); ++i) {
      const std::string_view p = parts[i];
      if (p.rfind("key=", 0) != 0) throw bad(fmt::format("unknown evdev option '{}'", p));
      if (key_given) throw bad("key= is given twice");
      key_given = true;
      const auto code = evdev_key_code(p.substr(4));
      if (!code)
        throw bad(
            fmt::format("unknown key '{}': a name as linux/input-event-codes.h spells it "
                        "(KEY_SPACE, KEY_B, BTN_LEFT, ...) or a code 1..{}",
                        p.substr(4), KEY_MAX));
      s.key = *code;
    }
    return s;
  }
  if (kind == "hid") {
    s.kind = DeadmanSpec::Kind::Hid;
    const auto ids = split(parts[0], ':');
    if (ids.size() != 2 || ids[0].size() > 4 || ids[1].size() > 4 ||
        !parse_number(ids[0], s.vendor_id, 16) || !parse_number(ids[1], s.product_id, 16))
      throw bad("hid needs the USB ids VID:PID in hex, e.g. hid:0c45:7403 (lsusb lists them)");
    bool byte_given = false, mask_given = false;
    for (std::size_t i = 1; i < parts.size(); ++i) {
      const std::string_view p = parts[i];
      if (p.rfind("byte=", 0) == 0 && !byte_given) {
        byte_given = true;
        if (!parse_number(p.substr(5), s.byte) || s.byte > 63)
          throw bad(fmt::format("byte '{}' is not a report byte 0..63", p.substr(5)));
      } else if (p.rfind("mask=", 0) == 0 && !mask_given) {
        mask_given = true;
        if (!parse_number(p.substr(5), s.mask, 0) || s.mask == 0)
          throw bad(fmt::format("mask '{}' is not a bit mask 1..255 (0x01..0xff)", p.substr(5)));
      } else {
        throw bad(fmt::format("unknown or repeated hid option '{}'", p));
      }
    }
    return s;
  }
  throw bad(fmt::format("unknown kind '{}'", kind));
}

void EvdevKeyDecoder::feed(std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    const std::size_t take = std::min(bytes.size(), kInputEventBytes - have_);
    std::memcpy(partial_.data() + have_, bytes.data(), take);
    have_ += take;
    bytes = bytes.subspan(take);
    if (have_ < kInputEventBytes) return;
    have_ = 0;
    ++records_;
    // After the 16-byte timeval: u16 type, u16 code, s32 value, in the host's (little) endian.
    ByteReader r(std::span<const std::uint8_t>(partial_).subspan(16));
    const std::uint16_t type = r.u16();
    const std::uint16_t code = r.u16();
    const auto value = static_cast<std::int32_t>(r.u32());
    if (type != EV_KEY || code != key_) continue;
    ++key_records_;
    pressed_ = value != 0;  // 1 press, 2 autorepeat, 0 release
  }
}

std::optional<bool> hid_report_pressed(std::span<const std::uint8_t> report, std::size_t byte,
                                       std::uint8_t mask) {
  if (byte >= report.size()) return std::nullopt;
  return (report[byte] & mask) != 0;
}

namespace {

proto::DeadmanState state_of(bool pressed) {
  return pressed ? proto::DeadmanState::Pressed : proto::DeadmanState::Released;
}

// A Linux event device, opened non-blocking; its key's state from EVIOCGKEY at open, then from the
// EV_KEY records read at each poll.
class EvdevDeadman final : public DeadmanInput {
 public:
  explicit EvdevDeadman(const DeadmanSpec& spec) : spec_(spec), decoder_(spec.key, false) {
    fd_ = ::open(spec.path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      const int e = errno;
      throw std::runtime_error(fmt::format(
          "--deadman evdev:{}: {}. {}", spec.path, std::strerror(e),
          e == ENOENT ? "List the input devices with `ls -l /dev/input/by-id/` (a foot pedal shows "
                        "as a keyboard, *-event-kbd) or `cat /proc/bus/input/devices`, and give "
                        "its /dev/input/eventN"
          : e == EACCES || e == EPERM
              ? "Event devices are readable by the input group: `sudo usermod -aG input $USER` "
                "and log in again, or add a udev rule for the device"
              : "Check the path names an input event device (/dev/input/eventN)"));
    }
    std::array<unsigned long, KEY_MAX / (8 * sizeof(unsigned long)) + 1> keys{};
    if (::ioctl(fd_, EVIOCGBIT(EV_KEY, sizeof keys), keys.data()) < 0) {
      const int e = errno;
      ::close(fd_);
      throw std::runtime_error(fmt::format(
          "--deadman evdev:{}: not an input event device ({}); give a /dev/input/eventN "
          "(`ls -l /dev/input/by-id/`)",
          spec.path, std::strerror(e)));
    }
    const auto has = [&](std::uint16_t code) {
      const std::size_t bits = 8 * sizeof(unsigned long);
      return ((keys[code / bits] >> (code % bits)) & 1UL) != 0;
    };
    if (!has(spec.key)) {
      ::close(fd_);
      throw std::runtime_error(fmt::format(
          "--deadman evdev:{}: the device has no key code {}; pick its key with key=NAME (`evtest "
          "{}` shows what the pedal or key sends)",
          spec.path, spec.key, spec.path));
    }
    char name[256] = {};
    if (::ioctl(fd_, EVIOCGNAME(sizeof name - 1), name) < 0) name[0] = 0;
    name_ = fmt::format("evdev:{} ({}) key {}", spec.path, name[0] ? name : "no name", spec.key);
    // The key's state now: held before the station started counts as held.
    std::array<unsigned long, KEY_MAX / (8 * sizeof(unsigned long)) + 1> down{};
    if (::ioctl(fd_, EVIOCGKEY(sizeof down), down.data()) >= 0) {
      const std::size_t bits = 8 * sizeof(unsigned long);
      decoder_ = EvdevKeyDecoder(spec.key, ((down[spec.key / bits] >> (spec.key % bits)) & 1) != 0);
    }
  }
  ~EvdevDeadman() override {
    if (fd_ >= 0) ::close(fd_);
  }

  proto::DeadmanState poll() override {
    ++stats_.polls;
    const bool before = decoder_.pressed();
    if (!failed_) {
      std::array<std::uint8_t, 64 * kInputEventBytes> buf{};
      while (true) {
        const ssize_t n = ::read(fd_, buf.data(), buf.size());
        if (n > 0) {
          decoder_.feed(std::span(buf.data(), static_cast<std::size_t>(n)));
          continue;
        }
        if (n < 0 && errno == EINTR) continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        // ENODEV when unplugged, 0 at an end: the pedal is gone, so it is not held.
        failed_ = true;
        ++stats_.errors;
        stats_.last_error = n < 0 ? std::strerror(errno) : "end of file";
        break;
      }
    }
    const bool pressed = !failed_ && decoder_.pressed();
    if (pressed != before) ++stats_.changes;
    if (failed_) decoder_ = EvdevKeyDecoder(spec_.key, false);
    return state_of(pressed);
  }
  std::string name() const override { return name_; }
  DeadmanStats stats() const override { return stats_; }

 private:
  DeadmanSpec spec_;
  int fd_ = -1;
  EvdevKeyDecoder decoder_;
  bool failed_ = false;
  std::string name_;
  DeadmanStats stats_;
};

// A HID device through hidapi (hidraw), non-blocking reads of its input reports.
class HidDeadman final : public DeadmanInput {
 public:
  explicit HidDeadman(const DeadmanSpec& spec) : spec_(spec) {
    if (hid_init() != 0) throw std::runtime_error("--deadman hid: hidapi failed to initialise");
    std::string path, seen;
    for (const HidCandidate& c : enumerate_hid()) {
      if (c.vendor_id == spec.vendor_id && c.product_id == spec.product_id && path.empty())
        path = c.path;
      seen += fmt::format("{}{:04x}:{:04x} ({})", seen.empty() ? "" : ", ", c.vendor_id,
                          c.product_id, c.product.empty() ? "no name" : c.product);
    }
    if (path.empty())
      throw std::runtime_error(fmt::format(
          "--deadman hid:{:04x}:{:04x}: no such HID device among the {} hidapi sees. Is the pedal "
          "plugged in (lsusb -d {:04x}:{:04x})? May your user read its /dev/hidraw* (a udev rule "
          "with MODE=\"0660\", GROUP=\"plugdev\")? A pedal that acts as a keyboard is read with "
          "evdev:/dev/input/eventN instead.",
          spec.vendor_id, spec.product_id, seen.empty() ? "none" : seen, spec.vendor_id,
          spec.product_id));
    dev_ = hid_open_path(path.c_str());
    if (dev_ == nullptr)
      throw std::runtime_error(fmt::format(
          "--deadman hid:{:04x}:{:04x}: {} cannot be opened (permissions: a udev rule for the "
          "device, or the plugdev group)",
          spec.vendor_id, spec.product_id, path));
    hid_set_nonblocking(dev_, 1);
    name_ = fmt::format("hid:{:04x}:{:04x} {} byte {} mask 0x{:02x}", spec.vendor_id,
                        spec.product_id, path, spec.byte, spec.mask);
  }
  ~HidDeadman() override {
    if (dev_ != nullptr) hid_close(dev_);
  }

  // Released until the first report says otherwise: a pedal reports when it changes.
  proto::DeadmanState poll() override {
    ++stats_.polls;
    const bool before = pressed_;
    while (!failed_) {
      std::array<std::uint8_t, 64> report{};
      const int n = hid_read(dev_, report.data(), report.size());
      if (n == 0) break;
      if (n < 0) {
        failed_ = true;
        ++stats_.errors;
        stats_.last_error = "hid_read failed (unplugged?)";
        break;
      }
      if (const auto p = hid_report_pressed(std::span(report.data(), static_cast<std::size_t>(n)),
                                            spec_.byte, spec_.mask))
        pressed_ = *p;
    }
    if (failed_) pressed_ = false;
    if (pressed_ != before) ++stats_.changes;
    return state_of(pressed_);
  }
  std::string name() const override { return name_; }
  DeadmanStats stats() const override { return stats_; }

 private:
  DeadmanSpec spec_;
  hid_device* dev_ = nullptr;
  bool pressed_ = false;
  bool failed_ = false;
  std::string name_;
  DeadmanStats stats_;
};

}  // namespace

std::unique_ptr<DeadmanInput> open_deadman(const DeadmanSpec& spec) {
  if (spec.kind == DeadmanSpec::Kind::Hid) return std::make_unique<HidDeadman>(spec);
  return std::make_unique<EvdevDeadman>(spec);
}

}  // namespace telex::local
