// SPDX-License-Identifier: MIT
#include "telex/devices/devices.h"

#include <libusb.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "telex/local/displays/hid.h"
#include "telex/local/inputs/glove.h"

namespace telex::devices {

const std::vector<KnownDevice>& known_devices() {
  static const std::vector<KnownDevice> table = [] {
    std::vector<KnownDevice> t{
        // libfreenect, src/freenect_internal.h (VID_MICROSOFT, PID_NUI_*, PID_K4W_*).
        {0x045e, 0x02ae, "Kinect for Xbox 360 camera", "--source freenect (issue 14) or openni"},
        {0x045e, 0x02bf, "Kinect for Windows camera", "--source freenect (issue 14) or openni"},
        {0x045e, 0x02b0, "Kinect for Xbox 360 motor", "tilt motor; not used"},
        {0x045e, 0x02ad, "Kinect for Xbox 360 audio", "microphones; not used"},
        {0x045e, 0x02be, "Kinect for Windows audio", "microphones; not used"},
        // OpenNI2's PS1080 driver opens PrimeSense's vendor id; its device URIs are
        // "1d27/PRODUCT@BUS/ADDRESS" (Carmine 1.08/1.09, Asus Xtion, PrimeSensor).
        {0x1d27, std::nullopt, "PrimeSense PS1080 sensor (Carmine, Xtion)", "--source openni"},
    };
    // The 5DT gloves this project reads (local_node/inputs/src/glove.cpp,
    // glove_model_from_product_id).
    for (const auto& p : local::glove_products())
      t.push_back({local::k5dtVendorId, p.product_id,
                   "5DT Data Glove " + std::to_string(local::sensor_count(p.model)) + " Ultra (" +
                       (p.left_hand ? "left, " : "right, ") + p.link + ")",
                   "--glove 5dt-usb"});
    return t;
  }();
  return table;
}

KnownDevice parse_known_device(std::string_view text) {
  const auto bad = [&] {
    return std::invalid_argument(
        "device id '" + std::string(text) +
        "': expected VID:PID=NAME with hex ids, e.g. 16c0:05df=controller");
  };
  const auto colon = text.find(':'), eq = text.find('=');
  if (colon == std::string_view::npos || eq == std::string_view::npos || eq < colon ||
      eq + 1 == text.size())
    throw bad();
  const auto hex = [&](std::string_view s) {
    unsigned v = 0;
    const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v, 16);
    if (s.empty() || s.size() > 4 || ec != std::errc() || p != s.data() + s.size()) throw bad();
    return static_cast<std::uint16_t>(v);
  };
  return {hex(text.substr(0, colon)), hex(text.substr(colon + 1, eq - colon - 1)),
          std::string(text.substr(eq + 1)), "named by --usb-id"};
}

std::optional<KnownDevice> identify(std::uint16_t vendor_id, std::uint16_t product_id,
                                    const std::vector<KnownDevice>& extra) {
  for (const bool exact : {true, false})
    for (const auto* table : {&extra, &known_devices()})
      for (const auto& d : *table)
        if (d.vendor_id == vendor_id && (exact ? d.product_id == product_id : !d.product_id))
          return d;
  return std::nullopt;
}

UsbScan scan_usb(const std::vector<KnownDevice>& extra) {
  UsbScan scan;
  libusb_context* ctx = nullptr;
  if (const int rc = libusb_init(&ctx); rc != 0) {
    scan.error = std::string("libusb: ") + libusb_strerror(static_cast<libusb_error>(rc)) +
                 " (no USB bus visible: /dev/bus/usb is missing in containers and VMs without "
                 "USB passthrough)";
    return scan;
  }
  libusb_device** list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  if (n < 0) {
    scan.error = std::string("libusb: ") + libusb_strerror(static_cast<libusb_error>(n));
  } else {
    scan.available = true;
    for (ssize_t i = 0; i < n; ++i) {
      libusb_device_descriptor d{};
      if (libusb_get_device_descriptor(list[i], &d) != 0) continue;
      UsbDevice u;
      u.bus = libusb_get_bus_number(list[i]);
      u.address = libusb_get_device_address(list[i]);
      u.vendor_id = d.idVendor;
      u.product_id = d.idProduct;
      u.known = identify(d.idVendor, d.idProduct, extra);
      scan.devices.push_back(u);
    }
    libusb_free_device_list(list, 1);
  }
  libusb_exit(ctx);
  std::sort(scan.devices.begin(), scan.devices.end(), [](const auto& a, const auto& b) {
    return std::tie(a.bus, a.address) < std::tie(b.bus, b.address);
  });
  return scan;
}

std::vector<HidDevice> scan_hid(const std::vector<KnownDevice>& extra) {
  std::vector<HidDevice> out;
  for (auto& c : local::enumerate_hid())
    out.push_back({std::move(c.path), c.vendor_id, c.product_id, std::move(c.manufacturer),
                   std::move(c.product), std::move(c.serial),
                   identify(c.vendor_id, c.product_id, extra)});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.path < b.path; });
  return out;
}

std::vector<std::string> scan_serial(const std::string& dev_dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dev_dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("ttyUSB", 0) == 0 || name.rfind("ttyACM", 0) == 0) out.push_back(e.path());
  }
  for (const auto& e :
       std::filesystem::directory_iterator(std::filesystem::path(dev_dir) / "serial/by-id", ec))
    out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace telex::devices
